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
use plots::plotters::style::{RGBColor, BLACK, BLUE, GREEN, MAGENTA, RED};
use plots::{line_charts, span, Layout, Panel, Series};
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
        draw(
            out,
            "margins.png",
            &title("guard margins (1 far, 0 at the stop level)"),
            &[margins_panel(&rec, t0)],
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
    let lag_sp = lag_series(&|r| r.setpoint.map(|p| p.position_m));
    let lag_m = lag_series(&|r| r.measured.map(|p| p.position_m));
    panel(
        "lag, ms",
        vec![
            Series::new("setpoint", lag_sp, ORANGE, 2),
            Series::new("measured", lag_m, RED, 2),
        ],
    )
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
    let colours = [BLACK, RED, BLUE, GREEN, MAGENTA, ORANGE, GREY];
    let series: Vec<Series> = by_name
        .into_iter()
        .enumerate()
        .map(|(i, (k, v))| {
            let c = colours.get(i).copied().unwrap_or(BLACK);
            Series::new(k.clone(), v, c, if k == "nearest" { 3 } else { 1 })
        })
        .collect();
    panel("margin", series)
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
        caption: None,
        x_desc: "t, s".into(),
        y_desc: y_desc.into(),
        x_range: span(pts().map(|p| p.0)),
        y_range: span(pts().map(|p| p.1)),
        series,
    }
}

fn draw(out: &Path, name: &str, title: &str, panels: &[Panel]) -> Result<PathBuf, OperatorError> {
    let path = out.join(name);
    let h = 260 * panels.len().max(1) as u32 + 60;
    line_charts(&path, (1100, h), title, panels, Layout::Stacked)?;
    Ok(path)
}
