#![allow(clippy::unwrap_used, clippy::expect_used)]
//! PID: proportional action, integral, anti-windup, derivative on measurement, filter,
//! deadband, saturation, robustness against any input.

use crate::common;

use common::DcMotor;
use proptest::prelude::*;
use servo::{AntiWindup, InputError, Pid, PidConfig, PidGains, PidInput};

const DT: f64 = 1e-3;

/// Runs `pid` on `plant` for `seconds` at 1 kHz towards `setpoint(t)` = (r, r_dot);
/// returns the plant positions after every sample.
fn run(
    pid: &mut Pid<f64>,
    plant: &mut DcMotor,
    seconds: f64,
    setpoint: impl Fn(f64) -> (f64, f64),
) -> Vec<f64> {
    let n = (seconds / DT).round() as usize;
    let mut xs = Vec::with_capacity(n);
    for k in 0..n {
        let (r, v) = setpoint(k as f64 * DT);
        let out = pid.update(&PidInput::new(r, plant.x).with_velocity(v), DT);
        assert!(out.error.is_none());
        for _ in 0..10 {
            plant.step(out.duty, DT / 10.0);
        }
        xs.push(plant.x);
    }
    xs
}

#[test]
fn p_only_step_gives_kp_times_the_error_and_saturates_at_the_limit() {
    let mut pid = Pid::new(PidGains::proportional(2.0));
    let out = pid.update(&PidInput::new(0.3, 0.0), DT);
    assert!((out.duty - 0.6).abs() < 1e-15);
    assert!(!out.saturated);
    assert_eq!(out.terms.p, out.duty);
    // Beyond the limit: clamped and reported.
    let out = pid.update(&PidInput::new(-2.0, 0.0), DT);
    assert_eq!(out.duty, -1.0);
    assert!(out.saturated);
    // A configured limit below 1.
    let mut g = PidGains::proportional(2.0);
    g.output_limit = 0.4;
    let mut pid = Pid::new(g);
    let out = pid.update(&PidInput::new(0.3, 0.0), DT);
    assert_eq!(out.duty, 0.4);
    assert!(out.saturated);
}

#[test]
fn integral_removes_a_constant_disturbance_on_a_dc_motor() {
    // A load that needs 0.05 duty to hold (gravity on a leg); setpoint 1 mm.
    let disturbance = -0.05 * DcMotor::leg().k;
    let mut pd = PidGains::leg();
    pd.ki = 0.0;
    let mut plant = DcMotor {
        disturbance,
        ..DcMotor::leg()
    };
    let xs = run(&mut Pid::new(pd), &mut plant, 2.0, |_| (1e-3, 0.0));
    let pd_error = 1e-3 - xs.last().unwrap();
    // PD alone: steady error = 0.05 duty / kp = 0.1 mm.
    assert!(
        (pd_error - 0.05 / pd.kp).abs() < 2e-6,
        "PD error {pd_error}"
    );

    let mut plant = DcMotor {
        disturbance,
        ..DcMotor::leg()
    };
    let mut pid = Pid::new(PidGains::leg());
    let xs = run(&mut pid, &mut plant, 2.0, |_| (1e-3, 0.0));
    let pid_error = 1e-3 - xs.last().unwrap();
    assert!(pid_error.abs() < 1e-8, "PID error {pid_error}");
    // The integral holds the disturbance.
    assert!((pid.integral() - 0.05).abs() < 1e-4);
}

/// Overshoot after a 50 mm step on a leg (the output saturates for ~150 ms).
fn step_overshoot(anti_windup: AntiWindup<f64>, integral_limit: f64) -> f64 {
    let mut g = PidGains::leg();
    g.kv = 0.0;
    g.friction_ff = 0.0;
    g.anti_windup = anti_windup;
    g.integral_limit = integral_limit;
    let mut plant = DcMotor::leg();
    let xs = run(&mut Pid::new(g), &mut plant, 1.5, |_| (0.05, 0.0));
    xs.iter().fold(f64::MIN, |m, x| m.max(*x)) - 0.05
}

#[test]
fn anti_windup_makes_the_overshoot_after_a_long_saturation_much_smaller() {
    let none = step_overshoot(AntiWindup::None, 1e9);
    let clamp = step_overshoot(AntiWindup::Clamp, 1e9);
    let back = step_overshoot(
        AntiWindup::BackCalculation {
            tracking_gain: 100.0,
        },
        1e9,
    );
    let default = step_overshoot(AntiWindup::Clamp, PidGains::<f64>::leg().integral_limit);
    println!(
        "overshoot after a 50 mm step: none {:.3} mm, clamp {:.4} mm, back-calculation {:.4} mm, \
         clamp + default integral limit {:.4} mm",
        none * 1e3,
        clamp * 1e3,
        back * 1e3,
        default * 1e3
    );
    assert!(none > 5e-3, "windup overshoot {none}");
    assert!(clamp < 0.05 * none);
    assert!(back < 0.05 * none);
    assert!(default < 0.05 * none);
}

#[test]
fn a_setpoint_step_causes_no_derivative_kick() {
    let mut g = PidGains::proportional(10.0);
    g.kd = 2.0;
    let mut pid = Pid::new(g);
    for _ in 0..10 {
        pid.update(&PidInput::new(0.0, 0.0), DT);
    }
    // Step of 10 mm: only P responds (a derivative of the error would add
    // kd * 0.01 / 1 ms = 20 duty and saturate).
    let out = pid.update(&PidInput::new(0.01, 0.0), DT);
    assert_eq!(out.terms.d, 0.0);
    assert!((out.duty - 0.1).abs() < 1e-15);
    assert!(!out.saturated);
    // The measurement moving does produce damping (opposing the motion).
    let out = pid.update(&PidInput::new(0.01, 0.001), DT);
    assert!(out.terms.d < 0.0);
}

#[test]
fn the_first_update_and_a_reset_are_bumpless() {
    let mut g = PidGains::leg();
    g.kv = 0.0;
    g.friction_ff = 0.0;
    let mut pid = Pid::new(g);
    // First sample far from 0: no derivative from the implicit previous value 0.
    let out = pid.update(&PidInput::new(0.25, 0.25), DT);
    assert_eq!(out.duty, 0.0);
    // Run with a moving measurement, then reset at a new position.
    for k in 0..100 {
        pid.update(&PidInput::new(0.25, 0.25 - 1e-5 * k as f64), DT);
    }
    assert!(pid.integral() != 0.0);
    pid.reset(0.1);
    assert_eq!(pid.integral(), 0.0);
    let out = pid.update(&PidInput::new(0.1, 0.1), DT);
    assert_eq!(out.duty, 0.0);
    // Changing the gains keeps the integral (the output does not jump).
    for _ in 0..10 {
        pid.update(&PidInput::new(0.1001, 0.1), DT);
    }
    let before = pid.update(&PidInput::new(0.1001, 0.1), DT).duty;
    let mut g2 = g;
    g2.ki *= 3.0;
    pid.set_gains(g2);
    let after = pid.update(&PidInput::new(0.1001, 0.1), DT).duty;
    // Only one sample of the tripled integral gain differs: 2 * ki * e * dt.
    assert!((after - before).abs() <= 2.0 * g.ki * 1e-4 * DT + 1e-12);
    // A preloaded integral starts the output there.
    pid.reset_with_integral(0.1, 0.07);
    assert!((pid.update(&PidInput::new(0.1, 0.1), DT).duty - 0.07).abs() < 1e-15);
}

/// Amplitude of the D output in the second half of a run at 10 kHz with the measurement
/// a sine of `freq_hz` and amplitude 1 um, kd = 1, filter cutoff `cutoff_hz`.
fn d_amplitude(freq_hz: f64, cutoff_hz: f64) -> f64 {
    let mut g = PidGains::proportional(0.0);
    g.kd = 1.0;
    g.derivative_cutoff_hz = cutoff_hz;
    let mut pid = Pid::new(g);
    let dt = 1e-4;
    let n = 20_000;
    let mut amp: f64 = 0.0;
    for k in 0..n {
        let y = 1e-6 * (std::f64::consts::TAU * freq_hz * k as f64 * dt).sin();
        let out = pid.update(&PidInput::new(0.0, y), dt);
        if k > n / 2 {
            amp = amp.max(out.terms.d.abs());
        }
    }
    amp
}

#[test]
fn the_derivative_low_pass_filter_attenuates_high_frequency_measurement_noise() {
    // 2 kHz noise, 100 Hz cutoff: the filtered derivative is < 6 % of the unfiltered one.
    let noise_filtered = d_amplitude(2000.0, 100.0);
    let noise_raw = d_amplitude(2000.0, 1e12);
    // A 5 Hz motion passes almost unchanged (> 99 %).
    let slow_filtered = d_amplitude(5.0, 100.0);
    let slow_raw = d_amplitude(5.0, 1e12);
    println!(
        "D amplitude 2 kHz: {noise_filtered:.3e} filtered vs {noise_raw:.3e} raw; \
         5 Hz: {slow_filtered:.3e} vs {slow_raw:.3e}"
    );
    assert!(noise_filtered < 0.06 * noise_raw);
    assert!(slow_filtered > 0.99 * slow_raw);
}

#[test]
fn inside_the_deadband_p_and_i_see_zero_error_and_the_edge_has_no_bump() {
    let mut g = PidGains::proportional(10.0);
    g.ki = 100.0;
    g.deadband = 0.01;
    let mut pid = Pid::new(g);
    for _ in 0..100 {
        let out = pid.update(&PidInput::new(0.009, 0.0), DT);
        assert_eq!(out.duty, 0.0);
    }
    assert_eq!(pid.integral(), 0.0);
    // Just outside: the output grows from zero (shrunk error), not from kp * deadband.
    let out = pid.update(&PidInput::new(0.0101, 0.0), DT);
    assert!((out.terms.p - 10.0 * 0.0001).abs() < 1e-12);
    // A slow sweep across the edge in both directions: no step larger than kp * d_e.
    let mut pid = Pid::new(PidGains { ki: 0.0, ..g });
    let mut last: f64 = -10.0 * 0.01; // the output at the first sample, e = -0.02
    for k in -3000..=3000 {
        let e = 0.02 * f64::from(k) / 3000.0; // steps of 6.7 um
        let duty = pid.update(&PidInput::new(e, 0.0), DT).duty;
        assert!((duty - last).abs() <= 10.0 * 0.02 / 3000.0 + 1e-12);
        if e.abs() < 0.01 - 1e-12 {
            assert_eq!(duty, 0.0);
        } else if e.abs() > 0.01 + 1e-12 {
            assert!(duty != 0.0 && duty.signum() == e.signum());
        }
        last = duty;
    }
}

#[test]
fn non_finite_inputs_give_a_zero_duty_and_an_error_and_leave_the_state_untouched() {
    let mut pid = Pid::new(PidGains::<f64>::leg());
    for _ in 0..10 {
        pid.update(&PidInput::new(1e-3, 0.0), DT);
    }
    let reference = pid;
    let cases = [
        (
            PidInput::new(f64::NAN, 0.0),
            DT,
            InputError::NonFiniteSetpoint,
        ),
        (
            PidInput::new(0.0, f64::INFINITY),
            DT,
            InputError::NonFiniteMeasurement,
        ),
        (
            PidInput::new(0.0, 0.0).with_velocity(f64::NAN),
            DT,
            InputError::NonFiniteVelocity,
        ),
        (
            PidInput::new(0.0, 0.0).with_acceleration(f64::NEG_INFINITY),
            DT,
            InputError::NonFiniteAcceleration,
        ),
        (PidInput::new(0.0, 0.0), 0.0, InputError::InvalidTimeStep),
        (PidInput::new(0.0, 0.0), -1e-3, InputError::InvalidTimeStep),
        (
            PidInput::new(0.0, 0.0),
            f64::NAN,
            InputError::InvalidTimeStep,
        ),
        (
            PidInput::new(0.0, 0.0),
            f64::INFINITY,
            InputError::InvalidTimeStep,
        ),
    ];
    for (input, dt, expected) in cases {
        let out = pid.update(&input, dt);
        assert_eq!(out.duty, 0.0);
        assert!(!out.saturated);
        assert_eq!(out.error, Some(expected));
        assert_eq!(pid, reference);
    }
}

#[test]
fn velocity_feed_forward_removes_most_of_the_lag_on_a_ramp() {
    // Ramp at 0.1 m/s for 0.3 s on a leg, no integral (to see the feed-forward alone).
    let lag = |kv: f64| {
        let mut g = PidGains::leg();
        g.ki = 0.0;
        g.friction_ff = 0.0; // the test plant has no friction
        g.kv = kv;
        let mut plant = DcMotor::leg();
        let xs = run(&mut Pid::new(g), &mut plant, 0.3, |t| (0.1 * t, 0.1));
        0.1 * 0.3 - xs.last().unwrap() // the plant ends at t = 0.3 s
    };
    let without = lag(0.0);
    let with = lag(1.0 / 0.378);
    println!(
        "lag at 0.1 m/s: {:.1} um without kv, {:.2} um with",
        without * 1e6,
        with * 1e6
    );
    assert!(without > 50e-6);
    assert!(with.abs() < 0.05 * without);
}

#[test]
fn the_default_config_is_valid_and_validate_names_bad_fields_and_joints() {
    let config = PidConfig::<f64>::default();
    config.validate().unwrap();
    PidConfig::<f32>::default().validate().unwrap();
    assert_eq!(config.joints[0], PidGains::leg());
    assert_eq!(config.joints[5], PidGains::link());

    let bad = |f: fn(&mut PidGains<f64>), joint: usize| {
        let mut c = PidConfig::<f64>::default();
        f(&mut c.joints[joint]);
        c.validate().unwrap_err()
    };
    let e = bad(|g| g.kd = -1.0, 2);
    assert_eq!((e.section, e.field, e.joint), ("pid", "kd", 2));
    assert_eq!(
        e.to_string(),
        "pid.kd of joint 2 (l3) must be finite and >= 0"
    );
    assert_eq!(bad(|g| g.kp = f64::NAN, 0).field, "kp");
    assert_eq!(bad(|g| g.ki = f64::INFINITY, 4).field, "ki");
    assert_eq!(bad(|g| g.kv = -0.1, 3).field, "kv");
    assert_eq!(
        bad(|g| g.derivative_cutoff_hz = 0.0, 1).field,
        "derivative_cutoff_hz"
    );
    assert_eq!(bad(|g| g.output_limit = 1.5, 5).field, "output_limit");
    assert_eq!(
        bad(|g| g.output_limit = 0.0, 5).requirement,
        "must be in (0, 1]"
    );
    assert_eq!(bad(|g| g.integral_limit = -1.0, 5).field, "integral_limit");
    assert_eq!(bad(|g| g.deadband = f64::NAN, 1).field, "deadband");
    assert_eq!(bad(|g| g.friction_band = 0.0, 1).field, "friction_band");
    let e = bad(
        |g| {
            g.anti_windup = AntiWindup::BackCalculation {
                tracking_gain: -2.0,
            }
        },
        4,
    );
    assert_eq!(e.field, "anti_windup.tracking_gain");
}

#[test]
fn the_pid_runs_in_f32() {
    let mut pid = Pid::<f32>::new(PidGains::leg());
    let mut x = 0.0f32;
    let mut v = 0.0f32;
    for _ in 0..2000 {
        let u = pid.update(&PidInput::new(1e-3, x), 1e-3).duty;
        // Explicit Euler of the leg model at 10 kHz.
        for _ in 0..10 {
            v += (0.378 * u - v) / 0.0056 * 1e-4;
            x += v * 1e-4;
        }
    }
    assert!((x - 1e-3).abs() < 2e-6, "x = {x}");
}

/// Any finite f64 (including huge and tiny ones).
fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1.0f64..1.0,
        -1e3f64..1e3,
        prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO,
    ]
}

fn gains() -> impl Strategy<Value = PidGains<f64>> {
    let g = || {
        prop_oneof![
            Just(0.0),
            0.0f64..1e4,
            prop::num::f64::POSITIVE.prop_filter("finite", |x| x.is_finite())
        ]
    };
    (
        (g(), g(), g(), 1e-3f64..1e6, g(), g(), g()),
        (0.01f64..=1.0, g(), 0.0f64..1.0, 0u8..3, g(), any::<bool>()),
    )
        .prop_map(
            |((kp, ki, kd, fc, kv, ka, ff), (limit, ilimit, db, aw, kt, dusv))| PidGains {
                kp,
                ki,
                kd,
                derivative_cutoff_hz: fc,
                derivative_uses_setpoint_velocity: dusv,
                kv,
                ka,
                friction_ff: ff,
                friction_band: 1e-3,
                output_limit: limit,
                integral_limit: ilimit,
                deadband: db,
                anti_windup: match aw {
                    0 => AntiWindup::None,
                    1 => AntiWindup::Clamp,
                    _ => AntiWindup::BackCalculation { tracking_gain: kt },
                },
            },
        )
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: for any valid gains and any sequence of finite inputs and positive
    /// finite time steps, the duty is finite and within the output limit (f64).
    #[test]
    fn output_is_always_finite_and_within_the_limit(
        g in gains(),
        samples in prop::collection::vec((finite(), finite(), finite(), finite(), prop_oneof![1e-4f64..1e-2, prop::num::f64::POSITIVE.prop_filter("finite", |x| x.is_finite())]), 1..60),
    ) {
        prop_assert!(g.validate(0).is_ok());
        let mut pid = Pid::new(g);
        for (r, v, a, y, dt) in samples {
            let out = pid.update(&PidInput { setpoint: r, setpoint_velocity: v, setpoint_acceleration: a, measured: y }, dt);
            prop_assert!(out.error.is_none());
            prop_assert!(out.duty.is_finite());
            prop_assert!(out.duty.abs() <= g.output_limit);
            prop_assert!(pid.integral().is_finite());
            prop_assert!(pid.filtered_velocity().is_finite());
        }
    }

    /// Property: the same in f32, where overflow to infinity is much easier.
    #[test]
    fn output_is_always_finite_and_within_the_limit_in_f32(
        g in gains(),
        samples in prop::collection::vec((prop::num::f32::NORMAL | prop::num::f32::ZERO, prop::num::f32::NORMAL | prop::num::f32::ZERO, prop::num::f32::NORMAL | prop::num::f32::SUBNORMAL, prop::num::f32::POSITIVE.prop_filter("finite", |x| x.is_finite())), 1..60),
    ) {
        let g = PidGains::<f32> {
            kp: g.kp as f32, ki: g.ki as f32, kd: g.kd as f32,
            derivative_cutoff_hz: g.derivative_cutoff_hz as f32,
            derivative_uses_setpoint_velocity: g.derivative_uses_setpoint_velocity,
            kv: g.kv as f32, ka: g.ka as f32, friction_ff: g.friction_ff as f32,
            friction_band: 1e-3, output_limit: g.output_limit as f32,
            integral_limit: g.integral_limit as f32, deadband: g.deadband as f32,
            anti_windup: match g.anti_windup {
                AntiWindup::None => AntiWindup::None,
                AntiWindup::Clamp => AntiWindup::Clamp,
                AntiWindup::BackCalculation { tracking_gain } => AntiWindup::BackCalculation { tracking_gain: tracking_gain as f32 },
            },
        };
        let mut pid = Pid::new(g);
        for (r, v, y, dt) in samples {
            let out = pid.update(&PidInput::new(r, y).with_velocity(v), dt);
            prop_assert!(out.duty.is_finite());
            prop_assert!(out.duty.abs() <= g.output_limit);
        }
    }
}
