//! The analysis the Python module exposes, in plain Rust: edge units in and out
//! (CONVENTIONS.md, "Units": poses `x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg`, joints in q
//! order in mm and degrees, Jacobians and forces in SI as `host-sim jacobian` and `forces`
//! print them), each step the command line's, with its error text.
//!
//! The same functions serve the bindings (`bindings`, feature `python`) and this crate's
//! Rust tests, so the values Python sees are the ones tested here without Python.

use kinematics_core::guards::Limits;
use kinematics_core::singularity::configurations::residuals;
use kinematics_core::singularity::lines::{analyse, Tolerances};
use kinematics_core::singularity::serial_cases::cases;
use kinematics_core::singularity::SvdDidNotConverge;
use kinematics_core::{
    actuator_forces, forward, inverse, jacobian as core_jacobian, measures, Branch, FkConfig,
    FkError, ForceError, IkError, JacobianError, Mechanism, Pose, Robot, RobotKind, Solution,
    Wrench,
};
use robot_config::edge::{joints_from_edge, joints_to_edge, pose_from_edge, pose_to_edge, POSE};
use robot_config::fields::{branch_from_bits, finite_values, FieldError, INITIAL_POSE, WRENCH};
use robot_config::verdict::{self, Check, VerdictError};
use thiserror::Error;

/// Why an analysis has no result: the input, or the step that failed with the core's
/// reason (the texts of the command line's `error` column).
#[derive(Debug, Error)]
pub enum AnalysisError {
    /// A value that is not finite, a branch out of range: the command line's parser's
    /// words (`robot_config::fields`).
    #[error(transparent)]
    Input(#[from] FieldError),
    #[error("ik: {0}")]
    Ik(IkError),
    #[error("fk: {0}")]
    Fk(FkError),
    #[error("jacobian: {0}")]
    Jacobian(JacobianError),
    #[error("jacobian: {0}")]
    Conditioning(SvdDidNotConverge),
    #[error("forces: {0}")]
    Forces(ForceError),
    #[error("singularity: {0}")]
    Singularity(SvdDidNotConverge),
    /// The guards of the branch cannot be set up for the robot and limits.
    #[error(transparent)]
    Guards(#[from] VerdictError),
    /// A design tool's settings or robot (workspace, synthesis, comparison).
    #[error(transparent)]
    Design(#[from] crate::design_tools::DesignToolError),
}

/// The smallest inverse condition number `forces` accepts by default (as `host-sim forces
/// --min-inv-cond`).
pub const MIN_INV_COND: f64 = 1e-6;

/// A branch from its number 0..=7.
pub fn branch(bits: i64) -> Result<Branch, AnalysisError> {
    Ok(branch_from_bits(bits)?)
}

/// A pose from its edge values (mm, deg), each component checked as the command line's
/// parser checks it.
pub fn pose(values: [f64; 6]) -> Result<Pose<f64>, AnalysisError> {
    pose_named(&POSE, values)
}

fn pose_named(names: &[&'static str; 6], values: [f64; 6]) -> Result<Pose<f64>, AnalysisError> {
    let v = finite_values(names, values)?;
    pose_from_edge(names, v).map_err(|e| AnalysisError::Input(e.into()))
}

/// The inverse kinematics of a pose (mm, deg) on a branch.
pub fn solve(
    robot: &Robot<f64>,
    pose: [f64; 6],
    b: Branch,
) -> Result<Solution<f64>, AnalysisError> {
    inverse(robot, &self::pose(pose)?, b).map_err(AnalysisError::Ik)
}

/// The joints (mm, deg, q order) of a pose (mm, deg) on a branch.
pub fn ik(robot: &Robot<f64>, pose: [f64; 6], b: Branch) -> Result<[f64; 6], AnalysisError> {
    Ok(joints_to_edge(robot, &solve(robot, pose, b)?.q()))
}

/// The joints of a pose on every branch, by branch number.
pub fn ik_branches(robot: &Robot<f64>, pose: [f64; 6]) -> [Result<[f64; 6], AnalysisError>; 8] {
    Branch::ALL.map(|b| ik(robot, pose, b))
}

/// What `fk` finds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fk {
    /// The pose, mm and deg (rotation vector of angle in [0, 180] deg).
    pub pose: [f64; 6],
    /// Newton iterations taken.
    pub iterations: u32,
}

/// The pose of joints (mm, deg, q order) on a branch, by the core's Newton iteration from
/// `initial` (mm, deg; the central configuration when None).
pub fn fk(
    robot: &Robot<f64>,
    joints: [f64; 6],
    b: Branch,
    initial: Option<[f64; 6]>,
) -> Result<Fk, AnalysisError> {
    let names = robot_config::edge::joint_columns(robot.kind());
    let q = joints_from_edge(robot, finite_values(&names, joints)?);
    let guess = match initial {
        Some(p) => pose_named(&INITIAL_POSE, p)?,
        None => Pose::central(robot.hc()),
    };
    let s = forward(robot, &q, b, &guess, &FkConfig::default()).map_err(AnalysisError::Fk)?;
    Ok(Fk {
        pose: pose_to_edge(&s.pose),
        iterations: s.iterations,
    })
}

/// The Jacobians at a pose, SI, row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JacobianValues {
    /// J = dq/dx (Eq. 7.18): rows in q order, columns [v; w].
    pub j: [[f64; 6]; 6],
    /// The tripod Jacobian J~ (Eq. 7.14): rows the Plücker lines l_1..l_6.
    pub jtilde: [[f64; 6]; 6],
    /// The inverse condition number of J~ with its moment columns over rp.
    pub inv_cond: f64,
}

fn rows(m: &nalgebra::Matrix6<f64>) -> [[f64; 6]; 6] {
    core::array::from_fn(|i| core::array::from_fn(|k| m[(i, k)]))
}

/// The Jacobians of a pose (mm, deg) on a branch.
pub fn jacobian(
    robot: &Robot<f64>,
    pose: [f64; 6],
    b: Branch,
) -> Result<JacobianValues, AnalysisError> {
    let sol = solve(robot, pose, b)?;
    let jac = core_jacobian(robot, &sol).map_err(AnalysisError::Jacobian)?;
    let inv_cond = kinematics_core::singularity::parallel_inv_cond(&jac.jtilde, robot.rp())
        .map_err(AnalysisError::Conditioning)?;
    Ok(JacobianValues {
        j: rows(&jac.j),
        jtilde: rows(&jac.jtilde),
        inv_cond,
    })
}

/// The actuator efforts tau = J^-T s_e (SI, q order) that hold the wrench s_e = [f (N);
/// t (N m)] at a pose (mm, deg) on a branch; refused below `min_inv_cond`.
pub fn forces(
    robot: &Robot<f64>,
    pose: [f64; 6],
    wrench: [f64; 6],
    b: Branch,
    min_inv_cond: f64,
) -> Result<[f64; 6], AnalysisError> {
    let sol = solve(robot, pose, b)?;
    let jac = core_jacobian(robot, &sol).map_err(AnalysisError::Jacobian)?;
    let se = Wrench::from(finite_values(&WRENCH, wrench)?);
    let s = actuator_forces(&jac, robot.rp(), &se, min_inv_cond).map_err(AnalysisError::Forces)?;
    Ok(s.tau.into())
}

/// One guard violated at a pose, in the guard's edge unit (mm, deg, N, N m; dimensionless
/// measures as is).
#[derive(Clone, Debug, PartialEq)]
pub struct ViolationValue {
    /// The guard's name (`stroke`, `workspace`, `tilt_cone`, ...).
    pub guard: &'static str,
    /// What it is about: empty for the robot, `chain1`, `q4`, `x`, ...
    pub subject: String,
    pub value: f64,
    /// The level the value violates.
    pub limit: f64,
    /// The guard's edge unit (`mm`, `deg`, `N`, `N m`, or empty).
    pub unit: &'static str,
    /// `warn` or `stop`.
    pub severity: String,
    /// As `host-sim check` lists it: `guard:subject:value:limit`.
    pub text: String,
}

/// The guards' verdict at a pose, as `host-sim check` reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckValues {
    /// No stop-level violation: the supervisor would accept the pose as a setpoint.
    pub ok: bool,
    /// The worst severity: empty, `warn` or `stop`.
    pub severity: String,
    /// Every violation, in evaluation order.
    pub violations: Vec<ViolationValue>,
    /// The verdict in words (the `guards` column of `ik`, `fk`, `jacobian`, `forces`).
    pub verdict: String,
}

/// The guards' verdict at a pose (mm, deg) on a branch, with the guards `check` prepared
/// for the robot and its limits.
pub fn check(check: &Check, pose: [f64; 6], b: Branch) -> Result<CheckValues, AnalysisError> {
    let readings = check.violations(&self::pose(pose)?, b)?;
    let worst = verdict::worst(&readings);
    Ok(CheckValues {
        ok: worst != Some(kinematics_core::guards::Severity::Stop),
        severity: worst.map(|s| s.to_string()).unwrap_or_default(),
        violations: readings
            .iter()
            .map(|r| ViolationValue {
                guard: r.guard.name(),
                subject: r.subject.to_string(),
                value: verdict::to_edge(r.guard, r.value),
                limit: verdict::to_edge(r.guard, r.limit),
                unit: r.guard.edge_unit().1,
                severity: r.severity.map(|s| s.to_string()).unwrap_or_default(),
                text: verdict::violation_text(r),
            })
            .collect(),
        verdict: verdict::verdict_words(&readings),
    })
}

/// The guards of `robot` with `limits` on every branch (as `host-sim check` prepares them).
pub fn guards(robot: &Robot<f64>, limits: &Limits<f64>) -> Check {
    Check::new(robot, limits)
}

/// A minimal dependent set of lines and its variety (thesis 10.2).
#[derive(Clone, Debug, PartialEq)]
pub struct CircuitValue {
    /// The variety's code: `2b`, `3A`..`3D`, `4A`..`4D`, `5A`, `5B`.
    pub variety: String,
    /// The line numbers 1..6 (l_i along leg i through p_i, l_{i+3} through b_i).
    pub lines: Vec<u8>,
}

/// The residual of one configuration of Table 10.3.
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualValue {
    /// `S1`..`S13` (`S6/7` for the shared condition).
    pub configuration: String,
    /// Dimensionless (lengths over rp, sines, singular values of unit rows); 0 when it holds.
    pub residual: f64,
    /// The chains or lines of the index set, as `host-sim singularity` writes it (`S9(1,2)`).
    pub which: String,
    /// The condition holds at the default tolerance (1e-6).
    pub holds: bool,
}

/// A motion the platform gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GainedValue {
    /// The unit scaled twist [v; rp w].
    pub twist_scaled: [f64; 6],
    /// The pitch in mm per rad; None for a translation.
    pub pitch_mm: Option<f64>,
    /// The point of the screw axis nearest o_p, relative to o_p (mm); None for a
    /// translation.
    pub axis_mm: Option<[f64; 3]>,
}

/// The singularity analysis of a pose, as `host-sim singularity` reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct SingularityValues {
    /// Serial measure per chain (RSPR |Cn2_i| in mm; USR |Cn1 Cr2 - Cr1 Cn2| in mm²).
    pub serial: [f64; 3],
    /// The same over rb (RSPR) or l1² (USR).
    pub serial_frac: [f64; 3],
    pub parallel_inv_cond: f64,
    pub det_sign: i8,
    /// `parallel` or `serial:N`.
    pub nearest: String,
    /// The rank of the six scaled lines.
    pub rank: u8,
    /// Singular values of the scaled lines over the largest.
    pub relative_sigma: [f64; 6],
    pub circuits: Vec<CircuitValue>,
    /// Every configuration's residual, in Table 10.3's order.
    pub residuals: Vec<ResidualValue>,
    /// The linear complex at rank 5 (`5A` general, `5B` special).
    pub complex: Option<String>,
    pub gained: Vec<GainedValue>,
    /// Per chain, the letters of the serial cases that hold (RSPR `a`..`d` of Eq. 10.6, USR
    /// `A`..`F` of Eq. 10.11), joined by `+`; empty when none.
    pub serial_cases: [String; 3],
}

/// The singularity analysis of a pose (mm, deg) on a branch.
pub fn singularity(
    robot: &Robot<f64>,
    pose: [f64; 6],
    b: Branch,
) -> Result<SingularityValues, AnalysisError> {
    let sol = solve(robot, pose, b)?;
    let m = measures(robot, &sol).map_err(AnalysisError::Singularity)?;
    let scale = match robot.kind() {
        RobotKind::Rspr => 1e3,
        RobotKind::Usr => 1e6,
    };
    let rp = robot.rp();
    let tol = Tolerances::default();
    let a = analyse(&sol, rp, &tol).map_err(|_| AnalysisError::Singularity(SvdDidNotConverge))?;
    let c = cases(robot, &sol, &tol).0;
    Ok(SingularityValues {
        serial: m.serial.0.map(|x| x * scale),
        serial_frac: m.serial_relative.0,
        parallel_inv_cond: m.parallel_inv_cond,
        det_sign: m.parallel_det_sign,
        nearest: m.nearest.to_string(),
        rank: a.rank,
        relative_sigma: a.relative_sigma,
        circuits: a
            .circuits
            .iter()
            .map(|c| CircuitValue {
                variety: c.variety.code().to_string(),
                lines: c.line_numbers().collect(),
            })
            .collect(),
        residuals: residuals(&sol, rp)
            .iter()
            .map(|r| ResidualValue {
                configuration: r.configuration.name().to_string(),
                residual: r.residual,
                which: r.to_string(),
                holds: r.holds(&tol),
            })
            .collect(),
        complex: a.complex.map(|v| v.code().to_string()),
        gained: a
            .gained
            .iter()
            .map(|g| {
                let t = g.twist;
                GainedValue {
                    twist_scaled: [t[0], t[1], t[2], rp * t[3], rp * t[4], rp * t[5]],
                    pitch_mm: g.pitch.map(|h| h * 1e3),
                    axis_mm: g.pitch.map(|_| (g.axis_point * 1e3).into()),
                }
            })
            .collect(),
        serial_cases: c.map(|x| x.letters().to_string()),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use kinematics_core::RsprGeometry;

    fn reference() -> Robot<f64> {
        Robot::Rspr(RsprGeometry::reference())
    }

    /// IK then FK from the central configuration returns the pose (the Newton iteration
    /// converges to 1e-12 m / rad; the edge values to 1e-8 mm, deg).
    #[test]
    fn ik_fk_round_trip() {
        let r = reference();
        let pose = [10.0, -5.0, 165.0, 5.0, 0.0, -3.0];
        let q = ik(&r, pose, Branch::OUTER).unwrap();
        let back = fk(&r, q, Branch::OUTER, None).unwrap();
        for (a, b) in pose.iter().zip(back.pose) {
            assert!((a - b).abs() < 1e-8, "{a} vs {b}");
        }
    }

    /// The central configuration is symmetric: the three legs have the same length and
    /// theta is 0 on the outer branch (CONVENTIONS.md, "Joints").
    #[test]
    fn central_pose_is_symmetric() {
        let q = ik(
            &reference(),
            [0.0, 0.0, 160.0, 0.0, 0.0, 0.0],
            Branch::OUTER,
        )
        .unwrap();
        assert!((q[0] - q[1]).abs() < 1e-9 && (q[1] - q[2]).abs() < 1e-9);
        for t in &q[3..] {
            assert!(t.abs() < 1e-9, "{t}");
        }
    }

    /// Errors carry the command line's text.
    #[test]
    fn errors_read_like_the_cli() {
        let r = reference();
        let e = ik(&r, [0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0], Branch::OUTER).unwrap_err();
        assert_eq!(e.to_string(), "z_mm: \"NaN\" is not a finite number");
        assert_eq!(
            branch(9).unwrap_err().to_string(),
            "branch: 9 is out of range 0..=7"
        );
        let e = ik(&r, [200.0, 0.0, 20.0, 0.0, 0.0, 0.0], Branch::OUTER).unwrap_err();
        assert_eq!(
            e.to_string(),
            "ik: chain 2: no real root (pose out of reach)"
        );
    }

    /// The guards accept the central pose and stop a pose typed in metres, with the
    /// `guards` column's words and `check`'s texts.
    #[test]
    fn check_accepts_the_centre_and_stops_metres() {
        use kinematics_core::guards::Limits;
        let r = reference();
        let g = guards(&r, &Limits::reference());
        let c = check(&g, [0.0, 0.0, 160.0, 0.0, 0.0, 0.0], Branch::OUTER).unwrap();
        assert!(c.ok && c.severity.is_empty() && c.violations.is_empty());
        assert_eq!(c.verdict, "ok");
        let c = check(&g, [0.0, 0.0, 0.16, 0.0, 0.0, 0.0], Branch::OUTER).unwrap();
        assert!(!c.ok);
        assert_eq!(c.severity, "stop");
        assert!(c.verdict.starts_with("stop: "), "{}", c.verdict);
        let w = c
            .violations
            .iter()
            .find(|v| v.guard == "workspace")
            .unwrap();
        assert_eq!(w.unit, "mm");
        assert!(w.text.starts_with("workspace:z:159.840:"), "{}", w.text);
    }

    /// The platform in the base plane: rank 3 and S1 holds (kinematics-core's tests
    /// construct it; here it checks the values pass through).
    #[test]
    fn platform_in_base_plane_is_s1() {
        let s = singularity(&reference(), [0.0; 6], Branch::OUTER).unwrap();
        assert_eq!(s.rank, 3);
        assert!(s
            .residuals
            .iter()
            .any(|r| r.configuration == "S1" && r.holds));
        assert_eq!(s.residuals.len(), 12);
    }

    /// tau . qdot = s_e . twist (virtual work) through the edge values: J maps a twist to
    /// qdot in SI, so tau . (J t) = s_e . t for any t.
    #[test]
    fn forces_satisfy_virtual_work() {
        let r = reference();
        let pose = [10.0, -5.0, 165.0, 5.0, 0.0, 0.0];
        let se = [7.0, 7.0, 7.0, 0.7, 0.7, 0.7];
        let tau = forces(&r, pose, se, Branch::OUTER, MIN_INV_COND).unwrap();
        let j = jacobian(&r, pose, Branch::OUTER).unwrap().j;
        let t = [0.3, -0.2, 0.1, 0.5, 0.4, -0.6];
        let qdot: Vec<f64> = j
            .iter()
            .map(|row| row.iter().zip(t).map(|(a, b)| a * b).sum())
            .collect();
        let lhs: f64 = tau.iter().zip(&qdot).map(|(a, b)| a * b).sum();
        let rhs: f64 = se.iter().zip(t).map(|(a, b)| a * b).sum();
        assert!(
            (lhs - rhs).abs() < 1e-9 * rhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
    }
}
