#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Properties of the teleoperation mapping (`Teleop`), over random master motions:
//!
//! - re-engaging after a clutch or a dead-man release never moves the target: the first
//!   `servo_cp` equals the held pose bit for bit, whatever the master did meanwhile, with
//!   the tremor filter and the limits on, for position and rate masters, across a scale
//!   change;
//! - with the filter off and the limits out of reach, scaling 1:5 (with a random
//!   registration rotation) moves the target by exactly a fifth of the master's motion,
//!   rotated into {0}, up to float rounding (a few ulps of the coordinates involved);
//! - a released dead-man holds: every tick emits `Hold(OperatorAbsent)` and the held
//!   pose does not change;
//! - no output exceeds the velocity and acceleration limits, with jittered ticks, wild
//!   master jumps and clutch toggles;
//! - the whole pipeline delays a slow sine by the filter's phase delay.

mod common;

use common::proptest_config;
use masters::pose::{rotate, rotation_increment, CartesianPose, Twist};
use masters::teleop::{
    HoldReason, MotionScale, Teleop, TeleopConfig, TeleopError, TeleopOutput, TremorSuppression,
};
use masters::{MasterInput, MasterSample, MotionLimits, OperatorButtons};
use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;

const DT: f64 = 0.01;

fn engaged() -> OperatorButtons {
    OperatorButtons {
        clutch: false,
        operator_present: true,
    }
}

fn pose_sample(t_s: f64, p: CartesianPose, buttons: OperatorButtons) -> MasterSample {
    MasterSample {
        t_s,
        input: MasterInput::Pose(p),
        buttons,
        device_time_us: None,
        deflection: None,
    }
}

fn twist_sample(t_s: f64, t: Twist, buttons: OperatorButtons) -> MasterSample {
    MasterSample {
        t_s,
        input: MasterInput::Twist(t),
        buttons,
        device_time_us: None,
        deflection: None,
    }
}

fn robot_start() -> CartesianPose {
    CartesianPose::from_position_rotation_vector([0.001, -0.002, 0.16], [0.05, 0.1, -0.2]).unwrap()
}

/// A master motion step: displacement (m) and rotation (rad) per tick.
fn step_strategy(max_mm: f64, max_deg: f64) -> impl Strategy<Value = ([f64; 3], [f64; 3])> {
    let d = max_mm * 1e-3;
    let r = max_deg.to_radians();
    (
        proptest::array::uniform3(-d..d),
        proptest::array::uniform3(-r..r),
    )
}

fn moved(p: &CartesianPose, (dp, dr): &([f64; 3], [f64; 3])) -> CartesianPose {
    CartesianPose {
        position_m: p.position_m + Vector3::from(*dp),
        orientation: rotate(&p.orientation, &Vector3::from(*dr)),
    }
}

fn pose_bits(p: &CartesianPose) -> [u64; 7] {
    let q = p.orientation.coords;
    [
        p.position_m.x.to_bits(),
        p.position_m.y.to_bits(),
        p.position_m.z.to_bits(),
        q.x.to_bits(),
        q.y.to_bits(),
        q.z.to_bits(),
        q.w.to_bits(),
    ]
}

proptest! {
    #![proptest_config(proptest_config(256))]

    /// Clutch, move the master anywhere, change the scale, release: the first target is
    /// the held pose bit for bit (pose master, filter and limits on).
    #[test]
    fn clutch_reengage_never_jumps(
        engaged_steps in proptest::collection::vec(step_strategy(0.5, 0.5), 1..40),
        clutched_steps in proptest::collection::vec(step_strategy(20.0, 10.0), 1..20),
        after_steps in proptest::collection::vec(step_strategy(0.5, 0.5), 1..10),
        new_scale in 0.05f64..2.0,
        release_deadman in any::<bool>(),
    ) {
        let mut tele = Teleop::new(TeleopConfig {
            scale: MotionScale::new(0.2, 0.5).unwrap(),
            ..TeleopConfig::default()
        }).unwrap();
        tele.start(0.0, robot_start()).unwrap();
        let mut t = 0.0;
        let mut master = CartesianPose::from_position_rotation_vector([0.1, 0.2, 0.3], [0.3, 0.0, 1.0]).unwrap();
        let mut last = None;
        for s in &engaged_steps {
            t += DT;
            master = moved(&master, s);
            if let TeleopOutput::ServoCp { pose, .. } = tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap() {
                last = Some(pose);
            }
        }
        let last = last.unwrap();
        prop_assert_eq!(pose_bits(&tele.held_pose()), pose_bits(&last));
        let decoupled = if release_deadman {
            OperatorButtons { clutch: false, operator_present: false }
        } else {
            OperatorButtons { clutch: true, operator_present: true }
        };
        for s in &clutched_steps {
            t += DT;
            master = moved(&master, s);
            let out = tele.step(t, Some(&pose_sample(t, master, decoupled))).unwrap();
            prop_assert!(matches!(out, TeleopOutput::Hold(_)), "{:?}", out);
        }
        tele.set_scale(MotionScale::new(new_scale, new_scale).unwrap()).unwrap();
        t += DT;
        let out = tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap();
        let TeleopOutput::ServoCp { pose, .. } = out else { panic!("{out:?}") };
        prop_assert_eq!(pose_bits(&pose), pose_bits(&last), "jump on re-engage");
        // and it goes on following from there
        for s in &after_steps {
            t += DT;
            master = moved(&master, s);
            let out = tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap();
            prop_assert!(matches!(out, TeleopOutput::ServoCp { .. }), "{:?}", out);
        }
    }

    /// The same for a rate master (virtual master integrated from the twist).
    #[test]
    fn clutch_reengage_never_jumps_rate_master(
        twists in proptest::collection::vec(proptest::array::uniform6(-0.02f64..0.02), 2..40),
        clutch_at in 1usize..39,
        clutch_len in 1usize..20,
    ) {
        let mut tele = Teleop::new(TeleopConfig::default()).unwrap();
        tele.start(0.0, robot_start()).unwrap();
        let mut t = 0.0;
        let mut held_before = None;
        let mut clutched_ticks = 0;
        for (k, tw) in twists.iter().enumerate() {
            t += DT;
            let clutch = k >= clutch_at && clutched_ticks < clutch_len;
            if clutch {
                clutched_ticks += 1;
            }
            let b = OperatorButtons { clutch, operator_present: true };
            let out = tele.step(t, Some(&twist_sample(t, Twist::from_array(*tw).unwrap(), b))).unwrap();
            match out {
                TeleopOutput::Hold(r) => {
                    prop_assert_eq!(r, HoldReason::Clutched);
                    if held_before.is_none() {
                        held_before = Some(tele.held_pose());
                    }
                }
                TeleopOutput::ServoCp { pose, .. } => {
                    if let Some(h) = held_before.take() {
                        prop_assert_eq!(pose_bits(&pose), pose_bits(&h));
                    }
                }
            }
        }
    }

    /// Scaling 1:5 (translation and rotation) with a random registration: the target
    /// moves by exactly a fifth of the master's motion mapped into {0}.
    #[test]
    fn scaling_one_fifth(
        steps in proptest::collection::vec(step_strategy(2.0, 2.0), 1..30),
        reg in proptest::array::uniform3(-3.0f64..3.0),
    ) {
        let registration = UnitQuaternion::from_scaled_axis(Vector3::from(reg));
        let mut tele = Teleop::new(TeleopConfig {
            scale: MotionScale::new(0.2, 0.2).unwrap(),
            registration,
            tremor: None,
            limits: MotionLimits {
                linear_speed_m_s: 1e6,
                angular_speed_rad_s: 1e6,
                linear_accel_m_s2: 1e9,
                angular_accel_rad_s2: 1e9,
            },
            ..TeleopConfig::default()
        }).unwrap();
        let start = robot_start();
        tele.start(0.0, start).unwrap();
        let master0 = CartesianPose::from_position_rotation_vector([0.05, -0.02, 0.1], [0.0, 0.4, 0.0]).unwrap();
        let mut master = master0;
        let mut t = DT;
        tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap();
        let mut target = start;
        for s in &steps {
            t += DT;
            master = moved(&master, s);
            let TeleopOutput::ServoCp { pose, .. } = tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap() else {
                panic!("following")
            };
            target = pose;
        }
        let d_master = master.position_m - master0.position_m;
        let want = registration * d_master * 0.2;
        let got = target.position_m - start.position_m;
        // a few ulps of the coordinates involved (positions ~0.2 m, f64)
        let tol = 1e-15 * 16.0 * (1.0 + start.position_m.norm() + master.position_m.norm());
        prop_assert!((got - want).norm() <= tol, "translation {got:?} vs {want:?}");
        let r_master = rotation_increment(&master0.orientation, &master.orientation);
        let r_want = registration * r_master * 0.2;
        let r_got = rotation_increment(&start.orientation, &target.orientation);
        prop_assert!((r_got - r_want).norm() <= 1e-13, "rotation {r_got:?} vs {r_want:?}");
    }

    /// Dead-man released: every tick holds, the held pose does not move.
    #[test]
    fn deadman_release_holds(
        engaged_steps in proptest::collection::vec(step_strategy(0.5, 0.5), 1..20),
        released_steps in proptest::collection::vec(step_strategy(10.0, 10.0), 1..30),
        clutch_too in proptest::collection::vec(any::<bool>(), 30),
    ) {
        let mut tele = Teleop::new(TeleopConfig::default()).unwrap();
        tele.start(0.0, robot_start()).unwrap();
        let mut master = CartesianPose::identity();
        let mut t = 0.0;
        for s in &engaged_steps {
            t += DT;
            master = moved(&master, s);
            tele.step(t, Some(&pose_sample(t, master, engaged()))).unwrap();
        }
        let held = tele.held_pose();
        for (s, c) in released_steps.iter().zip(&clutch_too) {
            t += DT;
            master = moved(&master, s);
            let b = OperatorButtons { clutch: *c, operator_present: false };
            let out = tele.step(t, Some(&pose_sample(t, master, b))).unwrap();
            prop_assert_eq!(out, TeleopOutput::Hold(HoldReason::OperatorAbsent));
            prop_assert_eq!(pose_bits(&tele.held_pose()), pose_bits(&held));
        }
    }

    /// No output exceeds the limits (the speed caps with the acceleration limits on):
    /// jittered ticks, master jumps up to 50 mm and 30 deg per tick, random clutch
    /// presses, with the tremor suppression on or off.
    #[test]
    fn limits_hold(
        steps in proptest::collection::vec(
            (step_strategy(50.0, 30.0), 0.004f64..0.02, prop::bool::weighted(0.05)),
            1..150,
        ),
        filter_on in any::<bool>(),
    ) {
        let limits = MotionLimits::with_acceleration();
        let mut tele = Teleop::new(TeleopConfig {
            tremor: if filter_on { TeleopConfig::default().tremor } else { None },
            limits,
            ..TeleopConfig::default()
        }).unwrap();
        tele.start(0.0, robot_start()).unwrap();
        let mut master = CartesianPose::identity();
        let mut t = 0.0;
        // (time, pose, linear velocity, angular velocity) of the previous output in a run
        let mut prev: Option<(f64, CartesianPose, Vector3<f64>, Vector3<f64>)> = None;
        let rel = 1.0 + 1e-9;
        for (s, dt, clutch) in &steps {
            t += dt;
            master = moved(&master, s);
            let b = OperatorButtons { clutch: *clutch, operator_present: true };
            match tele.step(t, Some(&pose_sample(t, master, b))).unwrap() {
                TeleopOutput::Hold(_) => prev = None,
                TeleopOutput::ServoCp { pose, .. } => {
                    let (v, w, dtk) = match prev {
                        Some((tp, pp, _, _)) => (
                            (pose.position_m - pp.position_m) / (t - tp),
                            rotation_increment(&pp.orientation, &pose.orientation) / (t - tp),
                            t - tp,
                        ),
                        // engagement: from rest, no motion
                        None => (Vector3::zeros(), Vector3::zeros(), *dt),
                    };
                    prop_assert!(v.norm() <= limits.linear_speed_m_s * rel, "speed {}", v.norm());
                    prop_assert!(w.norm() <= limits.angular_speed_rad_s * rel, "angular speed {}", w.norm());
                    let (v0, w0) = prev.map_or((Vector3::zeros(), Vector3::zeros()), |p| (p.2, p.3));
                    prop_assert!((v - v0).norm() <= limits.linear_accel_m_s2 * dtk * rel + 1e-15,
                        "acceleration {}", (v - v0).norm() / dtk);
                    prop_assert!((w - w0).norm() <= limits.angular_accel_rad_s2 * dtk * rel + 1e-12,
                        "angular acceleration {}", (w - w0).norm() / dtk);
                    prev = Some((t, pose, v, w));
                }
            }
        }
    }
}

/// Scale changes are refused while following and accepted while clutched.
#[test]
fn scale_changes_only_while_decoupled() {
    let mut tele = Teleop::new(TeleopConfig::default()).unwrap();
    tele.start(0.0, robot_start()).unwrap();
    let m = CartesianPose::identity();
    tele.step(0.01, Some(&pose_sample(0.01, m, engaged())))
        .unwrap();
    assert_eq!(
        tele.set_scale(MotionScale::new(0.5, 0.5).unwrap()),
        Err(TeleopError::ScaleWhileFollowing)
    );
    let clutched = OperatorButtons {
        clutch: true,
        operator_present: true,
    };
    tele.step(0.02, Some(&pose_sample(0.02, m, clutched)))
        .unwrap();
    assert_eq!(tele.set_scale(MotionScale::new(0.5, 0.5).unwrap()), Ok(()));
    assert!(matches!(
        MotionScale::new(0.0, 1.0),
        Err(TeleopError::Scale {
            which: "translation",
            ..
        })
    ));
    assert!(matches!(
        MotionScale::new(1.0, f64::NAN),
        Err(TeleopError::Scale {
            which: "rotation",
            ..
        })
    ));
}

/// A position master that stops sending is lost after the timeout; a stalled stream
/// holds for its tick; time must advance.
#[test]
fn master_lost_and_stream_gap() {
    let mut tele = Teleop::new(TeleopConfig::default()).unwrap();
    assert_eq!(
        tele.step(0.0, None),
        Ok(TeleopOutput::Hold(HoldReason::NotStarted))
    );
    tele.start(0.0, robot_start()).unwrap();
    assert_eq!(
        tele.step(0.01, None),
        Ok(TeleopOutput::Hold(HoldReason::NoMaster))
    );
    let m = CartesianPose::identity();
    assert!(matches!(
        tele.step(0.02, Some(&pose_sample(0.02, m, engaged()))),
        Ok(TeleopOutput::ServoCp { .. })
    ));
    assert!(matches!(
        tele.step(0.12, None),
        Ok(TeleopOutput::ServoCp { .. })
    ));
    assert_eq!(
        tele.step(0.13, None),
        Ok(TeleopOutput::Hold(HoldReason::MasterLost))
    );
    assert!(matches!(
        tele.step(0.14, Some(&pose_sample(0.14, m, engaged()))),
        Ok(TeleopOutput::ServoCp { .. })
    ));
    assert_eq!(
        tele.step(0.30, Some(&pose_sample(0.30, m, engaged()))),
        Ok(TeleopOutput::Hold(HoldReason::StreamGap))
    );
    assert!(matches!(
        tele.step(0.30, None),
        Err(TeleopError::TimeNotIncreasing { .. })
    ));
    assert!(matches!(
        tele.step(f64::NAN, None),
        Err(TeleopError::NonFiniteTime(_))
    ));
    let bad = pose_sample(
        0.31,
        CartesianPose {
            position_m: Vector3::new(f64::NAN, 0.0, 0.0),
            orientation: UnitQuaternion::identity(),
        },
        engaged(),
    );
    assert!(matches!(
        tele.step(0.31, Some(&bad)),
        Err(TeleopError::NonFiniteSample { .. })
    ));
}

/// The pipeline delays a slow motion by the classic filter's phase delay: a 1 Hz, 2 mm
/// sine of the master (scale 1, limits out of reach) comes out of `Teleop` 60.7 ms late (the
/// filter's phase delay at 1 Hz, `TremorFilter::phase_delay_s`), measured by the phase
/// of the output's 1 Hz Fourier component over whole periods after the transient.
#[test]
fn pipeline_delay_is_the_filter_delay() {
    let mut tele = Teleop::new(TeleopConfig {
        limits: MotionLimits {
            linear_speed_m_s: 1.0,
            angular_speed_rad_s: 10.0,
            linear_accel_m_s2: 100.0,
            angular_accel_rad_s2: 1000.0,
        },
        tremor: Some(TremorSuppression::classic()),
        ..TeleopConfig::default()
    })
    .unwrap();
    let expected = tele.filter().unwrap().phase_delay_s(1.0);
    let start = robot_start();
    tele.start(0.0, start).unwrap();
    let (mut re, mut im) = (0.0, 0.0);
    let f = 1.0;
    for k in 1..=1000 {
        let t = k as f64 * DT;
        let x = 0.002 * (2.0 * std::f64::consts::PI * f * (t - DT)).sin();
        let m = CartesianPose {
            position_m: Vector3::new(x, 0.0, 0.0),
            orientation: UnitQuaternion::identity(),
        };
        let out = tele.step(t, Some(&pose_sample(t, m, engaged()))).unwrap();
        let TeleopOutput::ServoCp { pose, .. } = out else {
            panic!("following")
        };
        // the master moved since engagement at t = DT, when x was 0
        if k > 500 {
            let y = pose.position_m.x - start.position_m.x;
            let ph = 2.0 * std::f64::consts::PI * f * (t - DT);
            re += y * ph.cos();
            im += y * ph.sin();
        }
    }
    let phase = re.atan2(im); // y ≈ A sin(ωt − φ): im ∝ cos φ, re ∝ −sin φ
    let delay = -phase / (2.0 * std::f64::consts::PI * f);
    assert!(
        (delay - expected).abs() < 1e-6,
        "measured {delay} s, filter phase delay {expected} s"
    );
    assert!((delay - 0.0607).abs() < 0.0005, "{delay}");
}
