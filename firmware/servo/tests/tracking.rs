#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Tracking-error monitor: stuck encoder, disconnected motor, following error, latching,
//! and no false trips during normal tracking.
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best

use crate::common;

use common::{smooth, SixJoints};
use proptest::prelude::*;
use servo::tracking::TrackingSample;
use servo::{
    FaultKind, JointServo, ServoConfig, TrackingConfig, TrackingFault, TrackingLimits,
    TrackingMonitor,
};

const DT: f64 = 1e-3;

/// Runs the default servo on the six test joints along a ramp of `speed` on joint
/// `joint` (the others hold 0) for up to 2 s; `measure` maps the true positions to what
/// the servo sees, `disconnected` cuts that joint's motor. Returns the fault and the
/// time it tripped, s.
fn run_until_fault(
    joint: usize,
    speed: f64,
    stuck_encoder: bool,
    disconnected: bool,
) -> Option<(TrackingFault<f64>, f64)> {
    let mut servo = JointServo::new(&ServoConfig::default()).unwrap();
    let mut plant = SixJoints::new();
    plant.disconnected[joint] = disconnected;
    for k in 0..2000 {
        let t = k as f64 * DT;
        let mut q = [0.0; 6];
        let mut v = [0.0; 6];
        q[joint] = speed * t;
        v[joint] = speed;
        let mut y = plant.positions();
        if stuck_encoder {
            y[joint] = 0.0;
        }
        let out = servo.update(&q, &v, &y, DT);
        if let Some(f) = out.fault {
            // Safe state from the tripping sample on.
            assert_eq!(out.duty, [0.0; 6]);
            return Some((f, t));
        }
        plant.step(&out.duty, DT);
    }
    None
}

#[test]
fn a_stuck_leg_encoder_trips_the_no_motion_check_before_the_window_time() {
    // Leg moving at 20 mm/s, encoder frozen: the motor actually runs, the servo sees 0.
    let l = TrackingLimits::<f64>::leg();
    let (f, t) = run_until_fault(0, 0.02, true, false).unwrap();
    println!(
        "stuck leg encoder at 20 mm/s: {f:?} after {:.0} ms",
        t * 1e3
    );
    assert_eq!(f.kind, FaultKind::NoMotion);
    assert_eq!(f.joint, Some(0));
    // Within the time the window check alone would need: window / speed + time to fault.
    assert!(t <= l.window / 0.02 + l.time_to_fault);
    assert!(f.duration > l.stuck_time);
    assert!(f.error > 0.0);
    assert_eq!(f.time_us, ((t + DT) * 1e6).round() as u64);
}

#[test]
fn a_disconnected_link_motor_trips_within_window_and_time() {
    // Link commanded at 0.5 rad/s, motor leads open: nothing moves.
    let l = TrackingLimits::<f64>::link();
    let (f, t) = run_until_fault(4, 0.5, false, true).unwrap();
    println!(
        "disconnected link motor at 0.5 rad/s: {f:?} after {:.0} ms",
        t * 1e3
    );
    assert_eq!(f.joint, Some(4));
    assert!(matches!(
        f.kind,
        FaultKind::NoMotion | FaultKind::FollowingError
    ));
    assert!(t <= l.window / 0.5 + l.time_to_fault + 2.0 * DT);
}

#[test]
fn a_slow_stuck_encoder_with_low_duty_is_caught_by_the_following_error_window() {
    // 1 mm/s on a leg: the error grows slowly; whichever check comes first, it trips
    // by window / speed + time to fault.
    let l = TrackingLimits::<f64>::leg();
    let (f, t) = run_until_fault(2, 0.001, true, false).unwrap();
    println!("stuck leg encoder at 1 mm/s: {f:?} after {:.0} ms", t * 1e3);
    assert_eq!(f.joint, Some(2));
    assert!(t <= l.window / 0.001 + l.time_to_fault + 3.0 * DT);
}

#[test]
fn the_following_error_must_persist_longer_than_the_time_to_fault() {
    let l = TrackingLimits::<f64>::leg(); // window 1 mm, 50 ms
    let mut m = TrackingMonitor::new(1, l);
    let s = |e: f64| TrackingSample {
        setpoint: e,
        setpoint_velocity: 0.0,
        measured: 0.0,
        duty: 0.0,
    };
    // 40 ms outside, back in, 40 ms outside again: no trip (the timer restarts).
    for k in 0..240u64 {
        let e = if (k / 40) % 2 == 0 { 1.5e-3 } else { 0.5e-3 };
        assert_eq!(m.update(&s(e), DT, k * 1000), None);
    }
    // Continuously outside: trips on the 51st sample (> 50 ms).
    let mut tripped = None;
    for k in 0..100u64 {
        if let Some(f) = m.update(&s(-1.2e-3), DT, 1_000_000 + k * 1000) {
            tripped = Some((k, f));
            break;
        }
    }
    let (k, f) = tripped.unwrap();
    assert_eq!(k, 50);
    assert_eq!(f.kind, FaultKind::FollowingError);
    assert_eq!(f.joint, Some(1));
    assert_eq!(f.error, -1.2e-3);
    assert!((f.duration - 0.051).abs() < 1e-9);
    assert_eq!(f.time_us, 1_050_000);
    assert_eq!(
        f.to_string(),
        "following error on joint 1 (l2): error -0.001200 m for 0.0510 s at t = 1050000 us"
    );
    // Latched: the same fault comes back whatever the input, until reset.
    assert_eq!(m.update(&s(0.0), DT, 2_000_000), Some(f));
    assert_eq!(m.fault(), Some(f));
    m.reset();
    assert_eq!(m.fault(), None);
    assert_eq!(m.update(&s(0.0), DT, 2_001_000), None);
}

#[test]
fn braking_or_low_duty_or_slow_commands_never_count_as_no_motion() {
    let mut m = TrackingMonitor::new(0, TrackingLimits::<f64>::leg());
    // Measured constant and within the window for 1 s in each case.
    let cases = [
        (0.01, -0.5), // duty opposes the commanded motion (braking)
        (0.01, 0.04), // duty below stuck_duty
        (0.001, 0.9), // commanded speed below stuck_min_speed
    ];
    for (v, duty) in cases {
        for k in 0..1000u64 {
            let s = TrackingSample {
                setpoint: 0.5e-3,
                setpoint_velocity: v,
                measured: 0.0,
                duty,
            };
            assert_eq!(m.update(&s, DT, k), None);
        }
    }
}

#[test]
fn after_a_fault_every_duty_stays_zero_until_reset() {
    let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
    // Joint 3 far outside its window with the others fine.
    let q = [0.0, 0.0, 0.0, 0.5, 0.0, 0.0];
    let mut fault = None;
    for _ in 0..100 {
        let out = servo.update(&q, &[0.0; 6], &[0.0; 6], DT);
        if out.fault.is_some() {
            assert_eq!(out.duty, [0.0; 6]);
            fault = out.fault;
            break;
        }
        assert!(out.duty[3] > 0.0);
    }
    let fault = fault.unwrap();
    assert_eq!(fault.kind, FaultKind::FollowingError);
    assert_eq!(fault.joint, Some(3));
    // Stays safe even with perfect tracking afterwards.
    for _ in 0..100 {
        let out = servo.update(&q, &[0.0; 6], &q, DT);
        assert_eq!(out.duty, [0.0; 6]);
        assert_eq!(out.saturated, [false; 6]);
        assert_eq!(out.fault, Some(fault));
    }
    assert_eq!(servo.tracking(3).unwrap().fault(), Some(fault));
    // Reset at the measured positions: running again, no kick.
    servo.reset(&q);
    let out = servo.update(&q, &[0.0; 6], &q, DT);
    assert_eq!(out.fault, None);
    assert!(out.duty.iter().all(|d| d.abs() < 1e-12));
}

#[test]
fn tracking_config_defaults_are_valid_and_validate_names_the_field() {
    TrackingConfig::<f64>::default().validate().unwrap();
    TrackingConfig::<f32>::default().validate().unwrap();
    let mut c = TrackingConfig::<f64>::default();
    c.joints[2].window = 0.0;
    let e = c.validate().unwrap_err();
    assert_eq!((e.section, e.field, e.joint), ("tracking", "window", 2));
    let mut c = TrackingConfig::<f64>::default();
    c.joints[4].stuck_duty = 1.5;
    assert_eq!(c.validate().unwrap_err().field, "stuck_duty");
    let mut c = TrackingConfig::<f64>::default();
    c.joints[5].time_to_fault = f64::NAN;
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "tracking.time_to_fault of joint 5 (theta3) must be finite and >= 0"
    );
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: a joint whose measurement follows a smooth setpoint within bounded noise
    /// (less than half the window and half the stuck motion) never trips, whatever the
    /// duty does.
    #[test]
    fn normal_tracking_within_the_window_never_trips_the_monitor(
        leg in any::<bool>(),
        amp in 0.0f64..1.0,
        freq in 0.05f64..5.0,
        noise_frac in 0.0f64..0.5,
        noise in prop::collection::vec(-1.0f64..1.0, 2000),
        duty in prop::collection::vec(-1.0f64..1.0, 2000),
    ) {
        let l: TrackingLimits<f64> = if leg { TrackingLimits::leg() } else { TrackingLimits::link() };
        let mut m = TrackingMonitor::new(0, l);
        // Amplitude up to 20 mm (legs) / 1 rad (links).
        let a = amp * if leg { 0.02 } else { 1.0 };
        let w = std::f64::consts::TAU * freq;
        let bound = noise_frac * l.window.min(l.stuck_motion);
        for k in 0..2000 {
            let t = k as f64 * DT;
            let s = TrackingSample {
                setpoint: a * (w * t).sin(),
                setpoint_velocity: a * w * (w * t).cos(),
                measured: a * (w * t).sin() + bound * noise[k],
                duty: duty[k],
            };
            prop_assert_eq!(m.update(&s, DT, k as u64 * 1000), None);
        }
    }

    /// Property: the whole servo with its own duties never trips when the measured
    /// positions follow the setpoints within +-3 encoder counts of noise.
    #[test]
    fn normal_tracking_with_encoder_noise_never_trips_the_servo(
        speed in 0.1f64..3.0,
        noise in prop::collection::vec(prop::array::uniform6(-3i32..=3), 1000),
    ) {
        let mut servo = JointServo::new(&ServoConfig::default()).unwrap();
        let count = [1.5e-6, 1.5e-6, 1.5e-6, 8.73e-5, 8.73e-5, 8.73e-5];
        for (k, n) in noise.iter().enumerate() {
            let (q, v) = smooth(k as f64 * DT * speed);
            let v = v.map(|x| x * speed);
            let mut y = q;
            for j in 0..6 {
                y[j] += f64::from(n[j]) * count[j];
            }
            let out = servo.update(&q, &v, &y, DT);
            prop_assert_eq!(out.fault, None);
            prop_assert!(out.duty.iter().all(|d| d.is_finite() && d.abs() <= 1.0));
        }
    }
}
