//! One scenario from start to end: the master's stream, the payload, the injected faults,
//! the closed loop and the measurements.

use crate::config::{PayloadUpdate, SimConfig};
use crate::engine::{payload_from_config, EngineError, Sim, TickSample, Timing};
use crate::metrics::{
    edge_pose, AccuracyVerdict, ActuatorSummary, FaultSummary, JointErrorSummary, Metrics,
    PhaseSummary, PoseErrorSummary, Refusals, StepSummary, SupervisorSummary, TickErrors,
};
use crate::scenario::{FaultEvent, Scenario};
use control::{Plan, Planner, ToolLoad};
use kinematics_core::guards::Limits;
use kinematics_core::supervisor::Mode;
use kinematics_core::{Pose, RsprGeometry};
use plant::PlantError;
use serde::Serialize;
use std::time::Instant;
use thiserror::Error;
use trajectory::Sampler;

/// Why a run stopped.
#[derive(Debug, Error)]
pub enum RunError {
    /// The closed loop.
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// A fault of the scenario that the plant refused.
    #[error("fault injection: {0}")]
    Fault(PlantError),
    #[error("sim: cannot start the master thread: {0}")]
    Thread(std::io::Error),
    #[error("sim: the master thread panicked")]
    MasterPanicked,
}

/// What the error figures mean (copied into every summary).
pub const TRACKING_DEFINITION: &str = "true pose (plant load-side joints through FK) at the \
instant the controller reads its encoders, against the supervisor's setpoint of that tick";
/// See [`TRACKING_DEFINITION`].
pub const TARGET_DEFINITION: &str = "the same true pose against the last target the master \
sent (includes the supervisor's rate limiting and its lag behind the stream)";

/// The settings a run used (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RunSettings {
    pub control_rate_hz: f64,
    pub plant_step_us: f64,
    pub leg_backlash_mm: f64,
    pub backlash_compensation: bool,
    pub compensated_leg_backlash_mm: f64,
    pub payload_attached_at_s: Option<f64>,
    pub payload_mass_kg: f64,
    pub payload_lever_mm: [f64; 3],
    /// The wrench the platform exerts on the tool at the start pose: the force, N, and
    /// its moment about o_p, N m, in {0}.
    pub payload_force_n: [f64; 3],
    pub payload_moment_nm: [f64; 3],
    pub payload_update: String,
    pub stream_rate_hz: f64,
    pub latency_ms: f64,
}

/// The definitions of the two pose errors (JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Definitions {
    pub tracking: &'static str,
    pub target: &'static str,
    pub tip: &'static str,
}

/// The JSON summary of a run.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Summary {
    pub scenario: String,
    pub description: String,
    pub settings: RunSettings,
    pub definitions: Definitions,
    pub simulated_s: f64,
    pub control_ticks: u64,
    pub wall_s: f64,
    /// Simulated time over wall-clock time.
    pub speed_up: f64,
    /// Where the wall-clock time went.
    pub timing: TimingSummary,
    pub tracking: PoseErrorSummary,
    pub target: PoseErrorSummary,
    pub joints: Vec<JointErrorSummary>,
    pub phases: Vec<PhaseSummary>,
    pub accuracy: Option<AccuracyVerdict>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<StepSummary>,
    pub actuators: Vec<ActuatorSummary>,
    pub supervisor: SupervisorSummary,
    pub faults: FaultSummary,
}

/// Where the wall-clock time of a run went (JSON), us per control tick.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TimingSummary {
    /// Threads the run used: 1, or 2 with the master side (stream and planner) running
    /// ahead of the drive side (servo half of the controller, plant, truth, metrics).
    pub threads: usize,
    pub per_tick_us: f64,
    /// The controller's servo half: encoders, FK, servo.
    pub controller_us: f64,
    /// The controller's planning half: the supervisor with its guards (on the master
    /// side's thread when `threads` is 2).
    pub planner_us: f64,
    /// The plant's steps of one tick (and the per-step payload mapping in "step" mode).
    pub plant_us: f64,
    /// The true pose (FK of the load-side joints) and the payload mapping.
    pub truth_and_payload_us: f64,
    /// Of `truth_and_payload_us`, the payload mapping alone.
    pub payload_us: f64,
    /// The master stream, metrics and trace (with 2 threads: the drive side's wall-clock
    /// time not in the parts above, waiting for plans included).
    pub other_us: f64,
}

/// One row of the trace (edge units).
#[derive(Clone, Debug, PartialEq)]
pub struct TraceRow {
    pub t_s: f64,
    pub mode: &'static str,
    pub warning: bool,
    pub target: [f64; 6],
    pub setpoint: [f64; 6],
    pub truth: [f64; 6],
    pub tip_error_mm: f64,
    pub orientation_error_deg: f64,
    pub target_tip_error_mm: f64,
    pub target_orientation_error_deg: f64,
    /// True minus setpoint: mm for legs, deg for links.
    pub joint_error: [f64; 6],
    pub duty: [f64; 6],
    pub current_a: [f64; 6],
    /// Joint loads: N for legs, N m for links.
    pub load: [f64; 6],
    /// The controller's measured pose (encoders -> FK; edge units), once it has one: the
    /// scene's `/measured_cp` (not in `trace.csv`).
    pub measured: Option<[f64; 6]>,
    /// The controller's measured joints (SI, q order): the scene's `/measured_js`.
    pub measured_q: [f64; 6],
}

/// A finished run.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub summary: Summary,
    /// Every `output.trace_every_ticks`-th tick.
    pub trace: Vec<TraceRow>,
}

fn mode_name(m: Mode) -> &'static str {
    match m {
        Mode::Holding => "holding",
        Mode::Verifying => "verifying",
        Mode::Moving => "moving",
        Mode::Braking => "braking",
        Mode::Stopped => "stopped",
    }
}

fn us(t: f64) -> u64 {
    (t * 1e6).round().max(0.0) as u64
}

/// The margin of the time comparisons (payload, faults), s.
const EPS: f64 = 1e-9;

/// Ticks per chunk the master side hands over when it runs on its own thread.
const PIPELINE_CHUNK: u64 = 256;
/// Chunks it may run ahead.
const PIPELINE_CHUNKS: usize = 4;

/// What the master side produced for one tick.
#[derive(Clone, Copy, Debug)]
struct Planned {
    plan: Plan<f64>,
    /// The master's own pose at the tick (for the target error and the lag; the last
    /// target sent before the first).
    master: Pose<f64>,
}

/// The master's side of a run: the target stream and the controller's planning half
/// (supervisor), which depends on nothing the plant does.
struct MasterSide<'a> {
    scenario: &'a Scenario,
    planner: Planner<f64, RsprGeometry<f64>>,
    tool: Option<ToolLoad<f64>>,
    dt: f64,
    sampler: Sampler,
    last_target: Pose<f64>,
    attached: bool,
    targets_sent: u64,
    first_refusal: Option<(f64, String)>,
    /// Wall-clock time in the planner, s.
    busy_s: f64,
}

impl<'a> MasterSide<'a> {
    fn new(
        scenario: &'a Scenario,
        cfg: &SimConfig,
        planner: Planner<f64, RsprGeometry<f64>>,
        tool: Option<ToolLoad<f64>>,
        dt: f64,
    ) -> Self {
        MasterSide {
            scenario,
            planner,
            tool,
            dt,
            sampler: Sampler::new(
                1.0 / cfg.master.stream_rate_hz,
                cfg.master.latency_ms * 1e-3,
            ),
            last_target: scenario.start,
            attached: false,
            targets_sent: 0,
            first_refusal: None,
            busy_s: 0.0,
        }
    }

    fn send(&mut self, pose: Pose<f64>, stamp_s: f64, t: f64, now_us: u64) {
        self.targets_sent += 1;
        if let Err(r) = self.planner.submit(&pose, us(stamp_s), now_us) {
            if self.first_refusal.is_none() {
                self.first_refusal = Some((t, r.to_string()));
            }
        }
    }

    /// Tick `tick`: the targets due by then (stamp + latency), the tool, the plan.
    fn step(&mut self, tick: u64) -> Planned {
        // As `Sim::time_s` and `Sim::now_us`.
        let t = tick as f64 * self.dt;
        let now_us = (t * 1e6).round() as u64;
        if let Some(a) = self.scenario.payload_attach_s {
            if !self.attached && t + EPS >= a {
                self.planner.set_tool(self.tool);
                self.attached = true;
            }
        }
        let (mut sampler, scenario) = (self.sampler, self.scenario);
        sampler.due(&scenario.stream, t, |stamp_s, pose| {
            self.send(pose, stamp_s, t, now_us);
            self.last_target = pose;
        });
        self.sampler = sampler;
        let started = Instant::now();
        let plan = self.planner.tick();
        self.busy_s += started.elapsed().as_secs_f64();
        if self.first_refusal.is_none() {
            // Path refusals happen while the supervisor verifies, after the submission.
            if let Some(r) = self.planner.supervisor().last_refusal() {
                self.first_refusal = Some((t, r.to_string()));
            }
        }
        Planned {
            plan,
            master: self
                .scenario
                .stream
                .master_pose(t)
                .unwrap_or(self.last_target),
        }
    }
}

/// The drive side of a run: the payload, the injected faults, the closed loop with the
/// master side's plans, the measurements and the trace.
struct DriveSide<'a> {
    scenario: &'a Scenario,
    sim: Sim,
    metrics: Metrics,
    /// The scenario's faults in time order, and the next one due.
    faults: Vec<FaultEvent>,
    next_fault: usize,
    /// The trace keeps every this many ticks.
    every: u64,
    trace: Vec<TraceRow>,
    total: u64,
    progress: &'a mut dyn FnMut(u64, u64),
}

impl<'a> DriveSide<'a> {
    fn new(
        scenario: &'a Scenario,
        sim: Sim,
        limits: &Limits<f64>,
        cfg: &SimConfig,
        total: u64,
        progress: &'a mut dyn FnMut(u64, u64),
    ) -> Self {
        let mut metrics = Metrics::new(
            sim.control_dt(),
            &scenario.phases,
            &scenario.steps,
            nominal_currents(&sim),
        );
        metrics.set_tip_accel_limit(limits.tip_accel);
        let mut faults = scenario.faults.clone();
        faults.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        let every = u64::from(cfg.output.trace_every_ticks);
        DriveSide {
            scenario,
            sim,
            metrics,
            faults,
            next_fault: 0,
            every,
            trace: Vec::with_capacity((total / every + 1) as usize),
            total,
            progress,
        }
    }

    /// Tick `tick` with the master side's plan for it.
    fn tick(&mut self, tick: u64, planned: &Planned) -> Result<(), RunError> {
        let t = self.sim.time_s();
        self.attach_payload(t);
        self.inject_faults(t)?;
        let s = self.sim.tick_with(&planned.plan)?;
        let e = self.metrics.add(&s, &planned.master);
        if tick.is_multiple_of(self.every) {
            self.trace.push(trace_row(&s, &e, &planned.master));
        }
        if tick.is_multiple_of(500) {
            (self.progress)(tick, self.total);
        }
        Ok(())
    }

    /// The payload goes on at the scenario's time.
    fn attach_payload(&mut self, t: f64) {
        if let Some(a) = self.scenario.payload_attach_s {
            if !self.sim.payload_on() && t + EPS >= a {
                self.sim.set_payload(true);
            }
        }
    }

    /// Injects into the plant every fault due by `t`.
    fn inject_faults(&mut self, t: f64) -> Result<(), RunError> {
        while let Some(f) = self.faults.get(self.next_fault) {
            if f.at_s > t + EPS {
                break;
            }
            self.sim
                .plant_mut()
                .inject(f.joint, f.fault)
                .map_err(RunError::Fault)?;
            self.metrics.injected(t, f.joint, format!("{:?}", f.fault));
            self.next_fault += 1;
        }
        Ok(())
    }
}

/// The nominal currents of the plant's motors in joint order, A.
fn nominal_currents(sim: &Sim) -> [f64; 6] {
    let p = sim.plant().config();
    [
        p.prismatic[0].drive.nominal_current_a,
        p.prismatic[1].drive.nominal_current_a,
        p.prismatic[2].drive.nominal_current_a,
        p.rotary[0].drive.nominal_current_a,
        p.rotary[1].drive.nominal_current_a,
        p.rotary[2].drive.nominal_current_a,
    ]
}

/// The trace's row of a tick.
fn trace_row(s: &TickSample, e: &TickErrors, master: &Pose<f64>) -> TraceRow {
    TraceRow {
        t_s: s.t_s,
        mode: mode_name(s.setpoint.mode),
        warning: s.setpoint.warning,
        target: edge_pose(master),
        setpoint: edge_pose(&s.setpoint.pose),
        truth: edge_pose(&s.true_pose),
        tip_error_mm: e.tracking.0,
        orientation_error_deg: e.tracking.1,
        target_tip_error_mm: e.target.0,
        target_orientation_error_deg: e.target.1,
        joint_error: e.joints,
        duty: s.duty,
        current_a: s.current_a,
        load: s.load,
        measured: s.measured.pose.as_ref().map(edge_pose),
        measured_q: s.measured.q,
    }
}

/// Runs `total` ticks on this thread, the master side's step before each drive tick; the
/// master side at the end.
fn run_serial<'a>(
    mut master: MasterSide<'a>,
    drive: &mut DriveSide<'_>,
    total: u64,
) -> Result<MasterSide<'a>, RunError> {
    for tick in 0..total {
        let planned = master.step(tick);
        drive.tick(tick, &planned)?;
    }
    Ok(master)
}

/// Runs `total` ticks with the master side on a thread of its own, ahead of the drive
/// side on this one by at most [`PIPELINE_CHUNKS`] chunks of [`PIPELINE_CHUNK`] ticks;
/// the master side at the end.
fn run_pipelined<'a>(
    mut master: MasterSide<'a>,
    drive: &mut DriveSide<'_>,
    total: u64,
) -> Result<MasterSide<'a>, RunError> {
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Planned>>(PIPELINE_CHUNKS);
        let handle = std::thread::Builder::new()
            .name("sim-master".into())
            .spawn_scoped(scope, move || {
                let mut tick = 0;
                while tick < total {
                    let n = PIPELINE_CHUNK.min(total - tick);
                    let chunk: Vec<Planned> = (tick..tick + n).map(|k| master.step(k)).collect();
                    tick += n;
                    if tx.send(chunk).is_err() {
                        break; // the drive side stopped (an error)
                    }
                }
                master
            })
            .map_err(RunError::Thread)?;
        let mut tick = 0;
        let mut failed = None;
        'drive: for chunk in rx.iter() {
            for planned in &chunk {
                if let Err(e) = drive.tick(tick, planned) {
                    failed = Some(e);
                    break 'drive;
                }
                tick += 1;
            }
        }
        drop(rx);
        let master = handle.join().map_err(|_| RunError::MasterPanicked)?;
        match failed {
            Some(e) => Err(e),
            None => Ok(master),
        }
    })
}

/// Runs `scenario`; `progress(done, total)` is called every few hundred ticks. With
/// `threads` >= 2 the master side (stream, supervisor) runs on a thread of its own, ahead
/// of the drive side; the results are the same as with 1.
pub fn run(
    robot: &RsprGeometry<f64>,
    limits: &Limits<f64>,
    cfg: &SimConfig,
    scenario: &Scenario,
    threads: usize,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Outcome, RunError> {
    let compensation = scenario
        .compensation
        .unwrap_or(cfg.control.backlash_compensation);
    let sim = Sim::new(robot, limits, cfg, &scenario.start, compensation)?;
    let dt = sim.control_dt();
    let total = (scenario.duration_s / dt).round().max(0.0) as u64;
    let master = MasterSide::new(scenario, cfg, sim.planner().clone(), sim.tool(true), dt);
    let mut drive = DriveSide::new(scenario, sim, limits, cfg, total, progress);
    let started = Instant::now();
    let master = if threads >= 2 {
        run_pipelined(master, &mut drive, total)?
    } else {
        run_serial(master, &mut drive, total)?
    };
    (drive.progress)(total, total);
    let wall_s = started.elapsed().as_secs_f64();
    let simulated_s = total as f64 * dt;
    let (sim, m) = (&drive.sim, &drive.metrics);
    let summary = Summary {
        scenario: scenario.name.clone(),
        description: scenario.description.clone(),
        settings: run_settings(cfg, scenario, compensation),
        definitions: Definitions {
            tracking: TRACKING_DEFINITION,
            target: TARGET_DEFINITION,
            tip: "the platform centre o_p",
        },
        simulated_s,
        control_ticks: total,
        wall_s,
        speed_up: if wall_s > 0.0 {
            simulated_s / wall_s
        } else {
            f64::INFINITY
        },
        timing: timing_summary(threads, total, wall_s, sim.timing(), master.busy_s),
        tracking: m.all.tracking.summary(),
        target: m.all.target.summary(),
        joints: m.all_joint_summaries(),
        phases: m.phase_summaries(),
        accuracy: m.accuracy(
            cfg.accuracy.judged_speed_mm_s,
            cfg.accuracy.tip_rms_mm,
            cfg.accuracy.tip_max_mm,
        ),
        steps: m.step_summaries(),
        actuators: m.actuators(scenario.payload_attach_s.is_some()),
        supervisor: supervisor_summary(&master, m, sim),
        faults: FaultSummary {
            injected: m.injected.clone(),
            servo: m.servo_fault(),
            true_fk_failures: sim.true_fk_failures(),
        },
    };
    Ok(Outcome {
        summary,
        trace: drive.trace,
    })
}

/// The settings of a run with `compensation` on or off.
fn run_settings(cfg: &SimConfig, scenario: &Scenario, compensation: bool) -> RunSettings {
    let payload = payload_from_config(cfg);
    let w = payload.wrench(&scenario.start);
    RunSettings {
        control_rate_hz: cfg.control.rate_hz,
        plant_step_us: cfg.plant_dt() * 1e6,
        leg_backlash_mm: cfg.plant.leg_backlash_mm,
        backlash_compensation: compensation,
        compensated_leg_backlash_mm: if compensation {
            cfg.control.compensated_leg_backlash_mm
        } else {
            0.0
        },
        payload_attached_at_s: scenario.payload_attach_s,
        payload_mass_kg: cfg.payload.mass_kg,
        payload_lever_mm: cfg.payload.lever_mm,
        payload_force_n: [w[0], w[1], w[2]],
        payload_moment_nm: [w[3], w[4], w[5]],
        payload_update: match cfg.plant.payload_update() {
            PayloadUpdate::Tick => "tick".into(),
            PayloadUpdate::Step => "step".into(),
            PayloadUpdate::Moved => format!(
                "moved (by {} mm or {} deg)",
                cfg.plant.payload_refresh_mm, cfg.plant.payload_refresh_deg
            ),
        },
        stream_rate_hz: cfg.master.stream_rate_hz,
        latency_ms: cfg.master.latency_ms,
    }
}

/// Where the `wall_s` of `total` ticks went, from the closed loop's `timing` and the
/// planner's `planner_s`.
fn timing_summary(
    threads: usize,
    total: u64,
    wall_s: f64,
    t: Timing,
    planner_s: f64,
) -> TimingSummary {
    let n = (total.max(1)) as f64 / 1e6;
    TimingSummary {
        threads,
        per_tick_us: wall_s / n,
        controller_us: t.controller_s / n,
        planner_us: planner_s / n,
        plant_us: t.plant_s / n,
        truth_and_payload_us: t.truth_s / n,
        payload_us: t.payload_s / n,
        other_us: if threads >= 2 {
            (wall_s - t.controller_s - t.plant_s - t.truth_s) / n
        } else {
            (wall_s - t.controller_s - planner_s - t.plant_s - t.truth_s) / n
        },
    }
}

/// What the supervisor did with the master's targets, and the drive's forward kinematics.
fn supervisor_summary(master: &MasterSide<'_>, m: &Metrics, sim: &Sim) -> SupervisorSummary {
    let sup = master.planner.supervisor();
    let c = sup.counters();
    let first = master.first_refusal.clone();
    let drive = sim.sensing().counters();
    SupervisorSummary {
        targets_sent: master.targets_sent,
        accepted: c.accepted,
        certified: c.certified,
        led: c.led,
        superseded: c.superseded,
        refused: Refusals {
            total: c.stale
                + c.out_of_order
                + c.too_far
                + c.path_refused
                + c.non_finite
                + c.refused_latched,
            stale: c.stale,
            out_of_order: c.out_of_order,
            too_far: c.too_far,
            path: c.path_refused,
            non_finite: c.non_finite,
            while_stopped: c.refused_latched,
            first_at_s: first.as_ref().map(|f| f.0),
            first_reason: first.map(|f| f.1),
        },
        warn_s: m.warn_s(),
        warn_by_guard: m.warn_by_guard(),
        lag: m.lag(),
        stopped_s: m.modes().stopped_s,
        modes: m.modes(),
        brakes: c.brakes,
        stops: c.stops,
        stop_reason: sup
            .latched()
            .map(|r| format!("{} ({}) value {:e}", r.guard, r.subject, r.value)),
        fk_failures: drive.fk_failures,
        fk_max_iterations: drive.fk_max_iterations,
    }
}
