//! `forces --path`: the actuator forces along the thesis's diagonal (the command itself:
//! host-sim/tests/design.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::forces_path::{forces_along, peaks, tau_columns, PathSpec};
use kinematics_core::{inverse, jacobian, Branch, Pose, Robot, RsprGeometry, UsrGeometry};
use nalgebra::{Vector3, Vector6};

/// Along the diagonal, every sample satisfies virtual work: tau . (J xdot) = s_e . xdot,
/// and the peaks are the largest magnitudes of the samples.
#[test]
fn path_forces_satisfy_virtual_work() {
    for robot in [
        Robot::Rspr(RsprGeometry::reference()),
        Robot::Usr(UsrGeometry::reference()),
    ] {
        let spec = PathSpec {
            samples: 11,
            ..PathSpec::thesis_diagonal()
        };
        let samples = forces_along(&robot, &spec);
        let se = Vector6::from(spec.wrench);
        let xdot = Vector6::new(0.3, -0.2, 0.5, 0.7, -1.1, 0.4);
        for s in &samples {
            let tau = Vector6::from(*s.tau.as_ref().unwrap());
            let p = s.pose;
            let pose = Pose::from_position_rotation_vector(
                Vector3::new(p[0], p[1], p[2]) / 1000.0,
                Vector3::new(p[3], p[4], p[5]).map(f64::to_radians),
            )
            .unwrap();
            let sol = inverse(&robot, &pose, Branch::OUTER).unwrap();
            let j = jacobian(&robot, &sol).unwrap();
            let lhs = tau.dot(&(j.j * xdot));
            let rhs = se.dot(&xdot);
            assert!(
                (lhs - rhs).abs() < 1e-9 * (1.0 + rhs.abs()),
                "{lhs} vs {rhs}"
            );
        }
        let pk = peaks(&samples);
        for (k, p) in pk.iter().enumerate() {
            let m = samples
                .iter()
                .map(|s| s.tau.as_ref().unwrap()[k].abs())
                .fold(0.0, f64::max);
            assert_eq!(*p, m, "{:?}", tau_columns(robot.kind()));
        }
    }
}
