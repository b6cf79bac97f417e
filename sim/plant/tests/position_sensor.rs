#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The second position channel: the absolute position sensors on the load side, their
//! resolution, noise and offset, and their faults (stuck, open wire, drift).
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best

mod common;
use common::*;
use plant::{Fault, PlantError, NUM_JOINTS};

const DT: f64 = 50e-6;

/// The position each reading stands for, by the sensors' own calibration.
fn positions(p: &plant::Plant) -> [f64; NUM_JOINTS] {
    let c = p.position_sensor_counts();
    std::array::from_fn(|j| p.position_sensor(j).unwrap().position_of(c[j]))
}

/// Property: the shipped sensors resolve 1.53 um on a leg (100 mm over 65536 counts) and
/// 0.0052 deg on a link (340 deg), and read the load-side position to within their offset
/// (2 counts) and noise (1 count rms, at most 3.5 counts): over 1000 readings at rest the
/// mean is within 0.1 count of the offset, and no reading is further off than 6 counts.
#[test]
fn the_sensors_read_the_load_side_position_within_offset_and_noise() -> TestResult {
    let mut p = plant()?;
    let cpu: [f64; NUM_JOINTS] =
        std::array::from_fn(|j| p.position_sensor(j).unwrap().counts_per_unit);
    for j in 0..3 {
        assert!(
            (1e6 / cpu[j] - 1.5259).abs() < 1e-3,
            "um per count {}",
            1e6 / cpu[j]
        );
    }
    for j in 3..6 {
        let deg = 1.0 / cpu[j] / 1f64.to_radians();
        assert!((deg - 0.005188).abs() < 1e-5, "deg per count {deg}");
    }
    let q = p.joint_positions();
    let mut sum = [0.0; NUM_JOINTS];
    let n = 1000;
    for _ in 0..n {
        p.advance(1e-3, DT)?;
        let c = p.position_sensor_counts();
        for j in 0..NUM_JOINTS {
            let ideal = p.position_sensor(j)?.ideal_counts(q[j]) - 2.0;
            let off = f64::from(c[j]) - ideal;
            assert!((off - 2.0).abs() <= 6.0, "joint {j}: {off} counts off");
            sum[j] += off;
        }
    }
    for j in 0..NUM_JOINTS {
        let mean = sum[j] / f64::from(n);
        assert!(
            (mean - 2.0).abs() < 0.1,
            "joint {j}: mean offset {mean} counts"
        );
    }
    Ok(())
}

/// Property: the sensor sits on the load side: while the motor crosses the backlash gap
/// the reading does not follow it, and it follows the load when the load moves.
#[test]
fn the_sensor_follows_the_load_not_the_motor() -> TestResult {
    let mut p = plant()?;
    let before = positions(&p);
    // A small push: the motor takes up the gap (0.06 mm) before the load moves.
    p.set_duty([0.02, 0.0, 0.0, 0.0, 0.0, 0.0])?;
    let mut crossed = false;
    for _ in 0..4000 {
        p.step(DT)?;
        let load = p.joint_positions()[0] - common::HOME[0];
        let motor = p.motor_side_joint_positions()[0] - common::HOME[0];
        let read = positions(&p)[0] - before[0];
        assert!(
            (read - load).abs() < 8e-6,
            "reads {read}, load moved {load}"
        );
        crossed |= motor - load > 50e-6;
    }
    assert!(crossed, "the motor crossed the gap ahead of the load");
    assert!(
        p.joint_positions()[0] - common::HOME[0] > 1e-3,
        "the load moved"
    );
    Ok(())
}

/// Property: a stuck sensor freezes at its reading, an open wire reads 0 counts, a
/// drifting one walks at its rate (10 um/s here: 5 um in 0.5 s), and clearing the faults
/// brings the true reading back; a drift of rate 0 or NaN is refused.
#[test]
fn stuck_open_and_drifting_sensors() -> TestResult {
    let mut p = plant()?;
    p.inject(0, Fault::PositionSensorStuck)?;
    p.inject(1, Fault::PositionSensorOpen)?;
    p.inject(2, Fault::PositionSensorDrift { per_s: 10e-6 })?;
    let frozen = p.position_sensor_counts()[0];
    let start = positions(&p)[2];
    p.set_duty([0.05, 0.0, 0.0, 0.0, 0.0, 0.0])?;
    p.advance(0.5, DT)?;
    p.set_duty([0.0; NUM_JOINTS])?;
    p.advance(0.05, DT)?;
    assert!(
        p.joint_positions()[0] - common::HOME[0] > 5e-3,
        "joint 0 moved"
    );
    assert_eq!(p.position_sensor_counts()[0], frozen);
    assert_eq!(p.position_sensor_counts()[1], 0);
    let walked = positions(&p)[2] - start;
    assert!((walked - 5.5e-6).abs() < 5e-6, "drifted {walked} m");
    assert!(p.sensor_faults(2)?.drift.is_some());
    for j in 0..3 {
        p.clear_faults(j)?;
    }
    let q = p.joint_positions();
    let r = positions(&p);
    for j in 0..3 {
        assert!(
            (r[j] - q[j]).abs() < 10e-6,
            "joint {j} reads {} at {}",
            r[j],
            q[j]
        );
    }
    for per_s in [0.0, f64::NAN] {
        let f = Fault::PositionSensorDrift { per_s };
        assert!(matches!(
            p.inject(3, f),
            Err(PlantError::InvalidFault(Fault::PositionSensorDrift { .. }))
        ));
    }
    Ok(())
}
