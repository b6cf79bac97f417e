//! `host-sim synth`: the dimensional synthesis scan of thesis section 8.2. Every robot of a
//! grid of characteristic dimensions (RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc) is
//! evaluated over the task with [`super::ranges::evaluate`] and kept when it meets the
//! design requirements of its kind: every task pose solved with its actuator forces, no
//! singularity measure below its level, actuator forces and torques, spherical-joint tilt
//! and (RSPR) actuator length within bounds, (USR) the joint angles inside their open
//! ranges. The task, the scan ranges and the bounds come from a TOML task file
//! ([`SynthTask`]; the default is `host-sim/tasks/thesis.toml`, embedded).
//!
//! The candidates are evaluated in parallel (rayon); the output keeps the scan order (first
//! dimension slowest), whatever the number of threads. The admissible robots are ranked by
//! size ([`Candidate::envelope_volume_cm3`]).

use super::ranges::{evaluate, quantity_names, QuantityRange, Ranges};
use super::{out_dir, write_csv};
use crate::columns::{pose_from_edge, POSE};
use crate::geometry_file::located;
use crate::task_box::{numbers, parse_grid, TaskBox};
use crate::units::{fixed, m_to_mm, mm_to_m};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kinematics_core::{inverse, Branch, Robot, RobotKind, RsprGeometry, UsrGeometry};
use rayon::prelude::*;
use serde::Deserialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// The thesis's task file, `host-sim/tasks/thesis.toml`: the defaults of every task file.
pub const THESIS_TASK_TOML: &str = include_str!("../../tasks/thesis.toml");

/// `host-sim synth`.
#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Task file (TOML): the task, the scan ranges and the bounds of each kind; absent keys
    /// keep the thesis's values [default: host-sim/tasks/thesis.toml, embedded].
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

/// The design requirements of one kind (edge units).
#[derive(Clone, Debug, PartialEq)]
pub struct Requirements {
    /// The wrench under which the force bounds hold: fx_n, fy_n, fz_n, tx_nm, ty_nm, tz_nm.
    pub wrench: [f64; 6],
    /// Largest |prismatic force|, N (infinite on the USR, which has none).
    pub max_force_n: f64,
    /// Largest |actuator torque|, N m.
    pub max_torque_nm: f64,
    /// Largest spherical-joint tilt, deg.
    pub max_tilt_deg: f64,
    /// RSPR: shortest admissible prismatic length, mm (0 = no bound).
    pub min_length_mm: f64,
    /// RSPR: the actuator's stroke, mm: lengths at most min_length_mm + stroke_mm (0 = no
    /// bound).
    pub stroke_mm: f64,
    /// Smallest parallel inverse condition number accepted over the task.
    pub min_parallel_inv_cond: f64,
    /// Smallest dimensionless serial measure accepted over the task.
    pub min_serial: f64,
    /// Open ranges (quantity over the chains as in [`Ranges::table_columns`], low, high)
    /// that the joint angles must stay strictly inside, deg.
    pub open_ranges_deg: Vec<(String, f64, f64)>,
}

impl Requirements {
    /// The thesis's requirements of a kind: those of `host-sim/tasks/thesis.toml`.
    pub fn thesis(kind: RobotKind) -> Result<Self, String> {
        Ok(SynthTask::thesis()?.kind(kind).requirements.clone())
    }
}

/// The scan of one kind: the dimension axes and the requirements.
#[derive(Clone, Debug, PartialEq)]
pub struct KindTask {
    /// The values of each dimension, mm, in [`dim_names`] order.
    pub axes: Vec<Vec<f64>>,
    pub requirements: Requirements,
}

/// A synthesis task: the task box and, per kind, the scan and its requirements.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthTask {
    pub task: TaskBox,
    pub rspr: KindTask,
    pub usr: KindTask,
}

/// The keys of a task file (all present after merging onto the thesis's file).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskFile {
    task: TaskSection,
    rspr: RsprSection,
    usr: UsrSection,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskSection {
    box_mm: [f64; 3],
    tilt_deg: f64,
    grid: [f64; 3],
    wrench: [f64; 6],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RsprSection {
    e_mm: [f64; 3],
    rb_mm: [f64; 3],
    rp_mm: [f64; 3],
    hc_mm: [f64; 3],
    max_force_n: f64,
    max_torque_nm: f64,
    max_tilt_deg: f64,
    min_length_mm: f64,
    stroke_mm: f64,
    min_parallel_inv_cond: f64,
    min_serial: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct UsrSection {
    e_mm: [f64; 3],
    rp_mm: [f64; 3],
    l1_mm: [f64; 3],
    l2_mm: [f64; 3],
    hc_mm: [f64; 3],
    max_torque_nm: f64,
    max_tilt_deg: f64,
    alpha_deg: [f64; 2],
    gamma_deg: [f64; 2],
    delta_deg: [f64; 2],
    min_parallel_inv_cond: f64,
    min_serial: f64,
}

/// Overlays `over` onto `base`, key by key; a key absent from `base` is an error.
fn merge(base: &mut toml::Table, over: toml::Table, prefix: &str) -> Result<(), String> {
    for (key, value) in over {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match (base.get_mut(&key), value) {
            (None, _) => return Err(format!("unknown field `{path}`")),
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o, &path)?,
            (Some(toml::Value::Table(_)), _) => {
                return Err(format!("`{path}` must be a table ([{path}])"))
            }
            (Some(slot), v) => *slot = v,
        }
    }
    Ok(())
}

/// The values from, from + step, ... <= to of a `[from, to, step]` range.
fn range_values(field: &str, [from, to, step]: [f64; 3]) -> Result<Vec<f64>, String> {
    if !(from.is_finite() && to.is_finite() && step.is_finite()) {
        return Err(format!("{field}: every value must be a finite number"));
    }
    if from < 0.0 {
        return Err(format!("{field}: from = {from} mm must be >= 0"));
    }
    if !(step > 0.0 && to >= from && (to - from) / step <= 1000.0) {
        return Err(format!(
            "{field}: need [from, to, step] with from <= to and step > 0, at most 1001 values"
        ));
    }
    let n = ((to - from) / step + 1e-9).floor() as usize + 1;
    Ok((0..n).map(|k| from + step * k as f64).collect())
}

/// A bound that must be a number > 0 (or >= 0 when `zero_ok`), infinity allowed.
fn bound(field: &str, v: f64, zero_ok: bool) -> Result<f64, String> {
    let ok = !v.is_nan() && if zero_ok { v >= 0.0 } else { v > 0.0 };
    if ok {
        Ok(v)
    } else {
        Err(format!(
            "{field}: {v} is not a number {} 0",
            if zero_ok { ">=" } else { ">" }
        ))
    }
}

/// An open range `[low, high]` with low < high.
fn open_range(field: &str, [lo, hi]: [f64; 2]) -> Result<(f64, f64), String> {
    if lo.is_finite() && hi.is_finite() && lo < hi {
        Ok((lo, hi))
    } else {
        Err(format!("{field}: need [low, high] with low < high, deg"))
    }
}

impl SynthTask {
    /// The thesis's task (`host-sim/tasks/thesis.toml`).
    pub fn thesis() -> Result<Self, String> {
        Self::parse(THESIS_TASK_TOML).map_err(|e| format!("the embedded thesis task: {e}"))
    }

    /// A task from the text of a task file: its keys over the thesis's, then validated.
    /// Messages name the field (`rspr.max_torque_nm: ...`).
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut base: toml::Table =
            toml::from_str(THESIS_TASK_TOML).map_err(|e| format!("thesis task: {e}"))?;
        let over: toml::Table = toml::from_str(text).map_err(|e| located(text, &e))?;
        merge(&mut base, over, "")?;
        let f: TaskFile = base.try_into().map_err(|e| e.to_string())?;
        Self::from_file(f)
    }

    /// Loads and validates a task file; messages name the file and the field.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read the task file {}: {e}", path.display()))?;
        Self::parse(&text).map_err(|e| format!("task file {}: {e}", path.display()))
    }

    fn from_file(f: TaskFile) -> Result<Self, String> {
        let t = &f.task;
        for (i, b) in t.box_mm.iter().enumerate() {
            if !(b.is_finite() && *b >= 0.0) {
                return Err(format!("task.box_mm[{i}]: {b} is not a length >= 0 mm"));
            }
        }
        if !t.tilt_deg.is_finite() {
            return Err(format!("task.tilt_deg: {} is not a number", t.tilt_deg));
        }
        if t.wrench.iter().any(|w| !w.is_finite()) {
            return Err("task.wrench: every component must be a finite number".into());
        }
        let grid_text = t.grid.map(|g| g.to_string()).join(",");
        let grid = parse_grid("task.grid", &grid_text)?;
        let task = TaskBox {
            grid,
            box_mm: t.box_mm,
            tilt_deg: t.tilt_deg,
        };
        let r = &f.rspr;
        let rspr = KindTask {
            axes: vec![
                range_values("rspr.e_mm", r.e_mm)?,
                range_values("rspr.rb_mm", r.rb_mm)?,
                range_values("rspr.rp_mm", r.rp_mm)?,
                range_values("rspr.hc_mm", r.hc_mm)?,
            ],
            requirements: Requirements {
                wrench: t.wrench,
                max_force_n: bound("rspr.max_force_n", r.max_force_n, false)?,
                max_torque_nm: bound("rspr.max_torque_nm", r.max_torque_nm, false)?,
                max_tilt_deg: bound("rspr.max_tilt_deg", r.max_tilt_deg, false)?,
                min_length_mm: bound("rspr.min_length_mm", r.min_length_mm, true)?,
                stroke_mm: bound("rspr.stroke_mm", r.stroke_mm, true)?,
                min_parallel_inv_cond: bound(
                    "rspr.min_parallel_inv_cond",
                    r.min_parallel_inv_cond,
                    true,
                )?,
                min_serial: bound("rspr.min_serial", r.min_serial, true)?,
                open_ranges_deg: Vec::new(),
            },
        };
        let u = &f.usr;
        let usr = KindTask {
            axes: vec![
                range_values("usr.e_mm", u.e_mm)?,
                range_values("usr.rp_mm", u.rp_mm)?,
                range_values("usr.l1_mm", u.l1_mm)?,
                range_values("usr.l2_mm", u.l2_mm)?,
                range_values("usr.hc_mm", u.hc_mm)?,
            ],
            requirements: Requirements {
                wrench: t.wrench,
                max_force_n: f64::INFINITY,
                max_torque_nm: bound("usr.max_torque_nm", u.max_torque_nm, false)?,
                max_tilt_deg: bound("usr.max_tilt_deg", u.max_tilt_deg, false)?,
                min_length_mm: 0.0,
                stroke_mm: 0.0,
                min_parallel_inv_cond: bound(
                    "usr.min_parallel_inv_cond",
                    u.min_parallel_inv_cond,
                    true,
                )?,
                min_serial: bound("usr.min_serial", u.min_serial, true)?,
                open_ranges_deg: vec![
                    open_range_named("alpha_deg", open_range("usr.alpha_deg", u.alpha_deg)?),
                    open_range_named("gamma_deg", open_range("usr.gamma_deg", u.gamma_deg)?),
                    open_range_named("delta_deg", open_range("usr.delta_deg", u.delta_deg)?),
                ],
            },
        };
        Ok(SynthTask { task, rspr, usr })
    }

    /// The scan and requirements of a kind.
    pub fn kind(&self, kind: RobotKind) -> &KindTask {
        match kind {
            RobotKind::Rspr => &self.rspr,
            RobotKind::Usr => &self.usr,
        }
    }

    /// The scan and requirements of a kind, mutable (for the command-line overrides).
    pub fn kind_mut(&mut self, kind: RobotKind) -> &mut KindTask {
        match kind {
            RobotKind::Rspr => &mut self.rspr,
            RobotKind::Usr => &mut self.usr,
        }
    }
}

fn open_range_named(name: &str, (lo, hi): (f64, f64)) -> (String, f64, f64) {
    (name.to_string(), lo, hi)
}

/// One scanned robot.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// The dimensions in mm: RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc.
    pub dims_mm: Vec<f64>,
    /// The size by which admissible robots are ranked: the volume of the vertical cylinder
    /// about z0 from the base plane to the platform centre at the central configuration
    /// (height hc) that holds every joint centre e_i, b_i, p_i of that configuration, cm^3.
    /// NaN when the robot could not be built.
    pub envelope_volume_cm3: f64,
    /// The ranges over the task, when the robot could be evaluated.
    pub ranges: Option<Ranges>,
    /// The first unmet requirement; None when admissible.
    pub rejected: Option<String>,
}

/// The values from, from + step, ... <= to of a `FROM,TO,STEP` flag.
pub fn steps(flag: &str, text: &str) -> Result<Vec<f64>, String> {
    let v: [f64; 3] = numbers(flag, text)?;
    range_values(flag, v)
}

/// The dimension names of a robot kind, in `dims_mm` order.
pub fn dim_names(kind: RobotKind) -> &'static [&'static str] {
    match kind {
        RobotKind::Rspr => &["e_mm", "rb_mm", "rp_mm", "hc_mm"],
        RobotKind::Usr => &["e_mm", "rp_mm", "l1_mm", "l2_mm", "hc_mm"],
    }
}

/// The robot of a kind with dimensions in mm ([`dim_names`] order).
pub fn robot_of(kind: RobotKind, d: &[f64]) -> Result<Robot<f64>, String> {
    let m: Vec<f64> = d.iter().map(|&x| mm_to_m(x)).collect();
    match (kind, m.as_slice()) {
        (RobotKind::Rspr, &[e, rb, rp, hc]) => RsprGeometry::new(e, rb, rp, hc)
            .map(Robot::Rspr)
            .map_err(|e| format!("geometry: {e}")),
        (RobotKind::Usr, &[e, rp, l1, l2, hc]) => UsrGeometry::new(e, rp, l1, l2, hc)
            .map(Robot::Usr)
            .map_err(|e| format!("geometry: {e}")),
        _ => Err("wrong number of dimensions".into()),
    }
}

/// The envelope volume of [`Candidate::envelope_volume_cm3`].
pub fn envelope_volume_cm3(robot: &Robot<f64>) -> Result<f64, String> {
    let hc_mm = m_to_mm(kinematics_core::Mechanism::hc(robot));
    let pose = pose_from_edge(&POSE, [0.0, 0.0, hc_mm, 0.0, 0.0, 0.0])?;
    let sol = inverse(robot, &pose, Branch::OUTER).map_err(|e| format!("central pose: {e}"))?;
    let radius_mm = sol
        .chains
        .0
        .iter()
        .flat_map(|c| [c.e, c.b, c.p])
        .map(|v| m_to_mm(v.x.hypot(v.y)))
        .fold(0.0, f64::max);
    Ok(std::f64::consts::PI * radius_mm * radius_mm * hc_mm / 1000.0)
}

/// The first unmet requirement of evaluated ranges; None when all are met. The order:
/// failed task poses, singularity, then each quantity in [`quantity_names`] order.
pub fn check(kind: RobotKind, r: &Ranges, req: &Requirements) -> Option<String> {
    if let Some(f) = r.failures.first() {
        return Some(format!("task pose failed: {f}"));
    }
    if r.parallel_inv_cond_min < req.min_parallel_inv_cond {
        return Some(format!(
            "parallel singularity: inv_cond {:.4} < {}",
            r.parallel_inv_cond_min, req.min_parallel_inv_cond
        ));
    }
    if r.serial_relative_min < req.min_serial {
        return Some(format!(
            "serial singularity: measure {:.4} < {}",
            r.serial_relative_min, req.min_serial
        ));
    }
    let t = |q: &str| r.get(q, "task").filter(|q| q.poses > 0);
    for name in quantity_names(kind) {
        let Some(q) = t(&name) else { continue };
        let abs = q.min.abs().max(q.max.abs());
        let bad = if name.starts_with('f') && name.ends_with("_n") {
            (abs > req.max_force_n).then(|| format!("|{name}| {abs:.2} > {} N", req.max_force_n))
        } else if name.ends_with("_nm") {
            (abs > req.max_torque_nm)
                .then(|| format!("|{name}| {abs:.3} > {} N m", req.max_torque_nm))
        } else if name.starts_with("tilt") {
            (q.max > req.max_tilt_deg)
                .then(|| format!("{name} {:.2} > {} deg", q.max, req.max_tilt_deg))
        } else if kind == RobotKind::Rspr && name.starts_with('l') && name.ends_with("_mm") {
            let longest = req.min_length_mm + req.stroke_mm;
            if req.min_length_mm > 0.0 && q.min < req.min_length_mm {
                Some(format!(
                    "{name} min {:.2} < {} mm (min_length_mm)",
                    q.min, req.min_length_mm
                ))
            } else if req.stroke_mm > 0.0 && q.max > longest {
                Some(format!(
                    "{name} max {:.2} > {longest} mm (min_length_mm + stroke_mm)",
                    q.max
                ))
            } else {
                None
            }
        } else {
            None
        };
        if bad.is_some() {
            return bad;
        }
    }
    for (group, lo, hi) in &req.open_ranges_deg {
        let columns = r.table_columns("task");
        if let Some(q) = columns.iter().find(|c| &c.quantity == group) {
            if q.min <= *lo || q.max >= *hi {
                return Some(format!(
                    "{group} {:.1}..{:.1} outside ({lo}, {hi})",
                    q.min, q.max
                ));
            }
        }
    }
    None
}

/// Evaluates one robot over the task.
pub fn candidate(
    kind: RobotKind,
    dims_mm: Vec<f64>,
    task: &TaskBox,
    req: &Requirements,
) -> Candidate {
    let robot = match robot_of(kind, &dims_mm) {
        Ok(r) => r,
        Err(e) => {
            return Candidate {
                dims_mm,
                envelope_volume_cm3: f64::NAN,
                ranges: None,
                rejected: Some(e),
            }
        }
    };
    let volume = envelope_volume_cm3(&robot).unwrap_or(f64::NAN);
    match evaluate(&robot, task, req.wrench, Branch::OUTER, 1e-9) {
        Ok(r) => Candidate {
            rejected: check(kind, &r, req),
            ranges: Some(r),
            envelope_volume_cm3: volume,
            dims_mm,
        },
        Err(e) => Candidate {
            dims_mm,
            envelope_volume_cm3: volume,
            ranges: None,
            rejected: Some(e),
        },
    }
}

/// The grid of dimensions, in scan order (first dimension slowest).
pub fn grid(axes: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = vec![Vec::new()];
    for axis in axes {
        out = out
            .iter()
            .flat_map(|prefix| {
                axis.iter().map(move |&v| {
                    let mut p = prefix.clone();
                    p.push(v);
                    p
                })
            })
            .collect();
    }
    out
}

/// Evaluates every robot on `jobs` rayon threads (0 = every core); the result keeps the
/// order of `dims`. `bar` advances by one per robot.
pub fn scan(
    kind: RobotKind,
    dims: Vec<Vec<f64>>,
    task: &TaskBox,
    req: &Requirements,
    jobs: usize,
    bar: &ProgressBar,
) -> Result<Vec<Candidate>, String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| format!("worker threads: {e}"))?;
    Ok(pool.install(|| {
        dims.into_par_iter()
            .map(|d| {
                let c = candidate(kind, d, task, req);
                bar.inc(1);
                c
            })
            .collect()
    }))
}

/// The admissible candidates ranked by size (envelope volume, then scan order).
pub fn ranked(found: &[Candidate]) -> Vec<&Candidate> {
    let mut ok: Vec<&Candidate> = found.iter().filter(|c| c.rejected.is_none()).collect();
    ok.sort_by(|a, b| a.envelope_volume_cm3.total_cmp(&b.envelope_volume_cm3));
    ok
}

/// The quantities over the chains reported for the tables, with whether each shows its
/// span (joint quantities and tilt) or only min and max (forces, as the thesis).
fn table_quantities(kind: RobotKind) -> Vec<(&'static str, bool)> {
    match kind {
        RobotKind::Rspr => vec![
            ("l_mm", true),
            ("theta_deg", true),
            ("tilt_deg", true),
            ("f_n", false),
            ("t_nm", false),
        ],
        RobotKind::Usr => vec![
            ("alpha_deg", true),
            ("beta_deg", true),
            ("gamma_deg", true),
            ("delta_deg", true),
            ("tilt_deg", true),
            ("t_alpha_nm", false),
            ("t_beta_nm", false),
        ],
    }
}

/// The column names of the ranked tables (CSV and Markdown).
pub fn ranked_header(kind: RobotKind) -> Vec<String> {
    let mut h = vec!["rank".to_string()];
    h.extend(dim_names(kind).iter().map(|s| s.to_string()));
    h.push("envelope_volume_cm3".into());
    for (q, span) in table_quantities(kind) {
        h.push(format!("{q}_min"));
        h.push(format!("{q}_max"));
        if span {
            h.push(format!("{q}_span"));
        }
    }
    h
}

/// One ranked row: rank, dimensions, size, the table quantities over the task.
pub fn ranked_row(kind: RobotKind, rank: usize, c: &Candidate, decimals: usize) -> Vec<String> {
    let mut r = vec![rank.to_string()];
    r.extend(c.dims_mm.iter().map(|&x| fixed(x, 1)));
    r.push(fixed(c.envelope_volume_cm3, 1));
    let cols: Vec<QuantityRange> = c
        .ranges
        .as_ref()
        .map(|g| g.table_columns("task"))
        .unwrap_or_default();
    for (q, span) in table_quantities(kind) {
        let d = if q.ends_with("_deg") || q.ends_with("_mm") {
            decimals.min(1)
        } else {
            decimals
        };
        match cols.iter().find(|x| x.quantity == q) {
            Some(x) => {
                r.push(fixed(x.min, d));
                r.push(fixed(x.max, d));
                if span {
                    r.push(fixed(x.span(), d));
                }
            }
            None => r.extend(std::iter::repeat_n(String::new(), 2 + usize::from(span))),
        }
    }
    r
}

/// The Markdown table of the ranked admissible robots.
pub fn markdown(kind: RobotKind, ranked: &[&Candidate], title: &str) -> String {
    let header = ranked_header(kind);
    let mut s = format!("# {title}\n\n");
    s.push_str(&format!("| {} |\n", header.join(" | ")));
    s.push_str(&format!(
        "|{}\n",
        header.iter().map(|_| " ---: |").collect::<String>()
    ));
    for (k, c) in ranked.iter().enumerate() {
        s.push_str(&format!(
            "| {} |\n",
            ranked_row(kind, k + 1, c, 2).join(" | ")
        ));
    }
    s
}

/// Applies the command-line overrides to a task.
fn apply_overrides(args: &SynthArgs, st: &mut SynthTask, kind: RobotKind) -> Result<(), String> {
    if let Some(g) = &args.grid {
        st.task.grid = parse_grid("--grid", g)?;
    }
    let flags: Vec<(&str, &Option<String>)> = match kind {
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
        return Err(format!("{flag} does not apply to the {kind:?} robot"));
    }
    let k = st.kind_mut(kind);
    for ((flag, value), axis) in flags.into_iter().zip(k.axes.iter_mut()) {
        if let Some(text) = value {
            *axis = steps(flag, text)?;
        }
    }
    Ok(())
}

/// Runs `synth` for the kind of the selected robot.
pub fn run(args: &SynthArgs, kind: RobotKind) -> Result<(), String> {
    let mut st = match &args.task {
        Some(p) => SynthTask::load(p)?,
        None => SynthTask::thesis()?,
    };
    apply_overrides(args, &mut st, kind)?;
    let source = args
        .task
        .as_ref()
        .map_or("host-sim/tasks/thesis.toml (embedded)".to_string(), |p| {
            p.display().to_string()
        });
    let k = st.kind(kind).clone();
    let dims = grid(&k.axes);
    if dims.len() > 200_000 {
        return Err(format!(
            "{} robots: narrow the ranges (at most 200000)",
            dims.len()
        ));
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
    let started = std::time::Instant::now();
    let found = scan(kind, dims, &st.task, &k.requirements, jobs, &bar)?;
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let names = quantity_names(kind);
    let mut header: Vec<String> = dim_names(kind).iter().map(|s| s.to_string()).collect();
    header.extend(
        [
            "envelope_volume_cm3",
            "admissible",
            "rejected",
            "parallel_inv_cond_min",
            "serial_min",
        ]
        .map(String::from),
    );
    for n in &names {
        header.push(format!("{n}_min"));
        header.push(format!("{n}_max"));
    }
    let rows: Vec<Vec<String>> = found
        .iter()
        .map(|c| {
            let mut r: Vec<String> = c.dims_mm.iter().map(|&x| fixed(x, 3)).collect();
            r.push(fixed(c.envelope_volume_cm3, 3));
            r.push(c.rejected.is_none().to_string());
            r.push(c.rejected.clone().unwrap_or_default());
            match &c.ranges {
                Some(g) => {
                    r.push(fixed(g.parallel_inv_cond_min, 6));
                    r.push(fixed(g.serial_relative_min, 6));
                }
                None => r.extend([String::new(), String::new()]),
            }
            for n in &names {
                match c.ranges.as_ref().and_then(|g| g.get(n, "task")) {
                    Some(q) if q.poses > 0 => {
                        r.push(fixed(q.min, 4));
                        r.push(fixed(q.max, 4));
                    }
                    _ => r.extend([String::new(), String::new()]),
                }
            }
            r
        })
        .collect();
    let dir = out_dir(args.out.as_deref(), "synth")?;
    let all_path = dir.join("synth.csv");
    write_csv(&all_path, &header, &rows)?;
    let best = ranked(&found);
    let ranked_rows: Vec<Vec<String>> = best
        .iter()
        .enumerate()
        .map(|(k, c)| ranked_row(kind, k + 1, c, 4))
        .collect();
    let csv_path = dir.join("admissible.csv");
    write_csv(&csv_path, &ranked_header(kind), &ranked_rows)?;
    let md_path = dir.join("admissible.md");
    let title = format!(
        "Admissible {kind:?} robots ranked by size ({} of {}; task {})",
        best.len(),
        found.len(),
        source
    );
    std::fs::write(&md_path, markdown(kind, &best, &title))
        .map_err(|e| format!("cannot write {}: {e}", md_path.display()))?;

    println!(
        "synth ({kind:?}, task {source}): {} robots scanned, {} admissible, {:.1} s ({:.1} robots/s)",
        found.len(),
        best.len(),
        seconds,
        found.len() as f64 / seconds.max(1e-9)
    );
    let [bx, by, bz] = st.task.box_mm;
    let [nx, ny, nz] = st.task.grid;
    println!(
        "task: {bx} x {by} x {bz} mm box at [0, 0, hc] on a {nx} x {ny} x {nz} grid, platform parallel and {:+} deg about [1,1,0]",
        st.task.tilt_deg
    );
    if let Some(c) = reference_of(kind, &found) {
        match &c.rejected {
            None => println!("the reference robot is admissible"),
            Some(why) => println!("the reference robot is NOT admissible: {why}"),
        }
    }
    for (k, c) in best.iter().enumerate().take(10) {
        let dims: Vec<String> = dim_names(kind)
            .iter()
            .zip(&c.dims_mm)
            .map(|(n, v)| format!("{n} {v}"))
            .collect();
        println!(
            "  {:>3}. {} ({:.0} cm^3)",
            k + 1,
            dims.join(", "),
            c.envelope_volume_cm3
        );
    }
    for p in [all_path, csv_path, md_path] {
        println!("  wrote {}", p.display());
    }
    Ok(())
}

/// The reference robot of a kind among the scanned candidates, if scanned.
fn reference_of(kind: RobotKind, found: &[Candidate]) -> Option<&Candidate> {
    let reference: Vec<f64> = match kind {
        RobotKind::Rspr => vec![20.0, 90.0, 50.0, 160.0],
        RobotKind::Usr => vec![30.0, 30.0, 60.0, 80.0, 80.0],
    };
    found.iter().find(|c| {
        c.dims_mm
            .iter()
            .zip(&reference)
            .all(|(a, b)| (a - b).abs() < 1e-9)
    })
}
