#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Backlash compensation: direction tracking with hysteresis, ramped offset, and the
//! load-side error of a back-and-forth move on a simulated deadband plant.

use crate::common;

use common::{max_abs, rms, triangle, BacklashJoint, DcMotor};
use servo::{
    BacklashCompensator, BacklashConfig, BacklashParams, BacklashRamp, Direction, Pid, PidGains,
    PidInput,
};

const DT: f64 = 1e-3;

/// Load-side errors `r - load` of a leg with 0.12 mm backlash following `trajectory`
/// for `seconds` at 1 kHz, compensated with `params` (None: no compensation); only the
/// samples after the first second count (settled, well past start-up).
fn load_errors_w(
    width: f64,
    params: Option<BacklashParams<f64>>,
    seconds: f64,
    trajectory: impl Fn(f64) -> (f64, f64),
) -> Vec<f64> {
    let mut joint = BacklashJoint::new(DcMotor::leg(), width);
    let mut pid = Pid::new(PidGains {
        friction_ff: 0.0, // the test plant has no friction
        ..PidGains::leg()
    });
    let mut comp = params.map(BacklashCompensator::new);
    let n = (seconds / DT).round() as usize;
    let mut errors = Vec::new();
    for k in 0..n {
        let t = k as f64 * DT;
        let (r, v) = trajectory(t);
        let (offset, rate) = match comp.as_mut() {
            Some(c) => {
                let o = c.update(r, DT);
                (o.offset, o.offset_rate)
            }
            None => (0.0, 0.0),
        };
        let out = pid.update(
            &PidInput::new(r + offset, joint.motor.x).with_velocity(v + rate),
            DT,
        );
        joint.step(out.duty, DT, 10);
        if t >= 1.0 {
            // The plant is now at t + DT: compare with the setpoint there.
            errors.push(trajectory(t + DT).0 - joint.load);
        }
    }
    errors
}

fn load_errors(
    params: Option<BacklashParams<f64>>,
    seconds: f64,
    trajectory: impl Fn(f64) -> (f64, f64),
) -> Vec<f64> {
    load_errors_w(0.12e-3, params, seconds, trajectory)
}

/// Figures (f64, 1 kHz, default leg gains and compensation, b = 0.12 mm), load-side
/// error RMS without -> with compensation: triangle 0..2 mm at 10 mm/s 56.7 -> 18.3 um
/// (max 85.5 -> 102.3 um: the sharp reversal itself), sine 1 mm at 2 Hz 55.7 -> 7.4 um
/// (max 60.2 -> 36.0 um). Printed with `--nocapture`.
#[cfg(not(feature = "backlash-off"))]
#[test]
fn compensation_makes_the_load_side_error_of_a_back_and_forth_move_much_smaller() {
    // Triangle 0..2 mm at 10 mm/s (reversal every 0.2 s), 3 s.
    let tri = |t| triangle(t, 2e-3, 10e-3);
    let off = load_errors(None, 3.0, tri);
    let on = load_errors(Some(BacklashParams::leg()), 3.0, tri);
    // Sinusoid 1 mm amplitude at 2 Hz (smooth reversals, peak 12.6 mm/s), 3 s.
    let w = std::f64::consts::TAU * 2.0;
    let sine = |t: f64| (1e-3 * (w * t).sin(), 1e-3 * w * (w * t).cos());
    let off_s = load_errors(None, 3.0, sine);
    let on_s = load_errors(Some(BacklashParams::leg()), 3.0, sine);
    println!(
        "triangle 2 mm @ 10 mm/s, b = 0.12 mm: load error RMS {:.1} um / max {:.1} um without, \
         RMS {:.1} um / max {:.1} um with compensation",
        rms(&off) * 1e6,
        max_abs(&off) * 1e6,
        rms(&on) * 1e6,
        max_abs(&on) * 1e6
    );
    println!(
        "sine 1 mm @ 2 Hz: RMS {:.1} um / max {:.1} um without, RMS {:.1} um / max {:.1} um with",
        rms(&off_s) * 1e6,
        max_abs(&off_s) * 1e6,
        rms(&on_s) * 1e6,
        max_abs(&on_s) * 1e6
    );
    // Without: the load lags by half the backlash, 60 um, in both directions.
    assert!(rms(&off) > 50e-6);
    assert!(rms(&on) < 0.35 * rms(&off));
    assert!(rms(&on_s) < 0.2 * rms(&off_s));
    // The remaining error is mostly the loop's own: the same moves without backlash in
    // the plant (printed for comparison).
    let tri0 = load_errors_w(0.0, None, 3.0, tri);
    let sine0 = load_errors_w(0.0, None, 3.0, sine);
    println!(
        "no backlash in the plant: triangle RMS {:.1} um / max {:.1} um, sine RMS {:.1} um / max {:.1} um",
        rms(&tri0) * 1e6,
        max_abs(&tri0) * 1e6,
        rms(&sine0) * 1e6,
        max_abs(&sine0) * 1e6
    );
}

#[cfg(not(feature = "backlash-off"))]
#[test]
fn the_offset_is_plus_or_minus_half_the_backlash_by_direction_and_ramped_over_the_distance() {
    let p = BacklashParams {
        ramp: BacklashRamp::Distance(0.1e-3),
        ..BacklashParams::<f64>::leg() // b = 0.12 mm, hysteresis 5 um
    };
    let mut c = BacklashCompensator::new(p);
    let mut r = 0.0;
    let mut last = c.update(r, DT).offset;
    assert_eq!(c.direction(), Direction::Unknown);
    assert_eq!(last, 0.0);
    let mut max_step: f64 = 0.0;
    // Forward 0.5 mm, back 0.5 mm, in 1 um steps.
    for k in 0..1000 {
        let dr = if k < 500 { 1e-6 } else { -1e-6 };
        r += dr;
        let o = c.update(r, DT);
        // Never more than b / ramp_distance per unit of setpoint travel: no jump.
        let step = (o.offset - last).abs();
        assert!(step <= 0.12e-3 / 0.1e-3 * 1e-6 + 1e-15);
        assert!((o.offset_rate - (o.offset - last) / DT).abs() < 1e-12);
        max_step = max_step.max(step);
        last = o.offset;
        if k == 499 {
            assert_eq!(c.direction(), Direction::Positive);
            assert!((o.offset - 0.06e-3).abs() < 1e-15);
        }
    }
    assert_eq!(c.direction(), Direction::Negative);
    assert!((last + 0.06e-3).abs() < 1e-15);
    assert!(max_step > 0.0);
}

#[test]
fn noise_smaller_than_the_hysteresis_does_not_toggle_the_direction() {
    let mut c = BacklashCompensator::new(BacklashParams::<f64>::leg());
    c.reset(0.0, Direction::Positive);
    // Moving forward with +-2 um noise (hysteresis 5 um): stays Positive.
    for k in 0..2000 {
        let noise = if k % 2 == 0 { 2e-6 } else { -2e-6 };
        c.update(1e-7 * k as f64 + noise, DT);
        assert_eq!(c.direction(), Direction::Positive);
    }
    // Standing still with the same noise: stays Positive.
    for k in 0..2000 {
        let noise = if k % 3 == 0 { 2.4e-6 } else { -2.4e-6 };
        c.update(2e-4 + noise, DT);
        assert_eq!(c.direction(), Direction::Positive);
    }
    // A real reversal beyond the hysteresis flips it.
    c.update(2e-4 - 10e-6, DT);
    assert_eq!(c.direction(), Direction::Negative);
}

#[cfg(not(feature = "backlash-off"))]
#[test]
fn a_time_ramp_brings_the_offset_in_over_the_configured_time() {
    let p = BacklashParams {
        ramp: BacklashRamp::Time(0.02),
        ..BacklashParams::<f64>::leg()
    };
    let mut c = BacklashCompensator::new(p);
    c.reset(0.0, Direction::Negative);
    assert!((c.offset() + 0.06e-3).abs() < 1e-15);
    // Reverse: the full change of b takes 20 ms, whatever the speed.
    c.update(10e-6, DT);
    let mut n = 1;
    while c.offset() < 0.06e-3 - 1e-15 {
        c.update(10e-6, DT);
        n += 1;
        assert!(n < 100);
    }
    assert!((19..=21).contains(&n), "{n} samples");
}

#[test]
fn disabling_ramps_the_offset_out_and_the_off_config_gives_zero() {
    let mut c = BacklashCompensator::new(BacklashParams::<f64>::leg());
    c.reset(0.0, Direction::Positive);
    let mut p = BacklashParams::leg();
    p.enabled = false;
    c.set_params(p);
    // Ramps out (b per 20 ms or per 0.12 mm of travel, whichever is faster), no jump.
    let mut last = c.offset();
    for k in 1..=200 {
        let o = c.update(1e-6 * k as f64, DT).offset;
        assert!((o - last).abs() <= (0.12e-3 * DT / 0.02).max(1e-6) + 1e-15);
        last = o;
    }
    assert_eq!(c.offset(), 0.0);
    let mut off = BacklashCompensator::new(BacklashConfig::<f64>::off().joints[0]);
    for k in 0..100 {
        assert_eq!(off.update((k as f64 * 0.1).sin() * 1e-3, DT).offset, 0.0);
    }
}

#[test]
fn non_finite_setpoints_and_bad_time_steps_leave_the_offset_alone() {
    let mut c = BacklashCompensator::new(BacklashParams::<f64>::leg());
    c.reset(0.0, Direction::Positive);
    let before = c.offset();
    for (r, dt) in [
        (f64::NAN, DT),
        (f64::INFINITY, DT),
        (0.0, 0.0),
        (0.0, f64::NAN),
    ] {
        let o = c.update(r, dt);
        assert_eq!(o.offset, before);
        assert_eq!(o.offset_rate, 0.0);
    }
    assert_eq!(c.direction(), Direction::Positive);
}

#[test]
fn backlash_config_defaults_are_valid_and_validate_names_the_field() {
    BacklashConfig::<f64>::default().validate().unwrap();
    BacklashConfig::<f32>::default().validate().unwrap();
    let mut c = BacklashConfig::<f64>::default();
    c.joints[1].width = -1e-4;
    let e = c.validate().unwrap_err();
    assert_eq!((e.section, e.field, e.joint), ("backlash", "width", 1));
    let mut c = BacklashConfig::<f64>::default();
    c.joints[3].ramp = BacklashRamp::Distance(0.0);
    assert_eq!(c.validate().unwrap_err().field, "ramp.distance");
    let mut c = BacklashConfig::<f64>::default();
    c.joints[5].hysteresis = f64::NAN;
    let e = c.validate().unwrap_err();
    assert_eq!(
        e.to_string(),
        "backlash.hysteresis of joint 5 (theta3) must be finite and >= 0"
    );
}

#[cfg(feature = "backlash-off")]
#[test]
fn the_backlash_off_feature_compiles_the_compensation_out() {
    let mut c = BacklashCompensator::new(BacklashParams::<f64>::leg());
    c.reset(0.0, Direction::Positive);
    for k in 0..100 {
        assert_eq!(c.update(k as f64 * 1e-5, DT).offset, 0.0);
    }
}

/// A steady external load imposes the flank: with the preload set positive, the offset
/// stays +b/2 while the setpoint moves down, and it follows the motion again once the
/// preload is released.
#[test]
fn preload_from_a_steady_load_overrides_the_motion_direction() {
    let mut c =
        servo::backlash::BacklashCompensator::new(servo::backlash::BacklashParams::<f64>::leg());
    let half = c.params().width / 2.0;
    c.set_preload(servo::backlash::Direction::Positive);
    let mut out = c.update(0.0, 1e-3);
    for k in 1..200 {
        out = c.update(-(k as f64) * 1e-5, 1e-3);
    }
    assert!(
        (out.offset - half).abs() < 1e-12,
        "offset {} with the load pushing down",
        out.offset
    );
    c.set_preload(servo::backlash::Direction::Unknown);
    for k in 200..400 {
        out = c.update(-(k as f64) * 1e-5, 1e-3);
    }
    assert!(
        (out.offset + half).abs() < 1e-12,
        "offset {} following the downward motion",
        out.offset
    );
}
