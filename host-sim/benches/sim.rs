//! Speed of the closed-loop simulation: one control tick (controller, 10 plant steps, the
//! true pose and the payload) while following the laparoscope loop at 25 mm/s, and its
//! parts. Real time is 1 ms per tick at 1 kHz: the speed-up is 1 ms over the tick's time.
//!
//! `cargo bench -p host-sim --bench sim`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::sim::config::SimConfig;
use host_sim::sim::engine::{plant_config, Sim};
use host_sim::sim::scenario::{Scenario, Stream};
use kinematics_core::guards::Limits;
use kinematics_core::{Pose, RsprGeometry};
use rspr_plant::Plant;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let robot = RsprGeometry::<f64>::reference();
    let limits = Limits::<f64>::reference();
    let cfg = SimConfig::from_toml_str(
        "[scenario.laparoscope]\npass_speeds_mm_s = [25.0]\npass_scales = [1.0]\n",
    )
    .unwrap();
    let scenario = Scenario::from_config("laparoscope", &cfg, robot.hc).unwrap();
    let Stream::Path(traj) = &scenario.stream else {
        panic!("the laparoscope scenario streams a path")
    };
    let period = traj.end_s();
    let centre = Pose::central(robot.hc);
    let mut group = c.benchmark_group("sim");

    // The whole tick, the master streaming the loop at 1 kHz over and over (the loop
    // starts and ends at rest at the centre).
    let mut sim = Sim::new(&robot, &limits, &cfg, &centre, true).unwrap();
    sim.set_payload(true);
    let mut stamp = 0u64;
    group.bench_function("closed_loop_tick_1khz_25mm_s", |b| {
        b.iter(|| {
            let t = sim.time_s();
            stamp = stamp.max(sim.now_us()) + 1;
            if let Some(p) = traj.pose(t % period) {
                let _ = sim.submit(&p, stamp);
            }
            black_box(sim.tick().unwrap());
        })
    });

    // The plant's share: 10 steps of 100 us at a mid-range duty.
    let mut plant = Plant::new(&plant_config(&cfg).unwrap()).unwrap();
    plant
        .set_duty([0.05, -0.05, 0.02, 0.03, -0.03, 0.01])
        .unwrap();
    group.bench_function("plant_10_steps", |b| {
        b.iter(|| {
            for _ in 0..10 {
                plant.step(black_box(1e-4)).unwrap();
            }
        })
    });

    // A tick while holding still (no target, the supervisor idle).
    let mut idle = Sim::new(&robot, &limits, &cfg, &centre, true).unwrap();
    idle.set_payload(true);
    group.bench_function("closed_loop_tick_holding", |b| {
        b.iter(|| black_box(idle.tick().unwrap()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
