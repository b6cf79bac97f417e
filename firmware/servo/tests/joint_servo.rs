#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The six-joint servo: closed-loop tracking with the default configuration, input
//! faults, configuration handling, f32.
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best

use crate::common;

use common::{smooth, SixJoints};
use servo::{
    BacklashConfig, Direction, FaultKind, JointServo, PidConfig, ServoConfig, TrackingConfig,
    JOINT_NAMES,
};

const DT: f64 = 1e-3;

/// Runs the servo on the test joints along `smooth` for `seconds`; returns the largest
/// |setpoint - position| per joint after the first 0.1 s, and the largest |duty|.
fn track(config: &ServoConfig<f64>, seconds: f64, dt: f64) -> ([f64; 6], f64) {
    let mut servo = JointServo::new(config).unwrap();
    let mut plant = SixJoints::new();
    let mut max_err = [0.0f64; 6];
    let mut max_duty = 0.0f64;
    let n = (seconds / dt).round() as usize;
    for k in 0..n {
        let t = k as f64 * dt;
        let (q, v) = smooth(t);
        let out = servo.update(&q, &v, &plant.positions(), dt);
        assert_eq!(out.fault, None, "at t = {t}");
        plant.step(&out.duty, dt);
        let (q_next, _) = smooth(t + dt);
        for j in 0..6 {
            max_duty = max_duty.max(out.duty[j].abs());
            if t > 0.1 {
                max_err[j] = max_err[j].max((q_next[j] - plant.positions()[j]).abs());
            }
        }
    }
    (max_err, max_duty)
}

#[test]
fn the_default_config_tracks_a_smooth_six_joint_trajectory_closely_at_1_and_10_khz() {
    // No backlash and no friction in these test joints: compensate neither.
    let mut config = ServoConfig {
        backlash: BacklashConfig::off(),
        ..ServoConfig::default()
    };
    for g in config.pid.joints.iter_mut() {
        g.friction_ff = 0.0;
    }
    for dt in [1e-3, 1e-4] {
        let (err, duty) = track(&config, 3.0, dt);
        println!(
            "dt {dt}: max error legs {:.2} {:.2} {:.2} um, links {:.2e} {:.2e} {:.2e} rad; max |duty| {duty:.3}",
            err[0] * 1e6,
            err[1] * 1e6,
            err[2] * 1e6,
            err[3],
            err[4],
            err[5]
        );
        // Legs: 31 mm/s peak; links 1.3 rad/s peak.
        for j in 0..3 {
            assert!(err[j] < 10e-6, "{}: {}", JOINT_NAMES[j], err[j]);
        }
        for j in 3..6 {
            assert!(err[j] < 1e-3, "{}: {}", JOINT_NAMES[j], err[j]);
        }
        assert!(duty < 1.0);
    }
}

#[cfg(not(feature = "backlash-off"))]
#[test]
fn the_backlash_offset_is_added_to_the_motor_setpoint() {
    let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
    servo.reset_backlash(&[0.0; 6], &[Direction::Positive; 6]);
    let offsets = servo.backlash_offsets();
    assert!((offsets[0] - 0.06e-3).abs() < 1e-15);
    assert!((offsets[3] - 20.0 / 3600.0 * std::f64::consts::PI / 180.0 / 2.0).abs() < 1e-15);
    // At rest at the setpoint, the loop pushes the motor towards the +b/2 flank.
    let out = servo.update(&[0.0; 6], &[0.0; 6], &[0.0; 6], DT);
    assert!((out.duty[0] - PidConfig::<f64>::default().joints[0].kp * 0.06e-3).abs() < 1e-12);
    assert!(out.duty[3] > 0.0);
}

#[test]
fn a_non_finite_input_latches_a_named_fault_and_zeroes_every_duty() {
    let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
    let q = [1e-3, 0.0, 0.0, 0.0, 0.0, 0.0];
    let out = servo.update(&q, &[0.0; 6], &[0.0; 6], DT);
    assert!(out.duty[0] > 0.0);
    let mut y = [0.0; 6];
    y[4] = f64::NAN;
    let out = servo.update(&q, &[0.0; 6], &y, DT);
    assert_eq!(out.duty, [0.0; 6]);
    let f = out.fault.unwrap();
    assert_eq!((f.kind, f.joint), (FaultKind::NonFiniteInput, Some(4)));
    assert_eq!(f.time_us, 2000);
    // Latched.
    let out = servo.update(&q, &[0.0; 6], &[0.0; 6], DT);
    assert_eq!(out.duty, [0.0; 6]);
    assert_eq!(out.fault, Some(f));
    servo.reset(&[0.0; 6]);
    // A non-finite velocity or acceleration is caught too.
    let mut v = [0.0; 6];
    v[1] = f64::INFINITY;
    let f = servo.update(&q, &v, &[0.0; 6], DT).fault.unwrap();
    assert_eq!((f.kind, f.joint), (FaultKind::NonFiniteInput, Some(1)));
    servo.reset(&[0.0; 6]);
    let mut a = [0.0; 6];
    a[5] = f64::NAN;
    let f = servo
        .update_with_acceleration(&q, &[0.0; 6], &a, &[0.0; 6], DT)
        .fault
        .unwrap();
    assert_eq!((f.kind, f.joint), (FaultKind::NonFiniteInput, Some(5)));
}

#[test]
fn an_invalid_time_step_latches_a_fault_and_zeroes_every_duty() {
    for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
        let out = servo.update(&[1e-3; 6], &[0.0; 6], &[0.0; 6], dt);
        assert_eq!(out.duty, [0.0; 6]);
        let f = out.fault.unwrap();
        assert_eq!((f.kind, f.joint), (FaultKind::InvalidTimeStep, None));
        assert_eq!(
            f.to_string(),
            "invalid time step: error 0.000000  for 0.0000 s at t = 0 us"
        );
    }
}

#[test]
fn the_servo_rejects_an_invalid_config_and_changes_gains_bumplessly() {
    let mut bad = ServoConfig::<f64>::default();
    bad.tracking.joints[3].stuck_motion = -1.0;
    let e = JointServo::new(&bad).unwrap_err();
    assert_eq!(
        e.to_string(),
        "tracking.stuck_motion of joint 3 (theta1) must be finite and > 0"
    );
    let mut bad = ServoConfig::<f64>::default();
    bad.pid.joints[0].ki = -1.0;
    assert_eq!(JointServo::new(&bad).unwrap_err().field, "ki");

    let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
    for _ in 0..100 {
        servo.update(&[1e-5; 6], &[0.0; 6], &[0.0; 6], DT);
    }
    let integrals = servo.integrals();
    assert!(integrals[0] > 0.0);
    // A rejected change leaves everything as it was.
    assert!(servo.set_config(&bad).is_err());
    assert_eq!(servo.config(), &ServoConfig::default());
    // A valid change keeps the integrals.
    let mut softer = ServoConfig::default();
    softer.pid.joints[0].kp *= 0.5;
    servo.set_config(&softer).unwrap();
    assert_eq!(servo.integrals(), integrals);
    assert_eq!(servo.pid(0).unwrap().gains().kp, softer.pid.joints[0].kp);
    assert!(servo.pid(6).is_none());
    TrackingConfig::<f64>::default().validate().unwrap();
}

#[test]
fn servo_time_is_the_sum_of_the_time_steps() {
    // (also with the backlash compensation compiled out: the servo still runs)
    let mut servo = JointServo::new(&ServoConfig::<f64>::default()).unwrap();
    for _ in 0..10_000 {
        servo.update(&[0.0; 6], &[0.0; 6], &[0.0; 6], 1e-4);
    }
    assert_eq!(servo.time_us(), 1_000_000);
}

#[test]
fn the_acceleration_feed_forward_is_applied_through_update_with_acceleration() {
    let config = ServoConfig::<f64>::default();
    let mut servo = JointServo::new(&config).unwrap();
    let a = [1.0; 6];
    let out = servo.update_with_acceleration(&[0.0; 6], &[0.0; 6], &a, &[0.0; 6], DT);
    for j in 0..6 {
        assert!((out.duty[j] - config.pid.joints[j].ka).abs() < 1e-15);
    }
}

#[test]
fn the_servo_runs_in_f32_at_10_khz() {
    let mut servo = JointServo::<f32>::new(&ServoConfig::default()).unwrap();
    let mut plant = SixJoints::new();
    let dt = 1e-4f32;
    for k in 0..20_000 {
        let (q, v) = smooth(f64::from(k as u32) * 1e-4);
        let y = plant.positions().map(|x| x as f32);
        let out = servo.update(&q.map(|x| x as f32), &v.map(|x| x as f32), &y, dt);
        assert_eq!(out.fault, None);
        plant.step(&out.duty.map(f64::from), 1e-4);
    }
    let (q, _) = smooth(2.0);
    let p = plant.positions();
    // Legs within 0.1 mm (incl. the 60 um backlash offset), links within 1 mrad.
    for j in 0..3 {
        assert!((q[j] - p[j]).abs() < 1e-4);
    }
    for j in 3..6 {
        assert!((q[j] - p[j]).abs() < 1e-3);
    }
}
