//! What the calibration commands print and write: the identification report, the
//! calibrated geometry file, the plan's CSV, the simulation's summary, and the residual
//! plots (PNG, via the `plots` crate).

use crate::identify::{Identifiability, Identification, ParameterResult};
use crate::model::RowResidual;
use crate::parameters::Unit;
use crate::plan::Plan;
use crate::rigid::Rigid;
use crate::simulate::{Outcome, PoseErrors};
use crate::CalibrationError;
use plots::{line_charts, span, Layout, Panel, Series};
use robot_config::per_chain_file::{self, CalibrationInfo};
use robot_config::units::{m_to_mm, rad_to_deg};
use std::fmt::Write;
use std::path::Path;

fn rms(v: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = v.clone().count().max(1) as f64;
    let s: f64 = v.clone().map(|x| x * x).sum();
    ((s / n).sqrt(), v.fold(0.0, f64::max))
}

fn residual_line(name: &str, rows: &[RowResidual]) -> String {
    let (p_rms, p_max) = rms(rows.iter().map(|r| m_to_mm(r.position_m)));
    let rot: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.rotation_rad.map(rad_to_deg))
        .collect();
    let mut s = format!("  {name:<44} position RMS {p_rms:.4} mm, max {p_max:.4} mm");
    if !rot.is_empty() {
        let (r_rms, r_max) = rms(rot.iter().copied());
        let _ = write!(s, "; orientation RMS {r_rms:.4} deg, max {r_max:.4} deg");
    }
    s
}

fn value(p: &ParameterResult, v: f64) -> String {
    match p.info.unit {
        Unit::Length => format!("{:+.4} mm", m_to_mm(v)),
        Unit::Angle => format!("{:+.4} deg", rad_to_deg(v)),
    }
}

fn transform_line(name: &str, t: &Rigid) -> String {
    let r = t.rotation_vector();
    format!(
        "  {name:<20} x,y,z {:.3}, {:.3}, {:.3} mm; rotation vector {:.4}, {:.4}, {:.4} deg",
        m_to_mm(t.t.x),
        m_to_mm(t.t.y),
        m_to_mm(t.t.z),
        rad_to_deg(r.x),
        rad_to_deg(r.y),
        rad_to_deg(r.z)
    )
}

/// The identification report.
pub fn identification_text(id: &Identification) -> String {
    let mut o = String::new();
    residuals(&mut o, id);
    identifiability(&mut o, &id.identifiability);
    let _ = writeln!(o, "\nParameters (deviation from nominal, one standard deviation, share in the determined subspace):");
    for p in &id.parameters {
        let _ = writeln!(o, "{}", parameter_line(p));
    }
    let _ = writeln!(o, "\nTransforms:");
    let _ = writeln!(
        o,
        "{}",
        transform_line("base in tracker", &id.base_in_tracker)
    );
    let _ = writeln!(
        o,
        "{}",
        transform_line("marker on platform", &id.marker_in_platform)
    );
    o
}

/// The residuals before and after, and the rows the robust loss down-weighted.
fn residuals(o: &mut String, id: &Identification) {
    let n = id.before.len();
    let _ = writeln!(o, "Calibration from {n} measured poses");
    let _ = writeln!(o, "Residuals (predicted - measured marker):");
    let _ = writeln!(
        o,
        "{}",
        residual_line("nominal robot, transforms registered:", &id.before)
    );
    let _ = writeln!(o, "{}", residual_line("calibrated:", &id.after));
    let down: Vec<String> = id
        .weights
        .iter()
        .enumerate()
        .filter(|(_, w)| **w < 0.5)
        .map(|(k, w)| format!("{} ({w:.2})", k + 1))
        .collect();
    if !down.is_empty() {
        let _ = writeln!(
            o,
            "  rows down-weighted by the robust loss: {}",
            down.join(", ")
        );
    }
}

/// What the measurements determine: the count, the singular values, the structural
/// degeneracies and the undetermined combinations.
fn identifiability(o: &mut String, ia: &Identifiability) {
    let _ = writeln!(o, "\nIdentifiability (SVD of the Jacobian of the whitened residuals over the parameters divided by their tolerances):");
    let sv = &ia.singular_values;
    let _ = writeln!(
        o,
        "  {} of {} combinations determined (singular value >= {}: known to better than their tolerance); \
         the other {} stay at their nominal values",
        ia.determined,
        sv.len(),
        ia.threshold,
        sv.len() - ia.determined
    );
    let _ = writeln!(
        o,
        "  singular values {:.3e} .. {:.3e} (determined), {:.3e} .. {:.3e} (not); condition {:.1}; observability index O1 {:.4}",
        sv.first().copied().unwrap_or(0.0),
        sv.get(ia.determined.saturating_sub(1)).copied().unwrap_or(0.0),
        sv.get(ia.determined).copied().unwrap_or(0.0),
        sv.last().copied().unwrap_or(0.0),
        ia.condition,
        ia.observability_index
    );
    let _ = writeln!(
        o,
        "  structurally undetermined, whatever the poses: each leg's offset against its encoder zero (3: only the sum \
         counts), a rigid motion of the base against the tracker transform (6) and of the platform against the \
         marker transform (6; with positions only the marker's orientation too); the basis of these (degenerate) \
         directions is arbitrary, their span is not"
    );
    let _ = writeln!(
        o,
        "  undetermined combinations (tolerance units; fixed at nominal):"
    );
    for c in &ia.undetermined {
        let terms: Vec<String> = c
            .terms
            .iter()
            .map(|(n, x)| format!("{x:+.2} {n}"))
            .collect();
        let _ = writeln!(o, "    sigma {:.2e}: {}", c.singular_value, terms.join(" "));
    }
}

/// A parameter's deviation, its standard deviation, its share in the determined subspace
/// and what that makes it.
fn parameter_line(p: &ParameterResult) -> String {
    let status = if p.determined_share > 0.99 {
        "determined"
    } else if p.determined_share < 0.01 {
        "not determined: nominal"
    } else {
        "in combinations only"
    };
    format!(
        "  {:<30} {:>14}  +- {:<14} share {:.3}  {status}",
        p.info.name,
        value(p, p.delta),
        value(p, p.std).trim_start_matches('+'),
        p.determined_share
    )
}

/// The calibrated geometry file's text.
pub fn geometry_text(id: &Identification, version: u32, source: &str) -> String {
    let (p, _) = rms(id.after.iter().map(|r| m_to_mm(r.position_m)));
    let comment = format!(
        "Calibrated by host-sim calibrate from {} poses; residual RMS {p:.4} mm.\n\
         Base in the tracker's frame: see report.txt.",
        id.after.len()
    );
    per_chain_file::text(
        &id.geometry,
        &CalibrationInfo {
            version,
            source: source.to_string(),
        },
        &comment,
    )
}

/// The residual of every row before and after, as CSV.
pub fn residuals_csv(id: &Identification) -> String {
    let mut s = String::from(
        "row,before_position_mm,after_position_mm,before_rotation_deg,after_rotation_deg,weight\n",
    );
    for (k, ((b, a), w)) in id.before.iter().zip(&id.after).zip(&id.weights).enumerate() {
        let rot = |r: &RowResidual| {
            r.rotation_rad
                .map_or(String::new(), |x| format!("{:.6}", rad_to_deg(x)))
        };
        let _ = writeln!(
            s,
            "{},{:.6},{:.6},{},{},{w:.4}",
            k + 1,
            m_to_mm(b.position_m),
            m_to_mm(a.position_m),
            rot(b),
            rot(a)
        );
    }
    s
}

fn series(values: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    values
        .enumerate()
        .map(|(k, v)| ((k + 1) as f64, v))
        .collect()
}

/// Two panels (position mm, orientation deg) of per-item values before and after.
fn before_after_plot(
    path: &Path,
    title: &str,
    x_desc: &str,
    position: [Vec<(f64, f64)>; 2],
    rotation: Option<[Vec<(f64, f64)>; 2]>,
    extra: Option<(&str, Vec<(f64, f64)>)>,
) -> Result<(), CalibrationError> {
    let n = position[0].len().max(1) as f64;
    let mk = |desc: &str, data: &[Vec<(f64, f64)>; 2], extra: Option<&(&str, Vec<(f64, f64)>)>| {
        let mut s = vec![
            Series::new(
                "before calibration",
                data[0].clone(),
                plots::plotters::style::RED,
                2,
            ),
            Series::new(
                "after calibration",
                data[1].clone(),
                plots::plotters::style::BLUE,
                2,
            ),
        ];
        if let Some((label, pts)) = extra {
            s.push(Series::new(
                *label,
                pts.clone(),
                plots::plotters::style::BLACK,
                1,
            ));
        }
        let all = s.iter().flat_map(|x| x.points.iter().map(|p| p.1));
        let (lo, hi) = span(all.chain([0.0]));
        Panel {
            levels: Vec::new(),
            bands: Vec::new(),
            caption: None,
            x_desc: x_desc.to_string(),
            y_desc: desc.to_string(),
            x_range: (0.0, n + 1.0),
            y_range: (lo.min(0.0), hi),
            series: s,
        }
    };
    let mut panels = vec![mk("position error, mm", &position, extra.as_ref())];
    if let Some(r) = rotation {
        panels.push(mk("orientation error, deg", &r, None));
    }
    line_charts(path, (1000, 700), title, &panels, Layout::Stacked)?;
    Ok(())
}

/// The residual plot of an identification (`residuals.png`).
pub fn residual_plot(path: &Path, id: &Identification) -> Result<(), CalibrationError> {
    let pos = [
        series(id.before.iter().map(|r| m_to_mm(r.position_m))),
        series(id.after.iter().map(|r| m_to_mm(r.position_m))),
    ];
    let any_rot = id.after.iter().any(|r| r.rotation_rad.is_some());
    let rot = any_rot.then(|| {
        [
            series(
                id.before
                    .iter()
                    .map(|r| r.rotation_rad.map_or(0.0, rad_to_deg)),
            ),
            series(
                id.after
                    .iter()
                    .map(|r| r.rotation_rad.map_or(0.0, rad_to_deg)),
            ),
        ]
    });
    before_after_plot(
        path,
        "Residuals of the measured poses: nominal robot (registered) and calibrated",
        "measurement row",
        pos,
        rot,
        None,
    )
}

fn errors_line(name: &str, e: &PoseErrors, orientation: bool) -> String {
    let mut s = format!(
        "  {name:<22} position RMS {:.4} mm, max {:.4} mm",
        m_to_mm(e.position_rms_m),
        m_to_mm(e.position_max_m)
    );
    if orientation {
        let _ = write!(
            s,
            "; orientation RMS {:.4} deg, max {:.4} deg",
            rad_to_deg(e.rotation_rms_rad),
            rad_to_deg(e.rotation_max_rad)
        );
    }
    s
}

/// The simulation's summary.
pub fn simulation_text(o: &Outcome, position_only: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Pose error over {} poses of the task box not used for the identification{}:",
        o.validation.len(),
        if position_only {
            " (position-only tracker: the error of the tracked point)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        s,
        "{}",
        errors_line("before calibration:", &o.before, !position_only)
    );
    let _ = writeln!(
        s,
        "{}",
        errors_line("after calibration:", &o.after, !position_only)
    );
    let _ = writeln!(
        s,
        "{}",
        errors_line("noise limit (expected):", &o.limit, !position_only)
    );
    let _ = writeln!(
        s,
        "Plan: observability index O1 {:.4} (as many random poses: {:.4})",
        o.plan_index.0, o.plan_index.1
    );
    s
}

/// The simulation's plot of the validation errors (`validation.png`).
pub fn simulation_plot(
    path: &Path,
    o: &Outcome,
    position_only: bool,
) -> Result<(), CalibrationError> {
    let pos = [
        series(o.errors_before.iter().map(|e| m_to_mm(e.0))),
        series(o.errors_after.iter().map(|e| m_to_mm(e.0))),
    ];
    let rot = (!position_only).then(|| {
        [
            series(o.errors_before.iter().map(|e| rad_to_deg(e.1))),
            series(o.errors_after.iter().map(|e| rad_to_deg(e.1))),
        ]
    });
    let limit = series(o.errors_limit.iter().map(|e| m_to_mm(e.0)));
    before_after_plot(
        path,
        "Pose error on poses not used for the identification",
        "validation pose",
        pos,
        rot,
        Some(("noise limit (expected)", limit)),
    )
}

/// The plan as CSV: the poses to visit and the nominal joints there.
pub fn plan_csv(plan: &Plan) -> String {
    let mut s = String::from(
        "pose,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg\n",
    );
    for (k, (x, q)) in plan.poses.iter().zip(&plan.joints).enumerate() {
        let r = x.rotation_vector();
        let _ = writeln!(
            s,
            "{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
            k + 1,
            m_to_mm(x.t.x),
            m_to_mm(x.t.y),
            m_to_mm(x.t.z),
            rad_to_deg(r.x),
            rad_to_deg(r.y),
            rad_to_deg(r.z),
            m_to_mm(q[0]),
            m_to_mm(q[1]),
            m_to_mm(q[2]),
            rad_to_deg(q[3]),
            rad_to_deg(q[4]),
            rad_to_deg(q[5]),
        );
    }
    s
}

/// The plan's summary.
pub fn plan_text(plan: &Plan) -> String {
    let ia = &plan.identifiability;
    format!(
        "Plan: {} poses of {} candidates (task box grid, tilts 0, 10, 20 deg, guards passed)\n  \
         observability index O1 {:.4} over the {} combinations the candidates determine \
         (as many random candidates: {:.4}); condition {:.1}\n",
        plan.poses.len(),
        plan.candidates,
        ia.observability_index,
        ia.singular_values.len(),
        plan.random_observability_index,
        ia.condition
    )
}
