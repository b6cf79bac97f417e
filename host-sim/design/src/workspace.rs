//! `host-sim workspace`: constant-height sections of the reachable workspace at a fixed
//! orientation (thesis section 8.4, cylindrical scan). For each height z and direction phi,
//! the largest radius rho such that the pose [rho cos phi, rho sin phi, z] has a valid,
//! guard-admissible solution: a coarse march outwards from the axis, then bisection.
//! Admissible = no stop-level violation from `Guards::evaluate_pose`, the workspace guard
//! excluded (that guard is the task box itself). The scan assumes each section is
//! star-shaped about the axis (it reports the first boundary crossing).
//!
//! Besides the section plots, a 3-D view of the boundary (the sections stacked at their
//! heights, joined along each scan direction, with the task box) per orientation, and a
//! verdict on the whole task box: every point of a grid through the box (at most 2 mm
//! apart, faces and corners included) checked at both orientations.

use crate::files::{out_dir, write_csv, FileError};
use kinematics_core::guards::{Guard, GuardSetupError, Guards, Limits, Reading, Severity};
use kinematics_core::{Branch, Mechanism, Robot};
use plots::plotters::coord::cartesian::Cartesian3d;
use plots::plotters::coord::types::RangedCoordf64;
use plots::plotters::prelude::*;
use plots::{line_charts, register_font, span, Layout, Panel, PlotError, Series};
use robot_config::edge::{pose_from_edge, POSE};
use robot_config::selection::SelectedLimits;
use robot_config::task_box::{pose_label, TaskBox};
use robot_config::units::{fixed, m_to_mm};
use std::fmt::Write as _;
use std::path::Path;
use thiserror::Error;

/// Why the workspace cannot be scanned or its output written.
#[derive(Debug, Error)]
pub enum WorkspaceError {
    /// The guards cannot be set up for the robot, branch and limits.
    #[error("guards: {0}")]
    Guards(GuardSetupError),
    /// The output directory or the CSV file.
    #[error(transparent)]
    File(#[from] FileError),
    /// A plot.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The scan settings (edge units).
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// Section heights, absolute, mm.
    pub z_mm: Vec<f64>,
    pub phi_step_deg: f64,
    pub step_mm: f64,
    pub tol_mm: f64,
    pub max_radius_mm: f64,
    /// Half-extents of the footprint in x and y, mm.
    pub footprint_half_mm: [f64; 2],
}

/// One constant-height section at one orientation.
#[derive(Clone, Debug, PartialEq)]
pub struct Section {
    /// `parallel` or `rotated`.
    pub orientation: &'static str,
    pub rotation_deg: [f64; 3],
    pub z_mm: f64,
    pub phi_deg: Vec<f64>,
    /// Largest admissible radius per direction, mm (0 when the axis point itself is not
    /// admissible; max_radius_mm when no boundary was found).
    pub rho_max_mm: Vec<f64>,
    /// Every scanned direction reaches at least the footprint's boundary.
    pub footprint_rays_inside: bool,
    /// The first point of the footprint's perimeter (1 mm spacing) that is not admissible,
    /// with its first stop-level violation; None when the whole perimeter is.
    pub footprint_violation: Option<String>,
}

impl Section {
    /// No admissible point at this height (not even on the axis).
    pub fn is_empty(&self) -> bool {
        self.rho_max_mm.iter().all(|r| *r <= 0.0)
    }

    /// The footprint lies inside the section (rays and perimeter).
    pub fn footprint_inside(&self) -> bool {
        self.footprint_rays_inside && self.footprint_violation.is_none()
    }
}

/// A guard reading in edge units: `guard:subject:value:limit unit`.
pub fn describe_reading(r: &Reading<f64>) -> String {
    let (factor, unit) = r.guard.edge_unit();
    format!(
        "{}:{}:{:.3}:{:.3} {}",
        r.guard,
        r.subject,
        r.value * factor,
        r.limit * factor,
        unit
    )
    .trim_end()
    .to_string()
}

/// The admissibility test of the scan.
pub struct Admissible {
    guards: Guards<f64, Robot<f64>>,
}

impl Admissible {
    /// Prepares the guards for a robot, branch and limits.
    pub fn new(
        robot: &Robot<f64>,
        branch: Branch,
        limits: &Limits<f64>,
    ) -> Result<Self, WorkspaceError> {
        Ok(Admissible {
            guards: Guards::new(*robot, branch, *limits).map_err(WorkspaceError::Guards)?,
        })
    }

    /// The first stop-level violation at a pose (mm, deg), the workspace guard excluded;
    /// None when the pose is admissible.
    pub fn violation(&self, pose_edge: [f64; 6]) -> Option<Reading<f64>> {
        let Ok(pose) = pose_from_edge(&POSE, pose_edge) else {
            return None;
        };
        let mut first = None;
        self.guards.evaluate_pose(&pose, &mut |r| {
            if first.is_none() && r.severity == Some(Severity::Stop) && r.guard != Guard::Workspace
            {
                first = Some(*r);
            }
        });
        first
    }

    /// True when the pose is admissible.
    pub fn ok(&self, pose_edge: [f64; 6]) -> bool {
        pose_from_edge(&POSE, pose_edge).is_ok() && self.violation(pose_edge).is_none()
    }
}

/// The largest admissible radius in direction phi at height z, mm.
pub fn rho_max(adm: &Admissible, scan: &Scan, z_mm: f64, phi_deg: f64, rot: [f64; 3]) -> f64 {
    let (s, c) = phi_deg.to_radians().sin_cos();
    let at = |rho: f64| adm.ok([rho * c, rho * s, z_mm, rot[0], rot[1], rot[2]]);
    if !at(0.0) {
        return 0.0;
    }
    let mut good = 0.0;
    let mut bad = None;
    while good < scan.max_radius_mm {
        let next = (good + scan.step_mm).min(scan.max_radius_mm);
        if at(next) {
            good = next;
        } else {
            bad = Some(next);
            break;
        }
    }
    let Some(mut bad) = bad else {
        return scan.max_radius_mm;
    };
    while bad - good > scan.tol_mm {
        let mid = 0.5 * (good + bad);
        if at(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    good
}

/// The radius of the footprint rectangle's boundary in direction phi, mm.
pub fn footprint_radius(half: [f64; 2], phi_deg: f64) -> f64 {
    let (s, c) = phi_deg.to_radians().sin_cos();
    let rx = if c.abs() > 1e-12 {
        half[0] / c.abs()
    } else {
        f64::INFINITY
    };
    let ry = if s.abs() > 1e-12 {
        half[1] / s.abs()
    } else {
        f64::INFINITY
    };
    rx.min(ry)
}

/// Points of the footprint's perimeter, about 1 mm apart, corners included, mm.
fn perimeter(half: [f64; 2]) -> Vec<[f64; 2]> {
    let [hx, hy] = half;
    let n = |len: f64| (len.ceil() as usize).max(1);
    let mut pts = Vec::new();
    let (nx, ny) = (n(2.0 * hx), n(2.0 * hy));
    for i in 0..=nx {
        let x = -hx + 2.0 * hx * i as f64 / nx as f64;
        pts.push([x, -hy]);
        pts.push([x, hy]);
    }
    for j in 1..ny {
        let y = -hy + 2.0 * hy * j as f64 / ny as f64;
        pts.push([-hx, y]);
        pts.push([hx, y]);
    }
    pts
}

/// Scans one section.
pub fn section(
    adm: &Admissible,
    scan: &Scan,
    orientation: &'static str,
    rot: [f64; 3],
    z_mm: f64,
) -> Section {
    let n = ((360.0 / scan.phi_step_deg).round() as usize).max(1);
    let phi_deg: Vec<f64> = (0..n).map(|k| k as f64 * 360.0 / n as f64).collect();
    let rho: Vec<f64> = phi_deg
        .iter()
        .map(|&p| rho_max(adm, scan, z_mm, p, rot))
        .collect();
    let footprint_rays_inside = phi_deg
        .iter()
        .zip(&rho)
        .all(|(&p, &r)| r + scan.tol_mm >= footprint_radius(scan.footprint_half_mm, p));
    let footprint_violation = perimeter(scan.footprint_half_mm)
        .into_iter()
        .find_map(|[x, y]| {
            let pose = [x, y, z_mm, rot[0], rot[1], rot[2]];
            adm.violation(pose)
                .map(|r| format!("({x:.1}, {y:.1}, {z_mm:.1}) mm: {}", describe_reading(&r)))
        });
    Section {
        orientation,
        rotation_deg: rot,
        z_mm,
        phi_deg,
        rho_max_mm: rho,
        footprint_rays_inside,
        footprint_violation,
    }
}

/// Scans every section at both task orientations.
pub fn scan_all(adm: &Admissible, scan: &Scan, task: &TaskBox) -> Vec<Section> {
    let mut out = Vec::new();
    for o in task.orientations() {
        for &z in &scan.z_mm {
            out.push(section(adm, scan, o.key, o.rotation_deg, z));
        }
    }
    out
}

/// Plots the sections of one orientation in the x-y plane with the footprint.
pub fn plot(
    sections: &[&Section],
    half: [f64; 2],
    title: &str,
    path: &Path,
) -> Result<(), PlotError> {
    let r = sections
        .iter()
        .flat_map(|s| s.rho_max_mm.iter().copied())
        .fold(half[0].max(half[1]), f64::max)
        * 1.1;
    let mut series: Vec<Series> = sections
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let color = section_color(k);
            if s.is_empty() {
                // No admissible point at this height: no line, no legend entry (the title
                // names the height).
                return Series {
                    label: None,
                    points: Vec::new(),
                    style: color.stroke_width(2),
                };
            }
            let mut pts: Vec<(f64, f64)> = s
                .phi_deg
                .iter()
                .zip(&s.rho_max_mm)
                .map(|(p, r)| {
                    let (sn, c) = p.to_radians().sin_cos();
                    (r * c, r * sn)
                })
                .collect();
            if let Some(first) = pts.first().copied() {
                pts.push(first);
            }
            let label = format!(
                "z = {:.1} mm{}",
                s.z_mm,
                if s.footprint_inside() {
                    ""
                } else {
                    " (footprint NOT inside)"
                }
            );
            Series::new(label, pts, color, 2)
        })
        .collect();
    let [hx, hy] = half;
    series.push(Series::new(
        "task box footprint",
        vec![(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)],
        BLACK,
        2,
    ));
    let panel = Panel {
        levels: Vec::new(),
        bands: Vec::new(),
        caption: None,
        x_desc: "x [mm]".into(),
        y_desc: "y [mm]".into(),
        x_range: (-r, r),
        y_range: (-r, r),
        series,
    };
    let empty: Vec<String> = sections
        .iter()
        .filter(|s| s.is_empty())
        .map(|s| format!("{:.0}", s.z_mm))
        .collect();
    let title = if empty.is_empty() {
        title.to_string()
    } else {
        format!(
            "{title}; no admissible point at z = {} mm",
            empty.join(", ")
        )
    };
    line_charts(path, (900, 900), &title, &[panel], Layout::Stacked)
}

/// The colour of the `k`-th section: the distinct palette without its red, which marks a
/// task box that is not inside.
fn section_color(k: usize) -> RGBColor {
    const COLORS: [usize; 9] = [0, 1, 2, 4, 5, 6, 7, 8, 9];
    plots::PALETTE[COLORS[k % COLORS.len()]]
}

/// The verdict on the whole task box.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxVerdict {
    /// Grid points checked (both orientations).
    pub points: usize,
    /// Spacing of the grid along x, y, z, mm.
    pub spacing_mm: [f64; 3],
    /// The first point that is not admissible, with its first stop-level violation; None
    /// when every point is.
    pub first_violation: Option<String>,
    /// The same per orientation, in [`TaskBox::orientations`] order.
    pub orientation_violations: [Option<String>; 2],
}

impl BoxVerdict {
    /// The box lies inside the admissible workspace (at every checked point).
    pub fn inside(&self) -> bool {
        self.first_violation.is_none()
    }
}

/// Checks every point of a grid through the task box at both orientations, neighbours at
/// most `max_spacing_mm` apart along each axis (corners and faces included).
pub fn task_box_verdict(
    adm: &Admissible,
    task: &TaskBox,
    hc_mm: f64,
    max_spacing_mm: f64,
) -> BoxVerdict {
    let n = |len: f64| ((len / max_spacing_mm).ceil() as usize).clamp(1, 1000) + 1;
    let grid = task.box_mm.map(n);
    let spacing_mm = [0, 1, 2].map(|k| task.box_mm[k] / (grid[k] - 1) as f64);
    let dense = TaskBox {
        grid,
        ..task.clone()
    };
    let poses = dense.poses(hc_mm);
    let mut orientation_violations: [Option<String>; 2] = [None, None];
    for tp in &poses {
        if let Some(slot) = orientation_violations.get_mut(tp.orientation) {
            if slot.is_none() {
                *slot = adm
                    .violation(tp.pose)
                    .map(|r| format!("{}: {}", pose_label(&tp.pose), describe_reading(&r)));
            }
        }
    }
    BoxVerdict {
        points: poses.len(),
        spacing_mm,
        first_violation: orientation_violations.iter().flatten().next().cloned(),
        orientation_violations,
    }
}

/// The chart of [`plot_3d`]: x, z and -y of {0}, mm.
type Chart3d<'a> = ChartContext<
    'a,
    BitMapBackend<'a>,
    Cartesian3d<RangedCoordf64, RangedCoordf64, RangedCoordf64>,
>;

/// A 3-D view of the boundary of one orientation: each section's boundary at its height,
/// the boundary points of each scan direction joined across the heights, and the task box
/// (red when `box_inside` is false, i.e. some box point fails at this orientation).
pub fn plot_3d(
    sections: &[&Section],
    task: &TaskBox,
    hc_mm: f64,
    box_inside: bool,
    title: &str,
    path: &Path,
) -> Result<(), PlotError> {
    register_font();
    // plotters' 3-D frame has its second axis vertical and is left-handed in this view:
    // (x, z, -y) of {0} keeps the picture right-handed. Empty sections (not even the axis
    // point admissible) are left out, so the meridians do not fall to the axis.
    let sections: Vec<&Section> = sections
        .iter()
        .copied()
        .filter(|s| s.rho_max_mm.iter().any(|&r| r > 0.0))
        .collect();
    let [bx, by, bz] = task.box_mm.map(|b| b / 2.0);
    let r = sections
        .iter()
        .flat_map(|s| s.rho_max_mm.iter().copied())
        .fold(bx.max(by), f64::max)
        * 1.05;
    let (zlo, zhi) = span(
        sections
            .iter()
            .map(|s| s.z_mm)
            .chain([hc_mm - bz, hc_mm + bz]),
    );
    let root = BitMapBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(PlotError::new)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(20)
        .build_cartesian_3d(-r..r, zlo..zhi, -r..r)
        .map_err(PlotError::new)?;
    chart.with_projection(|mut p| {
        p.yaw = 0.6;
        p.pitch = 0.35;
        p.scale = 0.8;
        p.into_matrix()
    });
    chart
        .configure_axes()
        .light_grid_style(BLACK.mix(0.1))
        .max_light_lines(3)
        .x_formatter(&|x| format!("x {x:.0}"))
        .y_formatter(&|z| format!("z {z:.0}"))
        .z_formatter(&|y| format!("y {:.0}", 0.0 - y))
        .draw()
        .map_err(PlotError::new)?;
    draw_boundary(&mut chart, &sections)?;
    draw_task_box(&mut chart, [bx, by, bz], hc_mm, box_inside)?;
    // The upper right of the view is behind the boundary's far walls: no data there.
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 15))
        .border_style(BLACK)
        .background_style(WHITE.mix(0.85))
        .draw()
        .map_err(PlotError::new)?;
    root.present().map_err(PlotError::new)
}

/// The point of a section at direction `phi` (deg) and radius `rho` at height `z`, in the
/// chart's (x, z, -y).
fn point_3d(phi: f64, rho: f64, z: f64) -> (f64, f64, f64) {
    let (sn, c) = phi.to_radians().sin_cos();
    (rho * c, z, -rho * sn)
}

/// Each section's boundary at its height (one colour each, in the legend), and the
/// meridians: the boundary along each scan direction across the heights.
fn draw_boundary(chart: &mut Chart3d<'_>, sections: &[&Section]) -> Result<(), PlotError> {
    for (k, s) in sections.iter().enumerate() {
        let color = section_color(k);
        let mut ring: Vec<(f64, f64, f64)> = s
            .phi_deg
            .iter()
            .zip(&s.rho_max_mm)
            .map(|(&p, &rho)| point_3d(p, rho, s.z_mm))
            .collect();
        if let Some(first) = ring.first().copied() {
            ring.push(first);
        }
        if s.is_empty() {
            // No boundary at this height: nothing to draw, no legend entry.
            continue;
        }
        chart
            .draw_series(LineSeries::new(ring, color.stroke_width(2)))
            .map_err(PlotError::new)?
            .label(format!("z = {:.1} mm", s.z_mm))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
    }
    if let Some(first) = sections.first() {
        for (j, &phi) in first.phi_deg.iter().enumerate() {
            let line: Vec<(f64, f64, f64)> = sections
                .iter()
                .filter_map(|s| s.rho_max_mm.get(j).map(|&rho| point_3d(phi, rho, s.z_mm)))
                .collect();
            chart
                .draw_series(LineSeries::new(line, BLACK.mix(0.25)))
                .map_err(PlotError::new)?;
        }
    }
    Ok(())
}

/// The edges of the task box of half-extents `half` (mm) about [0, 0, hc], black when
/// `inside`, red when not.
fn draw_task_box(
    chart: &mut Chart3d<'_>,
    [bx, by, bz]: [f64; 3],
    hc_mm: f64,
    inside: bool,
) -> Result<(), PlotError> {
    let corner = |i: usize| {
        let sx = if i & 1 == 0 { -bx } else { bx };
        let sy = if i & 2 == 0 { -by } else { by };
        let sz = if i & 4 == 0 { -bz } else { bz };
        (sx, hc_mm + sz, -sy)
    };
    let box_color = if inside { BLACK } else { RED };
    let mut edges = Vec::new();
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            if i & bit == 0 {
                edges.push(vec![corner(i), corner(i | bit)]);
            }
        }
    }
    for (k, e) in edges.into_iter().enumerate() {
        let series = chart
            .draw_series(LineSeries::new(e, box_color.stroke_width(3)))
            .map_err(PlotError::new)?;
        if k == 0 {
            series
                .label(if inside {
                    "task box (inside)"
                } else {
                    "task box (NOT inside)"
                })
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], box_color));
        }
    }
    Ok(())
}

/// A scan setting out of its range; `setting` is its name (`z_mm`, `phi_step_deg`,
/// `step_mm`, `tol_mm`, `max_radius_mm`, `box_mm`).
#[derive(Clone, Debug, PartialEq, Error)]
#[error("{setting}: {reason}")]
pub struct ScanSettingError {
    pub setting: &'static str,
    pub reason: String,
}

impl Scan {
    /// [`Scan::new`] after checking the settings: `z_mm` = [from, to, step] with from <=
    /// to, 0 < step and at most 1000 sections; the other steps, the tolerance and the
    /// radius finite and > 0; the task box's edges finite and >= 0.
    pub fn checked(
        hc_mm: f64,
        z_mm: [f64; 3],
        phi_step_deg: f64,
        step_mm: f64,
        tol_mm: f64,
        max_radius_mm: f64,
        task: &TaskBox,
    ) -> Result<Self, ScanSettingError> {
        let [from, to, step] = z_mm;
        if !(step > 0.0 && to >= from && (to - from) / step <= 1000.0) {
            return Err(ScanSettingError {
                setting: "z_mm",
                reason: "need FROM <= TO and 0 < STEP, at most 1000 sections".into(),
            });
        }
        for (setting, v) in [
            ("phi_step_deg", phi_step_deg),
            ("step_mm", step_mm),
            ("tol_mm", tol_mm),
            ("max_radius_mm", max_radius_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ScanSettingError {
                    setting,
                    reason: format!("{v} is not a number > 0"),
                });
            }
        }
        if !task.box_mm.iter().all(|b| b.is_finite() && *b >= 0.0) {
            return Err(ScanSettingError {
                setting: "box_mm",
                reason: "edge lengths must be >= 0 mm".into(),
            });
        }
        Ok(Scan::new(
            hc_mm,
            z_mm,
            phi_step_deg,
            step_mm,
            tol_mm,
            max_radius_mm,
            task,
        ))
    }

    /// The scan of the sections at `hc_mm + from, from + step, ... <= to` (mm, `z_mm` =
    /// [from, to, step]) with the footprint of `task`'s box; the other settings as given.
    pub fn new(
        hc_mm: f64,
        [from, to, step]: [f64; 3],
        phi_step_deg: f64,
        step_mm: f64,
        tol_mm: f64,
        max_radius_mm: f64,
        task: &TaskBox,
    ) -> Self {
        let count = ((to - from) / step + 1e-9).floor() as usize + 1;
        Scan {
            z_mm: (0..count).map(|k| hc_mm + from + step * k as f64).collect(),
            phi_step_deg,
            step_mm,
            tol_mm,
            max_radius_mm,
            footprint_half_mm: [task.box_mm[0] / 2.0, task.box_mm[1] / 2.0],
        }
    }
}

/// Runs `workspace`: every section of `scan` at both orientations of `task` on `branch`,
/// the verdict on the task box, `workspace.csv`, the section plots and the 3-D views of the
/// boundary written to `out` (default `target/design/workspace`). Returns the text to
/// print.
pub fn run(
    robot: &Robot<f64>,
    limits: &SelectedLimits,
    branch: Branch,
    scan: &Scan,
    task: &TaskBox,
    out: Option<&Path>,
) -> Result<String, WorkspaceError> {
    let hc_mm = m_to_mm(robot.hc());
    let adm = Admissible::new(robot, branch, &limits.limits)?;
    let sections = scan_all(&adm, scan, task);
    let dir = out_dir(out, "workspace")?;
    let csv_path = dir.join("workspace.csv");
    write_csv(&csv_path, &csv_header(), &csv_rows(&sections))?;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "workspace sections ({:?}, limits: {}), admissible = no stop-level guard violation, workspace guard excluded",
        robot.kind(),
        limits.source
    );
    let mut files = vec![csv_path];
    let of =
        |key: &str| -> Vec<&Section> { sections.iter().filter(|s| s.orientation == key).collect() };
    for o in task.orientations() {
        let mine = of(o.key);
        let _ = writeln!(text, "orientation {}:", o.label);
        for s in &mine {
            let _ = writeln!(text, "{}", section_line(s));
        }
        let png = dir.join(format!("sections_{}.png", o.key));
        let title = format!(
            "{:?} workspace sections, platform {}",
            robot.kind(),
            o.label
        );
        plot(&mine, scan.footprint_half_mm, &title, &png)?;
        files.push(png);
    }
    let verdict = task_box_verdict(&adm, task, hc_mm, 2.0);
    text.push_str(&verdict_text(&verdict, task, hc_mm));
    for (o, violation) in task
        .orientations()
        .iter()
        .zip(&verdict.orientation_violations)
    {
        let png = dir.join(format!("boundary_{}.png", o.key));
        let title = format!(
            "{:?} workspace boundary, platform {}",
            robot.kind(),
            o.label
        );
        plot_3d(&of(o.key), task, hc_mm, violation.is_none(), &title, &png)?;
        files.push(png);
    }
    for f in files {
        let _ = writeln!(text, "  wrote {}", f.display());
    }
    Ok(text)
}

/// The columns of `workspace.csv`.
fn csv_header() -> Vec<String> {
    [
        "orientation",
        "rx_deg",
        "ry_deg",
        "rz_deg",
        "z_mm",
        "phi_deg",
        "rho_max_mm",
    ]
    .map(String::from)
    .to_vec()
}

/// The rows of `workspace.csv`: one per section and scan direction.
fn csv_rows(sections: &[Section]) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for s in sections {
        for (p, r) in s.phi_deg.iter().zip(&s.rho_max_mm) {
            let mut row = vec![s.orientation.to_string()];
            row.extend(s.rotation_deg.iter().map(|&x| fixed(x, 6)));
            row.extend([fixed(s.z_mm, 3), fixed(*p, 3), fixed(*r, 3)]);
            rows.push(row);
        }
    }
    rows
}

/// A section's line of the summary: its height, its radii and whether the footprint lies
/// inside it.
fn section_line(s: &Section) -> String {
    let lo = s.rho_max_mm.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = s.rho_max_mm.iter().copied().fold(0.0, f64::max);
    let verdict = if s.footprint_inside() {
        "footprint inside".to_string()
    } else {
        format!(
            "footprint NOT inside{}{}",
            if s.footprint_rays_inside {
                ""
            } else {
                " (some ray short of it)"
            },
            s.footprint_violation
                .as_ref()
                .map(|v| format!("; first failing perimeter point {v}"))
                .unwrap_or_default()
        )
    };
    format!(
        "  z {:7.1} mm: rho_max {:7.2} .. {:7.2} mm; {verdict}",
        s.z_mm, lo, hi
    )
}

/// The summary's lines of the verdict on the task box, overall and per orientation.
fn verdict_text(verdict: &BoxVerdict, task: &TaskBox, hc_mm: f64) -> String {
    let mut text = String::new();
    let [bx, by, bz] = task.box_mm;
    let [sx, sy, sz] = verdict.spacing_mm;
    let _ = writeln!(
        text,
        "task box {bx} x {by} x {bz} mm at [0, 0, {hc_mm:.1}] mm, platform parallel and {:+} deg about [1,1,0] ({} points, {sx:.2} x {sy:.2} x {sz:.2} mm apart): {}",
        task.tilt_deg,
        verdict.points,
        if verdict.inside() {
            "inside the workspace"
        } else {
            "NOT inside the workspace"
        }
    );
    for (o, violation) in task
        .orientations()
        .iter()
        .zip(&verdict.orientation_violations)
    {
        let _ = match violation {
            None => writeln!(text, "  platform {}: every point admissible", o.label),
            Some(v) => writeln!(text, "  platform {}: first failing point {v}", o.label),
        };
    }
    text
}
