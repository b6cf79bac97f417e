//! `singularity`: the serial measure of each chain, the parallel measure and the nearest
//! singularity (CONVENTIONS.md, "Measures"), and the line-geometry classification of
//! thesis chapter 10 (`kinematics_core::singularity::{lines, configurations,
//! serial_cases}`); `singularity-scan`: the nearest configuration of each S-type over a
//! task box.

use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{BatchError, Calculation};
use crate::columns::{parse_branch, Row, POSE};
use crate::flags::{FlagError, TaskBoxArgs};
use clap::Args;
use kinematics_core::singularity::configurations::{residuals, Configuration};
use kinematics_core::singularity::lines::{analyse, GainedMotion, Tolerances};
use kinematics_core::singularity::serial_cases::cases;
use kinematics_core::{inverse, measures, Mechanism, Robot, RobotKind};
use robot_config::edge::pose_from_edge;
use robot_config::units::significant;
use std::io::Write;

/// `host-sim singularity`: in x_mm..rz_deg,branch; out the input, then the serial measures
/// (RSPR serial1_mm.. = |Cn2_i| and serial1_frac.. = over rb; USR serial1_mm2.. =
/// |Cn1 Cr2 - Cr1 Cn2| and serial1_frac.. = over l1²), parallel_inv_cond, det_sign,
/// nearest (`parallel` or `serial:N`), then the line geometry (rank, circuits,
/// configurations, complex, gained), the serial cases (serial1_case..serial3_case) and
/// `error`.
#[derive(Debug, Args)]
pub struct SingularityArgs {
    #[command(flatten)]
    pub input: PoseInput,
}

/// The singularity measures of each row.
pub struct Singularity<'a> {
    pub robot: &'a Robot<f64>,
}

impl Singularity<'_> {
    /// The serial measure's columns and the factor from SI to their unit.
    fn serial_columns(&self) -> ([&'static str; 3], f64) {
        match self.robot.kind() {
            RobotKind::Rspr => (["serial1_mm", "serial2_mm", "serial3_mm"], 1e3),
            RobotKind::Usr => (["serial1_mm2", "serial2_mm2", "serial3_mm2"], 1e6),
        }
    }
}

impl Calculation for Singularity<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "singularity"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        pose_columns()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        let mut c = self.serial_columns().0.to_vec();
        c.extend(["serial1_frac", "serial2_frac", "serial3_frac"]);
        c.extend(["parallel_inv_cond", "det_sign", "nearest"]);
        c.extend(LINE_COLUMNS);
        c
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let sol = solve_row(self.robot, row)?;
        let m = measures(self.robot, &sol).map_err(RowError::Singularity)?;
        let scale = self.serial_columns().1;
        let mut out: Vec<String> = m.serial.0.iter().map(|&x| significant(x * scale)).collect();
        out.extend(m.serial_relative.0.iter().map(|&x| significant(x)));
        out.push(significant(m.parallel_inv_cond));
        out.push(m.parallel_det_sign.to_string());
        out.push(m.nearest.to_string());
        let tol = Tolerances::default();
        let rp = self.robot.rp();
        let a = analyse(&sol, rp, &tol)
            .map_err(|_| RowError::Singularity(kinematics_core::singularity::SvdDidNotConverge))?;
        out.push(a.rank.to_string());
        out.push(join(a.circuits.iter().map(|c| c.to_string())));
        out.push(join(
            residuals(&sol, rp)
                .iter()
                .filter(|r| r.holds(&tol))
                .map(|r| r.to_string()),
        ));
        out.push(a.complex.map(|v| v.to_string()).unwrap_or_default());
        out.push(join(a.gained.iter().map(|g| gained_words(g, rp))));
        for c in cases(self.robot, &sol, &tol).0 {
            out.push(c.letters().to_string());
        }
        Ok(out)
    }
}

/// The line-geometry columns of `singularity`.
pub const LINE_COLUMNS: [&str; 8] = [
    "rank",
    "circuits",
    "configurations",
    "complex",
    "gained",
    "serial1_case",
    "serial2_case",
    "serial3_case",
];

fn join(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(" ")
}

/// A gained motion in words: the unit scaled twist [v; rp w], the pitch (mm per rad,
/// `inf` for a translation) and the point of its axis nearest o_p (mm, relative to o_p).
pub fn gained_words(g: &GainedMotion<f64>, rp: f64) -> String {
    let t = g.twist;
    let parts = [t[0], t[1], t[2], rp * t[3], rp * t[4], rp * t[5]]
        .map(|x| format!("{x:.6}"))
        .join(",");
    match g.pitch {
        Some(h) => format!(
            "twist=({parts})|pitch_mm={:.6}|axis_mm=({:.3},{:.3},{:.3})",
            h * 1e3,
            g.axis_point.x * 1e3,
            g.axis_point.y * 1e3,
            g.axis_point.z * 1e3
        ),
        None => format!("twist=({parts})|pitch_mm=inf"),
    }
}

/// Runs `singularity`.
pub fn run(args: &SingularityArgs, robot: &Robot<f64>) -> Result<(), BatchError<RowError>> {
    execute(
        &Singularity { robot },
        args.input.csv,
        &args.input.flags(),
        &args.input.defaults(),
    )
}

/// `host-sim singularity-scan`: over a task box, the pose nearest each S-configuration of
/// thesis Table 10.3 (its residual: lengths over rp, sines, or singular values; 0 at the
/// configuration).
#[derive(Debug, Args)]
pub struct SingularityScanArgs {
    #[command(flatten)]
    pub task: TaskBoxArgs,
    /// Grid points along x, y and z of the box, per orientation.
    #[arg(long, value_name = "NX,NY,NZ", default_value = "9,9,5")]
    pub grid: String,
    /// Inverse-kinematics branch 0..=7.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
}

/// The nearest pose of one configuration in a scan.
#[derive(Clone, Debug, PartialEq)]
pub struct Nearest {
    pub configuration: Configuration,
    /// The smallest residual over the poses solved.
    pub residual: f64,
    /// Its indices (`Residual::indices` words, e.g. `S9(1,2)`).
    pub which: String,
    /// The pose, mm and deg.
    pub pose: [f64; 6],
}

/// The scan's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    pub nearest: Vec<Nearest>,
    pub poses: usize,
    pub failed: usize,
}

/// Scans the poses (mm, deg) on a branch.
pub fn scan(robot: &Robot<f64>, branch: kinematics_core::Branch, poses: &[[f64; 6]]) -> Scan {
    let mut nearest: Vec<Nearest> = Configuration::ALL
        .iter()
        .map(|&configuration| Nearest {
            configuration,
            residual: f64::INFINITY,
            which: String::new(),
            pose: [0.0; 6],
        })
        .collect();
    let mut failed = 0;
    for p in poses {
        let Ok(pose) = pose_from_edge(&POSE, *p) else {
            failed += 1;
            continue;
        };
        let Ok(sol) = inverse(robot, &pose, branch) else {
            failed += 1;
            continue;
        };
        for (n, r) in nearest.iter_mut().zip(residuals(&sol, robot.rp()).iter()) {
            if r.residual < n.residual {
                n.residual = r.residual;
                n.which = r.to_string();
                n.pose = *p;
            }
        }
    }
    Scan {
        nearest,
        poses: poses.len(),
        failed,
    }
}

/// Runs `singularity-scan`.
pub fn run_scan(args: &SingularityScanArgs, robot: &Robot<f64>) -> Result<(), FlagError> {
    let task = args.task.task_box(&args.grid)?;
    let branch = parse_branch(&args.branch).map_err(|error| FlagError::Field {
        flag: "--branch",
        error,
    })?;
    let poses: Vec<[f64; 6]> = task
        .poses(robot.hc() * 1e3)
        .iter()
        .map(|p| p.pose)
        .collect();
    let s = scan(robot, branch, &poses);
    let mut out = String::new();
    out.push_str(&format!(
        "# {} ({} poses, {} without a solution on branch {})\n",
        task.describe(robot.hc() * 1e3),
        s.poses,
        s.failed,
        branch.bits()
    ));
    out.push_str("configuration,residual,which,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n");
    for n in &s.nearest {
        let pose: Vec<String> = n.pose.iter().map(|&v| significant(v)).collect();
        out.push_str(&format!(
            "{},{},\"{}\",{}\n",
            n.configuration,
            significant(n.residual),
            n.which,
            pose.join(",")
        ));
    }
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    lock.write_all(out.as_bytes())
        .and_then(|()| lock.flush())
        .map_err(|e| FlagError::Invalid {
            flag: "stdout",
            reason: e.to_string(),
        })
}
