#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The monitors and limits on their own: the current limit's duties, the encoder jump
//! threshold, the motor circuit checks, and a stronger stop over a latched weaker one.

use control::current::{CurrentConfig, CurrentMonitor};
use control::monitors::{DriveSample, EncoderCheck, EncoderCheckConfig, MotorCheck};
use master_link::FaultCause;
use proptest::prelude::*;

/// The reference board's encoder counts per unit (the board profile's).
fn cpu() -> [f64; 6] {
    board_profile::BoardProfile::REFERENCE.counts_per_unit()
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property (found by the fuzzer): whatever the commanded duty, the joint speeds (a
    /// joint back-driven beyond its no-load speed included) and the supply, the current
    /// limit leaves every duty finite and within [-1, 1], and within the range the model
    /// allows when that range meets [-1, 1].
    #[test]
    fn the_current_limit_keeps_duties_within_what_a_bridge_applies(
        duty in prop::array::uniform6(prop_oneof![-3.0f64..3.0, Just(f64::NAN)]),
        qdot in prop::array::uniform6(-2.0f64..2.0),
        supply in prop_oneof![0.0f64..40.0, Just(f64::NAN)],
    ) {
        let mut m = CurrentMonitor::new(CurrentConfig::<f64>::default());
        let mut d = duty;
        // Links: rad/s, scaled up to their range.
        let qdot: [f64; 6] = std::array::from_fn(|j| if j < 3 { qdot[j] } else { qdot[j] * 30.0 });
        m.limit(&mut d, &qdot, supply);
        for j in 0..6 {
            prop_assert!(d[j].is_finite() && d[j].abs() <= 1.0, "joint {j}: {}", d[j]);
        }
    }
}

/// Property: an encoder jump is found when one tick brings more counts than 1.5 x the
/// joint's top speed allows (+2), never below.
#[test]
fn an_encoder_jump_is_the_top_speed_with_its_margin() {
    let cfg = EncoderCheckConfig::reference(cpu());
    let motors = CurrentConfig::<f64>::default().motors;
    let drive = DriveSample {
        duty: [0.0; 6],
        current: [0.0; 6],
        supply_v: 24.0,
        torque: false,
    };
    for j in 0..6 {
        let limit = cfg.top_speed[j] * cfg.jump_margin * 1e-3 * cpu()[j] + 2.0;
        for (counts, jump) in [
            (limit.floor() as i64, false),
            (limit.ceil() as i64 + 1, true),
        ] {
            let mut c = EncoderCheck::new(cfg);
            assert_eq!(c.check(&[0; 6], 1e-3, &motors, &drive), None);
            let mut now = [0i64; 6];
            now[j] = counts;
            let f = c.check(&now, 1e-3, &motors, &drive);
            assert_eq!(
                f.map(|f| (f.cause, f.joint)),
                jump.then_some((FaultCause::EncoderJump, Some(j))),
                "joint {j}, {counts} counts (limit {limit})"
            );
        }
    }
}

/// Property: the motor check names an open circuit (no current under a duty that should
/// drive one) and a shorted winding (three times the model's current), each after its
/// count, on the joint concerned; a healthy sample clears neither at once (leaky count).
#[test]
fn the_motor_check_finds_open_and_shorted_circuits() {
    let motors = CurrentConfig::<f64>::default().motors;
    let lim = [5.23, 5.23, 5.23, 0.66, 0.66, 0.66];
    for (j, current, cause) in [
        (2usize, 0.0, FaultCause::MotorOpen),
        (4, 0.6, FaultCause::CurrentImplausible),
    ] {
        let mut m = MotorCheck::new(&motors);
        let mut duty = [0.0; 6];
        duty[j] = if j < 3 { 0.02 } else { 0.01 };
        let mut i = [0.0; 6];
        i[j] = current;
        // The model: V d / R at rest: 1.38 A on the leg, 0.11 A on the link.
        let d = DriveSample {
            duty,
            current: i,
            supply_v: 24.0,
            torque: true,
        };
        let mut found = None;
        for k in 0..5 {
            found = m.check(&d, &[0.0; 6], &[0.0; 6], &motors, &lim);
            if k < 4 {
                assert_eq!(found, None, "{cause:?} after {} samples", k + 1);
            }
        }
        let f = found.expect("found after 5 samples");
        assert_eq!((f.cause, f.joint), (cause, Some(j)));
    }
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: a healthy motor is never judged open or shorted for the encoders'
    /// quantisation. Each joint creeps or runs (a duty from zero up to about twenty counts
    /// a tick, changing from tick to tick), draws the model's current at its true speed
    /// (`(V·d − Ke·ω)/R`: no load, or a load that slows or drives it; the winding's
    /// resistance up to 30 % off; within the regulation limit), and is measured as the
    /// counts it crossed over each tick (within one count's speed of the truth: a joint
    /// creeping at a count a tick reads 0, 1 or 2). Over 60 ticks the motor check finds
    /// nothing: the true current lies within the band the model allows for a speed known
    /// to within one count a tick, however the counts fall.
    #[test]
    fn quantised_speeds_do_not_fake_open_or_shorted_circuits(
        base in proptest::array::uniform6(-0.02f64..0.02),
        wobble in proptest::collection::vec(proptest::array::uniform6(-0.005f64..0.005), 60),
        slip in proptest::array::uniform6(prop_oneof![Just(0.0f64), -0.3f64..0.3]),
        r_scale in proptest::array::uniform6(0.7f64..1.3),
        phase in proptest::array::uniform6(0.0f64..1.0),
    ) {
        let motors = CurrentConfig::<f64>::default().motors;
        let lim = [5.23, 5.23, 5.23, 0.66, 0.66, 0.66];
        let (v, dt) = (24.0, 1e-3);
        let mut check = MotorCheck::new(&motors);
        // Position in counts (fractional), from a random phase between counts.
        let mut pos = phase;
        let resolution: [f64; 6] = std::array::from_fn(|j| 1.0 / (cpu()[j] * dt));
        for w in &wobble {
            let d: [f64; 6] = std::array::from_fn(|j| base[j] + w[j]);
            let mut current = [0.0; 6];
            let mut qdot = [0.0; 6];
            for j in 0..6 {
                let m = &motors[j];
                // The no-load speed of the duty, slowed or driven by the load's slip.
                let w_motor = d[j] * v / m.back_emf_v_s_per_rad * (1.0 - slip[j]);
                let r = m.resistance_ohm * r_scale[j];
                current[j] = ((v * d[j] - m.back_emf_v_s_per_rad * w_motor) / r)
                    .clamp(-lim[j], lim[j]);
                let before = pos[j].floor();
                pos[j] += w_motor / m.motor_rad_per_unit * cpu()[j] * dt;
                qdot[j] = (pos[j].floor() - before) / cpu()[j] / dt;
            }
            let sample = DriveSample { duty: d, current, supply_v: v, torque: true };
            let found = check.check(&sample, &qdot, &resolution, &motors, &lim);
            prop_assert_eq!(found, None, "duties {:?} currents {:?} speeds {:?}", d, current, qdot);
        }
    }
}
