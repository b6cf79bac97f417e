//! Cost of one control tick on the Cortex-M4: runs the control application and its parts
//! between the instruction-count markers of `on_target::bench`. Under QEMU with the
//! `insncount` plugin (see run.sh) every region's count is recorded; this program prints
//! the label of each region (`@region ...`) right after it, and run.sh joins the two into
//! the table. Without the plugin it simply runs (and exits 0).
#![no_std]
// Test code on the target: a panic is a failed test (semihosting exits non-zero).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]
#![no_main]

use control::absolute::{ChannelCalibration, ChannelCheck, ChannelConfig, ChannelInputs};
use control::current::CurrentConfig;
use control::monitors::EncoderCheckConfig;
use control::{Controller, ControllerConfig, PoseStatus, Sensing, TickReport, ToolLoad};
use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::debug;
use kinematics_core::guards::{Guards, Limits, MotionSample, Stage, Staged};
use kinematics_core::ik::{inverse_into, platform_chain, Solution};
use kinematics_core::jacobian::{jacobian_into, Jacobians};
use kinematics_core::lu::Lu6;
use kinematics_core::mechanism::{radial, Mechanism};
use kinematics_core::singularity::{parallel_inv_cond, ConditionEstimator};
use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::supervisor::{interpolate, Mode, Supervisor, SupervisorConfig};
use kinematics_core::tilt::{tilt_angles, SocketAxes};
use kinematics_core::{
    forward, inverse, measures, Branch, Chain, FkConfig, FkTracker, Joints, PerChainGeometry, Pose,
    RsprGeometry, Twist,
};
use nalgebra::{ComplexField, Matrix6, RealField, Rotation3, Vector3, Vector6};
use on_target::bench::{bench_profile_off, bench_profile_on, calibrate, measure};
use on_target::hprintln;
use on_target::stub::{absolute_counts_per_unit, PlantStub};
use panic_semihosting as _;
use servo::encoder::{EncoderConfig, Encoders};
use servo::{JointServo, Pid, PidGains, PidInput, ServoConfig};

/// The board's model: the per-chain geometry (here the reference robot's), as the board
/// image runs it.
type G32 = PerChainGeometry<f32>;

fn reference_robot() -> G32 {
    PerChainGeometry::from(RsprGeometry::<f32>::reference())
}

fn arr(q: &Joints<f32>) -> [f32; 6] {
    [q[0], q[1], q[2], q[3], q[4], q[5]]
}

fn target_a() -> Pose<f32> {
    Pose {
        t: Vector3::new(0.008, -0.005, 0.163),
        r: Rotation3::from_scaled_axis(Vector3::new(0.05, -0.03, 0.0)),
    }
}

fn target_b() -> Pose<f32> {
    Pose {
        t: Vector3::new(0.004, 0.002, 0.158),
        r: Rotation3::from_scaled_axis(Vector3::new(-0.02, 0.04, 0.03)),
    }
}

/// Outside the workspace box (20 mm above it): refused by the path check.
fn target_outside() -> Pose<f32> {
    Pose {
        t: Vector3::new(0.004, 0.002, 0.195),
        r: Rotation3::identity(),
    }
}

/// A turn of 15 deg about a tilted axis and 6 mm: path samples rotated by more than
/// 0.1 rad (the trigonometric branch of the pose update).
fn target_turn() -> Pose<f32> {
    Pose {
        t: Vector3::new(-0.002, 0.004, 0.160),
        r: Rotation3::from_scaled_axis(Vector3::new(0.2, -0.12, 0.1)),
    }
}

/// What a tick did, for its label.
fn tick_kind(verifying_before: bool, mode: Mode, moving: bool) -> &'static str {
    match (mode, verifying_before, moving) {
        (Mode::Braking, _, _) => "braking",
        (Mode::Stopped, _, _) => "stopped",
        (_, false, false) => "holding",
        (_, true, false) => "verifying a target, robot holding",
        (_, false, true) => "moving",
        (_, true, true) => "moving + verifying the next target",
    }
}

fn moving(twist: &Twist<f32>) -> bool {
    twist.iter().any(|x| *x != 0.0)
}

/// Where the full-tick scenario is.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Phase {
    ToA,
    ToB,
    Outside { since: u32 },
    Turn { since: u32 },
    Braking,
    Rest { since: u32 },
}

/// The ticks of the full-tick scenario the profile covers: all by default, or `FIRST..END`
/// from `TICK_COST_PROFILE_TICKS` at build time (e.g. `60..190`: moving to target A).
fn profile_window() -> (u32, u32) {
    let parse = |s: &str| s.trim().parse::<u32>().ok();
    option_env!("TICK_COST_PROFILE_TICKS")
        .and_then(|w| w.split_once(".."))
        .and_then(|(a, b)| Some((parse(a)?, parse(b)?)))
        .unwrap_or((0, u32::MAX))
}

/// The full control tick: the controller with the motor stub, through hold, verify, move,
/// re-target while moving, and arrival. Profiled.
fn full_tick() {
    let g = reference_robot();
    let q0 = arr(&inverse(&g, &Pose::central(g.hc()), Branch::OUTER)
        .map(|s| s.q())
        .unwrap_or_default());
    let mut plant = PlantStub::new(q0.map(f64::from), [65_500, 10, 32_000, 65_530, 0, 40_000]);
    let cfg = ControllerConfig::<f32>::default();
    // The sensing as the runtime has it after homing: the counters read q0, the pose
    // solved once.
    let Ok(mut sensing) =
        Sensing::homed_at(g, Branch::OUTER, &cfg.encoders, cfg.fk, plant.raw(), &q0)
    else {
        panic!("sensing setup");
    };
    let Ok(mut ctl) = Controller::<f32, G32>::new(g, cfg, sensing.measured()) else {
        panic!("controller setup");
    };
    // The second position channel, fitted: read in the tick with the counters, checked
    // against the encoders after the outputs (as the runtime does).
    let calibration = ChannelCalibration {
        counts_per_unit: core::array::from_fn(|j| absolute_counts_per_unit(j) as f32),
        mid: q0,
        step_counts: board_profile::position_channel::PositionChannel::REFERENCE.step_counts()
            as f32,
    };
    sensing.set_channel(calibration);
    let mut channel = ChannelCheck::new(ChannelConfig::reference(
        &calibration,
        &cfg.encoders.counts_per_unit,
        &cfg.servo.backlash.joints.map(|b| b.width),
        &EncoderCheckConfig::reference(cfg.encoders.counts_per_unit).top_speed,
        &CurrentConfig::default().motors.map(|m| m.continuous_a),
        1.0 / cfg.rate_hz,
    ));
    let currents = [0.0f32; 6];
    let mut prev_mode = Mode::Holding;
    let mut now_us = 1_000u64;
    let (mut fk_iters, mut fk_ticks) = (0u32, 0u32);
    let window = profile_window();
    let mut ticks_run = 0u32; // (measured)
    let mut phase = Phase::ToA;
    for k in 0..2000u32 {
        if k == window.0 {
            bench_profile_on();
        }
        if k == window.1 {
            bench_profile_off();
            hprintln!("@profiled {}", k - window.0);
        }
        // The master's part: targets A, then B while moving, the tool attached; at rest on
        // B a target outside the workspace (refused), then a turn of 15 deg (verified in
        // about 150 ticks), and 200 ticks into that motion the heartbeat stops (the controller brakes and holds).
        let mut submitted = false;
        let mut submit = |ctl: &mut Controller<f32, G32>, target: &Pose<f32>| {
            let ok = ctl.submit(target, now_us, now_us).is_ok();
            submitted = ok;
            ok
        };
        match (phase, k) {
            (Phase::ToA, 5) => {
                submit(&mut ctl, &target_a());
            }
            (Phase::ToA, 200) => {
                submit(&mut ctl, &target_b());
                // From here on with the thesis's tool (1.2 kg on 0.1 m): the planner also
                // updates the lead screws' flanks under its weight.
                ctl.set_tool(Some(ToolLoad::thesis()));
                phase = Phase::ToB;
            }
            (Phase::ToB, _) if prev_mode == Mode::Holding && k > 210 => {
                submit(&mut ctl, &target_outside());
                phase = Phase::Outside { since: k };
            }
            (Phase::Outside { since }, _) if k > since + 60 => {
                submit(&mut ctl, &target_turn());
                phase = Phase::Turn { since: k };
            }
            (Phase::Turn { since }, _) if k == since + 350 => {
                ctl.hold();
                phase = Phase::Braking;
            }
            (Phase::Braking, _) if prev_mode == Mode::Holding => {
                phase = Phase::Rest { since: k };
            }
            (Phase::Rest { since }, _) if k > since + 10 => break,
            _ => {}
        }
        let verifying_before = submitted || prev_mode == Mode::Verifying;
        let mut report: Option<TickReport<f32>> = None;
        // The full tick, from the readings to the outputs: the counters, then the planner's
        // step and the drive.
        measure(&mut || {
            sensing.read(&mut plant);
            let measured = sensing.read_absolute(&mut plant);
            let r = ctl.tick(measured);
            r.apply(&mut plant);
            report = Some(r);
        });
        ticks_run = k + 1;
        let Some(r) = report else { break };
        let kind = tick_kind(verifying_before, r.mode, moving(ctl.supervisor().twist()));
        let tool = if k >= 200 { ", with the tool" } else { "" };
        hprintln!("@label Controller::tick: {}{}", kind, tool);
        // The rest of the period, after the outputs (out of the tick's profile): the
        // measured pose (FK tracker), the controller's evaluation phase and the second
        // position channel against the encoders.
        let profiling = (window.0..window.1).contains(&k);
        if profiling {
            bench_profile_off();
        }
        let mut finding = None;
        measure(&mut || {
            sensing.follow_pose();
            ctl.evaluate();
            let m = sensing.measured();
            let p = m.absolute.unwrap_or([0.0; 6]);
            finding = channel.check(&ChannelInputs {
                raw: m.absolute_raw.as_ref(),
                p: &p,
                motor: &m.motor,
                current: &currents,
                holding: false,
                epoch: sensing.reference_epoch(),
            });
        });
        black_box(finding);
        if profiling {
            bench_profile_on();
        }
        hprintln!("@label after the outputs: {}{}", kind, tool);
        match sensing.measured().status {
            PoseStatus::Unchanged => fk_ticks += 1,
            PoseStatus::Stepped(it) | PoseStatus::Solved(it) => {
                fk_iters += it;
                fk_ticks += 1;
            }
            PoseStatus::NotHomed | PoseStatus::Failed(_) => {}
        }
        prev_mode = r.mode;
        plant.step(1e-3);
        now_us += 1000;
        if r.servo.fault.is_some() {
            hprintln!("@info servo fault {:?}", r.servo.fault);
            break;
        }
    }
    if ticks_run < window.1 {
        bench_profile_off();
        hprintln!("@profiled {}", ticks_run.saturating_sub(window.0));
    }
    hprintln!(
        "@info full tick: FK took {} Newton steps per tick on average ({} ticks); counters {:?}; FK tracker {:?}",
        fk_iters as f32 / fk_ticks.max(1) as f32,
        fk_ticks,
        sensing.counters(),
        sensing.fk_counts()
    );
    hprintln!(
        "@info full tick: supervisor {:?}",
        ctl.supervisor().counters()
    );
}

/// The supervisor alone, through the same kind of scenario.
fn supervisor_tick() {
    let Ok(mut sup) = Supervisor::new(
        reference_robot(),
        Branch::OUTER,
        Limits::reference(),
        SupervisorConfig::default(),
        &Pose::central(0.160),
    ) else {
        panic!("supervisor setup");
    };
    let mut prev_mode = Mode::Holding;
    for k in 0..400u32 {
        let now = 1_000 + u64::from(k) * 1000;
        let mut submitted = false;
        if k == 2 {
            submitted = sup.submit(&target_a(), now, now).is_ok();
        }
        if k == 150 {
            submitted = sup.submit(&target_b(), now, now).is_ok();
        }
        let verifying_before = submitted || prev_mode == Mode::Verifying;
        let mut out = None;
        measure(&mut || out = Some(sup.step()));
        let Some(o) = out else { break };
        let kind = tick_kind(verifying_before, o.mode, moving(&o.twist));
        hprintln!("@label Supervisor::step: {}", kind);
        measure(&mut || sup.evaluate());
        hprintln!("@label Supervisor::evaluate: {}", kind);
        prev_mode = o.mode;
    }
}

/// Poses along the path from the central pose to target A (where the robot works).
fn path(n: usize) -> impl Iterator<Item = Pose<f32>> {
    let (a, b) = (Pose::central(0.160f32), target_a());
    (0..n).map(move |k| interpolate(&a, &b, (k as f32 + 0.5) / n as f32))
}

/// Each part alone, at poses along the path.
fn parts() {
    let g = reference_robot();
    let fk_cfg = FkConfig::<f32>::default();
    let Ok(guards) = Guards::new(g, Branch::OUTER, Limits::reference()) else {
        panic!("guards setup");
    };
    let Ok(axes) = SocketAxes::new(&g) else {
        panic!("axes")
    };
    let limits = Limits::<f32>::reference();
    let n = 10;
    // Histograms of the Newton steps taken (0, 1, 2, 3, >= 4).
    let (mut warm_steps, mut cold_steps) = ([0u32; 5], [0u32; 5]);
    // Sweeps of the warm-started SVD (0, 1, 2, 3, >= 4).
    let mut warm_sweeps = [0u32; 5];
    // One control tick of motion at the 25 mm/s limit (+ 1.5 deg/s about x).
    let step_v = Vector3::new(0.025e-3f32, 0.0, 0.0);
    let step_w = Vector3::new(0.026e-3f32, 0.0, 0.0);
    let quantize = |q: &Joints<f32>| {
        let mut q = *q;
        for j in 0..6 {
            let c = board_profile::BoardProfile::REFERENCE.joints[j].counts_per_unit() as f32;
            q[j] = ComplexField::round(q[j] * c) / c;
        }
        q
    };
    for pose in path(n) {
        let pose = black_box(pose);
        // In place, as the control path solves (`inverse_into`, `jacobian_into`).
        let mut sol = Solution::zeroed(Branch::OUTER);
        let mut ok = false;
        measure(&mut || ok = inverse_into(&g, &pose, Branch::OUTER, &mut sol).is_ok());
        hprintln!("@label inverse kinematics (3 chains, in place)");
        if !ok {
            continue;
        }
        let mut dir = Vector3::zeros();
        let chain = black_box(Chain::Two);
        measure(&mut || dir = radial::<f32>(chain));
        hprintln!("@label   radial(chain): cos, sin of the constant chain angle");
        let mut pc = None;
        measure(&mut || pc = Some(platform_chain(&g, &pose, chain)));
        hprintln!("@label   platform_chain (per chain, includes radial)");
        black_box((dir, pc));
        let mut jac = Jacobians::zeroed();
        measure(&mut || ok = jacobian_into(&g, &sol, &mut jac).is_ok());
        hprintln!("@label Jacobian J = Js^-1 Jtilde (in place)");
        if !ok {
            continue;
        }

        // Forward kinematics from quantized encoder joints, warm-started one tick away.
        let next = pose.displaced(&step_v, &step_w);
        if let Ok(s) = inverse(&g, &next, Branch::OUTER) {
            let q = quantize(&s.q());
            let mut fk = None;
            measure(&mut || fk = forward(&g, &q, Branch::OUTER, &pose, &fk_cfg).ok());
            hprintln!("@label FK: full solver, warm start 1 tick away");
            if let Some(fk) = fk {
                warm_steps[fk.iterations.min(4) as usize] += 1;
            }
            // The controller's FK: the tracker, started two ticks earlier. Its first update
            // (one tick earlier) takes a Newton step and factorises Jtilde; the next, the
            // steady state while moving, a step with those factors (a chord step).
            let before = pose.displaced(&(-step_v), &(-step_w));
            let prev = inverse(&g, &pose, Branch::OUTER);
            let earlier = inverse(&g, &before, Branch::OUTER);
            if let (Ok(s_prev), Ok(s_before)) = (prev, earlier) {
                let q_prev = quantize(&s_prev.q());
                let q_before = quantize(&s_before.q());
                if let Ok(tracker) = FkTracker::new(&g, &q_before, Branch::OUTER, &before, &fk_cfg)
                {
                    let mut tr = tracker;
                    let mut out = None;
                    measure(&mut || {
                        tr = tracker;
                        out = tr.update(&g, &q_prev, &fk_cfg).ok();
                    });
                    hprintln!(
                        "@label FK: FkTracker::update, first tick (Newton step, factorises Jtilde)"
                    );
                    let primed = tr;
                    measure(&mut || {
                        tr = primed;
                        out = tr.update(&g, &q, &fk_cfg).ok();
                    });
                    hprintln!(
                        "@label FK: FkTracker::update, next tick (a step with those factors)"
                    );
                    black_box(out);
                    black_box(tr.counts());
                }
            }
            let mut fk = None;
            let central = Pose::central(0.160f32);
            measure(&mut || fk = forward(&g, &q, Branch::OUTER, &central, &fk_cfg).ok());
            hprintln!("@label FK: full solver, cold start (central pose)");
            if let Some(fk) = fk {
                cold_steps[fk.iterations.min(4) as usize] += 1;
            }
        }

        let mut verdict_ok = false;
        measure(&mut || {
            let mut stop = false;
            let s = guards.evaluate_pose(&pose, &mut |r| stop |= r.severity.is_some());
            verdict_ok = s.is_some() && !stop;
        });
        hprintln!("@label guards: evaluate_pose (IK + every pose guard)");
        let mut m = None;
        measure(&mut || m = measures(&g, &sol).ok());
        hprintln!("@label   singularity measures (Jtilde, 6x6 SVD, det)");
        let jt = jac.jtilde;
        let mut ic = None;
        measure(&mut || ic = parallel_inv_cond(&jt, 0.05).ok());
        hprintln!("@label     parallel_inv_cond, cold start (6x6 f32 Jacobi SVD)");
        // Warm: the estimator last ran at the pose one tick of motion earlier.
        let before = pose.displaced(&-step_v, &-step_w);
        if let Ok(sb) = inverse(&g, &before, Branch::OUTER) {
            let jt_before = kinematics_core::jacobian::tripod_jacobian(&sb);
            let mut warm = ConditionEstimator::new();
            let _ = warm.inv_cond(&jt_before, 0.05);
            let mut est = warm;
            measure(&mut || {
                est = warm;
                ic = est.inv_cond(&jt, 0.05).ok();
            });
            hprintln!("@label     parallel_inv_cond, warm start one tick away");
            warm_sweeps[est.last_sweeps().min(4) as usize] += 1;
            // As the staged checks run it: the start (W = A V), then one sweep per stage.
            measure(&mut || {
                est = warm;
                black_box(est.begin(&jt, 0.05).is_ok());
            });
            hprintln!("@label     staged: ConditionEstimator::begin (scaling, W = A V)");
            let begun = est;
            measure(&mut || {
                est = begun;
                black_box(est.sweep());
            });
            hprintln!("@label     staged: ConditionEstimator::sweep (one sweep, warm)");
        }
        let mut det = 0.0f32;
        measure(&mut || det = jt.determinant());
        hprintln!("@label     det(Jtilde) alone (nalgebra's 6x6 LU)");
        let mut lu = None;
        measure(&mut || lu = Lu6::new(&jt));
        hprintln!("@label   lu::Lu6::new: Jtilde factorised (written out)");
        if let Some(f) = lu {
            let b = black_box(Vector6::new(1.0f32, -2.0, 0.5, 0.1, -0.3, 0.2));
            let mut x = Vector6::zeros();
            measure(&mut || x = f.solve(&b));
            hprintln!("@label   lu::Lu6::solve (Jtilde x = b)");
            measure(&mut || x = f.solve_transposed(&b));
            hprintln!("@label   lu::Lu6::solve_transposed (Jtilde^T x = b)");
            black_box(x);
        }
        let mut tilts = None;
        measure(&mut || tilts = Some(tilt_angles(&sol, &axes)));
        hprintln!("@label   spherical-joint tilt angles");
        let ic = ic.unwrap_or(0.05);
        let mut st = None;
        measure(&mut || {
            st = forces_with_inv_cond(&jac, &limits.payload, ic, limits.parallel.stop).ok()
        });
        hprintln!("@label   statics for the payload (Lu6 of Jtilde, transposed solve)");
        let prev = MotionSample {
            twist: Twist::zeros(),
            qdot: Joints::zeros(),
        };
        let tw = Twist::new(0.02, 0.01, 0.0, 0.1, 0.0, 0.05);
        let cur = MotionSample {
            twist: tw,
            qdot: jac.j * tw,
        };
        measure(&mut || {
            guards.evaluate_motion(&prev, &cur, 1e-3, &mut |r| {
                black_box(r);
            })
        });
        hprintln!("@label guards: evaluate_motion (speeds, accelerations)");
        // The stages of the supervisor's staged evaluation, one per call as the supervisor
        // runs them (the SVD warm-started by an evaluation one tick of motion earlier),
        // then the certified region of the finished evaluation and the test of a straight
        // motion against it (the supervisor's fast path: a target's segment, a braking
        // stretch).
        let mut staged = Staged::new(Branch::OUTER);
        let mut cond = ConditionEstimator::new();
        staged.start(&pose.displaced(&-step_v, &-step_w));
        while !staged.is_finished() {
            guards.advance(&mut staged, &mut cond);
        }
        staged.start(&pose);
        while let Some(stage) = staged.next_stage() {
            measure(&mut || guards.advance(&mut staged, &mut cond));
            hprintln!(
                "@label guards: staged evaluation, stage {}",
                match stage {
                    Stage::Kinematic => "Kinematic (IK, kinematic guards)",
                    Stage::Jacobian => "Jacobian (J, SVD begin)",
                    Stage::Parallel => "Parallel (one SVD sweep)",
                    Stage::Statics => "Statics (payload efforts)",
                }
            );
        }
        if let Some(full) = staged.full() {
            let mut cert = None;
            measure(&mut || cert = guards.certify(&full));
            hprintln!("@label guards: certify (the region of one full evaluation)");
            if let Some(c) = cert {
                let to = pose.displaced(
                    &Vector3::new(2e-4, -1e-4, 0.0),
                    &Vector3::new(0.0, 0.0, 1e-4),
                );
                let mut inside = false;
                measure(&mut || inside = c.contains_motion(&pose, &to));
                hprintln!("@label   Certificate::contains_motion (one straight motion)");
                black_box(inside);
            }
        }
        black_box((verdict_ok, m, det, tilts, st));
    }
    hprintln!(
        "@info forward kinematics alone: Newton steps (0/1/2/3/4+) warm start {:?}, cold start {:?} (FkSolution::iterations, a kept polishing step included)",
        warm_steps,
        cold_steps
    );
    hprintln!(
        "@info parallel measure: Jacobi sweeps (0/1/2/3/4+) warm start one tick away {:?}",
        warm_sweeps
    );
}

/// The servo side: encoders and the six PIDs.
fn servo_parts() {
    let g = reference_robot();
    let Ok(mut enc) = Encoders::<f32>::new(&EncoderConfig::default()) else {
        panic!("enc")
    };
    let Ok(mut js) = JointServo::<f32>::new(&ServoConfig::default()) else {
        panic!("servo")
    };
    let mut pid = Pid::new(PidGains::<f32>::leg());
    let mut raw = [65_500u16, 10, 32_000, 65_530, 0, 40_000];
    enc.update(&raw);
    let mut prev: Option<[f32; 6]> = None;
    for (k, pose) in path(20).enumerate() {
        let Ok(s) = inverse(&g, &pose, Branch::OUTER) else {
            continue;
        };
        let sp = arr(&s.q());
        if prev.is_none() {
            enc.set_positions(&sp);
            js.reset(&sp);
        }
        for (j, r) in raw.iter_mut().enumerate() {
            *r = r.wrapping_add((k as u16 * 7 + j as u16) % 5);
        }
        let mut q = [0.0f32; 6];
        let mut hw = PlantStubCounts(raw);
        measure(&mut || q = enc.read(&mut hw));
        hprintln!("@label encoders: read 6 counters -> joints");
        let spd = prev.map_or([0.0; 6], |p| {
            let mut v = [0.0; 6];
            for j in 0..6 {
                v[j] = (sp[j] - p[j]) * 1e3;
            }
            v
        });
        let meas = core::array::from_fn(|j| sp[j] + 2e-6 * (j as f32 - 2.5));
        let mut out = None;
        measure(&mut || out = Some(js.update(&sp, &spd, &meas, 1e-3)));
        hprintln!("@label JointServo::update (6 x backlash + PID + tracking)");
        let input = PidInput::new(sp[0], meas[0]).with_velocity(spd[0]);
        let mut o = None;
        measure(&mut || o = Some(pid.update(&input, 1e-3)));
        hprintln!("@label   Pid::update alone (one joint)");
        black_box((q, out, o));
        prev = Some(sp);
    }
}

struct PlantStubCounts([u16; 6]);
impl hal::QuadratureCounter for PlantStubCounts {
    fn counts(&mut self) -> [u16; 6] {
        self.0
    }
}

/// Math primitives as the kinematics uses them (nalgebra's f32 RealField, libm).
fn primitives() {
    for k in 0..8 {
        let x = black_box(0.1f32 + 0.37 * k as f32);
        let y = black_box(0.9f32 - 0.21 * k as f32);
        let mut r = 0.0f32;
        measure(&mut || r = ComplexField::sqrt(x));
        hprintln!("@label libm: sqrt (f32)");
        measure(&mut || r = RealField::atan2(y, x));
        hprintln!("@label libm: atan2 (f32)");
        measure(&mut || r = ComplexField::sin(x));
        hprintln!("@label libm: sin (f32; computes in f64 = soft-float on the M4)");
        measure(&mut || r = ComplexField::cos(x));
        hprintln!("@label libm: cos (f32; computes in f64 = soft-float on the M4)");
        measure(&mut || {
            let (s, c) = ComplexField::sin_cos(x);
            r = s + c
        });
        hprintln!("@label libm: sin_cos (f32)");
        measure(&mut || r = ComplexField::floor(x));
        hprintln!("@label libm: floor (f32)");
        measure(&mut || r = ComplexField::exp(-x));
        hprintln!("@label libm: exp (f32)");
        let v = black_box(Vector3::new(x * 0.1, y * 0.1, 0.05));
        let mut rot = Rotation3::identity();
        measure(&mut || rot = Rotation3::from_scaled_axis(v));
        hprintln!("@label nalgebra: Rotation3::from_scaled_axis");
        let m = black_box(Matrix6::<f32>::from_fn(|i, j| {
            if i == j {
                2.0 + x
            } else {
                0.1 * ((i * 7 + j * 3) % 5) as f32 - 0.2
            }
        }));
        let b = black_box(Vector6::new(1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0));
        let mut sol = None;
        measure(&mut || sol = m.lu().solve(&b));
        hprintln!("@label nalgebra: 6x6 LU solve");
        black_box((r, rot, sol));
    }
}

/// The master link's authentication, in the link's tasks (not the control tick): the
/// HMAC-SHA256 tag of a frame, a keyed frame decoded and checked against the same frame
/// without a key, a keyed status frame encoded, and a session id issued (SHA-256).
fn link_auth() {
    use master_link::{
        decode_frame_with, encode_with, BoardToMaster, Header, LinkKey, MasterToBoard,
        StatusReport, MAX_FRAME_LEN,
    };
    let key = LinkKey::new(&[0x5a; 32]);
    let header = Header {
        session: 0x1234_5678,
        seq: 77,
    };
    let heartbeat = [5u8, 0x78, 0x56, 0x34, 0x12, 77, 0, 7];
    let mut tag = [0u8; 8];
    measure(&mut || tag = key.tag(black_box(&heartbeat)));
    hprintln!("@label link: HMAC-SHA256 tag of a heartbeat's header and body (8 B)");
    let target = MasterToBoard::PoseTarget {
        timestamp_us: 123_456_789,
        position_m: [0.004, -0.002, 0.161],
        rotation_vector_rad: [0.01, -0.02, 0.03],
    };
    for (k, label) in [
        (
            None,
            "link: decode a PoseTarget frame, no key (COBS, CRC, postcard)",
        ),
        (
            Some(&key),
            "link: decode a PoseTarget frame with its tag checked (HMAC-SHA256)",
        ),
    ] {
        let mut wire = [0u8; MAX_FRAME_LEN];
        let n = encode_with(&target, header, k, &mut wire).unwrap();
        for _ in 0..3 {
            let mut frame = wire;
            let mut ok = false;
            measure(&mut || {
                ok = decode_frame_with::<MasterToBoard>(&mut frame[..n - 1], k).is_ok()
            });
            hprintln!("@label {}", label);
            assert!(ok);
        }
    }
    let status = BoardToMaster::Status(StatusReport::default());
    for (k, label) in [
        (None, "link: encode a status frame, no key"),
        (Some(&key), "link: encode a status frame with its tag"),
    ] {
        let mut wire = [0u8; MAX_FRAME_LEN];
        let mut n = 0;
        measure(&mut || n = encode_with(&status, header, k, &mut wire).unwrap_or(0));
        hprintln!("@label {}", label);
        black_box(n);
    }
    let mut issuer =
        control::link::SessionIssuer::new(control::link::BoardIdentity::new(&[1; 12], Some(&key)));
    let mut id = 0;
    measure(&mut || id = issuer.issue(0xABCD, 1_000_000));
    hprintln!("@label link: a session id for a Hello (SHA-256, once per Hello)");
    black_box((tag, id));
}

#[entry]
fn main() -> ! {
    hprintln!("@begin");
    calibrate();
    full_tick();
    supervisor_tick();
    parts();
    servo_parts();
    primitives();
    link_auth();
    hprintln!("@end");
    debug::exit(debug::EXIT_SUCCESS);
    #[allow(clippy::empty_loop)]
    loop {}
}
