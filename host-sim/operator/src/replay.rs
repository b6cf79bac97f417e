//! `host-sim replay FILE`: a recorded teleoperation session's summary and its plots.
//!
//! Plots (PNG, `plots` crate), in millimetres, degrees and milliseconds over the session's
//! time:
//! - `input.png`: the master's input (a rate master's twist, or a position master's pose)
//!   and its buttons (clutch, operator present);
//! - `position.png` and `orientation.png`: per axis, what the operator commanded (the
//!   scaled input), the targets sent (`servo_cp`), the board's setpoint (`setpoint_cp`)
//!   and the measured pose (`measured_cp`);
//! - `lag.png`: each status's lag behind the commanded path (setpoint and measured pose;
//!   see `masters::latency`);
//! - `margins.png`: the guard margins the board reported (nearest, serial, parallel,
//!   stroke, tilt, collision, workspace).

use crate::error::OperatorError;
use masters::latency::{lag_at, LagConfig, Stamped};
use masters::recording::{Recording, RecordingSummary};
use masters::MasterInput;
use plots::plotters::style::{RGBColor, BLACK, BLUE, GREEN, RED};
use plots::{
    break_gaps, intervals, line_charts, span, Band, Layout, Level, Panel, Series, PALETTE,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What `replay` found and wrote.
#[derive(Clone, Debug)]
pub struct Replay {
    /// The summary (also printed).
    pub summary: RecordingSummary,
    /// The plots written.
    pub plots: Vec<PathBuf>,
}

const ORANGE: RGBColor = RGBColor(230, 120, 0);
const GREY: RGBColor = RGBColor(120, 120, 120);

/// Reads `file`, writes the plots to `out`.
pub fn replay(file: &Path, out: &Path) -> Result<Replay, OperatorError> {
    let rec = Recording::open(file)?;
    std::fs::create_dir_all(out).map_err(|source| OperatorError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let t0 = first_time(&rec);
    let title = |what: &str| format!("{what}: {}", rec.session.master);
    let [x, y, z, rx, ry, rz] = pose_panels(&rec, t0);
    let plots = vec![
        draw(
            out,
            "input.png",
            &title("master input"),
            &input_panels(&rec, t0),
        )?,
        draw(out, "position.png", &title("position"), &[x, y, z])?,
        draw(out, "orientation.png", &title("orientation"), &[rx, ry, rz])?,
        draw(
            out,
            "lag.png",
            &title("lag behind the commanded path"),
            &[lag_panel(&rec, t0)],
        )?,
        draw_sized(
            out,
            "margins.png",
            &title("guard margins (100 % far, 0 % at the stop level)"),
            &[margins_panel(&rec, t0)],
            // Room for the legend's thirteen rows above the data.
            700,
        )?,
    ];
    Ok(Replay {
        summary: rec.summary(),
        plots,
    })
}

/// The master's input (a rate master's twist, a position master's pose) and its buttons,
/// over the time since `t0`.
fn input_panels(rec: &Recording, t0: f64) -> Vec<Panel> {
    let mut panels = Vec::new();
    let twist: Vec<(f64, [f64; 6])> = rec
        .inputs()
        .filter_map(|r| match r.input {
            MasterInput::Twist(t) => {
                let a = t.to_array();
                Some((
                    r.t_s - t0,
                    [
                        a[0] * 1e3,
                        a[1] * 1e3,
                        a[2] * 1e3,
                        a[3].to_degrees(),
                        a[4].to_degrees(),
                        a[5].to_degrees(),
                    ],
                ))
            }
            MasterInput::Pose(_) => None,
        })
        .collect();
    let pose_in: Vec<(f64, [f64; 6])> = rec
        .inputs()
        .filter_map(|r| match r.input {
            MasterInput::Pose(p) => Some((r.t_s - t0, p.to_mm_deg())),
            MasterInput::Twist(_) => None,
        })
        .collect();
    if !twist.is_empty() {
        panels.push(axes_panel("velocity, mm/s", &twist, 0));
        panels.push(axes_panel("angular velocity, deg/s", &twist, 3));
    }
    if !pose_in.is_empty() {
        panels.push(axes_panel("master position, mm", &pose_in, 0));
        panels.push(axes_panel("master rotation vector, deg", &pose_in, 3));
    }
    let buttons = |f: &dyn Fn(&masters::recording::InputRecord) -> bool, k: f64| {
        rec.inputs()
            .map(|r| (r.t_s - t0, if f(r) { k } else { 0.0 }))
            .collect::<Vec<_>>()
    };
    let clutch = buttons(&|r| r.clutch, 1.0);
    let present = buttons(&|r| r.operator_present, 0.9);
    panels.push(Panel {
        levels: Vec::new(),
        bands: Vec::new(),
        caption: Some("buttons (1 = pressed)".into()),
        x_desc: "t, s".into(),
        y_desc: "pressed".into(),
        x_range: span(clutch.iter().map(|p| p.0)),
        y_range: (-0.1, 1.1),
        series: vec![
            Series::new("clutch", clutch, RED, 2),
            Series::new("operator present", present, BLUE, 2),
        ],
    });
    panels
}

/// Per pose axis (x, y, z, rx, ry, rz): the commanded pose, the targets sent, the board's
/// setpoint and the measured pose, over the time since `t0`.
fn pose_panels(rec: &Recording, t0: f64) -> [Panel; 6] {
    let commanded: Vec<(f64, [f64; 6])> = rec
        .targets()
        .filter_map(|r| Some((r.input_t_s? - t0, r.commanded?.to_mm_deg())))
        .collect();
    let target: Vec<(f64, [f64; 6])> = rec
        .targets()
        .map(|r| (r.t_s - t0, r.pose.to_mm_deg()))
        .collect();
    let setpoint: Vec<(f64, [f64; 6])> = rec
        .statuses()
        .filter_map(|r| Some((r.t_s - t0, r.setpoint?.to_mm_deg())))
        .collect();
    let measured: Vec<(f64, [f64; 6])> = rec
        .statuses()
        .filter_map(|r| Some((r.t_s - t0, r.measured?.to_mm_deg())))
        .collect();
    let names = ["x, mm", "y, mm", "z, mm", "rx, deg", "ry, deg", "rz, deg"];
    std::array::from_fn(|k| {
        let col = |v: &[(f64, [f64; 6])]| -> Vec<(f64, f64)> {
            v.iter().map(|(t, a)| (*t, a[k])).collect()
        };
        let series = vec![
            Series::new("commanded", col(&commanded), GREY, 1),
            Series::new("target (servo_cp)", col(&target), BLUE, 1),
            Series::new("setpoint (setpoint_cp)", col(&setpoint), ORANGE, 2),
            Series::new("measured (measured_cp)", col(&measured), RED, 1),
        ];
        panel(names[k], series)
    })
}

/// Each status's lag behind the commanded path (setpoint and measured pose), ms, over the
/// time since `t0`.
fn lag_panel(rec: &Recording, t0: f64) -> Panel {
    let reference: Vec<Stamped> = rec
        .targets()
        .filter_map(|r| Some((r.input_t_s?, r.commanded?.position_m)))
        .collect();
    let cfg = LagConfig::default();
    let lag_series =
        |pick: &dyn Fn(&masters::recording::StatusRecord) -> Option<nalgebra::Vector3<f64>>| {
            rec.statuses()
                .filter_map(|r| {
                    let p = pick(r)?;
                    Some((r.t_s - t0, lag_at(&reference, r.t_s, &p, &cfg)? * 1e3))
                })
                .collect::<Vec<_>>()
        };
    let lag_sp = break_gaps(lag_series(&|r| r.setpoint.map(|p| p.position_m)), GAP_S);
    let lag_m = break_gaps(lag_series(&|r| r.measured.map(|p| p.position_m)), GAP_S);
    // The setpoint wide underneath, the measured pose thin on top: both show where they
    // coincide.
    let mut p = panel(
        "lag, ms",
        vec![
            Series::new("setpoint", lag_sp, ORANGE, 4),
            Series::new("measured", lag_m, BLUE, 1),
        ],
    );
    p.bands = activity_bands(rec, t0);
    p
}

/// Statuses further apart than this are a gap (the board reports every 20 ms): no line
/// is drawn across it, s.
const GAP_S: f64 = 0.5;

/// The clutch periods (clutch pressed: the master moves without moving the robot) and
/// the holds (targets limited by the mapping's workspace edge), over the time since `t0`.
fn activity_bands(rec: &Recording, t0: f64) -> Vec<Band> {
    let clutch: Vec<(f64, bool)> = rec.inputs().map(|r| (r.t_s - t0, r.clutch)).collect();
    let limited: Vec<(f64, bool)> = rec.targets().map(|r| (r.t_s - t0, r.limited)).collect();
    let mut out: Vec<Band> = intervals(&clutch)
        .into_iter()
        .map(|x| Band {
            label: "clutch pressed: the robot holds".into(),
            x,
            color: GREY,
        })
        .collect();
    out.extend(intervals(&limited).into_iter().map(|x| Band {
        label: "held at the workspace edge".into(),
        x,
        color: RED,
    }));
    out
}

/// The guard margins the board reported, the nearest drawn thicker, over the time since
/// `t0`.
fn margins_panel(rec: &Recording, t0: f64) -> Panel {
    let mut by_name: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for r in rec.statuses() {
        for (k, v) in &r.margins {
            by_name.entry(k.clone()).or_default().push((r.t_s - t0, *v));
        }
    }
    let series: Vec<Series> = by_name
        .into_iter()
        .enumerate()
        .map(|(i, (k, v))| {
            let c = if k == "nearest" {
                BLACK
            } else {
                PALETTE[i % PALETTE.len()]
            };
            let v = break_gaps(v.into_iter().map(|(t, m)| (t, m * 100.0)).collect(), GAP_S);
            Series::new(k.clone(), v, c, if k == "nearest" { 3 } else { 1 })
        })
        .collect();
    let mut p = panel("margin, % of the guard's range left", series);
    p.levels = margin_levels();
    p.y_range = (-5.0, 105.0);
    p.bands = activity_bands(rec, t0);
    p
}

/// The levels of the margins: every guard stops at 0 %; the stroke and link ranges and
/// the singularity measures warn where `board_words::margins` says.
fn margin_levels() -> Vec<Level> {
    let mut levels = vec![Level {
        label: "stop level: 0 % (every guard)".into(),
        y: 0.0,
        color: RED,
    }];
    let mut warns: Vec<(f64, Vec<&str>)> = Vec::new();
    for m in board_words::margins(&master_link::GuardMargins::default()) {
        if let Some(w) = m.warn {
            let w = (f64::from(w) * 1000.0).round() / 10.0;
            match warns.iter_mut().find(|(v, _)| *v == w) {
                Some((_, names)) => names.push(m.guard),
                None => warns.push((w, vec![m.guard])),
            }
        }
    }
    for (k, (w, names)) in warns.into_iter().enumerate() {
        levels.push(Level {
            label: format!("warn level: {w:.1} % ({})", names.join(", ")),
            y: w,
            color: [ORANGE, PALETTE[4], PALETTE[5]][k % 3],
        });
    }
    levels
}

fn first_time(rec: &Recording) -> f64 {
    rec.inputs()
        .map(|r| r.t_s)
        .chain(rec.targets().map(|r| r.t_s))
        .chain(rec.statuses().map(|r| r.t_s))
        .fold(f64::INFINITY, f64::min)
        .min(f64::MAX)
}

fn axes_panel(y_desc: &str, v: &[(f64, [f64; 6])], first: usize) -> Panel {
    let colours = [RED, BLUE, GREEN];
    let names = if first == 0 {
        ["x", "y", "z"]
    } else {
        ["rx", "ry", "rz"]
    };
    let series = (0..3)
        .map(|k| {
            let pts = v.iter().map(|(t, a)| (*t, a[first + k])).collect();
            Series::new(names[k], pts, colours[k], 1)
        })
        .collect();
    panel(y_desc, series)
}

fn panel(y_desc: &str, series: Vec<Series>) -> Panel {
    let pts = || series.iter().flat_map(|s| s.points.iter());
    Panel {
        levels: Vec::new(),
        bands: Vec::new(),
        caption: None,
        x_desc: "t, s".into(),
        y_desc: y_desc.into(),
        x_range: span(pts().map(|p| p.0)),
        y_range: span(pts().map(|p| p.1)),
        series,
    }
}

fn draw(out: &Path, name: &str, title: &str, panels: &[Panel]) -> Result<PathBuf, OperatorError> {
    draw_sized(out, name, title, panels, 260)
}

/// Draws `panels` stacked, each `panel_px` high.
fn draw_sized(
    out: &Path,
    name: &str,
    title: &str,
    panels: &[Panel],
    panel_px: u32,
) -> Result<PathBuf, OperatorError> {
    let path = out.join(name);
    let h = panel_px * panels.len().max(1) as u32 + 60;
    line_charts(&path, (1100, h), title, panels, Layout::Stacked)?;
    Ok(path)
}
