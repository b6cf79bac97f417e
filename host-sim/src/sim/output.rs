//! The files a run writes: `summary.json`, `trace.csv`, `path.png`, `errors.png`.

use super::run::{Outcome, TraceRow};
use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};

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
pub fn write_trace<W: Write>(rows: &[TraceRow], out: W) -> Result<(), String> {
    let mut w = csv::Writer::from_writer(out);
    let err = |e: csv::Error| format!("trace: {e}");
    w.write_record(trace_header()).map_err(err)?;
    for r in rows {
        w.write_record(row_fields(r)).map_err(err)?;
    }
    w.flush().map_err(|e| format!("trace: {e}"))
}

/// The files written for one run.
#[derive(Clone, Debug, Default)]
pub struct Written {
    pub files: Vec<PathBuf>,
}

/// Writes `summary.json`, `trace.csv` and (when `plots`) the PNGs into `dir`.
pub fn write_all(outcome: &Outcome, dir: &Path, plots: bool) -> Result<Written, String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("cannot create the output directory {}: {e}", dir.display()))?;
    let mut written = Written::default();
    let json =
        serde_json::to_string_pretty(&outcome.summary).map_err(|e| format!("summary: {e}"))?;
    let p = dir.join("summary.json");
    std::fs::write(&p, json + "\n").map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    written.files.push(p);
    let p = dir.join("trace.csv");
    let f = std::fs::File::create(&p).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    write_trace(&outcome.trace, std::io::BufWriter::new(f))?;
    written.files.push(p);
    if plots {
        let p = dir.join("path.png");
        plot_path(&outcome.trace, &outcome.summary.scenario, &p)?;
        written.files.push(p);
        let p = dir.join("errors.png");
        plot_errors(&outcome.trace, &outcome.summary.scenario, &p)?;
        written.files.push(p);
    }
    Ok(written)
}

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The embedded DejaVu Sans is a valid font; a failure would only lose the text.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad, hi + pad)
}

type PlotResult = Result<(), String>;
/// Picks a pose out of a trace row.
type PoseOf = fn(&TraceRow) -> &[f64; 6];
/// Picks a value out of a trace row.
type ValueOf = fn(&TraceRow) -> f64;

fn perr<E: std::fmt::Display>(e: E) -> String {
    format!("plot: {e}")
}

/// The path seen from above (x-y) and from the side (x-z): target, setpoint and truth.
pub fn plot_path(rows: &[TraceRow], scenario: &str, path: &Path) -> PlotResult {
    register_font();
    let root = BitMapBackend::new(path, (1400, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(perr)?;
    let root = root
        .titled(
            &format!("{scenario}: platform centre path (target, setpoint, true)"),
            ("sans-serif", 22),
        )
        .map_err(perr)?;
    let (left, right) = root.split_horizontally(700);
    let series: [(&str, RGBColor, PoseOf); 3] = [
        ("master target", RGBColor(170, 170, 170), |r| &r.target),
        ("setpoint", BLUE, |r| &r.setpoint),
        ("true", RED, |r| &r.truth),
    ];
    for (area, (ax, ay), ylabel) in [(&left, (0, 1), "y [mm]"), (&right, (0, 2), "z [mm]")] {
        let xr = span(rows.iter().flat_map(|r| [r.target[ax], r.truth[ax]]));
        let yr = span(rows.iter().flat_map(|r| [r.target[ay], r.truth[ay]]));
        let mut chart = ChartBuilder::on(area)
            .caption(
                if ay == 1 {
                    "x-y (top view)"
                } else {
                    "x-z (side view)"
                },
                ("sans-serif", 18),
            )
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("x [mm]")
            .y_desc(ylabel)
            .draw()
            .map_err(perr)?;
        for (name, color, get) in series {
            chart
                .draw_series(LineSeries::new(
                    rows.iter().map(|r| (get(r)[ax], get(r)[ay])),
                    color.stroke_width(if name == "true" { 1 } else { 2 }),
                ))
                .map_err(perr)?
                .label(name)
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

/// The errors over time: tip tracking error, tip error against the target, orientation.
pub fn plot_errors(rows: &[TraceRow], scenario: &str, path: &Path) -> PlotResult {
    register_font();
    let root = BitMapBackend::new(path, (1400, 1000)).into_drawing_area();
    root.fill(&WHITE).map_err(perr)?;
    let root = root
        .titled(
            &format!("{scenario}: errors of the true pose over time"),
            ("sans-serif", 22),
        )
        .map_err(perr)?;
    let panels = root.split_evenly((3, 1));
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
    for (area, (title, unit, get, color)) in panels.iter().zip(specs) {
        let hi = rows.iter().map(get).fold(0.0f64, f64::max).max(1e-6) * 1.1;
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_end, 0.0..hi)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .y_desc(unit)
            .draw()
            .map_err(perr)?;
        chart
            .draw_series(LineSeries::new(rows.iter().map(|r| (r.t_s, get(r))), color))
            .map_err(perr)?;
    }
    root.present().map_err(perr)
}
