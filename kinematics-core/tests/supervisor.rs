#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The setpoint supervisor: whatever the master sends, no output setpoint violates a
//! stop-level guard or exceeds the speed and acceleration limits.

use crate::common;

use common::*;
use kinematics_core::guards::*;
use kinematics_core::mechanism::PlatformChain;
use kinematics_core::supervisor::*;
use kinematics_core::*;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

type Sup = Supervisor<f64, RsprGeometry<f64>>;

fn supervisor(limits: Limits<f64>) -> Sup {
    Supervisor::new(
        RsprGeometry::reference(),
        Branch::OUTER,
        limits,
        SupervisorConfig::default(),
        &Pose::central(0.160),
    )
    .unwrap()
}

/// What the master may send in one tick.
#[derive(Clone, Debug)]
enum Event {
    Nothing,
    /// A target near the task box (mm offsets, rotation vector in rad).
    Target([f64; 3], [f64; 3]),
    NaN,
    /// A jump of metres.
    Jump,
    /// Outside the workspace (box + 40 mm in x).
    Outside,
    /// Rotated 100 deg about z: through serial singularities and link-angle limits.
    Twisted,
    /// A stamp older than the last one.
    Replay,
    /// A stamp older than the stale limit.
    Stale,
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        6 => Just(Event::Nothing),
        6 => (prop::array::uniform3(-30.0..30.0f64), prop::array::uniform3(-0.4..0.4f64)).prop_map(|(t, r)| Event::Target(t, r)),
        1 => Just(Event::NaN),
        1 => Just(Event::Jump),
        1 => Just(Event::Outside),
        1 => Just(Event::Twisted),
        1 => Just(Event::Replay),
        1 => Just(Event::Stale),
    ]
}

/// Runs a stream of events, one per `hold` ticks, and checks every output.
fn run(events: &[(Event, u16)]) -> Result<Counters, TestCaseError> {
    run_scheduled(events, &mut |_| true)
}

/// [`run`], with the evaluation phase of tick k run only when `evaluates(k)` says so (the
/// step always runs): what a scheduling fault looks like to the supervisor.
fn run_scheduled(
    events: &[(Event, u16)],
    evaluates: &mut dyn FnMut(u64) -> bool,
) -> Result<Counters, TestCaseError> {
    let limits = Limits::reference();
    let mut sup = supervisor(limits);
    let mut k: u64 = 0;
    let dt = 1e-3;
    let mut now_us: u64 = 1_000_000;
    let mut last = sup.tick();
    let slack = 1.0 + 1e-9;
    for (ev, hold) in events {
        let (target, stamp) = match ev {
            Event::Nothing => (None, now_us),
            Event::Target(t, r) => (
                Some(Pose {
                    t: Vector3::new(t[0] * 1e-3, t[1] * 1e-3, 0.160 + t[2] * 0.5e-3),
                    r: Rotation3::from_scaled_axis(Vector3::from_row_slice(r)),
                }),
                now_us,
            ),
            Event::NaN => (
                Some(Pose {
                    t: Vector3::new(f64::NAN, 0.0, 0.16),
                    r: Rotation3::identity(),
                }),
                now_us,
            ),
            Event::Jump => (Some(Pose::central(2.5)), now_us),
            Event::Outside => (
                Some(Pose {
                    t: Vector3::new(0.065, 0.0, 0.16),
                    r: Rotation3::identity(),
                }),
                now_us,
            ),
            Event::Twisted => (
                Some(Pose {
                    t: Vector3::new(0.0, 0.0, 0.16),
                    r: Rotation3::from_scaled_axis(Vector3::new(0.0, 0.0, 100.0 * DEG)),
                }),
                now_us,
            ),
            Event::Replay => (Some(Pose::central(0.16)), now_us.saturating_sub(500)),
            Event::Stale => (Some(Pose::central(0.16)), now_us.saturating_sub(1_000_000)),
        };
        if let Some(t) = target {
            let _ = sup.submit(&t, stamp, now_us);
        }
        for _ in 0..*hold {
            now_us += 1000;
            let out = sup.step();
            k += 1;
            if evaluates(k) {
                sup.evaluate();
            }
            // Never a stop-level violation at the output.
            let (verdict, _) = sup.guards().check_pose(&out.pose);
            prop_assert!(
                !verdict.is_stop(),
                "output violates {:?}",
                verdict.first_stop()
            );
            prop_assert!(out.mode != Mode::Stopped, "latched stop {:?}", out.stop);
            // Never faster or harder than the limits.
            let v = out.twist.fixed_rows::<3>(0).norm();
            let w = out.twist.fixed_rows::<3>(3).norm();
            let dv = (out.twist - last.twist).fixed_rows::<3>(0).norm() / dt;
            let dw = (out.twist - last.twist).fixed_rows::<3>(3).norm() / dt;
            prop_assert!(
                v <= limits.tip_speed * slack && w <= limits.angular_speed * slack,
                "speed {v} m/s, {w} rad/s"
            );
            prop_assert!(
                dv <= limits.tip_accel * slack && dw <= limits.angular_accel * slack,
                "accel {dv} m/s², {dw} rad/s²"
            );
            // The setpoint moves by what its twist says.
            let moved = (out.pose.t - last.pose.t).norm();
            prop_assert!(moved <= limits.tip_speed * dt * slack + 1e-15);
            for j in 0..6 {
                let (vmax, amax) = if j < 3 {
                    (limits.joint_speed[0], limits.joint_accel[0])
                } else {
                    (limits.joint_speed[1], limits.joint_accel[1])
                };
                prop_assert!(
                    out.qdot[j].abs() <= vmax * slack,
                    "joint {} speed {}",
                    j + 1,
                    out.qdot[j]
                );
                prop_assert!(
                    (out.qdot[j] - last.qdot[j]).abs() / dt <= amax * slack,
                    "joint {} accel",
                    j + 1
                );
            }
            last = out;
        }
    }
    Ok(*sup.counters())
}

proptest! {
    #![proptest_config(proptest_config::cases(128))]

    /// For random target streams (including NaN, jumps of metres, poses outside the
    /// workspace, paths through singular configurations, replays and stale stamps), the
    /// output never violates a stop-level guard and never exceeds the speed and
    /// acceleration limits.
    #[test]
    fn output_is_always_safe_and_limited(events in prop::collection::vec((event(), 1u16..200), 1..40)) {
        let c = run(&events)?;
        // Every bad target was counted.
        let nan = events.iter().filter(|(e, _)| matches!(e, Event::NaN)).count() as u32;
        prop_assert_eq!(c.non_finite, nan);
        let jumps = events.iter().filter(|(e, _)| matches!(e, Event::Jump)).count() as u32;
        prop_assert!(c.too_far >= jumps);
        prop_assert_eq!(c.evaluations_missed, 0);
    }

    /// The same when the evaluation phase does not run after some steps (a scheduling
    /// fault: single periods at random, one in `every`, and outages of `outage` periods
    /// from tick `at`): a step that finds it missing brakes a moving robot on the stretch
    /// checked before, so the output still never violates a stop-level guard nor exceeds
    /// the limits, and no stop latches.
    #[test]
    fn output_is_safe_and_limited_when_evaluations_are_missed(
        events in prop::collection::vec((event(), 1u16..200), 1..40),
        every in 2u64..40, at in 0u64..2000, outage in 1u64..300, seed in any::<u64>(),
    ) {
        let mut state = seed | 1;
        let mut evaluates = |k: u64| {
            // xorshift: a fixed pseudo-random pattern per case.
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            !(state % every == 0 || (at..at + outage).contains(&k))
        };
        let c = run_scheduled(&events, &mut evaluates)?;
        let ticks: u64 = events.iter().map(|(_, h)| u64::from(*h)).sum();
        if ticks > at + outage {
            prop_assert!(c.evaluations_missed > 0);
        }
    }
}

/// Non-finite, stale, replayed and too-distant targets are refused at once and counted.
#[test]
fn bad_targets_are_refused_and_counted() {
    let mut sup = supervisor(Limits::reference());
    let now = 10_000_000;
    let nan = Pose {
        t: Vector3::new(0.0, f64::NAN, 0.16),
        r: Rotation3::identity(),
    };
    assert_eq!(sup.submit(&nan, now, now), Err(Refusal::NonFinite));
    assert!(matches!(
        sup.submit(&Pose::central(0.16), now - 200_000, now),
        Err(Refusal::Stale { age_us: 200_000 })
    ));
    assert!(sup.submit(&Pose::central(0.161), now, now).is_ok());
    assert_eq!(
        sup.submit(&Pose::central(0.162), now, now),
        Err(Refusal::OutOfOrder)
    );
    assert!(matches!(
        sup.submit(&Pose::central(3.0), now + 1, now),
        Err(Refusal::TooFar { .. })
    ));
    let c = sup.counters();
    assert_eq!(
        (c.non_finite, c.stale, c.out_of_order, c.too_far),
        (1, 1, 1, 1)
    );
}

/// A target outside the workspace is refused by the path check and the robot holds.
#[test]
fn target_outside_the_workspace_is_refused_and_the_robot_holds() {
    let mut sup = supervisor(Limits::reference());
    let target = Pose {
        t: Vector3::new(0.035, 0.0, 0.16),
        r: Rotation3::identity(),
    };
    sup.submit(&target, 1000, 1000).unwrap();
    let out = sup.tick();
    assert!(
        matches!(sup.last_refusal(), Some(Refusal::Path { reading, .. }) if reading.guard == Guard::Workspace)
    );
    for _ in 0..100 {
        let o = sup.tick();
        assert_eq!(o.pose, out.pose);
        assert_eq!(o.mode, Mode::Holding);
    }
    assert_eq!(sup.counters().path_refused, 1);
}

/// The robot reaches a verified target and stops there, at the speed limit in between.
#[test]
fn reaches_a_safe_target_at_the_speed_limit() {
    let mut sup = supervisor(Limits::reference());
    let target = Pose {
        t: Vector3::new(0.015, -0.010, 0.165),
        r: Rotation3::from_scaled_axis(Vector3::new(0.1, 0.05, 0.0)),
    };
    sup.submit(&target, 1000, 1000).unwrap();
    let mut peak: f64 = 0.0;
    let mut ticks = 0;
    loop {
        let o = sup.tick();
        peak = peak.max(o.twist.fixed_rows::<3>(0).norm());
        ticks += 1;
        if o.mode == Mode::Holding && ticks > 10 {
            break;
        }
        assert!(ticks < 10_000, "did not arrive");
    }
    let (dp, dr) = pose_error(sup.setpoint(), &target);
    assert!(dp < 1e-9 && dr < 1e-9, "{dp} m {dr} rad off");
    println!(
        "reached an 18.7 mm / 6.4 deg target in {ticks} ticks, peak speed {:.2} mm/s",
        peak * 1e3
    );
    assert!(peak > 0.9 * 0.025);
}

/// A straight segment between two safe poses that crosses an out-of-limit region is
/// refused, at the check's resolution. A leg's length bulges along many straight segments
/// (its spherical joint runs on the link circle, whose chord is concave); for random
/// segments through the task box with such a bulge, the stroke maximum is set halfway
/// between the longest leg at the ends and the longest leg along a 200-sample dense path,
/// so the ends are safe and the middle is not. The supervisor must refuse every one.
#[test]
fn unsafe_paths_between_safe_poses_are_refused_at_the_check_resolution() {
    let g = RsprGeometry::<f64>::reference();
    let cfg = SupervisorConfig::<f64>::default();
    let mut rng = 0x2545F4914F6CDD1Du64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let longest = |p: &Pose<f64>| {
        inverse(&g, p, Branch::OUTER)
            .unwrap()
            .q()
            .fixed_rows::<3>(0)
            .max()
    };
    let (mut bulging, mut refused, mut thinnest) = (0, 0, f64::INFINITY);
    for _ in 0..3000 {
        let mid = Vector3::new(
            (next() - 0.5) * 0.03,
            (next() - 0.5) * 0.03,
            0.16 + (next() - 0.5) * 0.02,
        );
        let dir = Vector3::new(next() - 0.5, next() - 0.5, (next() - 0.5) * 0.2).normalize()
            * (0.005 + 0.015 * next());
        let r = Rotation3::from_scaled_axis(Vector3::new(
            (next() - 0.5) * 0.3,
            (next() - 0.5) * 0.3,
            0.0,
        ));
        let a = Pose { t: mid - dir, r };
        let b = Pose { t: mid + dir, r };
        let ends = longest(&a).max(longest(&b));
        let path = (0..=200)
            .map(|k| longest(&interpolate(&a, &b, k as f64 / 200.0)))
            .fold(0.0, f64::max);
        if path < ends + 1e-6 {
            continue;
        }
        let mut limits = Limits::reference();
        limits.stroke[1] = 0.5 * (ends + path);
        let guards = Guards::new(g, Branch::OUTER, limits).unwrap();
        if guards.check_pose(&a).0.is_stop() || guards.check_pose(&b).0.is_stop() {
            continue;
        }
        bulging += 1;
        // The width of the unsafe stretch, as a fraction of the segment.
        let unsafe_samples = (0..=200)
            .filter(|k| longest(&interpolate(&a, &b, *k as f64 / 200.0)) > limits.stroke[1])
            .count();
        thinnest = thinnest.min(unsafe_samples as f64 / 200.0 * 2.0 * dir.norm());
        let mut sup = Supervisor::new(g, Branch::OUTER, limits, cfg, &a).unwrap();
        sup.submit(&b, 1, 1).unwrap();
        // Up to 120 samples of 5 stages when the SVD starts warm (a few more for the first,
        // cold), one stage per tick.
        for _ in 0..800 {
            sup.tick();
        }
        if matches!(sup.last_refusal(), Some(Refusal::Path { reading, .. }) if reading.guard == Guard::Stroke)
        {
            refused += 1;
        }
    }
    println!("{bulging} segments with a bulging leg (unsafe stretch down to {:.2} mm long): {refused} refused", thinnest * 1e3);
    assert!(
        bulging >= 20,
        "the test needs unsafe segments to mean anything"
    );
    assert_eq!(refused, bulging);
}

/// Bad settings and an unsafe start pose are refused by name.
#[test]
fn supervisor_settings_are_validated() {
    let bad = SupervisorConfig {
        dt: 0.0,
        ..SupervisorConfig::<f64>::default()
    };
    assert!(matches!(
        Supervisor::new(
            RsprGeometry::reference(),
            Branch::OUTER,
            Limits::reference(),
            bad,
            &Pose::central(0.16)
        ),
        Err(SupervisorError::Config(_))
    ));
    let outside = Pose::central(0.125);
    assert!(matches!(
        Supervisor::new(
            RsprGeometry::reference(),
            Branch::OUTER,
            Limits::reference(),
            SupervisorConfig::default(),
            &outside
        ),
        Err(SupervisorError::UnsafeStart(Some(_)))
    ));
}

/// The reference RSPR with a fault switch and call counters. While `broken` is set, chain
/// 2 finds no solution anywhere (what a corrupted computation or geometry would look like
/// to the supervisor). The supervisor predicts every other stop it could meet and brakes
/// before it (see `output_is_always_safe_and_limited`), so a fault the path check could
/// not see is the way to reach its last resort, the latched stop. The counters count the
/// chains' inverse kinematics and serial blocks (the Jacobians).
#[derive(Clone)]
struct Faulty {
    robot: RsprGeometry<f64>,
    broken: std::rc::Rc<std::cell::Cell<bool>>,
    chain_iks: std::rc::Rc<std::cell::Cell<u32>>,
    serial_blocks: std::rc::Rc<std::cell::Cell<u32>>,
}

fn faulty() -> Faulty {
    Faulty {
        robot: RsprGeometry::reference(),
        broken: Default::default(),
        chain_iks: Default::default(),
        serial_blocks: Default::default(),
    }
}

/// A supervisor with the default settings holding the central pose of `robot`.
fn on_faulty(robot: Faulty) -> Supervisor<f64, Faulty> {
    Supervisor::new(
        robot,
        Branch::OUTER,
        Limits::reference(),
        SupervisorConfig::default(),
        &Pose::central(0.160),
    )
    .unwrap()
}

impl Mechanism<f64> for Faulty {
    fn rp(&self) -> f64 {
        self.robot.rp()
    }
    fn e(&self) -> f64 {
        self.robot.e()
    }
    fn hc(&self) -> f64 {
        self.robot.hc()
    }
    fn joint_kinds(&self) -> [JointKind; 6] {
        self.robot.joint_kinds()
    }
    fn length_scale(&self) -> f64 {
        self.robot.length_scale()
    }
    fn chain_ik(
        &self,
        chain: Chain,
        pc: &PlatformChain<f64>,
        bit_set: bool,
        out: &mut ChainSolution<f64>,
    ) -> Result<(), IkFailure> {
        self.chain_iks.set(self.chain_iks.get() + 1);
        if self.broken.get() && chain == Chain::Two {
            return Err(IkFailure::NoRealRoot);
        }
        self.robot.chain_ik(chain, pc, bit_set, out)
    }
    fn serial_block(&self, s: &ChainSolution<f64>) -> SerialBlock<f64> {
        self.serial_blocks.set(self.serial_blocks.get() + 1);
        self.robot.serial_block(s)
    }
    fn serial_measure(&self, s: &ChainSolution<f64>) -> (f64, f64) {
        self.robot.serial_measure(s)
    }
}

/// A stop-level violation of the candidate setpoint holds the last safe setpoint at once,
/// latches the reason and refuses new targets until cleared; clearing resumes from where it
/// held.
#[test]
fn stop_holds_latches_and_clears() {
    let robot = faulty();
    let broken = robot.broken.clone();
    let mut sup = on_faulty(robot);
    let target = Pose {
        t: Vector3::new(0.005, 0.0, 0.160),
        r: Rotation3::identity(),
    };
    sup.submit(&target, 1000, 1000).unwrap();
    // About 58 ticks verify the 5 mm path (11 samples 0.5 mm apart, each a full evaluation
    // in 5 stages when the SVD starts warm, a few more for the first, one stage per tick),
    // then the motion starts.
    let mut out = sup.tick();
    for _ in 0..80 {
        out = sup.tick();
    }
    assert_eq!(out.mode, Mode::Moving);
    let held = *sup.setpoint();
    broken.set(true);
    out = sup.tick();
    assert_eq!(out.mode, Mode::Stopped);
    let stop = out.stop.unwrap();
    assert_eq!(
        (stop.guard, stop.subject),
        (Guard::Reach, Subject::Chain(Chain::Two))
    );
    assert_eq!(out.pose, held, "holds the last safe setpoint");
    assert_eq!(out.twist, Twist::zeros());
    assert_eq!(sup.submit(&target, 2000, 2000), Err(Refusal::Latched));
    for _ in 0..10 {
        let o = sup.tick();
        assert_eq!((o.mode, o.pose), (Mode::Stopped, held));
    }
    assert_eq!(sup.counters().stops, 1);
    // Not cleared while the setpoint is still unsafe (here: unsolvable).
    assert!(sup.clear().is_err());
    broken.set(false);
    assert!(sup.clear().is_ok());
    assert_eq!(sup.tick().mode, Mode::Holding);
    assert!(sup.latched().is_none());
    assert_eq!(*sup.setpoint(), held, "resumes from where it held");
}

/// A fast stream of targets never starves the path check: streamed at 1 kHz along a line
/// at 100 mm/s (four times the speed limit, so the setpoint falls ever further behind), the
/// newest target is verified as soon as the previous check ends and the robot keeps moving,
/// reaching the end of the stream.
#[test]
fn fast_target_stream_is_followed_not_starved() {
    let mut sup = supervisor(Limits::reference());
    let mut now = 1_000u64;
    let end = Vector3::new(0.018, 0.0, 0.160);
    for k in 1..=180 {
        now += 1000;
        let x = (k as f64 * 0.1e-3).min(0.018);
        let target = Pose {
            t: Vector3::new(x, 0.0, 0.160),
            r: Rotation3::identity(),
        };
        let _ = sup.submit(&target, now, now);
        sup.tick();
    }
    assert!(
        sup.setpoint().t.x > 0.002,
        "the robot moved while the stream ran: {}",
        sup.setpoint().t.x
    );
    for _ in 0..2000 {
        sup.tick();
    }
    assert!(
        (sup.setpoint().t - end).norm() < 1e-9,
        "{:?}",
        sup.setpoint().t
    );
    assert!(sup.counters().accepted >= 2 && sup.counters().superseded > 0);
}

/// Property: once the checker has certified the region around the goal (the idle checker
/// evaluates it), a target whose segment lies in the region is accepted on submission,
/// before any tick, and followed; a target beyond the region near the workspace boundary
/// is not certified and goes through the staged path check (accepted some ticks later,
/// or refused on a violation); the certified fast path never lets a setpoint out of the
/// stop-level guards.
#[test]
fn targets_in_a_certified_region_are_accepted_at_once() {
    let mut sup = supervisor(Limits::reference());
    let mut now = 1_000u64;
    // The idle checker certifies the region around the start (a full evaluation: a few
    // ticks).
    for _ in 0..20 {
        now += 1000;
        sup.tick();
    }
    // The region at the centre: about 1.5 mm of translation alone, 0.44 deg of rotation
    // alone (the reference limits with the tool as payload).
    let cert = sup.certificate().copied().unwrap();
    assert_eq!(cert.center.t, Vector3::new(0.0, 0.0, 0.160));
    assert!(
        cert.reach_t > 0.5e-3 && cert.reach_r > 0.1 * DEG,
        "{cert:?}"
    );
    let near = Pose {
        t: Vector3::new(0.0002, -0.0001, 0.16005),
        r: Rotation3::from_scaled_axis(Vector3::new(0.0, 0.0, 0.02 * DEG)),
    };
    assert!(cert.contains_motion(sup.setpoint(), &near));
    sup.submit(&near, now, now).unwrap();
    assert_eq!(sup.counters().certified, 1, "{:?}", sup.counters());
    assert_eq!(sup.counters().accepted, 1, "accepted on submission");
    for _ in 0..600 {
        now += 1000;
        let out = sup.tick();
        assert!(!sup.guards().check_pose(&out.pose).0.is_stop());
    }
    assert!(
        (sup.setpoint().t - near.t).norm() < 1e-9,
        "{:?}",
        sup.setpoint().t
    );
    // At the workspace's edge (box half 20 mm + margin 5 mm): beyond the region.
    let edge = Pose {
        t: Vector3::new(0.0245, 0.0, 0.1605),
        r: Rotation3::identity(),
    };
    sup.submit(&edge, now, now).unwrap();
    assert_eq!(
        sup.counters().certified,
        1,
        "not certified: {:?}",
        sup.counters()
    );
    assert_eq!(sup.counters().accepted, 1, "verified in stages first");
    let mut ticks = 0;
    while sup.counters().accepted == 1 && ticks < 2000 {
        ticks += 1;
        let out = sup.tick();
        assert!(!sup.guards().check_pose(&out.pose).0.is_stop());
    }
    assert_eq!(sup.counters().accepted, 2, "the staged check accepted it");
    assert!(ticks > 5, "after {ticks} ticks");
}

/// Constant bounded work per tick: whatever the master sends, a tick runs at most two
/// inverse kinematics (the candidate's and one stage of the full evaluation in progress)
/// and at most two Jacobians; the parallel measure's SVD and the statics are stages of
/// their own (`staged_evaluation_reaches_the_one_shot_verdict` in `guards.rs`). The
/// instructions per tick on the Cortex-M4 are measured by the firmware's QEMU run.
#[test]
fn work_per_tick_is_bounded() {
    let robot = faulty();
    let (iks, blocks) = (robot.chain_iks.clone(), robot.serial_blocks.clone());
    let mut sup = on_faulty(robot);
    let mut now = 1_000u64;
    let (mut worst_iks, mut worst_blocks, mut moving) = (0, 0, 0);
    let mut seed = 7u64;
    for k in 0..6000u64 {
        now += 1000;
        // A new target every 250 ms somewhere around the task box, every fifth one
        // outside the workspace; a 1 kHz stream of small steps in between.
        if k % 250 == 0 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = |s: u32| ((seed >> s) & 0xffff) as f64 / 65535.0 - 0.5;
            let reach = if (k / 250) % 5 == 4 { 0.14 } else { 0.05 };
            let target = Pose {
                t: Vector3::new(reach * u(0), reach * u(16), 0.160 + 0.02 * u(32)),
                r: Rotation3::from_scaled_axis(Vector3::new(0.4 * u(48), 0.4 * u(8), 0.0)),
            };
            let _ = sup.submit(&target, now, now);
        } else if (k / 250) % 2 == 1 {
            let p = sup.setpoint();
            let next = Pose {
                t: p.t + Vector3::new(2e-5, 0.0, 0.0),
                r: p.r,
            };
            let _ = sup.submit(&next, now, now);
        }
        iks.set(0);
        blocks.set(0);
        let out = sup.tick();
        if out.twist != Twist::zeros() {
            moving += 1;
        }
        worst_iks = worst_iks.max(iks.get());
        worst_blocks = worst_blocks.max(blocks.get());
        prop_assert_ok(iks.get() <= 6, k, "chain IKs", iks.get());
        prop_assert_ok(blocks.get() <= 6, k, "serial blocks", blocks.get());
    }
    println!(
        "worst tick: {worst_iks} chain IKs, {worst_blocks} serial blocks; {moving} moving \
         ticks; {:?}",
        sup.counters()
    );
    assert!(moving > 1000 && sup.counters().accepted > 10 && sup.counters().refused() >= 2);
}

fn prop_assert_ok(ok: bool, tick: u64, what: &str, n: u32) {
    assert!(ok, "tick {tick}: {n} {what} (at most 6: two evaluations)");
}

/// Sends a target 18 mm along x and ticks until the setpoint moves at the 25 mm/s limit
/// (asserted); returns its speed.
fn at_the_speed_limit_along_x(sup: &mut Sup) -> f64 {
    let far = Pose {
        t: Vector3::new(0.018, 0.0, 0.160),
        r: Rotation3::identity(),
    };
    sup.submit(&far, 1000, 1000).unwrap();
    let mut v = 0.0;
    for _ in 0..600 {
        v = sup.tick().twist.fixed_rows::<3>(0).norm();
        if v > 0.0249 {
            break;
        }
    }
    assert!(v > 0.0249, "at the speed limit: {v}");
    v
}

/// `brake` (the firmware's hold when the master falls silent) stops the robot at full
/// deceleration: moving at the 25 mm/s limit it comes to rest within v²/2a (1.25 mm) plus
/// one tick, without a latched stop, and takes new targets afterwards.
#[test]
fn brake_stops_within_the_braking_distance_and_takes_new_targets() {
    let mut sup = supervisor(Limits::reference());
    let v = at_the_speed_limit_along_x(&mut sup);
    let at = sup.setpoint().t.x;
    sup.brake();
    let mut ticks = 0;
    loop {
        let out = sup.tick();
        ticks += 1;
        assert_ne!(out.mode, Mode::Stopped);
        if out.twist == Twist::zeros() {
            break;
        }
        assert!(ticks < 200);
    }
    let travel = sup.setpoint().t.x - at;
    let bound = v * v / (2.0 * 0.25) + v * 1e-3;
    println!(
        "braked from {v} m/s in {ticks} ticks over {:.3} mm (bound {:.3})",
        travel * 1e3,
        bound * 1e3
    );
    assert!(travel > 0.0 && travel <= bound, "{travel} > {bound}");
    for _ in 0..10 {
        assert_eq!(sup.tick().mode, Mode::Holding);
    }
    assert_eq!(sup.counters().brakes, 0, "a commanded stop, not a guard's");
    let back = Pose::central(0.160);
    sup.submit(&back, 2_000_000, 2_000_000).unwrap();
    for _ in 0..3000 {
        sup.tick();
    }
    assert!((sup.setpoint().t - back.t).norm() < 1e-9);
}

/// A verified target next to a stop-level boundary is reached, not braked short of: the
/// braking point looks no farther than the goal the profile stops at (the profile keeps 5 %
/// of the deceleration in hand, and a newer target replaces the goal only once a
/// braking-point check has looked past it), and never past the boundary. The platform goes
/// down 12 mm (also tilted 10 deg) to a pose where a leg is 0.1 mm above its minimum stroke.
/// (With a braking point looking 3L ticks ahead regardless of the goal, it stopped 0.475 mm
/// short.)
#[test]
fn a_target_next_to_a_boundary_is_reached() {
    let robot = RsprGeometry::reference();
    for tilt in [0.0, 10.0 * DEG] {
        let target = Pose {
            t: Vector3::new(0.004, -0.003, 0.148),
            r: Rotation3::from_scaled_axis(Vector3::new(tilt, 0.0, 0.0)),
        };
        let legs = inverse(&robot, &target, Branch::OUTER).unwrap().q();
        let shortest = legs.x.min(legs.y).min(legs.z);
        let mut limits = Limits::reference();
        limits.stroke[0] = shortest - 0.1e-3;
        let mut sup = supervisor(limits);
        sup.submit(&target, 1000, 1000).unwrap();
        let mut out = sup.tick();
        for _ in 0..4000 {
            out = sup.tick();
            assert_ne!(out.mode, Mode::Stopped);
            let q = inverse(&robot, &out.pose, Branch::OUTER).unwrap().q();
            assert!(q.x.min(q.y).min(q.z) >= limits.stroke[0]);
        }
        let (dp, dr) = pose_error(sup.setpoint(), &target);
        println!(
            "tilt {:.0} deg: leg {:.3} mm, limit {:.3} mm; at rest {:.3} mm, {:.4} deg from \
             the target; {:?}",
            tilt / DEG,
            shortest * 1e3,
            limits.stroke[0] * 1e3,
            dp * 1e3,
            dr / DEG,
            sup.counters()
        );
        assert_eq!(out.twist, Twist::zeros());
        assert!(dp < 1e-9 && dr < 1e-9, "{dp:e} m, {dr:e} rad short");
        assert_eq!(sup.counters().brakes, 0);
    }
}

/// Regression (found by a fresh-seed run): the robot brakes along its twist towards the
/// serial singularity of chain 2; the joint accelerations must stay within their limits,
/// including the part J̇·twist that the Cartesian deceleration does not control.
#[test]
fn braking_towards_a_serial_singularity_keeps_the_joint_accelerations() {
    let events = [
        (
            Event::Target(
                [20.55242308737629, 23.158022640548538, 6.598334304459649],
                [0.28565585000157057, -0.2506164179833699, 0.239507245020635],
            ),
            113,
        ),
        (Event::Nothing, 195),
        (Event::Nothing, 126),
        (Event::Nothing, 193),
        (Event::Nothing, 128),
        (
            Event::Target(
                [-10.320426214708577, -22.28751961283577, -27.830585399528807],
                [0.0, 0.0, 0.0],
            ),
            4,
        ),
        (Event::Nothing, 95),
        (Event::Nothing, 176),
        (Event::Nothing, 137),
        (Event::Nothing, 152),
        (Event::Nothing, 92),
        (Event::Nothing, 159),
        (Event::Nothing, 143),
    ];
    run(&events).unwrap();
}

/// Regression (found by a fresh-seed run): turning back and forth near link 3's serial
/// singularity.
#[test]
fn turning_near_a_serial_singularity_keeps_the_joint_accelerations() {
    let t = |r: [f64; 3]| Event::Target([0.0, 0.0, 0.0], r);
    let events = [
        (
            t([0.223389068635184, -0.22479084651756343, 0.157671242657365]),
            101,
        ),
        (
            Event::Target(
                [17.15715101764255, -17.254897408357266, 9.793696603008812],
                [
                    -0.16303878527273521,
                    -0.36777652769157937,
                    -0.16232353003110517,
                ],
            ),
            188,
        ),
        (Event::Nothing, 183),
        (Event::Nothing, 171),
        (Event::Nothing, 120),
        (t([0.3491529511311262, -0.3390650687745866, 0.0]), 169),
        (Event::Nothing, 20),
        (Event::Nothing, 154),
        (Event::Stale, 142),
        (t([0.0, 0.24717507478661105, 0.2606301706097746]), 183),
        (Event::Nothing, 169),
        (Event::Nothing, 194),
        (Event::Nothing, 178),
    ];
    run(&events).unwrap();
}

/// The acceleration of the streams of the lead's tests, m/s² (within the robot's 0.25).
const STREAM_ACCEL: f64 = 0.1;

/// The stream's x at tick `k` (1 ms each) from `x0`: up to `speed` at STREAM_ACCEL, then
/// on at `speed`.
fn ramped_x(x0: f64, speed: f64, k: u64) -> f64 {
    let (t, ramp) = (k as f64 * 1e-3, speed / STREAM_ACCEL);
    x0 + if t < ramp {
        0.5 * STREAM_ACCEL * t * t
    } else {
        speed * (t - 0.5 * ramp)
    }
}

/// Streams targets along x from x0, one per tick, for `ticks` ticks: from rest at
/// [`STREAM_ACCEL`] to `speed` m/s, then the same pose for `still` ticks (standing still)
/// and then nothing for `silent` ticks. Returns the (target x, setpoint x) of every tick.
fn stream_along_x(
    sup: &mut Sup,
    now: &mut u64,
    x0: f64,
    speed: f64,
    ticks: u64,
    still: u64,
    silent: u64,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut x = x0;
    for k in 0..ticks + still + silent {
        *now += 1000;
        if k < ticks {
            x = ramped_x(x0, speed, k);
        }
        if k < ticks + still {
            let target = Pose {
                t: Vector3::new(x, 0.0, 0.160),
                r: Rotation3::identity(),
            };
            sup.submit(&target, *now, *now).unwrap();
        }
        out.push((x, sup.tick().pose.t.x));
    }
    out
}

/// The lead (`supervisor::lead`): a stream inside the certified regions, accelerating
/// within the robot's limits, is followed on the master's pose, not the braking curve's
/// distance (1.34 mm, 54 ms at 25 mm/s) behind it: from the end of the ramp on, the
/// setpoint stands within one tick's motion (u·dt: the setpoint after the tick against the
/// target before it) of the newest target at 10 and 25 mm/s. Without the lead it trails by
/// the braking curve's distance.
#[test]
fn a_steady_stream_is_followed_on_the_masters_pose() {
    for (speed, lead) in [(0.010, true), (0.025, true), (0.025, false)] {
        let cfg = SupervisorConfig {
            lead,
            ..SupervisorConfig::default()
        };
        let mut sup = Supervisor::new(
            RsprGeometry::reference(),
            Branch::OUTER,
            Limits::reference(),
            cfg,
            &Pose::central(0.160),
        )
        .unwrap();
        // Settle on the start first (the region around it is certified while idle).
        let (start, mut now) = (-0.012, 1_000_000);
        stream_along_x(&mut sup, &mut now, start, 0.0, 1, 1500, 0);
        let run = stream_along_x(&mut sup, &mut now, start, speed, 900, 0, 0);
        // From the end of the ramp (v/a: 50 and 125 ms) and a velocity window on.
        let from = (speed / STREAM_ACCEL * 1e3) as usize + 300;
        let worst = run[from..]
            .iter()
            .map(|(t, s)| t - s)
            .fold(0.0f64, |m, e| m.max(e.abs()));
        if lead {
            assert!(
                worst <= speed * 1e-3 * (1.0 + 1e-6),
                "{speed} m/s: the setpoint trails the stream by {worst} m"
            );
        } else {
            let d = kinematics_core::supervisor::lead::lead_distance(speed, 0.95 * 0.25, 1e-3);
            assert!(worst > 0.9 * d, "without the lead it trails by {worst} m");
        }
    }
}

/// A stream that stops abruptly at 25 mm/s is overshot by at most the lead (the braking
/// curve's distance, 1.34 mm, plus the tick of motion the velocity window still holds), and
/// the robot goes back to the master's last pose once the stream has stood still for a
/// window; when the stream falls silent instead, once it has been silent for SILENCE_US.
/// No refusal, no stop, and the limits hold throughout (the property tests check them on
/// random streams).
#[test]
fn an_abrupt_stop_of_the_stream_is_overshot_by_at_most_the_lead_and_undone() {
    use kinematics_core::supervisor::lead::{lead_distance, SILENCE_US};
    let d = lead_distance(0.025, 0.95 * 0.25, 1e-3);
    for (still, silent) in [(600u64, 0u64), (1, 600 + SILENCE_US / 1000)] {
        let mut sup = supervisor(Limits::reference());
        let mut now = 1_000_000;
        stream_along_x(&mut sup, &mut now, -0.012, 0.0, 1, 1500, 0);
        let run = stream_along_x(&mut sup, &mut now, -0.012, 0.025, 700, still, silent);
        let last = run[699].0;
        let over = run.iter().map(|(_, s)| s - last).fold(0.0f64, f64::max);
        assert!(
            over <= d + 0.025e-3 && over > 0.5 * d,
            "overshoot {over} m, lead {d} m"
        );
        let end = run.last().unwrap().1;
        assert!(
            (end - last).abs() < 1e-12,
            "ends at {end}, the master at {last}"
        );
        let c = sup.counters();
        assert_eq!((c.refused(), c.stops), (0, 0));
        assert!(c.led > 0);
    }
}

/// The same abrupt stop of a stream at 100 Hz whose targets arrive 3 ms after their
/// stamps: the lead then also covers that delay and the target's mean age while it is the
/// newest ((T - dt)/2 = 4.5 ms), 0.19 mm more at 25 mm/s, and the overshoot stays within
/// that lead (plus a tick of motion; 1.20 mm against 1.53 mm); the robot goes back to the
/// master's last pose.
#[test]
fn an_abrupt_stop_of_a_late_100_hz_stream_is_overshot_by_at_most_its_lead() {
    use kinematics_core::supervisor::lead::lead_distance;
    let (speed, delay_us, every) = (0.025, 3_000u64, 10u64);
    let lead = lead_distance(speed, 0.95 * 0.25, 1e-3) + speed * (3e-3 + 4.5e-3);
    let mut sup = supervisor(Limits::reference());
    let mut now = 1_000_000u64;
    let x0 = -0.012;
    let at = |x: f64| Pose {
        t: Vector3::new(x, 0.0, 0.160),
        r: Rotation3::identity(),
    };
    // Settle on the start first (the region around it is certified while idle).
    stream_along_x(&mut sup, &mut now, x0, 0.0, 1, 1500, 0);
    // (The late stamps start after the settling ones: stamps only go forward.)
    now += delay_us;
    let (mut x, mut over) = (x0, 0.0f64);
    let (ticks, still) = (700u64, 600u64);
    for k in 0..ticks + still {
        now += 1000;
        if k < ticks {
            x = ramped_x(x0, speed, k);
        }
        if k % every == 0 {
            sup.submit(&at(x), now - delay_us, now).unwrap();
        }
        let s = sup.tick().pose.t.x;
        if k >= ticks {
            over = over.max(s - x);
        }
    }
    println!("overshoot {:.4} mm, lead {:.4} mm", over * 1e3, lead * 1e3);
    assert!(
        over <= lead + speed * 1e-3 && over > 0.5 * lead,
        "overshoot {over} m, lead {lead} m"
    );
    let end = sup.tick().pose.t.x;
    assert!((end - x).abs() < 1e-12, "ends at {end}, the master at {x}");
    let c = sup.counters();
    assert_eq!((c.refused(), c.stops), (0, 0));
    assert!(c.led > 0);
}

/// A target accepted at once in a certified region supersedes both the path in
/// verification and the target queued behind it: the robot ends on the newest target,
/// never on an older queued one taken after it (a far target A in verification, B queued,
/// C certified, then D verified: the robot ends on D).
#[test]
fn a_certified_target_supersedes_the_queued_one_too() {
    let cfg = SupervisorConfig {
        lead: false,
        ..SupervisorConfig::default()
    };
    let start = Pose::central(0.160);
    let mut sup = Supervisor::new(
        RsprGeometry::reference(),
        Branch::OUTER,
        Limits::reference(),
        cfg,
        &start,
    )
    .unwrap();
    let at = |x_mm: f64| Pose {
        t: Vector3::new(x_mm * 1e-3, 0.0, 0.160),
        r: Rotation3::identity(),
    };
    let mut now = 1_000_000u64;
    let mut send = |sup: &mut Sup, p: &Pose<f64>, ticks: u32| {
        now += 1000;
        sup.submit(p, now, now).unwrap();
        for _ in 0..ticks {
            sup.tick();
        }
    };
    // Idle: the region around the start is certified.
    for _ in 0..50 {
        sup.tick();
    }
    assert!(sup.certificate().is_some_and(|c| c.contains(&at(0.05))));
    send(&mut sup, &at(12.0), 1); // A: in verification
    send(&mut sup, &at(-12.0), 1); // B: queued
    send(&mut sup, &at(0.05), 1); // C: certified, supersedes A and B
    send(&mut sup, &at(6.0), 3000); // D: verified, then reached
    assert!(
        (sup.setpoint().t - at(6.0).t).norm() < 1e-9,
        "ends at {:?}, not on the newest target",
        sup.setpoint().t
    );
}

/// The step and the evaluation phase are two calls: a step that finds the evaluation phase
/// did not run since the step before (a scheduling fault) brakes a moving robot at once, on
/// the stretch checked before, counts it, and stops within the braking distance; a robot
/// standing still only counts it. Once the evaluation runs again, targets are taken.
#[test]
fn a_step_without_the_evaluation_phase_before_it_brakes() {
    let mut sup = supervisor(Limits::reference());
    at_the_speed_limit_along_x(&mut sup);
    // Steps alone from here: the first follows the last tick's evaluation phase and moves
    // on; the second finds none since and brakes.
    assert_eq!(sup.step().mode, Mode::Moving);
    assert_eq!(sup.counters().evaluations_missed, 0);
    let v = sup.twist().fixed_rows::<3>(0).norm();
    let at = sup.setpoint().t.x;
    let out = sup.step();
    assert_eq!(out.mode, Mode::Braking);
    assert_eq!(sup.counters().evaluations_missed, 1);
    assert!(out.twist.fixed_rows::<3>(0).norm() < v);
    let mut ticks = 1;
    while sup.step().twist != Twist::zeros() {
        ticks += 1;
        assert!(ticks < 200, "still moving");
    }
    let travel = sup.setpoint().t.x - at;
    let bound = v * v / (2.0 * 0.25) + v * 1e-3;
    println!(
        "no evaluation phase: braked from {v} m/s in {ticks} ticks over {:.3} mm (bound {:.3})",
        travel * 1e3,
        bound * 1e3
    );
    assert!(travel > 0.0 && travel <= bound, "{travel} > {bound}");
    assert!(sup.counters().evaluations_missed >= ticks);
    // Standing still, a missing evaluation phase moves nothing.
    let missed = sup.counters().evaluations_missed;
    let still = sup.step();
    assert_eq!(still.twist, Twist::zeros());
    assert_eq!(sup.counters().evaluations_missed, missed + 1);
    assert_eq!(
        sup.counters().stops,
        0,
        "a controlled stop, not a latched one"
    );
    // With the evaluation phase back, a new target is verified and reached.
    let back = Pose::central(0.160);
    sup.submit(&back, 2_000_000, 2_000_000).unwrap();
    for _ in 0..3000 {
        sup.tick();
    }
    assert!((sup.setpoint().t - back.t).norm() < 1e-9);
    // (The first tick's step still followed a step alone.)
    assert_eq!(sup.counters().evaluations_missed, missed + 2);
}
