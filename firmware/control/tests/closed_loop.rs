#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The control application in closed loop with the plant model: the same code as on the
//! board, the plant integrated at 10x the control rate.

use common::PlantHw;
use control::{Controller, ControllerConfig, Sensing};
use hal::{Brakes, MotorOutputs};
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use nalgebra::{Rotation3, Vector3};

use crate::common;

type Sense = Sensing<f64, RsprGeometry<f64>>;

fn setup() -> (PlantHw, Controller<f64, RsprGeometry<f64>>, Sense) {
    let g = RsprGeometry::<f64>::reference();
    let q0 = inverse(&g, &Pose::central(g.hc), Branch::OUTER)
        .unwrap()
        .q();
    let q0 = [q0[0], q0[1], q0[2], q0[3], q0[4], q0[5]];
    let mut hw = common::plant_hw(q0);
    let sensing = common::homed_sensing(&mut hw, q0);
    let ctl = Controller::new(g, ControllerConfig::default(), sensing.measured()).unwrap();
    (hw, ctl, sensing)
}

/// A verified target is reached and held: the true platform pose (from the plant's
/// load-side joints) ends within 60 µm of the target (half the plant's backlash).
#[test]
fn follows_a_target_in_closed_loop() {
    let (mut hw, mut ctl, mut sensing) = setup();
    let g = RsprGeometry::<f64>::reference();
    let target = Pose {
        t: Vector3::new(0.008, -0.005, 0.163),
        r: Rotation3::from_scaled_axis(Vector3::new(0.05, -0.03, 0.0)),
    };
    ctl.submit(&target, 1_000, 1_000).unwrap();
    let mut worst_following: f64 = 0.0;
    for _ in 0..2500 {
        // Drives on at every tick (a fault disables them within the tick).
        hw.enable();
        hw.set_brakes_released(true);
        let r = ctl.tick(sensing.update(&mut hw));
        r.apply(&mut hw);
        ctl.evaluate();
        assert!(r.servo.fault.is_none(), "{:?}", r.servo.fault);
        hw.step_ms();
        let q = hw.plant.joint_positions();
        let err = (0..3)
            .map(|j| (q[j] - ctl.supervisor().setpoint_joints()[j]).abs())
            .fold(0.0, f64::max);
        worst_following = worst_following.max(err);
    }
    let q = hw.plant.joint_positions();
    let truth = kinematics_core::forward(
        &g,
        &nalgebra::Vector6::from_row_slice(&q),
        Branch::OUTER,
        &target,
        &Default::default(),
    )
    .unwrap();
    let err = (truth.pose.t - target.t).norm();
    println!(
        "final true tip error {:.2} µm, worst leg following error {:.2} µm",
        err * 1e6,
        worst_following * 1e6
    );
    // The load side rests anywhere within the 0.12 mm lead-screw backlash once stopped.
    assert!(err < 60e-6, "tip error {err}");
}

/// A stuck encoder trips the tracking-error fault and every output goes off.
#[test]
fn stuck_encoder_trips_the_tracking_fault() {
    let (mut hw, mut ctl, mut sensing) = setup();
    hw.plant.inject(0, plant::Fault::EncoderStuck).unwrap();
    let target = Pose {
        t: Vector3::new(0.0, 0.0, 0.170),
        r: Rotation3::identity(),
    };
    ctl.submit(&target, 1_000, 1_000).unwrap();
    let mut tripped_at = None;
    for k in 0..2000 {
        // Drives on at every tick (a fault disables them within the tick).
        hw.enable();
        hw.set_brakes_released(true);
        let r = ctl.tick(sensing.update(&mut hw));
        r.apply(&mut hw);
        ctl.evaluate();
        if r.servo.fault.is_some() && tripped_at.is_none() {
            tripped_at = Some(k);
        }
        if tripped_at.is_some() {
            assert!(hw.plant.duty().iter().all(|d| *d == 0.0));
        }
        hw.step_ms();
    }
    let k = tripped_at.expect("the stuck encoder must trip the fault");
    println!("stuck encoder tripped after {k} ms");
    assert!(k < 200);
}
