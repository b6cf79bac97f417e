//! The design tools on the command line: `forces --path`, `report`, `ranges`, `workspace`,
//! `synth` and `compare` (the `design` crate). Each turns its flags into the library's
//! settings, runs the tool and prints the text it returns.

use crate::columns::parse_branch;
use crate::commands::forces::{self as row_forces, ForcesArgs};
use crate::error::CliError;
use crate::flags::{self, numbers, FlagError, TaskBoxArgs};
use clap::{Args, ValueEnum};
use design::compare::Pair;
use design::forces_path::{PathSpec, THESIS_WRENCH};
use design::report::Task;
use design::synth::{grid, SynthTask};
use design::workspace::Scan;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kinematics_core::guards::Limits;
use kinematics_core::{Mechanism, Robot, RobotKind};
use robot_config::selection::{SelectedLimits, SelectedRobot};
use robot_config::task_box::TaskBox;
use robot_config::units::m_to_mm;
use std::io::IsTerminal;
use std::path::PathBuf;

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

/// Runs `forces`: the path form when `--path` is given, else the row-wise form.
pub fn forces(
    args: &ForcesCommandArgs,
    robot: &Robot<f64>,
    limits: &Limits<f64>,
) -> Result<(), CliError> {
    let Some(choice) = args.path.path else {
        return row_forces::run(&args.row, robot, limits);
    };
    let PathChoice::Diagonal = choice;
    let p = &args.path;
    if p.samples < 2 {
        return Err(below_two(p.samples).into());
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
        branch: parse_branch(&args.row.input.branch).map_err(FlagError::from)?,
        min_inv_cond: args.row.min_inv_cond,
    };
    print!(
        "{}",
        design::forces_path::run(robot, &spec, p.out.as_deref())?
    );
    Ok(())
}

/// `--samples` below 2.
fn below_two(samples: usize) -> FlagError {
    FlagError::Invalid {
        flag: "--samples",
        reason: format!("{samples} is below 2"),
    }
}

/// `host-sim report`: the task is the thesis's (CONVENTIONS.md, "The reference robot").
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Grid points along x, y and z of the task box.
    #[arg(long, value_name = "NX,NY,NZ", default_value = "5,5,3")]
    pub grid: String,
    /// The task box and its second orientation.
    #[command(flatten)]
    pub task: TaskBoxArgs,
    /// Wrench for the actuator forces, fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm (thesis default).
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        default_value = "7,7,7,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    pub wrench: String,
    /// Smallest inverse condition number at which forces are computed (as `forces`).
    #[arg(long, value_name = "X", default_value_t = 1e-6)]
    pub min_inv_cond: f64,
}

/// Runs `report`: prints the report to stdout.
pub fn report(args: &ReportArgs, selected: &SelectedRobot) -> Result<(), CliError> {
    let task = Task {
        task_box: args.task.task_box(&args.grid)?,
        min_inv_cond: flags::min_inv_cond(args.min_inv_cond)?,
        wrench: numbers("--wrench", &args.wrench)?,
    };
    print!("{}", design::report::render(selected, &task));
    Ok(())
}

/// `host-sim ranges`.
#[derive(Debug, Args)]
pub struct RangesArgs {
    /// Grid points along x, y and z of the task box.
    #[arg(long, value_name = "NX,NY,NZ", default_value = "9,9,5")]
    pub grid: String,
    /// The task box and its second orientation.
    #[command(flatten)]
    pub task: TaskBoxArgs,
    /// Wrench for the actuator forces, fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm.
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        default_value = "7,7,7,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    pub wrench: String,
    /// Inverse-kinematics branch 0..=7.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
    /// Write CSV (quantity,orientation,min,max,span,poses) to stdout instead of the table.
    #[arg(long)]
    pub csv: bool,
    /// Also write ranges.csv into this directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Runs `ranges`: the table (or CSV) of the ranges over the task.
pub fn ranges(args: &RangesArgs, selected: &SelectedRobot) -> Result<(), CliError> {
    let robot = &selected.robot;
    let task = args.task.task_box(&args.grid)?;
    let wrench: [f64; 6] = numbers("--wrench", &args.wrench)?;
    let branch = parse_branch(&args.branch).map_err(FlagError::from)?;
    let r = design::ranges::evaluate(robot, &task, wrench, branch, 1e-6)?;
    let csv = design::ranges::to_csv(&r);
    if let Some(dir) = &args.out {
        let dir = design::files::out_dir(Some(dir), "ranges")?;
        design::files::write_text(&dir.join("ranges.csv"), &csv)?;
    }
    if args.csv {
        print!("{csv}");
    } else {
        let title = format!(
            "ranges over the task: {}, branch {}, task {}, {:+} deg about [1,1,0], wrench {}",
            selected.source,
            args.branch,
            task.describe(m_to_mm(robot.hc())),
            task.tilt_deg,
            args.wrench
        );
        print!("{}", design::ranges::to_table(&r, &title));
    }
    Ok(())
}

/// `host-sim workspace`.
#[derive(Debug, Args)]
pub struct WorkspaceArgs {
    /// Heights of the sections relative to hc: from, to, step, mm.
    #[arg(
        long,
        value_name = "FROM_MM,TO_MM,STEP_MM",
        default_value = "-30,30,10",
        allow_hyphen_values = true
    )]
    pub z_mm: String,
    /// Angular step of the scan directions phi, deg (divides 360 best; 45 deg multiples
    /// then hit the footprint's corners).
    #[arg(long, value_name = "DEG", default_value_t = 5.0)]
    pub phi_step_deg: f64,
    /// Step of the coarse march outwards, mm.
    #[arg(long, value_name = "MM", default_value_t = 1.0)]
    pub step_mm: f64,
    /// Bisection tolerance on rho, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.01)]
    pub tol_mm: f64,
    /// Largest radius scanned, mm.
    #[arg(long, value_name = "MM", default_value_t = 150.0)]
    pub max_radius_mm: f64,
    /// The task box and its second orientation.
    #[command(flatten)]
    pub task: TaskBoxArgs,
    /// Inverse-kinematics branch 0..=7.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
    /// Output directory [default: target/design/workspace].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// The scan and the task box of the flags.
fn scan(args: &WorkspaceArgs, hc_mm: f64) -> Result<(Scan, TaskBox), FlagError> {
    let z_mm: [f64; 3] = numbers("--z-mm", &args.z_mm)?;
    let task = args.task.task_box("1,1,1")?;
    let scan = Scan::checked(
        hc_mm,
        z_mm,
        args.phi_step_deg,
        args.step_mm,
        args.tol_mm,
        args.max_radius_mm,
        &task,
    )
    .map_err(|e| FlagError::Invalid {
        flag: match e.setting {
            "z_mm" => "--z-mm",
            "phi_step_deg" => "--phi-step-deg",
            "step_mm" => "--step-mm",
            "tol_mm" => "--tol-mm",
            "max_radius_mm" => "--max-radius-mm",
            _ => "--box",
        },
        reason: e.reason,
    })?;
    Ok((scan, task))
}

/// Runs `workspace`.
pub fn workspace(
    args: &WorkspaceArgs,
    robot: &Robot<f64>,
    limits: &SelectedLimits,
) -> Result<(), CliError> {
    let (scan, task) = scan(args, m_to_mm(robot.hc()))?;
    let branch = parse_branch(&args.branch).map_err(FlagError::from)?;
    print!(
        "{}",
        design::workspace::run(robot, limits, branch, &scan, &task, args.out.as_deref())?
    );
    Ok(())
}

/// `host-sim synth`.
#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Task file (TOML): the task, the scan ranges and the bounds of each kind; absent keys
    /// keep the thesis's values [default: host-sim/design/tasks/thesis.toml, embedded].
    #[arg(long, value_name = "FILE.toml")]
    pub task: Option<PathBuf>,
    /// Override the task file's eccentricity range e: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub e_mm: Option<String>,
    /// Override the RSPR rotating-link length range rb: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub rb_mm: Option<String>,
    /// Override the platform radius range rp: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub rp_mm: Option<String>,
    /// Override the USR lower-link range l1: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub l1_mm: Option<String>,
    /// Override the USR upper-link range l2: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub l2_mm: Option<String>,
    /// Override the central height range hc: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub hc_mm: Option<String>,
    /// Override the task file's grid points along x, y, z.
    #[arg(long, value_name = "NX,NY,NZ")]
    pub grid: Option<String>,
    /// Worker threads [default: every core].
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Output directory [default: target/design/synth].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Applies the command-line overrides to a task.
fn apply_overrides(args: &SynthArgs, st: &mut SynthTask, kind: RobotKind) -> Result<(), FlagError> {
    if let Some(g) = &args.grid {
        st.task.grid = flags::grid("--grid", g)?;
    }
    let flags: Vec<(&'static str, &Option<String>)> = match kind {
        RobotKind::Rspr => vec![
            ("--e-mm", &args.e_mm),
            ("--rb-mm", &args.rb_mm),
            ("--rp-mm", &args.rp_mm),
            ("--hc-mm", &args.hc_mm),
        ],
        RobotKind::Usr => vec![
            ("--e-mm", &args.e_mm),
            ("--rp-mm", &args.rp_mm),
            ("--l1-mm", &args.l1_mm),
            ("--l2-mm", &args.l2_mm),
            ("--hc-mm", &args.hc_mm),
        ],
    };
    let other = match kind {
        RobotKind::Rspr => [("--l1-mm", &args.l1_mm), ("--l2-mm", &args.l2_mm)],
        RobotKind::Usr => [("--rb-mm", &args.rb_mm), ("--rb-mm", &args.rb_mm)],
    };
    if let Some((flag, _)) = other.iter().find(|(_, v)| v.is_some()) {
        return Err(FlagError::NotForRobot { flag, kind });
    }
    let k = st.kind_mut(kind);
    for ((flag, value), axis) in flags.into_iter().zip(k.axes.iter_mut()) {
        if let Some(text) = value {
            *axis = flags::steps(flag, text)?;
        }
    }
    Ok(())
}

/// Runs `synth` for the kind of the selected robot, with a progress bar on a terminal.
pub fn synth(args: &SynthArgs, kind: RobotKind) -> Result<(), CliError> {
    let mut st = match &args.task {
        Some(p) => SynthTask::load(p)?,
        None => SynthTask::thesis()?,
    };
    apply_overrides(args, &mut st, kind)?;
    let source = args.task.as_ref().map_or(
        "host-sim/design/tasks/thesis.toml (embedded)".to_string(),
        |p| p.display().to_string(),
    );
    let dims = grid(&st.kind(kind).axes);
    if dims.len() > 200_000 {
        return Err(CliError::TooManyRobots(dims.len()));
    }
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::with_draw_target(Some(dims.len() as u64), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    if let Ok(style) =
        ProgressStyle::with_template("synth [{bar:40}] {pos}/{len} robots, {per_sec}, eta {eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    let jobs = args.jobs.unwrap_or(0);
    let out = design::synth::run(&st, kind, dims, &source, jobs, args.out.as_deref(), &|| {
        bar.inc(1)
    });
    bar.finish_and_clear();
    print!("{}", out?);
    Ok(())
}

/// `host-sim compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Number of samples along the path (>= 2), ends included.
    #[arg(long, value_name = "N", default_value_t = 101)]
    pub samples: usize,
    /// Wrench fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm.
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        default_value = "7,7,7,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    pub wrench: String,
    /// Inverse-kinematics branch 0..=7 of both robots.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
    /// Output directory [default: target/design/compare].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Runs `compare` with the selected RSPR's rb, rp and hc (e set to 0).
pub fn compare(args: &CompareArgs, robot: &Robot<f64>) -> Result<(), CliError> {
    let Robot::Rspr(g) = robot else {
        return Err(CliError::CompareNeedsRspr);
    };
    if args.samples < 2 {
        return Err(below_two(args.samples).into());
    }
    let pair = Pair::new(g.rb, g.rp, g.hc)?;
    let spec = PathSpec {
        samples: args.samples,
        wrench: numbers("--wrench", &args.wrench)?,
        branch: parse_branch(&args.branch).map_err(FlagError::from)?,
        ..PathSpec::thesis_diagonal()
    };
    // The same comparison with the selected RSPR's eccentricity (the prototype's 20 mm):
    // on both robots, and on the RSPR only against the RRPS at e = 0.
    let mut others = Vec::new();
    if g.e > 0.0 {
        let eccentric = Pair::with_eccentricity(g.e, g.rb, g.rp, g.hc)?;
        others.push(eccentric);
        others.push(Pair {
            rspr: eccentric.rspr,
            rrps: pair.rrps,
        });
    }
    print!(
        "{}",
        design::compare::run_with(&pair, &others, &spec, args.out.as_deref())?
    );
    Ok(())
}

/// `host-sim dct`.
#[derive(Debug, Args)]
pub struct DctArgs {
    /// Tool point pose x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg (the central configuration is
    /// 0,0,110,0,0,0); without it, the appendix's evaluation.
    #[arg(long, value_name = "X,Y,Z,RX,RY,RZ", allow_hyphen_values = true)]
    pub pose: Option<String>,
    /// Branch 0..=63: the lower mechanism's sliders in bits 0-2, the upper's in 3-5 (a set
    /// bit takes the minus root).
    #[arg(long, value_name = "0..63", default_value_t = 0)]
    pub branch: u8,
    /// Wrench fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm the tool point exerts.
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        default_value = "7,7,7,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    pub wrench: String,
    /// Efficiency of the lead screw, 0 < eta <= 1.
    #[arg(long, value_name = "ETA", default_value_t = 1.0)]
    pub eta: f64,
    /// Grid of the task box per orientation (the evaluation).
    #[arg(long, value_name = "NX,NY,NZ", default_value = "9,9,5")]
    pub grid: String,
}

/// Runs `dct`.
pub fn dct(args: &DctArgs) -> Result<(), CliError> {
    use design::dct_robot::{report, DctRobot};
    use robot_config::edge::{pose_from_edge, POSE};
    let robot = DctRobot::table_4_1();
    if args.branch > 63 {
        return Err(FlagError::Invalid {
            flag: "--branch",
            reason: format!("{} is out of range 0..=63", args.branch),
        }
        .into());
    }
    let Some(pose) = &args.pose else {
        let grid = flags::grid("--grid", &args.grid)?;
        print!("{}", report(&robot, grid, args.branch));
        return Ok(());
    };
    if !(args.eta > 0.0 && args.eta <= 1.0) {
        return Err(FlagError::Invalid {
            flag: "--eta",
            reason: format!("{} is not in (0, 1]", args.eta),
        }
        .into());
    }
    let p = pose_from_edge(&POSE, numbers("--pose", pose)?).map_err(|e| FlagError::Invalid {
        flag: "--pose",
        reason: e.to_string(),
    })?;
    let se = kinematics_core::Wrench::<f64>::from(numbers::<6>("--wrench", &args.wrench)?);
    let sol = robot.inverse(&p, args.branch)?;
    let j = robot.jacobian(&sol)?;
    let tau = robot.efforts(&sol, &se, args.eta)?;
    let q = sol.q(robot.planar.rc);
    let list = |v: &mut dyn Iterator<Item = f64>, digits: usize| {
        v.map(|x| format!("{x:.digits$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "joints q (arc length, mm; lower 1-3, upper 1-3): {}",
        list(&mut q.iter().map(|x| x * 1e3), 6)
    );
    println!(
        "slider angles phi (deg): {}",
        list(
            &mut sol
                .phi_lower
                .iter()
                .chain(&sol.phi_upper)
                .map(|x| design::dct_robot::wrap(*x).to_degrees()),
            6
        )
    );
    for (name, t) in [("lower", &sol.lower), ("upper", &sol.upper)] {
        println!(
            "{name} triangle: centre ({:.6}, {:.6}) mm, psi {:.6} deg",
            t.p.x * 1e3,
            t.p.y * 1e3,
            t.psi.to_degrees()
        );
    }
    println!(
        "link: tool point {:.6} mm from the lower centre",
        sol.s * 1e3
    );
    println!("J = dq/dx (rows q, columns [v; w], SI):");
    for r in j.row_iter() {
        println!("  {}", list(&mut r.iter().copied(), 9));
    }
    println!(
        "slider forces tau (N, eta {}): {}",
        args.eta,
        list(&mut tau.iter().copied(), 6)
    );
    Ok(())
}
