//! `host-sim forces --path diagonal`: the actuator forces and torques tau = J^-T s_e along
//! a straight path of the platform centre at a fixed orientation (thesis Appendix A
//! section 4, Fig. 8.5/8.6): by default from [-20,-20,-10] to [20,20,10] mm about
//! [0, 0, hc], the platform rotated 20 deg about [1,1,1], wrench [7,7,7 N, 0.7,0.7,0.7 N m].

use crate::files::{out_dir, write_csv, OutputError};
use kinematics_core::{
    actuator_forces, inverse, jacobian, Branch, ForceError, IkError, JacobianError, JointKind,
    Mechanism, Robot, RobotKind, Wrench,
};
use plots::{line_charts, span, Layout, Panel, PlotError, Series, CHAIN_COLORS};
use robot_config::edge::{pose_from_edge, EdgeError, POSE};
use robot_config::units::{fixed, m_to_mm, significant};
use std::fmt::Write as _;
use std::path::Path;
use thiserror::Error;

/// 20 deg about [1,1,1]/sqrt(3) as a rotation vector component, deg.
pub const DIAGONAL_ROTATION_COMPONENT_DEG: f64 = 11.547_005_383_792_516;
/// The thesis's wrench: [7, 7, 7 N, 0.7, 0.7, 0.7 N m].
pub const THESIS_WRENCH: [f64; 6] = [7.0, 7.0, 7.0, 0.7, 0.7, 0.7];

/// What to evaluate along the path (edge units).
#[derive(Clone, Debug, PartialEq)]
pub struct PathSpec {
    /// Start and end of the platform centre, mm, relative to [0, 0, hc].
    pub from_mm: [f64; 3],
    pub to_mm: [f64; 3],
    /// The fixed orientation, rotation vector in deg.
    pub rotation_deg: [f64; 3],
    /// Number of samples, ends included (>= 2).
    pub samples: usize,
    /// fx_n, fy_n, fz_n, tx_nm, ty_nm, tz_nm.
    pub wrench: [f64; 6],
    pub branch: Branch,
    /// Smallest accepted inverse condition number (as `forces`).
    pub min_inv_cond: f64,
}

impl PathSpec {
    /// The thesis's diagonal (Appendix A section 4) with 101 samples on branch 0.
    pub fn thesis_diagonal() -> Self {
        PathSpec {
            from_mm: [-20.0, -20.0, -10.0],
            to_mm: [20.0, 20.0, 10.0],
            rotation_deg: [DIAGONAL_ROTATION_COMPONENT_DEG; 3],
            samples: 101,
            wrench: THESIS_WRENCH,
            branch: Branch::OUTER,
            min_inv_cond: 1e-6,
        }
    }
}

/// Why tau could not be computed at a pose: the step that failed and the core's reason.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum TauError {
    #[error(transparent)]
    Pose(#[from] EdgeError),
    #[error("ik: {0}")]
    Ik(IkError),
    #[error("jacobian: {0}")]
    Jacobian(JacobianError),
    #[error("forces: {0}")]
    Forces(ForceError),
}

/// One sample of the path.
#[derive(Clone, Debug, PartialEq)]
pub struct PathSample<E = TauError> {
    /// Path parameter 0..=1.
    pub s: f64,
    /// x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
    pub pose: [f64; 6],
    /// tau in q order (N or N m), or why it could not be computed.
    pub tau: Result<[f64; 6], E>,
}

/// The force columns of a robot in q order, with units (CONVENTIONS.md, "Forces").
pub fn tau_columns(kind: RobotKind) -> [&'static str; 6] {
    match kind {
        RobotKind::Rspr => ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm"],
        RobotKind::Usr => [
            "t_alpha1_nm",
            "t_alpha2_nm",
            "t_alpha3_nm",
            "t_beta1_nm",
            "t_beta2_nm",
            "t_beta3_nm",
        ],
    }
}

/// tau at one pose (edge units).
pub fn tau_at(
    robot: &Robot<f64>,
    pose_edge: [f64; 6],
    wrench: [f64; 6],
    branch: Branch,
    min_inv_cond: f64,
) -> Result<[f64; 6], TauError> {
    let pose = pose_from_edge(&POSE, pose_edge)?;
    let sol = inverse(robot, &pose, branch).map_err(TauError::Ik)?;
    let jac = jacobian(robot, &sol).map_err(TauError::Jacobian)?;
    let st = actuator_forces(&jac, robot.rp(), &Wrench::from(wrench), min_inv_cond)
        .map_err(TauError::Forces)?;
    let mut out = [0.0; 6];
    out.iter_mut().zip(st.tau.iter()).for_each(|(o, t)| *o = *t);
    Ok(out)
}

/// The poses of the path (edge units), with their parameter s.
pub fn path_poses(hc_mm: f64, spec: &PathSpec) -> Vec<(f64, [f64; 6])> {
    let n = spec.samples.max(2);
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            let c = |k: usize| spec.from_mm[k] + s * (spec.to_mm[k] - spec.from_mm[k]);
            let [rx, ry, rz] = spec.rotation_deg;
            (s, [c(0), c(1), c(2) + hc_mm, rx, ry, rz])
        })
        .collect()
}

/// The forces at every sample of the path.
pub fn forces_along(robot: &Robot<f64>, spec: &PathSpec) -> Vec<PathSample> {
    path_poses(m_to_mm(robot.hc()), spec)
        .into_iter()
        .map(|(s, pose)| PathSample {
            s,
            pose,
            tau: tau_at(robot, pose, spec.wrench, spec.branch, spec.min_inv_cond),
        })
        .collect()
}

/// The largest |tau_j| along the path, per joint (NaN when no sample was computed).
pub fn peaks<E>(samples: &[PathSample<E>]) -> [f64; 6] {
    let mut p = [f64::NAN; 6];
    for t in samples.iter().filter_map(|s| s.tau.as_ref().ok()) {
        for (pk, v) in p.iter_mut().zip(t) {
            *pk = if pk.is_nan() {
                v.abs()
            } else {
                pk.max(v.abs())
            };
        }
    }
    p
}

/// The CSV header of the path form.
pub fn header(kind: RobotKind) -> Vec<String> {
    let mut h: Vec<String> = vec!["s".into()];
    h.extend(POSE.iter().map(|c| c.to_string()));
    h.extend(tau_columns(kind).iter().map(|c| c.to_string()));
    h.push("error".into());
    h
}

fn rows(samples: &[PathSample]) -> Vec<Vec<String>> {
    samples
        .iter()
        .map(|smp| {
            let mut r = vec![fixed(smp.s, 6)];
            r.extend(smp.pose.iter().map(|&x| fixed(x, 6)));
            match &smp.tau {
                Ok(t) => {
                    r.extend(t.iter().map(|&x| significant(x)));
                    r.push(String::new());
                }
                Err(e) => {
                    r.extend(std::iter::repeat_n(String::new(), 6));
                    r.push(e.to_string());
                }
            }
            r
        })
        .collect()
}

/// Plots the forces (first three joints) and torques (last three) against s.
pub fn plot(
    robot: &Robot<f64>,
    samples: &[PathSample],
    title: &str,
    path: &Path,
) -> Result<(), PlotError> {
    let names = tau_columns(robot.kind());
    let kinds = robot.joint_kinds();
    let panels: Vec<Panel> = (0..2)
        .map(|p| {
            let joints = 3 * p..3 * p + 3;
            let computed = || samples.iter().filter_map(|s| s.tau.as_ref().ok());
            Panel {
                levels: Vec::new(),
                bands: Vec::new(),
                caption: None,
                x_desc: "path parameter s".into(),
                y_desc: match kinds.get(3 * p) {
                    Some(JointKind::Linear) => "N",
                    _ => "N m",
                }
                .into(),
                x_range: (0.0, 1.0),
                y_range: span(computed().flat_map(|t| t[joints.clone()].to_vec())),
                series: joints
                    .zip(CHAIN_COLORS)
                    .map(|(j, color)| {
                        let points = samples
                            .iter()
                            .filter_map(|s| s.tau.as_ref().ok().map(|t| (s.s, t[j])))
                            .collect();
                        Series::new(names[j], points, color, 2)
                    })
                    .collect(),
            }
        })
        .collect();
    line_charts(path, (1200, 900), title, &panels, Layout::Stacked)
}

/// Runs `forces --path`: the forces along the path of `spec`, written as
/// `forces_path.csv` and `forces_path.png` to `out` (default `target/design/forces`).
/// Returns the summary to print: failed samples, peaks, the files.
pub fn run(robot: &Robot<f64>, spec: &PathSpec, out: Option<&Path>) -> Result<String, OutputError> {
    let samples = forces_along(robot, spec);
    let dir = out_dir(out, "forces")?;
    let csv_path = dir.join("forces_path.csv");
    write_csv(&csv_path, &header(robot.kind()), &rows(&samples))?;
    let png = dir.join("forces_path.png");
    let v = |a: &[f64; 3]| format!("{:.1}, {:.1}, {:.1}", a[0], a[1], a[2]);
    let title = format!(
        "{:?}: actuator forces along [{}] -> [{}] mm about [0,0,hc], r = ({}) deg",
        robot.kind(),
        v(&spec.from_mm),
        v(&spec.to_mm),
        v(&spec.rotation_deg)
    );
    plot(robot, &samples, &title, &png)?;
    let failed = samples.iter().filter(|s| s.tau.is_err()).count();
    let mut text = String::new();
    let _ = writeln!(
        text,
        "forces along the path: {} samples, {} failed (see the error column)",
        samples.len(),
        failed
    );
    let pk = peaks(&samples);
    for (name, v) in tau_columns(robot.kind()).iter().zip(pk) {
        let _ = writeln!(text, "  peak |{name}| = {v:.3}");
    }
    let _ = writeln!(text, "  wrote {}", csv_path.display());
    let _ = writeln!(text, "  wrote {}", png.display());
    Ok(text)
}
