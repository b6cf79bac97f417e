//! `host-sim forces --path diagonal`: the actuator forces and torques tau = J^-T s_e along
//! a straight path of the platform centre at a fixed orientation (thesis Appendix A
//! section 4, Fig. 8.5/8.6): by default from [-20,-20,-10] to [20,20,10] mm about
//! [0, 0, hc], the platform rotated 20 deg about [1,1,1], wrench [7,7,7 N, 0.7,0.7,0.7 N m].

use super::{out_dir, perr, register_font, span, write_csv};
use crate::columns::{parse_branch, pose_from_edge, POSE};
use crate::commands::forces::{self, ForcesArgs};
use crate::task_box::numbers;
use crate::units::{fixed, m_to_mm, significant};
use clap::{Args, ValueEnum};
use kinematics_core::{
    actuator_forces, inverse, jacobian, Branch, JointKind, Mechanism, Robot, RobotKind, Wrench,
};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// 20 deg about [1,1,1]/sqrt(3) as a rotation vector component, deg.
pub const DIAGONAL_ROTATION_COMPONENT_DEG: f64 = 11.547_005_383_792_516;
/// The thesis's wrench: [7, 7, 7 N, 0.7, 0.7, 0.7 N m].
pub const THESIS_WRENCH: [f64; 6] = [7.0, 7.0, 7.0, 0.7, 0.7, 0.7];

/// `host-sim forces`: the row-wise form (`--pose` or `--csv`) or the path form (`--path`).
#[derive(Debug, Args)]
#[command(mut_arg("pose", |a| a.required_unless_present_any(["csv", "path"])))]
#[command(mut_arg("wrench", |a| a.required_unless_present_any(["csv", "path"])))]
pub struct ForcesCommandArgs {
    #[command(flatten)]
    pub row: ForcesArgs,
    #[command(flatten)]
    pub path: PathArgs,
}

/// A named path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PathChoice {
    /// A straight line from --from to --to (mm, about [0, 0, hc]) at the fixed orientation
    /// --rotation-deg; defaults: the thesis's diagonal [-20,-20,-10] -> [20,20,10] mm,
    /// 20 deg about [1,1,1].
    Diagonal,
}

/// The path form of `forces`.
#[derive(Debug, Args)]
pub struct PathArgs {
    /// Path form: the forces along a straight path; writes forces_path.csv and
    /// forces_path.png to --out (default target/design/forces/). The wrench defaults to
    /// the thesis's 7,7,7,0.7,0.7,0.7 and the branch to 0.
    #[arg(long, value_enum, conflicts_with_all = ["csv", "pose"])]
    pub path: Option<PathChoice>,
    /// Start of the path, mm, relative to [0, 0, hc].
    #[arg(
        long = "from",
        value_name = "DX_MM,DY_MM,DZ_MM",
        default_value = "-20,-20,-10",
        allow_hyphen_values = true
    )]
    pub from_mm: String,
    /// End of the path, mm, relative to [0, 0, hc].
    #[arg(
        long = "to",
        value_name = "DX_MM,DY_MM,DZ_MM",
        default_value = "20,20,10",
        allow_hyphen_values = true
    )]
    pub to_mm: String,
    /// The fixed platform orientation as a rotation vector, deg [default: 20 deg about
    /// [1,1,1]/sqrt(3)].
    #[arg(
        long,
        value_name = "RX,RY,RZ",
        default_value = "11.547005383792516,11.547005383792516,11.547005383792516",
        allow_hyphen_values = true
    )]
    pub rotation_deg: String,
    /// Number of samples along the path (>= 2), ends included.
    #[arg(long, value_name = "N", default_value_t = 101)]
    pub samples: usize,
    /// Output directory [default: target/design/forces].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

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

/// One sample of the path.
#[derive(Clone, Debug, PartialEq)]
pub struct PathSample {
    /// Path parameter 0..=1.
    pub s: f64,
    /// x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
    pub pose: [f64; 6],
    /// tau in q order (N or N m), or why it could not be computed.
    pub tau: Result<[f64; 6], String>,
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
) -> Result<[f64; 6], String> {
    let pose = pose_from_edge(&POSE, pose_edge)?;
    let sol = inverse(robot, &pose, branch).map_err(|e| format!("ik: {e}"))?;
    let jac = jacobian(robot, &sol).map_err(|e| format!("jacobian: {e}"))?;
    let st = actuator_forces(&jac, robot.rp(), &Wrench::from(wrench), min_inv_cond)
        .map_err(|e| format!("forces: {e}"))?;
    let mut out = [0.0; 6];
    out.iter_mut().zip(st.tau.iter()).for_each(|(o, t)| *o = *t);
    Ok(out)
}

/// The forces at every sample of the path.
pub fn forces_along(robot: &Robot<f64>, spec: &PathSpec) -> Vec<PathSample> {
    let hc_mm = m_to_mm(robot.hc());
    let n = spec.samples.max(2);
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            let c = |k: usize| spec.from_mm[k] + s * (spec.to_mm[k] - spec.from_mm[k]);
            let [rx, ry, rz] = spec.rotation_deg;
            let pose = [c(0), c(1), c(2) + hc_mm, rx, ry, rz];
            PathSample {
                s,
                pose,
                tau: tau_at(robot, pose, spec.wrench, spec.branch, spec.min_inv_cond),
            }
        })
        .collect()
}

/// The largest |tau_j| along the path, per joint (NaN when no sample was computed).
pub fn peaks(samples: &[PathSample]) -> [f64; 6] {
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
                    r.push(e.clone());
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
) -> Result<(), String> {
    register_font();
    let kind = robot.kind();
    let kinds = robot.joint_kinds();
    let names = tau_columns(kind);
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(perr)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(perr)?;
    let panels = root.split_evenly((2, 1));
    let colors = [RED, BLUE, RGBColor(0, 130, 0)];
    for (p, area) in panels.iter().enumerate() {
        let joints = 3 * p..3 * p + 3;
        let yr = span(
            samples
                .iter()
                .filter_map(|s| s.tau.as_ref().ok())
                .flat_map(|t| t[joints.clone()].to_vec()),
        );
        let unit = match kinds.get(3 * p) {
            Some(JointKind::Linear) => "N",
            _ => "N m",
        };
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..1.0, yr.0..yr.1)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("path parameter s")
            .y_desc(unit)
            .draw()
            .map_err(perr)?;
        for (j, color) in joints.zip(colors) {
            chart
                .draw_series(LineSeries::new(
                    samples
                        .iter()
                        .filter_map(|s| s.tau.as_ref().ok().map(|t| (s.s, t[j]))),
                    color.stroke_width(2),
                ))
                .map_err(perr)?
                .label(names[j])
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(perr)?;
    }
    root.present().map_err(perr)
}

/// Runs `forces`: the path form when `--path` is given, else the row-wise form.
pub fn run(args: &ForcesCommandArgs, robot: &Robot<f64>) -> Result<(), String> {
    let Some(choice) = args.path.path else {
        return forces::run(&args.row, robot);
    };
    let PathChoice::Diagonal = choice;
    let p = &args.path;
    if p.samples < 2 {
        return Err(format!("--samples: {} is below 2", p.samples));
    }
    let spec = PathSpec {
        from_mm: numbers("--from", &p.from_mm)?,
        to_mm: numbers("--to", &p.to_mm)?,
        rotation_deg: numbers("--rotation-deg", &p.rotation_deg)?,
        samples: p.samples,
        wrench: match &args.row.wrench {
            Some(w) => numbers("--wrench", w)?,
            None => THESIS_WRENCH,
        },
        branch: parse_branch(&args.row.input.branch)?,
        min_inv_cond: args.row.min_inv_cond,
    };
    let samples = forces_along(robot, &spec);
    let dir = out_dir(p.out.as_deref(), "forces")?;
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
    println!(
        "forces along the path: {} samples, {} failed (see the error column)",
        samples.len(),
        failed
    );
    let pk = peaks(&samples);
    for (name, v) in tau_columns(robot.kind()).iter().zip(pk) {
        println!("  peak |{name}| = {v:.3}");
    }
    println!("  wrote {}", csv_path.display());
    println!("  wrote {}", png.display());
    Ok(())
}
