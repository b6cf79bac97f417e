#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The drive side of the plant: the drivers' current regulation, the bridges' enable, the
//! holding brakes, the supply, and the drive faults (shorts, driver failures, encoder
//! glitches).
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best

mod common;
use common::*;
use plant::{Fault, PlantError, NUM_JOINTS};
use proptest::prelude::*;

const DT: f64 = 50e-6;

proptest! {
    #![proptest_config(proptest_config::cases(64))]

    /// Property: whatever the duty and the external load, the driver's regulation keeps
    /// every |current| at or below the joint's limit, and with the load seized the motor
    /// effort it allows is at most `n Kt I_lim`, which the configuration sets to the
    /// rating over the transmission's efficiency (220 N, 0.5 N m delivered).
    #[test]
    fn the_regulation_caps_the_current_at_any_duty_and_load(
        duty in prop::array::uniform6(-1.0f64..1.0),
        load in prop::array::uniform6(-1.0f64..1.0),
        seized in any::<bool>(),
    ) {
        let mut p = plant().unwrap();
        let rated = p.rated_efforts();
        let load: [f64; NUM_JOINTS] = std::array::from_fn(|j| load[j] * 1.5 * rated[j]);
        p.set_external_load(load).unwrap();
        if seized {
            for j in 0..NUM_JOINTS {
                p.inject(j, Fault::LoadSeized).unwrap();
            }
        }
        p.set_duty(duty).unwrap();
        for _ in 0..2000 {
            p.step(DT).unwrap();
            for j in 0..NUM_JOINTS {
                let m = p.joint(j).unwrap().model();
                prop_assert!(p.currents()[j].abs() <= m.current_limit * (1.0 + 1e-12));
            }
        }
        for j in 0..NUM_JOINTS {
            let m = p.joint(j).unwrap().model();
            let n_kt = m.transmission.ratio * m.motor.torque_constant;
            prop_assert!(
                p.stats().peak_abs_motor_effort[j] <= n_kt * m.current_limit * (1.0 + 1e-12)
            );
        }
    }
}

/// Property: stalled at full duty, the current settles at the limit (not at V/R, 69 A on
/// a leg), and the regulation is counted; the effort delivered to the seized load is
/// the rating at most (220 N, 0.5 N m) and at least 90 % of it.
#[test]
fn a_stalled_motor_is_held_at_the_current_limit() -> TestResult {
    let rating = [220.0, 220.0, 220.0, 0.5, 0.5, 0.5];
    let mut p = plant()?;
    p.set_duty([1.0; NUM_JOINTS])?;
    p.advance(0.05, DT)?;
    for j in 0..NUM_JOINTS {
        p.inject(j, Fault::LoadSeized)?;
    }
    p.reset_stats();
    p.advance(0.1, DT)?;
    for j in 0..NUM_JOINTS {
        let m = *p.joint(j)?.model();
        assert_close("current", p.currents()[j], m.current_limit, 1e-9);
        assert!(p.stats().current_limited_steps[j] > 1000, "joint {j}");
        let n_kt_eta = m.transmission.ratio * m.motor.torque_constant * m.transmission.efficiency;
        let delivered = n_kt_eta * m.current_limit;
        assert!(
            delivered <= rating[j] * 1.01 && delivered >= rating[j] * 0.9,
            "joint {j}: {delivered}"
        );
    }
    Ok(())
}

/// Property: the bridges off, the motors coast: no current, and a joint under an
/// external load accelerates freely (falls), faster than with the bridge on at duty 0,
/// which shorts the motor and brakes it by its back-EMF.
#[test]
fn bridges_off_coast_and_duty_zero_brakes() -> TestResult {
    // Half the ratings: enough to back-drive the screws and gear trains.
    let load = [-110.0, -110.0, -110.0, -0.25, -0.25, -0.25];
    let run = |enabled: bool| -> Result<[f64; NUM_JOINTS], Box<dyn std::error::Error>> {
        let mut p = plant()?;
        p.set_bridges_enabled(enabled);
        p.set_external_load(load)?;
        p.set_duty([0.0; NUM_JOINTS])?;
        p.advance(0.05, DT)?;
        if !enabled {
            assert_eq!(p.currents(), [0.0; NUM_JOINTS]);
            assert_eq!(p.bridges_on(), [false; NUM_JOINTS]);
        }
        Ok(p.joint_positions())
    };
    let coast = run(false)?;
    let braked = run(true)?;
    for j in 0..NUM_JOINTS {
        let fall_coast = HOME[j] - coast[j];
        let fall_braked = HOME[j] - braked[j];
        assert!(
            fall_coast > 0.0 && fall_coast > 2.0 * fall_braked,
            "joint {j}: coast {fall_coast}, braked {fall_braked}"
        );
    }
    Ok(())
}

/// Property: a brake holds the joint against its rated load (220 N, 0.5 N m, applied
/// over 50 ms: no impact) with the bridges off, moving it by the backlash at most, only
/// once its engage time has passed; released, the load moves the joint again after the
/// release time.
#[test]
fn brakes_hold_the_rated_load_after_their_engage_time() -> TestResult {
    let rating = [220.0, 220.0, 220.0, 0.5, 0.5, 0.5];
    let mut p = plant()?;
    let cfg = p.config().brake;
    p.set_bridges_enabled(false);
    // Applied long ago: holding.
    p.set_brakes_released([false; NUM_JOINTS]);
    p.advance(cfg.engage_ms * 1e-3 + 1e-3, DT)?;
    assert_eq!(p.brakes_holding(), [true; NUM_JOINTS]);
    let before = p.joint_positions();
    for k in 1..=50 {
        let s = f64::from(k) / 50.0;
        p.set_external_load(rating.map(|r| -r * s))?;
        p.advance(1e-3, DT)?;
    }
    p.advance(0.5, DT)?;
    let after = p.joint_positions();
    for j in 0..NUM_JOINTS {
        let backlash = p.joint(j)?.model().backlash.width;
        assert!(
            (after[j] - before[j]).abs() <= backlash + 1e-12,
            "joint {j} moved {} under its brake",
            after[j] - before[j]
        );
    }
    // Released: not before the release time, then the load (now half the rating) moves
    // the joints.
    p.set_external_load(rating.map(|r| -0.5 * r))?;
    p.set_brakes_released([true; NUM_JOINTS]);
    p.advance(cfg.release_ms * 1e-3 * 0.5, DT)?;
    assert_eq!(p.brakes_holding(), [true; NUM_JOINTS]);
    p.advance(cfg.release_ms * 1e-3, DT)?;
    assert_eq!(p.brakes_holding(), [false; NUM_JOINTS]);
    p.advance(0.05, DT)?;
    let moved = p.joint_positions();
    for j in 0..NUM_JOINTS {
        assert!(
            moved[j] < after[j] - 1e-4,
            "joint {j} did not move when released"
        );
    }
    // Applied while falling: it takes the engage time, then stops the joint.
    p.set_brakes_released([false; NUM_JOINTS]);
    p.advance(cfg.engage_ms * 1e-3 * 0.5, DT)?;
    assert_eq!(p.brakes_holding(), [false; NUM_JOINTS]);
    p.advance(cfg.engage_ms * 1e-3 + 0.02, DT)?;
    let stopped = p.joint_positions();
    p.advance(0.2, DT)?;
    for j in 0..NUM_JOINTS {
        let backlash = p.joint(j)?.model().backlash.width;
        assert!(
            (p.joint_positions()[j] - stopped[j]).abs() <= backlash,
            "joint {j} still moving with the brake applied"
        );
    }
    Ok(())
}

/// Property: the motor can be driven against a closed brake without moving at a small
/// duty (the brake check of the enable sequence).
#[test]
fn a_small_torque_against_a_closed_brake_does_not_move_the_joint() -> TestResult {
    let mut p = plant()?;
    p.set_brakes_released([false; NUM_JOINTS]);
    p.advance(0.05, DT)?;
    let before = p.motor_side_joint_positions();
    // 40 % of the rated current, both ways.
    for sign in [1.0, -1.0] {
        let duty: [f64; NUM_JOINTS] = std::array::from_fn(|j| {
            let m = p.joint(j).map(|jt| *jt.model()).unwrap();
            sign * 0.4 * m.motor.nominal_current * m.circuit_resistance() / m.bridge.supply
        });
        p.set_duty(duty)?;
        p.advance(0.1, DT)?;
        for j in 0..NUM_JOINTS {
            let d = p.motor_side_joint_positions()[j] - before[j];
            assert!(d.abs() < 1e-9, "joint {j} moved {d} against the brake");
        }
    }
    Ok(())
}

/// Property: a shorted motor trips its driver as soon as the bridge drives it (the
/// drivers' fault output goes active and that bridge turns off); re-enabling clears the
/// latch and the short trips it again.
#[test]
fn a_shorted_motor_trips_the_driver() -> TestResult {
    let mut p = plant()?;
    p.inject(2, Fault::MotorShorted)?;
    assert!(!p.driver_fault());
    p.set_duty([0.2; NUM_JOINTS])?;
    p.step(DT)?;
    assert!(p.driver_fault());
    assert_eq!(p.bridges_on(), [true, true, false, true, true, true]);
    p.set_bridges_enabled(false);
    p.set_bridges_enabled(true);
    assert!(!p.driver_fault());
    p.step(DT)?;
    assert!(p.driver_fault());
    Ok(())
}

/// Property: a failed driver keeps its fault output active while it is enabled.
#[test]
fn a_failed_driver_reports_its_fault() -> TestResult {
    let mut p = plant()?;
    p.inject(4, Fault::DriverFailed)?;
    p.step(DT)?;
    assert!(p.driver_fault());
    assert!(!p.bridges_on()[4]);
    Ok(())
}

/// Property: a partly shorted winding with the regulation lost draws more than the
/// limit (the overcurrent the firmware must catch) but below the driver's own overcurrent
/// protection at this duty; with the regulation intact the current stays at the limit.
#[test]
fn a_winding_short_overcurrents_only_without_the_regulation() -> TestResult {
    for lost in [false, true] {
        let mut p = plant()?;
        for j in 0..NUM_JOINTS {
            p.inject(j, Fault::LoadSeized)?;
            p.inject(
                j,
                Fault::WindingShort {
                    resistance_ratio: 0.25,
                },
            )?;
            if lost {
                p.inject(j, Fault::CurrentRegulationLost)?;
            }
        }
        // Legs: 3 x 5.23 A < 0.05 x 24 V / 0.16 ohm < 15 A; links: 3 x 0.66 A < ... < 2 A.
        p.set_duty([0.06, 0.06, 0.06, 0.04, 0.04, 0.04])?;
        p.advance(0.02, DT)?;
        assert!(!p.driver_fault());
        for j in 0..NUM_JOINTS {
            let m = p.joint(j)?.model();
            let i = p.currents()[j];
            if lost {
                assert!(i > 1.5 * m.current_limit, "joint {j}: {i}");
            } else {
                assert_close("current", i, m.current_limit, 1e-9);
            }
        }
    }
    Ok(())
}

/// Property: an encoder glitch moves the counter by exactly the injected counts, without
/// motion, and nothing stays injected.
#[test]
fn an_encoder_jump_moves_the_counter_once() -> TestResult {
    let mut p = plant()?;
    let c0 = p.encoder_counts();
    p.inject(1, Fault::EncoderJump { counts: -700 })?;
    let c1 = p.encoder_counts();
    assert_eq!(c1[1], c0[1].wrapping_sub(700));
    assert_eq!(p.faults(1)?, Default::default());
    assert_eq!(
        p.inject(1, Fault::EncoderJump { counts: 0 }),
        Err(PlantError::InvalidFault(Fault::EncoderJump { counts: 0 }))
    );
    Ok(())
}

/// Property: the supply voltage scales the drive (half the supply, half the no-load
/// speed, within the friction's share) and bad values are refused.
#[test]
fn the_supply_voltage_scales_the_drive() -> TestResult {
    let mut p = unregulated_plant()?;
    p.set_duty([0.5; NUM_JOINTS])?;
    p.advance(0.3, DT)?;
    let full = p.joint_velocities();
    let mut q = unregulated_plant()?;
    q.set_supply_voltage(12.0)?;
    assert_eq!(q.supply_voltage(), 12.0);
    q.set_duty([0.5; NUM_JOINTS])?;
    q.advance(0.3, DT)?;
    let half = q.joint_velocities();
    for j in 0..NUM_JOINTS {
        let r = half[j] / full[j];
        assert!(r > 0.4 && r < 0.5, "joint {j}: ratio {r}");
    }
    assert!(q.set_supply_voltage(f64::NAN).is_err());
    assert!(q.set_supply_voltage(-1.0).is_err());
    Ok(())
}

/// Property: a failing encoder that keeps one count in n counts a fraction 1/n of the
/// motion (to one count).
#[test]
fn a_failing_encoder_counts_a_fraction_of_the_motion() -> TestResult {
    let mut p = unregulated_plant()?;
    p.inject(3, Fault::EncoderCountsOneIn { one_in: 10 })?;
    let mut ext = CounterExtender::new(&p);
    let x0 = p.motor_side_joint_positions()[3];
    p.set_duty([0.0, 0.0, 0.0, 0.3, 0.0, 0.0])?;
    for _ in 0..2000 {
        p.step(DT)?;
        ext.update(&p);
    }
    let cpu = p.counts_per_joint_unit()[3];
    let truth = (p.motor_side_joint_positions()[3] - x0) * cpu;
    let counted = ext.total[3] as f64;
    assert!(truth > 1000.0, "{truth}");
    assert!(
        (counted - truth / 10.0).abs() <= 1.0,
        "{counted} vs {truth}"
    );
    assert!(p
        .inject(3, Fault::EncoderCountsOneIn { one_in: 1 })
        .is_err());
    Ok(())
}

/// Property: a transistor stuck on drives the full supply with no regulation: the
/// driver's own overcurrent protection latches its fault and turns the bridge off before
/// the current passes its trip by more than one step's rise.
#[test]
fn a_stuck_bridge_trips_the_drivers_overcurrent_protection() -> TestResult {
    let mut p = plant()?;
    p.inject(0, Fault::BridgeStuckOn)?;
    p.set_duty([0.0; NUM_JOINTS])?;
    let mut peak = 0.0f64;
    for _ in 0..200 {
        p.step(DT)?;
        peak = peak.max(p.currents()[0].abs());
    }
    assert!(p.driver_fault());
    assert!(!p.bridges_on()[0]);
    let ocp = p.joint(0)?.model().driver_ocp;
    assert!(peak > ocp && peak < 3.0 * ocp, "peak {peak} A");
    Ok(())
}
