//! Speed of the closed-loop simulation; the target is at least 100x faster than real time.
//!
//! `cargo bench -p simulation --bench sim`
//!
//! * First, outside criterion, one whole default run (`host-sim sim`: the laparoscope
//!   scenario with `host-sim/simulation/default.toml`), printed as its real-time factor and the
//!   wall-clock time per simulated millisecond (= per 1 kHz control tick) of each part:
//!   controller, plant, truth (FK of the plant's joints) and payload mapping, and the rest
//!   (master stream, metrics, trace).
//! * `sim/default_scenario_1s`: a 1-s slice of that run (from 1 s into the 25 mm/s pass,
//!   the fastest motion), the master streaming the path. One element is one simulated
//!   second, so criterion's throughput in elem/s **is the real-time factor**.
//! * `sim/default_run_2_threads`: the whole default run on two threads (the master side
//!   ahead of the drive side, as `host-sim sim` runs it on a 2-core machine); one element
//!   is one simulated millisecond: elem/s in thousands is the real-time factor.
//! * `sim/plant_1ms`: the plant alone per simulated millisecond (10 steps of 100 us), the
//!   duties and joint loads of that slice replayed tick by tick (one element is one
//!   simulated ms: elem/s in thousands is the plant's own real-time factor).
//! * `sim/tick_holding`: one control tick while holding still at the centre with the
//!   tool (supervisor idle, joints held by friction).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use kinematics_core::guards::Limits;
use kinematics_core::{Pose, RsprGeometry};
use plant::NUM_JOINTS;
use simulation::config::SimConfig;
use simulation::engine::Sim;
use simulation::run::run;
use simulation::scenario::Scenario;
use std::hint::black_box;
use trajectory::{Sampler, Stream};

/// The master of `host-sim sim` (simulation::run): the stream sampled as the run samples
/// it, each target handed over once its stamp plus the latency has passed.
struct Master<'a> {
    stream: &'a Stream,
    sampler: Sampler,
}

impl Master<'_> {
    fn send(&mut self, sim: &mut Sim) {
        let t = sim.time_s();
        self.sampler.due(self.stream, t, |ts, p| {
            let _ = sim.submit(&p, (ts * 1e6).round() as u64);
        });
    }
}

fn bench(c: &mut Criterion) {
    let robot = RsprGeometry::<f64>::reference();
    let limits = Limits::<f64>::reference();
    let cfg = SimConfig::builtin().unwrap();
    let scenario = Scenario::from_config("laparoscope", &cfg, robot.hc).unwrap();

    // The whole default run, as `host-sim sim` does it: on one thread and on two (the
    // default on this 2-core machine: the master side runs ahead of the drive side).
    for threads in [1, 2] {
        let out = run(&robot, &limits, &cfg, &scenario, threads, &mut |_, _| {}).unwrap();
        let s = &out.summary;
        let per_ms = 1e-3 / cfg.control_dt();
        let t = &s.timing;
        eprintln!(
            "default run ({}, {} thread(s)): {:.2} s simulated in {:.3} s: {:.0}x real time; \
             per simulated ms: {:.2} us; drive side: controller servo half {:.2} + plant {:.2} \
             + truth and payload {:.2} + other {:.2}; planner (supervisor) {:.2}",
            s.scenario,
            threads,
            s.simulated_s,
            s.wall_s,
            s.speed_up,
            t.per_tick_us * per_ms,
            t.controller_us * per_ms,
            t.plant_us * per_ms,
            t.truth_and_payload_us * per_ms,
            t.other_us * per_ms,
            t.planner_us * per_ms,
        );
    }

    // The slice: the closed loop brought to 1 s into the 25 mm/s pass.
    let pass = scenario
        .phases
        .iter()
        .find(|p| p.speed_mm_s == Some(25.0))
        .expect("a 25 mm/s pass");
    let mut master = Master {
        stream: &scenario.stream,
        sampler: Sampler::new(
            1.0 / cfg.master.stream_rate_hz,
            cfg.master.latency_ms * 1e-3,
        ),
    };
    let mut sim = Sim::new(&robot, &limits, &cfg, &scenario.start, true).unwrap();
    sim.set_payload(cfg.payload.enabled);
    let slice_ticks = (1.0 / cfg.control_dt()).round() as u64;
    let start_tick = ((pass.start_s + 1.0) / cfg.control_dt()).round() as u64;
    while sim.ticks() < start_tick {
        master.send(&mut sim);
        sim.tick().unwrap();
    }
    let (sim_at_slice, sampler_at_slice) = (sim.clone(), master.sampler);

    // Record the slice's duties and loads for the plant alone.
    let mut record: Vec<([f64; NUM_JOINTS], [f64; NUM_JOINTS])> = Vec::new();
    for _ in 0..slice_ticks {
        master.send(&mut sim);
        let s = sim.tick().unwrap();
        record.push((s.duty, s.load));
    }

    let mut group = c.benchmark_group("sim");
    group.throughput(Throughput::Elements(1));
    group.sample_size(20);
    group.bench_function("default_scenario_1s", |b| {
        b.iter_batched(
            || (sim_at_slice.clone(), sampler_at_slice),
            |(mut sim, sampler)| {
                let mut m = Master {
                    stream: &scenario.stream,
                    sampler,
                };
                for _ in 0..slice_ticks {
                    m.send(&mut sim);
                    black_box(sim.tick().unwrap());
                }
                sim
            },
            BatchSize::PerIteration,
        )
    });

    // The whole default run (18.5 s simulated) as `host-sim sim` runs it on this machine:
    // the master side on its own thread. One element is one simulated millisecond, so
    // elem/s in thousands is the real-time factor.
    let simulated_ms = (scenario.duration_s / cfg.control_dt()).round() * cfg.control_dt() * 1e3;
    group.sample_size(10);
    group.throughput(Throughput::Elements(simulated_ms.round() as u64));
    group.bench_function("default_run_2_threads", |b| {
        b.iter(|| black_box(run(&robot, &limits, &cfg, &scenario, 2, &mut |_, _| {}).unwrap()))
    });
    group.throughput(Throughput::Elements(1));

    let plant_at_slice = sim_at_slice.plant().clone();
    let mut plant = plant_at_slice.clone();
    let steps = cfg.control.plant_steps_per_tick;
    let dt = cfg.plant_dt();
    let mut k = 0;
    group.sample_size(100);
    group.bench_function("plant_1ms", |b| {
        b.iter(|| {
            if k == record.len() {
                k = 0;
                plant = plant_at_slice.clone();
            }
            let (duty, load) = record[k];
            plant.set_duty(duty).unwrap();
            plant.set_external_load(load).unwrap();
            for _ in 0..steps {
                plant.step(black_box(dt)).unwrap();
            }
            k += 1;
        })
    });

    let centre = Pose::central(robot.hc);
    let mut idle = Sim::new(&robot, &limits, &cfg, &centre, true).unwrap();
    idle.set_payload(true);
    group.bench_function("tick_holding", |b| {
        b.iter(|| black_box(idle.tick().unwrap()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
