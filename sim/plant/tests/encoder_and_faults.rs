#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Encoder resolution and wrapping, duty saturation, fault injection.
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best

mod common;
use common::*;
use plant::{Fault, PlantError, NUM_JOINTS};

const DT: f64 = 50e-6;

/// Property: one motor revolution is 2000 counts, which is 3 mm on a leg (0.0015 mm per
/// count) and 10 deg on a link (0.005 deg per count).
#[test]
fn one_motor_revolution_is_2000_counts_3_mm_and_10_deg() -> TestResult {
    let p = plant()?;
    let cpu = p.counts_per_joint_unit();
    for j in 0..3 {
        assert_close("counts per 3 mm", cpu[j] * 3e-3, 2000.0, 1e-9);
        assert_close("mm per count", 1e3 / cpu[j], 0.0015, 1e-15);
        let travel = p
            .joint(j)?
            .model()
            .transmission
            .joint_travel_per_motor_rev();
        assert_close("m per motor rev", travel, 3e-3, 1e-15);
    }
    for j in 3..6 {
        assert_close(
            "counts per 10 deg",
            cpu[j] * 10f64.to_radians(),
            2000.0,
            1e-9,
        );
        assert_close(
            "deg per count",
            1.0 / cpu[j] / 1f64.to_radians(),
            0.005,
            1e-15,
        );
        let travel = p
            .joint(j)?
            .model()
            .transmission
            .joint_travel_per_motor_rev();
        assert_close("deg per motor rev", travel.to_degrees(), 10.0, 1e-12);
    }
    Ok(())
}

/// Property: at every step the (extended) count is the motor-side travel quantised with
/// floor from the mid-count reset, `floor(dx * counts_per_unit + 1/2)`, with the sign of
/// the motion; after one motor revolution it reads 2000 (or -2000 backwards).
#[test]
fn counts_follow_the_motor_shaft_with_floor_quantisation_and_sign() -> TestResult {
    for sign in [1.0, -1.0] {
        let mut p = plant()?;
        let cpu = p.counts_per_joint_unit();
        let x0 = p.motor_side_joint_positions();
        let mut ext = CounterExtender::new(&p);
        p.set_duty([0.02 * sign; NUM_JOINTS])?;
        let mut done = [false; NUM_JOINTS];
        while !done.iter().all(|d| *d) {
            p.step(DT)?;
            let counts = ext.update(&p);
            let x = p.motor_side_joint_positions();
            for j in 0..NUM_JOINTS {
                let expect = ((x[j] - x0[j]) * cpu[j] + 0.5).floor() as i64;
                assert_eq!(counts[j], expect, "joint {j}");
                // The first step past one motor revolution (steps are < 0.5 count).
                let travel = (x[j] - x0[j]) * cpu[j];
                if !done[j] && travel.abs() >= 2000.0 {
                    assert!(travel.abs() < 2000.5, "step too coarse: {travel}");
                    assert_eq!(counts[j], (2000.0 * sign) as i64, "joint {j}");
                    done[j] = true;
                }
            }
            assert!(p.time() < 2.0, "too slow");
        }
    }
    Ok(())
}

/// Property: over moves much longer than 65536 counts, in both directions, the raw u16
/// counter is the true count modulo 2^16, and extending it recovers the true count.
#[test]
fn the_u16_counter_wraps_correctly_over_long_moves_both_ways() -> TestResult {
    // Unregulated, to reach the top speeds quickly.
    let mut p = unregulated_plant()?;
    let cpu = p.counts_per_joint_unit();
    let x0 = p.motor_side_joint_positions();
    let mut ext = CounterExtender::new(&p);
    let mut max = [0i64; NUM_JOINTS];
    let mut min = [0i64; NUM_JOINTS];
    for (duty, time) in [(1.0, 0.4), (-1.0, 0.8), (1.0, 0.2)] {
        p.set_duty([duty; NUM_JOINTS])?;
        let steps = (time / DT) as usize;
        for _ in 0..steps {
            p.step(DT)?;
            let counts = ext.update(&p);
            let raw = p.encoder_counts();
            let x = p.motor_side_joint_positions();
            for j in 0..NUM_JOINTS {
                let truth = ((x[j] - x0[j]) * cpu[j] + 0.5).floor() as i64;
                assert_eq!(counts[j], truth, "joint {j}");
                assert_eq!(i64::from(raw[j]), truth.rem_euclid(65_536), "joint {j}");
                max[j] = max[j].max(truth);
                min[j] = min[j].min(truth);
            }
        }
    }
    for j in 0..NUM_JOINTS {
        assert!(
            max[j] > 65_536 && min[j] < -65_536,
            "joint {j}: {} .. {}",
            min[j],
            max[j]
        );
    }
    Ok(())
}

/// Property: a duty outside [-1, 1] is saturated to the supply and reported (in the return
/// value and, while held, in the stats); a non-finite duty is an error and changes nothing.
#[test]
fn duty_saturation_is_reported_and_nan_is_rejected() -> TestResult {
    let mut p = plant()?;
    let sat = p.set_duty([1.5, 0.2, -3.0, 0.0, 1.0, -1.0])?;
    assert_eq!(sat.0, [true, false, true, false, false, false]);
    assert!(sat.any());
    assert_eq!(p.duty(), [1.0, 0.2, -1.0, 0.0, 1.0, -1.0]);
    p.advance(1e-3, DT)?;
    assert_eq!(p.stats().saturated_steps, [20, 0, 20, 0, 0, 0]);
    let err = p.set_duty([0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]);
    assert!(matches!(err, Err(PlantError::NotFinite { joint: 1, .. })));
    assert_eq!(p.duty(), [1.0, 0.2, -1.0, 0.0, 1.0, -1.0]);
    assert!(p.set_external_load([f64::INFINITY; 6]).is_err());
    assert!(matches!(p.step(0.0), Err(PlantError::InvalidStep { .. })));
    assert!(p.step(f64::NAN).is_err());
    Ok(())
}

/// Property: a stuck encoder freezes its counter while the joint keeps moving; after
/// clearing, counting resumes from the frozen value (missed counts stay missed).
#[test]
fn a_stuck_encoder_freezes_the_counter_while_the_joint_moves() -> TestResult {
    let mut p = plant()?;
    p.set_duty([0.2; NUM_JOINTS])?;
    p.advance(0.05, DT)?;
    let frozen = p.encoder_counts();
    let q_before = p.joint_positions();
    p.inject(1, Fault::EncoderStuck)?;
    p.inject(4, Fault::EncoderStuck)?;
    p.advance(0.1, DT)?;
    let now = p.encoder_counts();
    let q_after = p.joint_positions();
    for j in [1, 4] {
        assert_eq!(now[j], frozen[j], "joint {j} counter moved");
        assert!(q_after[j] - q_before[j] > 1e-3, "joint {j} did not move");
    }
    for j in [0, 2, 3, 5] {
        assert_ne!(now[j], frozen[j], "healthy joint {j} counter froze");
    }
    assert!(p.faults(1)?.encoder_stuck);
    p.clear_faults(1)?;
    p.advance(0.01, DT)?;
    assert_ne!(p.encoder_counts()[1], frozen[1]);
    Ok(())
}

/// Property: a disconnected motor carries no current and produces no drive: a full duty
/// does not move the joint; an external load then moves it without back-EMF braking.
#[test]
fn a_disconnected_motor_gives_zero_current_and_no_drive() -> TestResult {
    let mut p = plant()?;
    p.inject(0, Fault::MotorDisconnected)?;
    p.inject(3, Fault::MotorDisconnected)?;
    p.set_duty([1.0; NUM_JOINTS])?;
    p.advance(0.05, DT)?;
    let i = p.currents();
    let q = p.joint_positions();
    for j in [0, 3] {
        assert_eq!(i[j], 0.0);
        assert_eq!(q[j], HOME[j], "joint {j} moved without a motor");
    }
    assert!(
        p.stats().peak_abs_current_a[1] > 1.0 && q[1] > HOME[1] + 1e-3,
        "healthy joint did not drive"
    );
    assert_eq!(p.stats().peak_abs_current_a[0], 0.0);
    // Back-driven by a load, the open motor still passes no current.
    p.set_duty([0.0; NUM_JOINTS])?;
    p.set_external_load([50.0, 0.0, 0.0, 0.5, 0.0, 0.0])?;
    p.advance(0.05, DT)?;
    assert_eq!(p.currents()[0], 0.0);
    assert!(p.joint_velocities()[0] > 0.0 && p.joint_velocities()[3] > 0.0);
    Ok(())
}

/// Property: an encoder that loses one count in n under-counts by 1/n of the travel.
#[test]
fn a_lossy_encoder_undercounts_by_one_in_n() -> TestResult {
    let mut p = plant()?;
    p.inject(2, Fault::EncoderLosesCounts { one_in: 50 })?;
    let cpu = p.counts_per_joint_unit();
    let x0 = p.motor_side_joint_positions();
    let mut ext = CounterExtender::new(&p);
    p.set_duty([0.3; NUM_JOINTS])?;
    for _ in 0..2000 {
        p.step(DT)?;
        ext.update(&p);
    }
    let x = p.motor_side_joint_positions();
    let truth = ((x[2] - x0[2]) * cpu[2] + 0.5).floor();
    let got = ext.total[2] as f64;
    assert!(truth > 5000.0);
    assert_close("lost counts", truth - got, truth / 50.0, 1.0);
    Ok(())
}

/// Property: fault injection and queries on a joint index outside 0..6 are errors, not
/// panics; a zero loss ratio is rejected.
#[test]
fn bad_fault_arguments_are_errors() -> TestResult {
    let mut p = plant()?;
    assert_eq!(
        p.inject(6, Fault::EncoderStuck),
        Err(PlantError::JointOutOfRange { joint: 6 })
    );
    assert!(p.clear_faults(99).is_err());
    assert!(p.faults(6).is_err());
    assert!(p.joint(6).is_err());
    assert!(p
        .inject(0, Fault::EncoderLosesCounts { one_in: 0 })
        .is_err());
    Ok(())
}

/// Property: a seized load stops the joint; the motor still turns through the backlash
/// (invisible to the load) and then stalls.
#[test]
fn a_seized_load_lets_the_motor_cross_the_backlash_only() -> TestResult {
    let mut p = plant()?;
    p.inject(0, Fault::LoadSeized)?;
    p.inject(3, Fault::LoadSeized)?;
    p.set_duty([0.5; NUM_JOINTS])?;
    p.advance(0.05, DT)?;
    for j in [0, 3] {
        let model = p.joint(j)?.model();
        assert_eq!(p.joint_positions()[j], HOME[j]);
        let gap = p.motor_side_joint_positions()[j] - p.joint_positions()[j];
        assert_close("gap", gap, model.backlash.half(), 1e-12);
        assert_eq!(p.motor_side_joint_velocities()[j], 0.0);
    }
    Ok(())
}
