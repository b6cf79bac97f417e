//! `host-sim calibrate` on the command line: the flags of the `calibration` crate's
//! identification, pose plan and simulation, and the files they write.

use crate::error::CliError;
use crate::flags::{numbers, FlagError};
use calibration::identify::{identify, Loss, Options};
use calibration::measurements::JointRanges;
use calibration::model::Noise;
use calibration::plan::{default_marker, plan, shortfall, PlanOptions};
use calibration::rigid::Rigid;
use calibration::simulate::{run as simulate, Scenario};
use calibration::{measurements, report};
use clap::{Args, Subcommand};
use kinematics_core::{PerChainGeometry, Robot};
use robot_config::selection::{SelectedLimits, SelectedRobot};
use robot_config::units::{deg_to_rad, mm_to_m};
use std::path::{Path, PathBuf};

/// `host-sim calibrate` arguments: identify from measurements, or one of the subcommands.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct CalibrateArgs {
    #[command(subcommand)]
    pub action: Option<CalibrateAction>,
    #[command(flatten)]
    pub identify: IdentifyArgs,
}

/// The subcommands of `calibrate`.
#[derive(Debug, Subcommand)]
pub enum CalibrateAction {
    /// The poses to measure: N poses of the task box that maximise the identifiability
    /// (observability index O1), with the nominal joints there; writes plan.csv.
    Plan(PlanArgs),
    /// The proof in simulation: a true robot perturbed within the tolerances, a noisy
    /// tracker; prints the pose error over unseen poses of the task box before and after
    /// calibration and the limit the noise allows; writes report.txt, validation.png,
    /// residuals.png and measurements.csv.
    Simulate(SimulateArgs),
    /// Sends a calibrated geometry file to the board, which checks it (CRC, version,
    /// plausibility, IK of the central pose) and stores it in flash with the drives off;
    /// prints the version the board reports before and after, or why it refused.
    Upload(UploadArgs),
}

/// `host-sim calibrate upload` arguments.
#[derive(Debug, Args)]
pub struct UploadArgs {
    /// The board: a Unix socket (QEMU) or a serial device.
    #[arg(long, value_name = "PATH")]
    pub connect: PathBuf,
    /// The calibrated geometry (robot = "rspr-per-chain", with its [calibration] version).
    #[arg(long, value_name = "FILE.toml")]
    pub file: PathBuf,
    /// Serial devices: the baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// How long to wait for the board (connection, hello, the flash write), s.
    #[arg(long, default_value_t = 15.0)]
    pub timeout_s: f64,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

/// The tracker's noise, shared by the identification, the plan and the simulation.
#[derive(Debug, Args)]
pub struct NoiseArgs {
    /// The tracker's position noise (one standard deviation per axis), mm.
    #[arg(long, default_value_t = 0.1)]
    pub noise_mm: f64,
    /// The tracker's orientation noise (one standard deviation per axis), deg.
    #[arg(long, default_value_t = 0.05)]
    pub noise_deg: f64,
}

/// The loss of the identification.
#[derive(Debug, Args)]
pub struct LossArgs {
    /// Robust loss against outliers: huber:C or cauchy:C, C in noise standard deviations
    /// (e.g. cauchy:3) [default: plain least squares].
    #[arg(long, value_name = "LOSS")]
    pub robust: Option<String>,
}

impl NoiseArgs {
    fn noise(&self) -> Result<Noise, FlagError> {
        for (flag, v) in [
            ("--noise-mm", self.noise_mm),
            ("--noise-deg", self.noise_deg),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(FlagError::Invalid {
                    flag,
                    reason: format!("must be positive, got {v}"),
                });
            }
        }
        Ok(Noise {
            position_m: mm_to_m(self.noise_mm),
            rotation_rad: deg_to_rad(self.noise_deg),
        })
    }
}

impl LossArgs {
    fn loss(&self) -> Result<Loss, FlagError> {
        let Some(text) = &self.robust else {
            return Ok(Loss::Squared);
        };
        let bad = || FlagError::Invalid {
            flag: "--robust",
            reason: format!("expected huber:C or cauchy:C with C > 0, got {text:?}"),
        };
        let (kind, c) = text.split_once(':').ok_or_else(bad)?;
        let c: f64 = c.trim().parse().map_err(|_| bad())?;
        if !(c.is_finite() && c > 0.0) {
            return Err(bad());
        }
        match kind.trim() {
            "huber" => Ok(Loss::Huber(c)),
            "cauchy" => Ok(Loss::Cauchy(c)),
            _ => Err(bad()),
        }
    }
}

/// `host-sim calibrate --measurements FILE` arguments.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// The measurements (CSV: l1_mm..theta3_deg, x_mm, y_mm, z_mm and optionally rx_deg,
    /// ry_deg, rz_deg, label; see host-sim/calibration/src/measurements.rs). The starting
    /// robot is the selected one (--geometry: the nominal RSPR, or an earlier calibration).
    #[arg(long, value_name = "FILE.csv")]
    pub measurements: Option<PathBuf>,
    /// The marker's pose on the platform from its drawing, the first guess:
    /// x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg in {p} [default: 20,0,30,0,0,0].
    #[arg(long, value_name = "POSE")]
    pub marker: Option<String>,
    /// The calibration's version written into the geometry file (the board reports it).
    #[arg(long, default_value_t = 1)]
    pub version: u32,
    /// Drop the rows whose joints lie outside the robot's ranges (the limits' stroke and
    /// link angle, widened by 2 mm and 2 deg) and list them, instead of refusing the file.
    #[arg(long)]
    pub drop_out_of_range: bool,
    /// Write the calibration and exit 0 even when the poses determine fewer parameter
    /// combinations than the planner's 60 poses (the report warns either way).
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub noise: NoiseArgs,
    #[command(flatten)]
    pub loss: LossArgs,
    /// Output directory: calibrated.toml, report.txt, residuals.csv, residuals.png
    /// [default: target/calibration/].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// `host-sim calibrate plan` arguments.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Poses to choose.
    #[arg(long, default_value_t = 60)]
    pub poses: usize,
    /// The tracker measures positions only (a laser tracker's reflector).
    #[arg(long)]
    pub position_only: bool,
    /// The marker's expected pose on the platform (as for calibrate --marker).
    #[arg(long, value_name = "POSE")]
    pub marker: Option<String>,
    #[command(flatten)]
    pub noise: NoiseArgs,
    /// Output file [default: target/calibration/plan.csv].
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
}

/// `host-sim calibrate simulate` arguments.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The seed of the true robot, the tracker's noise and the validation poses.
    #[arg(long, default_value_t = 19)]
    pub seed: u64,
    /// Identification poses (planned).
    #[arg(long, default_value_t = 60)]
    pub poses: usize,
    /// Validation poses (random in the task box, tilts up to 20 deg).
    #[arg(long, default_value_t = 300)]
    pub validation: usize,
    /// Tolerances of the true robot: positions and lengths, mm.
    #[arg(long, default_value_t = 0.5)]
    pub tolerance_mm: f64,
    /// Tolerances of the true robot: axes, deg.
    #[arg(long, default_value_t = 0.5)]
    pub tolerance_deg: f64,
    /// Tolerances of the true robot: encoder zeros, counts.
    #[arg(long, default_value_t = 20.0)]
    pub tolerance_counts: f64,
    /// The tracker measures positions only.
    #[arg(long)]
    pub position_only: bool,
    /// Rows given a gross error (moved by --outlier-mm along (5, -3, 4), turned by 2 deg),
    /// to try --robust.
    #[arg(long, default_value_t = 0)]
    pub outliers: usize,
    /// How far an outlier row's position is moved, mm.
    #[arg(long, default_value_t = 7.07)]
    pub outlier_mm: f64,
    #[command(flatten)]
    pub noise: NoiseArgs,
    #[command(flatten)]
    pub loss: LossArgs,
    /// Output directory [default: target/calibration/simulate/].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

fn marker(text: &Option<String>) -> Result<Rigid, FlagError> {
    match text {
        None => Ok(default_marker()),
        Some(t) => Ok(Rigid::from_mm_deg(numbers("--marker", t)?)),
    }
}

/// The per-chain robot to start from: the selected RSPR.
fn start(selected: &SelectedRobot) -> Result<PerChainGeometry<f64>, CliError> {
    match selected.robot {
        Robot::Rspr(g) => Ok(PerChainGeometry::from(g)),
        Robot::RsprPerChain(g) => Ok(g),
        Robot::Usr(_) => Err(CliError::CalibrateNeedsRspr),
    }
}

fn out_dir(out: &Option<PathBuf>, sub: &str) -> Result<PathBuf, CliError> {
    let dir = robot_config::output::out_dir(out.as_deref(), &["calibration", sub]);
    std::fs::create_dir_all(&dir).map_err(|e| CliError::Output {
        path: dir.clone(),
        error: e.to_string(),
    })?;
    Ok(dir)
}

fn write(path: &Path, text: &str) -> Result<(), CliError> {
    std::fs::write(path, text).map_err(|e| CliError::Output {
        path: path.to_path_buf(),
        error: e.to_string(),
    })
}

/// Runs `calibrate`.
pub fn run(
    args: &CalibrateArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CliError> {
    match &args.action {
        Some(CalibrateAction::Plan(a)) => run_plan(a, selected, limits),
        Some(CalibrateAction::Simulate(a)) => run_simulate(a),
        Some(CalibrateAction::Upload(a)) => run_upload(a),
        None => run_identify(&args.identify, selected, limits),
    }
}

/// The planner's pose count the measurements are compared with.
const PLANNED_POSES: usize = 60;

fn run_identify(
    args: &IdentifyArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CliError> {
    let Some(path) = &args.measurements else {
        return Err(FlagError::Invalid {
            flag: "--measurements",
            reason: "the measurement file is needed (or use calibrate plan / calibrate simulate)"
                .into(),
        }
        .into());
    };
    let file = std::fs::File::open(path).map_err(|e| CliError::Input {
        path: path.clone(),
        error: e.to_string(),
    })?;
    let mut rows = measurements::read(file).map_err(calibration::CalibrationError::from)?;
    let bad = measurements::out_of_range(&rows, &JointRanges::from_limits(&limits.limits));
    if !bad.is_empty() {
        let lines: Vec<String> = bad.iter().map(ToString::to_string).collect();
        if !args.drop_out_of_range {
            return Err(CliError::OutOfRange {
                count: bad.len(),
                first: lines.join("; "),
            });
        }
        let mut dropped: Vec<usize> = bad.iter().map(|b| b.row).collect();
        dropped.dedup();
        eprintln!("dropped {} rows out of range:", dropped.len());
        for l in &lines {
            eprintln!("  {l}");
        }
        rows = rows
            .into_iter()
            .enumerate()
            .filter(|(k, _)| !dropped.contains(&(k + 1)))
            .map(|(_, m)| m)
            .collect();
    }
    let reference = start(selected)?;
    let opts = Options {
        noise: args.noise.noise()?,
        loss: args.loss.loss()?,
        ..Options::default()
    };
    let id = identify(&reference, &rows, marker(&args.marker)?, &opts)?;
    let dir = out_dir(&args.out, "")?;
    let planned = plan(
        &reference,
        &PlanOptions {
            poses: PLANNED_POSES,
            position_only: rows.iter().all(|m| m.rotation.is_none()),
            noise: opts.noise,
            limits: limits.limits,
            marker_in_platform: marker(&args.marker)?,
            ..PlanOptions::default()
        },
    )?;
    let short = shortfall(&id.identifiability, rows.len(), &planned);
    let mut text = report::identification_text(&id);
    if let Some(s) = &short {
        text.push_str(&format!("\nWARNING: {s}.\n"));
    }
    print!("{text}");
    let source = format!("host-sim calibrate --measurements {}", path.display());
    write(
        &dir.join("calibrated.toml"),
        &report::geometry_text(&id, args.version, &source),
    )?;
    write(&dir.join("report.txt"), &text)?;
    write(&dir.join("residuals.csv"), &report::residuals_csv(&id))?;
    report::residual_plot(&dir.join("residuals.png"), &id)?;
    println!(
        "wrote calibrated.toml (version {}), report.txt, residuals.csv, residuals.png to {}",
        args.version,
        dir.display()
    );
    match short {
        Some(s) if !args.force => Err(CliError::Underdetermined(s.to_string())),
        _ => Ok(()),
    }
}

fn run_plan(
    args: &PlanArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CliError> {
    let robot = start(selected)?;
    let opts = PlanOptions {
        poses: args.poses,
        position_only: args.position_only,
        noise: args.noise.noise()?,
        limits: limits.limits,
        marker_in_platform: marker(&args.marker)?,
        ..PlanOptions::default()
    };
    let p = plan(&robot, &opts)?;
    let path = match &args.out {
        Some(p) => p.clone(),
        None => out_dir(&None, "")?.join("plan.csv"),
    };
    write(&path, &report::plan_csv(&p))?;
    print!("{}", report::plan_text(&p));
    println!("wrote {}", path.display());
    Ok(())
}

fn run_simulate(args: &SimulateArgs) -> Result<(), CliError> {
    if !(args.outlier_mm.is_finite() && args.outlier_mm >= 0.0) {
        return Err(FlagError::Invalid {
            flag: "--outlier-mm",
            reason: format!("expected a distance >= 0 mm, got {}", args.outlier_mm),
        }
        .into());
    }
    let mut s = Scenario {
        seed: args.seed,
        poses: args.poses,
        validation: args.validation,
        position_only: args.position_only,
        outliers: args.outliers,
        outlier_m: mm_to_m(args.outlier_mm),
        noise: args.noise.noise()?,
        loss: args.loss.loss()?,
        ..Scenario::default()
    };
    s.tolerances.length_m = mm_to_m(args.tolerance_mm);
    s.tolerances.axis_rad = deg_to_rad(args.tolerance_deg);
    s.tolerances.zero_counts = args.tolerance_counts;
    let o = simulate(&s)?;
    let dir = out_dir(&args.out, "simulate")?;
    let mut text = format!(
        "Simulated calibration, seed {}: true robot within ±{} mm, ±{} deg, ±{} counts; \
         tracker noise {} mm, {} deg{}; {} planned poses\n",
        args.seed,
        args.tolerance_mm,
        args.tolerance_deg,
        args.tolerance_counts,
        args.noise.noise_mm,
        args.noise.noise_deg,
        if args.position_only {
            " (positions only)"
        } else {
            ""
        },
        args.poses
    );
    text.push_str(&report::simulation_text(&o, args.position_only));
    print!("{text}");
    text.push('\n');
    text.push_str(&report::identification_text(&o.identification));
    write(&dir.join("report.txt"), &text)?;
    let mut csv = Vec::new();
    measurements::write(&mut csv, &o.rows).map_err(calibration::CalibrationError::from)?;
    write(
        &dir.join("measurements.csv"),
        &String::from_utf8_lossy(&csv),
    )?;
    report::simulation_plot(&dir.join("validation.png"), &o, args.position_only)?;
    report::residual_plot(&dir.join("residuals.png"), &o.identification)?;
    println!(
        "wrote report.txt, measurements.csv, validation.png, residuals.png to {}",
        dir.display()
    );
    Ok(())
}

fn run_upload(args: &UploadArgs) -> Result<(), CliError> {
    use teleop::session::{GeometryAnswer, Session};
    let (geometry, info) = robot_config::geometry_file::load_per_chain(&args.file)?;
    let record = control::geometry_store::record_of(&geometry, info.version);
    let timeout = std::time::Duration::from_secs_f64(args.timeout_s.max(0.0));
    let link = teleop::link::open_with_key(&args.connect, args.baud, timeout, args.key.key()?)?;
    let mut s = Session::new(link);
    s.hello(args.timeout_s)?;
    println!(
        "board reports calibrated geometry version {}",
        s.geometry_version.unwrap_or(0)
    );
    match s.store_geometry(record, args.timeout_s)? {
        GeometryAnswer::Stored(v) => {
            println!("stored calibrated geometry version {v}");
            Ok(())
        }
        GeometryAnswer::Refused(reason) => Err(CliError::Upload(format!(
            "refused: {}",
            board_words::geometry_refusal(reason)
        ))),
        GeometryAnswer::Nack(reason) => Err(CliError::Upload(format!(
            "refused: {}",
            board_words::reason(reason)
        ))),
        GeometryAnswer::Unexpected(what) => {
            Err(CliError::Upload(format!("unexpected reply {what}")))
        }
    }
}
