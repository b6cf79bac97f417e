//! The files a run writes: `summary.json`, `trace.csv`, `path.png`, `errors.png`, and the
//! run's 3-D scene for Foxglove, `scene.mcap` ([`write_scene`]).

use crate::metrics::PhaseSummary;
use crate::run::{Outcome, TraceRow};
use plots::plotters::prelude::*;
use plots::{line_charts, span, Band, Layout, Panel, PlotError, Series, PALETTE};
use std::io::Write;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A file of a run that cannot be written.
#[derive(Debug, Error)]
pub enum OutputError {
    #[error("cannot create the output directory {}: {source}", dir.display())]
    CreateDir {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The summary as JSON.
    #[error("summary: {0}")]
    Summary(serde_json::Error),
    /// The trace as CSV.
    #[error("trace: {0}")]
    Trace(csv::Error),
    /// The trace's final flush.
    #[error("trace: {0}")]
    TraceFlush(std::io::Error),
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The scene's MCAP file.
    #[error("{}: {error}", path.display())]
    Scene { path: PathBuf, error: String },
}

const POSE_COLS: [&str; 6] = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"];
const JOINTS: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// The trace's header.
pub fn trace_header() -> Vec<String> {
    let mut h: Vec<String> = vec!["t_s".into(), "mode".into(), "warning".into()];
    for prefix in ["target", "setpoint", "true"] {
        h.extend(POSE_COLS.iter().map(|c| format!("{prefix}_{c}")));
    }
    h.extend(
        [
            "tip_error_mm",
            "orientation_error_deg",
            "target_tip_error_mm",
            "target_orientation_error_deg",
        ]
        .map(String::from),
    );
    for (j, name) in JOINTS.iter().enumerate() {
        h.push(format!("error_{name}_{}", if j < 3 { "mm" } else { "deg" }));
    }
    h.extend(JOINTS.iter().map(|n| format!("duty_{n}")));
    h.extend(JOINTS.iter().map(|n| format!("current_{n}_a")));
    for (j, name) in JOINTS.iter().enumerate() {
        h.push(format!("load_{name}_{}", if j < 3 { "n" } else { "nm" }));
    }
    h
}

fn row_fields(r: &TraceRow) -> Vec<String> {
    let f = |x: f64| format!("{x:.6}");
    let mut v = vec![
        format!("{:.4}", r.t_s),
        r.mode.into(),
        r.warning.to_string(),
    ];
    for p in [&r.target, &r.setpoint, &r.truth] {
        v.extend(p.iter().map(|x| f(*x)));
    }
    v.extend(
        [
            r.tip_error_mm,
            r.orientation_error_deg,
            r.target_tip_error_mm,
            r.target_orientation_error_deg,
        ]
        .map(f),
    );
    v.extend(r.joint_error.iter().map(|x| f(*x)));
    v.extend(r.duty.iter().map(|x| format!("{x:.4}")));
    v.extend(r.current_a.iter().map(|x| format!("{x:.4}")));
    v.extend(r.load.iter().map(|x| format!("{x:.4}")));
    v
}

/// Writes the trace as CSV.
pub fn write_trace<W: Write>(rows: &[TraceRow], out: W) -> Result<(), OutputError> {
    let mut w = csv::Writer::from_writer(out);
    w.write_record(trace_header()).map_err(OutputError::Trace)?;
    for r in rows {
        w.write_record(row_fields(r)).map_err(OutputError::Trace)?;
    }
    w.flush().map_err(OutputError::TraceFlush)
}

/// The files written for one run.
#[derive(Clone, Debug, Default)]
pub struct Written {
    pub files: Vec<PathBuf>,
}

/// Writes `summary.json`, `trace.csv` and (when `plots`) the PNGs into `dir`.
pub fn write_all(outcome: &Outcome, dir: &Path, plots: bool) -> Result<Written, OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::CreateDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut written = Written::default();
    let json = serde_json::to_string_pretty(&outcome.summary).map_err(OutputError::Summary)?;
    let p = dir.join("summary.json");
    std::fs::write(&p, json + "\n").map_err(|source| OutputError::Write {
        path: p.clone(),
        source,
    })?;
    written.files.push(p);
    let p = dir.join("trace.csv");
    let f = std::fs::File::create(&p).map_err(|source| OutputError::Write {
        path: p.clone(),
        source,
    })?;
    write_trace(&outcome.trace, std::io::BufWriter::new(f))?;
    written.files.push(p);
    if plots {
        let p = dir.join("path.png");
        plot_path(&outcome.trace, &outcome.summary.scenario, &p)?;
        written.files.push(p);
        let p = dir.join("errors.png");
        plot_errors(
            &outcome.trace,
            &outcome.summary.scenario,
            &outcome.summary.phases,
            &p,
        )?;
        written.files.push(p);
    }
    Ok(written)
}

/// Picks a pose out of a trace row.
type PoseOf = fn(&TraceRow) -> &[f64; 6];
/// Picks a value out of a trace row.
type ValueOf = fn(&TraceRow) -> f64;

/// The path seen from above (x-y) and from the side (x-z): target, setpoint and truth.
pub fn plot_path(rows: &[TraceRow], scenario: &str, path: &Path) -> Result<(), PlotError> {
    let series: [(&str, RGBColor, PoseOf); 3] = [
        ("master target", RGBColor(170, 170, 170), |r| &r.target),
        ("setpoint", BLUE, |r| &r.setpoint),
        ("true", RED, |r| &r.truth),
    ];
    let panels: Vec<Panel> = [((0, 1), "y [mm]"), ((0, 2), "z [mm]")]
        .into_iter()
        .map(|((ax, ay), ylabel)| Panel {
            levels: Vec::new(),
            bands: Vec::new(),
            caption: Some(
                if ay == 1 {
                    "x-y (top view)"
                } else {
                    "x-z (side view)"
                }
                .into(),
            ),
            x_desc: "x [mm]".into(),
            y_desc: ylabel.into(),
            x_range: span(rows.iter().flat_map(|r| [r.target[ax], r.truth[ax]])),
            y_range: span(rows.iter().flat_map(|r| [r.target[ay], r.truth[ay]])),
            series: series
                .iter()
                .map(|(name, color, get)| {
                    let points = rows.iter().map(|r| (get(r)[ax], get(r)[ay])).collect();
                    Series::new(*name, points, *color, if *name == "true" { 1 } else { 2 })
                })
                .collect(),
        })
        .collect();
    line_charts(
        path,
        (1400, 700),
        &format!("{scenario}: platform centre path (target, setpoint, true)"),
        &panels,
        Layout::SideBySide,
    )
}

/// The errors over time: tip tracking error, tip error against the target, orientation;
/// the judged phases (the passes) shaded, and within them the intervals where the master's
/// stream asks more than the tip acceleration limit (the report names both).
pub fn plot_errors(
    rows: &[TraceRow],
    scenario: &str,
    phases: &[PhaseSummary],
    path: &Path,
) -> Result<(), PlotError> {
    let mut bands: Vec<Band> = Vec::new();
    for (k, p) in phases.iter().enumerate() {
        bands.push(Band {
            label: format!("phase: {}", p.name),
            x: (p.start_s, p.end_s),
            color: PALETTE[[0, 2, 4, 9][k % 4]],
        });
    }
    for p in phases {
        for [a, b] in p.beyond_limits.iter().flat_map(|l| l.intervals_s.iter()) {
            bands.push(Band {
                label: "stream beyond the tip acceleration limit".into(),
                x: (*a, *b),
                color: PALETTE[3],
            });
        }
    }
    let t_end = rows.last().map(|r| r.t_s).unwrap_or(1.0).max(1e-3);
    let specs: [(&str, &str, ValueOf, RGBColor); 3] = [
        (
            "tip tracking error (true vs setpoint of the same tick)",
            "mm",
            |r| r.tip_error_mm,
            RED,
        ),
        (
            "tip error vs the master's target (includes rate limiting)",
            "mm",
            |r| r.target_tip_error_mm,
            BLUE,
        ),
        (
            "orientation tracking error",
            "deg",
            |r| r.orientation_error_deg,
            RGBColor(0, 130, 0),
        ),
    ];
    let panels: Vec<Panel> = specs
        .into_iter()
        .map(|(title, unit, get, color)| Panel {
            levels: Vec::new(),
            bands: bands.clone(),
            caption: Some(title.into()),
            x_desc: "t [s]".into(),
            y_desc: unit.into(),
            x_range: (0.0, t_end),
            y_range: (
                0.0,
                rows.iter().map(get).fold(0.0f64, f64::max).max(1e-6) * 1.1,
            ),
            series: vec![Series {
                label: None,
                points: rows.iter().map(|r| (r.t_s, get(r))).collect(),
                style: color.stroke_width(1),
            }],
        })
        .collect();
    line_charts(
        path,
        (1400, 1000),
        &format!("{scenario}: errors of the true pose over time"),
        &panels,
        Layout::Stacked,
    )
}

/// A pose from its edge values (mm, deg).
fn pose_of_edge(v: &[f64; 6]) -> Option<kinematics_core::Pose<f64>> {
    kinematics_core::Pose::from_position_rotation_vector(
        nalgebra::Vector3::new(v[0], v[1], v[2]) * 1e-3,
        nalgebra::Vector3::new(v[3], v[4], v[5]).map(f64::to_radians),
    )
    .ok()
}

/// Writes the run's scene for Foxglove to `path` (MCAP, zstd chunks, through the Foxglove
/// SDK): the channels of `host-sim view` (`scene::TOPICS`) at the trace's instants, in the
/// run's virtual time: the robot description, its transforms and joint states at the
/// controller's measured pose, the measured, setpoint and target (`/servo_cp`: the
/// master's stream) poses, the measured and setpoint joints, the kinematic guard margins
/// at the setpoint (as the board reports them) and the state (enabled throughout; the
/// supervisor's stop, if any).
pub fn write_scene(
    outcome: &Outcome,
    robot: &kinematics_core::Robot<f64>,
    limits: &kinematics_core::guards::Limits<f64>,
    path: &Path,
) -> Result<PathBuf, OutputError> {
    let err = |e: String| OutputError::Scene {
        path: path.to_path_buf(),
        error: e,
    };
    let branch = kinematics_core::Branch::OUTER;
    let description = robot_description::Description::new(robot, limits, branch)
        .map_err(|e| err(e.to_string()))?;
    let urdf = robot_description::to_urdf(description.tree(), "the simulated robot");
    let guards = kinematics_core::guards::Guards::new(*robot, branch, *limits)
        .map_err(|e| err(format!("guards: {e:?}")))?;
    let ctx = foxglove::Context::new();
    // A run writes its scene afresh, as every other file of the run (the SDK's own
    // `create_new_buffered_file` refuses an existing file: a second run would fail).
    let file = std::fs::File::create(path).map_err(|e| err(e.to_string()))?;
    let writer = ctx
        .mcap_writer()
        .create(std::io::BufWriter::new(file))
        .map_err(|e| err(e.to_string()))?;
    let mut scene = scene::Scene::new(&ctx, description, urdf);
    scene.log_description(0);
    for r in &outcome.trace {
        let time_ns = (r.t_s * 1e9).round().max(0.0) as u64;
        let setpoint = pose_of_edge(&r.setpoint);
        scene.log(&scene::Snapshot {
            time_ns,
            measured: r.measured.as_ref().and_then(pose_of_edge),
            setpoint,
            target: pose_of_edge(&r.target),
            measured_joints: Some(r.measured_q),
            margins: setpoint.and_then(|p| scene::margins_at(&guards, &p)),
            state: Some(scene::RobotState {
                state: "Enabled".into(),
                stop: if r.mode == "stopped" {
                    "the supervisor's stop".into()
                } else {
                    String::new()
                },
                fault: String::new(),
                fault_latched: false,
            }),
        });
    }
    writer.close().map_err(|e| err(e.to_string()))?;
    Ok(path.to_path_buf())
}
