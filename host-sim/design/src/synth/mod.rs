//! `host-sim synth`: the dimensional synthesis scan of thesis section 8.2. Every robot of a
//! grid of characteristic dimensions (RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc) is
//! evaluated over the task with [`crate::ranges::evaluate`] and kept when it meets the
//! design requirements of its kind: every task pose solved with its actuator forces, no
//! singularity measure below its level, actuator forces and torques, spherical-joint tilt
//! and (RSPR) actuator length within bounds, (USR) the joint angles inside their open
//! ranges. The task, the scan ranges and the bounds come from a TOML task file
//! ([`SynthTask`], module [`task`]; the default is `host-sim/design/tasks/thesis.toml`,
//! embedded).
//!
//! The candidates are evaluated in parallel (rayon); the output keeps the scan order (first
//! dimension slowest), whatever the number of threads. The admissible robots are ranked by
//! size ([`Candidate::envelope_volume_cm3`]).

pub mod task;

pub use task::{
    range_values, KindTask, RangeError, Requirements, SynthTask, SynthTaskError, THESIS_TASK_TOML,
};

use crate::files::{out_dir, write_csv, write_text, FileError};
use crate::ranges::{
    evaluate, quantity_names, QuantityRange, Ranges, RangesError, TaskPoseFailure,
};
use kinematics_core::{
    inverse, Branch, GeometryError, Mechanism, Robot, RobotKind, RsprGeometry, UsrGeometry,
};
use rayon::prelude::*;
use robot_config::edge::{pose_from_edge, POSE};
use robot_config::task_box::TaskBox;
use robot_config::units::{fixed, m_to_mm, mm_to_m};
use std::fmt::Write as _;
use std::path::Path;
use thiserror::Error;

/// The scan cannot run or its files cannot be written.
#[derive(Debug, Error)]
pub enum SynthError {
    /// The pool of worker threads.
    #[error("worker threads: {0}")]
    Threads(rayon::ThreadPoolBuildError),
    /// An output file.
    #[error(transparent)]
    File(#[from] FileError),
}

/// A robot of the grid that cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum RobotOfError {
    #[error("geometry: {0}")]
    Geometry(GeometryError),
    /// Not one dimension per name of [`dim_names`].
    #[error("wrong number of dimensions")]
    Dimensions { kind: RobotKind, given: usize },
}

/// Why a candidate is not admissible: the first unmet requirement, with its figures.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum Rejection {
    /// The robot cannot be built.
    #[error(transparent)]
    Robot(#[from] RobotOfError),
    /// It cannot be evaluated over the task.
    #[error(transparent)]
    Ranges(#[from] RangesError),
    /// A task pose without solution, measures or forces.
    #[error("task pose failed: {0}")]
    TaskPose(TaskPoseFailure),
    #[error("parallel singularity: inv_cond {inv_cond:.4} < {min}")]
    Parallel { inv_cond: f64, min: f64 },
    #[error("serial singularity: measure {measure:.4} < {min}")]
    Serial { measure: f64, min: f64 },
    /// |force| over the task above the bound, N.
    #[error("|{quantity}| {value:.2} > {max} N")]
    Force {
        quantity: String,
        value: f64,
        max: f64,
    },
    /// |torque| over the task above the bound, N m.
    #[error("|{quantity}| {value:.3} > {max} N m")]
    Torque {
        quantity: String,
        value: f64,
        max: f64,
    },
    /// Spherical-joint tilt above the bound, deg.
    #[error("{quantity} {value:.2} > {max} deg")]
    Tilt {
        quantity: String,
        value: f64,
        max: f64,
    },
    /// RSPR leg shorter than the actuator's shortest length, mm.
    #[error("{quantity} min {value:.2} < {min} mm (min_length_mm)")]
    ShortLeg {
        quantity: String,
        value: f64,
        min: f64,
    },
    /// RSPR leg longer than the actuator's longest length, mm.
    #[error("{quantity} max {value:.2} > {max} mm (min_length_mm + stroke_mm)")]
    LongLeg {
        quantity: String,
        value: f64,
        max: f64,
    },
    /// A joint angle over the chains outside its open range, deg.
    #[error("{group} {min:.1}..{max:.1} outside ({low}, {high})")]
    OpenRange {
        group: String,
        min: f64,
        max: f64,
        low: f64,
        high: f64,
    },
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
    pub rejected: Option<Rejection>,
}

/// The dimension names of a robot kind, in `dims_mm` order.
pub fn dim_names(kind: RobotKind) -> &'static [&'static str] {
    match kind {
        RobotKind::Rspr => &["e_mm", "rb_mm", "rp_mm", "hc_mm"],
        RobotKind::Usr => &["e_mm", "rp_mm", "l1_mm", "l2_mm", "hc_mm"],
    }
}

/// The robot of a kind with dimensions in mm ([`dim_names`] order).
pub fn robot_of(kind: RobotKind, d: &[f64]) -> Result<Robot<f64>, RobotOfError> {
    let m: Vec<f64> = d.iter().map(|&x| mm_to_m(x)).collect();
    match (kind, m.as_slice()) {
        (RobotKind::Rspr, &[e, rb, rp, hc]) => RsprGeometry::new(e, rb, rp, hc)
            .map(Robot::Rspr)
            .map_err(RobotOfError::Geometry),
        (RobotKind::Usr, &[e, rp, l1, l2, hc]) => UsrGeometry::new(e, rp, l1, l2, hc)
            .map(Robot::Usr)
            .map_err(RobotOfError::Geometry),
        _ => Err(RobotOfError::Dimensions {
            kind,
            given: d.len(),
        }),
    }
}

/// The envelope volume of [`Candidate::envelope_volume_cm3`].
pub fn envelope_volume_cm3(robot: &Robot<f64>) -> Result<f64, RangesError> {
    let hc_mm = m_to_mm(robot.hc());
    let pose = pose_from_edge(&POSE, [0.0, 0.0, hc_mm, 0.0, 0.0, 0.0])?;
    let sol = inverse(robot, &pose, Branch::OUTER).map_err(RangesError::CentralPose)?;
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
pub fn check(kind: RobotKind, r: &Ranges, req: &Requirements) -> Option<Rejection> {
    if let Some(f) = r.failures.first() {
        return Some(Rejection::TaskPose(*f));
    }
    if r.parallel_inv_cond_min < req.min_parallel_inv_cond {
        return Some(Rejection::Parallel {
            inv_cond: r.parallel_inv_cond_min,
            min: req.min_parallel_inv_cond,
        });
    }
    if r.serial_relative_min < req.min_serial {
        return Some(Rejection::Serial {
            measure: r.serial_relative_min,
            min: req.min_serial,
        });
    }
    let t = |q: &str| r.get(q, "task").filter(|q| q.poses > 0);
    for name in quantity_names(kind) {
        let Some(q) = t(&name) else { continue };
        let abs = q.min.abs().max(q.max.abs());
        let bad = if name.starts_with('f') && name.ends_with("_n") {
            (abs > req.max_force_n).then(|| Rejection::Force {
                quantity: name.clone(),
                value: abs,
                max: req.max_force_n,
            })
        } else if name.ends_with("_nm") {
            (abs > req.max_torque_nm).then(|| Rejection::Torque {
                quantity: name.clone(),
                value: abs,
                max: req.max_torque_nm,
            })
        } else if name.starts_with("tilt") {
            (q.max > req.max_tilt_deg).then(|| Rejection::Tilt {
                quantity: name.clone(),
                value: q.max,
                max: req.max_tilt_deg,
            })
        } else if kind == RobotKind::Rspr && name.starts_with('l') && name.ends_with("_mm") {
            let longest = req.min_length_mm + req.stroke_mm;
            if req.min_length_mm > 0.0 && q.min < req.min_length_mm {
                Some(Rejection::ShortLeg {
                    quantity: name.clone(),
                    value: q.min,
                    min: req.min_length_mm,
                })
            } else if req.stroke_mm > 0.0 && q.max > longest {
                Some(Rejection::LongLeg {
                    quantity: name.clone(),
                    value: q.max,
                    max: longest,
                })
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
                return Some(Rejection::OpenRange {
                    group: group.clone(),
                    min: q.min,
                    max: q.max,
                    low: *lo,
                    high: *hi,
                });
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
                rejected: Some(e.into()),
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
            rejected: Some(e.into()),
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
/// order of `dims`. `progress` is called once per robot evaluated (from the workers).
pub fn scan(
    kind: RobotKind,
    dims: Vec<Vec<f64>>,
    task: &TaskBox,
    req: &Requirements,
    jobs: usize,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<Candidate>, SynthError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(SynthError::Threads)?;
    Ok(pool.install(|| {
        dims.into_par_iter()
            .map(|d| {
                let c = candidate(kind, d, task, req);
                progress();
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

/// Runs `synth` for `kind`: every robot of `dims` (the grid of the task's scan ranges,
/// [`grid`]) evaluated over `st`'s task on `jobs` threads (0 = every core), `progress`
/// called once per robot; writes `synth.csv`, `admissible.csv` and `admissible.md` to
/// `out` (default `target/design/synth`). `source` names the task in the output. Returns
/// the summary to print.
pub fn run(
    st: &SynthTask,
    kind: RobotKind,
    dims: Vec<Vec<f64>>,
    source: &str,
    jobs: usize,
    out: Option<&Path>,
    progress: &(dyn Fn() + Sync),
) -> Result<String, SynthError> {
    let k = st.kind(kind);
    let started = std::time::Instant::now();
    let found = scan(kind, dims, &st.task, &k.requirements, jobs, progress)?;
    let seconds = started.elapsed().as_secs_f64();
    let dir = out_dir(out, "synth")?;
    let all_path = dir.join("synth.csv");
    let names = quantity_names(kind);
    let rows: Vec<Vec<String>> = found.iter().map(|c| scan_row(c, &names)).collect();
    write_csv(&all_path, &scan_header(kind, &names), &rows)?;
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
    write_text(&md_path, &markdown(kind, &best, &title))?;
    let mut text = summary(st, kind, source, &found, &best, seconds);
    for p in [all_path, csv_path, md_path] {
        let _ = writeln!(text, "  wrote {}", p.display());
    }
    Ok(text)
}

/// The columns of `synth.csv`: the dimensions, the verdict, the margins and each
/// quantity's range over the task.
fn scan_header(kind: RobotKind, names: &[String]) -> Vec<String> {
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
    for n in names {
        header.push(format!("{n}_min"));
        header.push(format!("{n}_max"));
    }
    header
}

/// A candidate's row of `synth.csv` (empty fields where it was not evaluated).
fn scan_row(c: &Candidate, names: &[String]) -> Vec<String> {
    let mut r: Vec<String> = c.dims_mm.iter().map(|&x| fixed(x, 3)).collect();
    r.push(fixed(c.envelope_volume_cm3, 3));
    r.push(c.rejected.is_none().to_string());
    r.push(
        c.rejected
            .as_ref()
            .map(ToString::to_string)
            .unwrap_or_default(),
    );
    match &c.ranges {
        Some(g) => {
            r.push(fixed(g.parallel_inv_cond_min, 6));
            r.push(fixed(g.serial_relative_min, 6));
        }
        None => r.extend([String::new(), String::new()]),
    }
    for n in names {
        match c.ranges.as_ref().and_then(|g| g.get(n, "task")) {
            Some(q) if q.poses > 0 => {
                r.push(fixed(q.min, 4));
                r.push(fixed(q.max, 4));
            }
            _ => r.extend([String::new(), String::new()]),
        }
    }
    r
}

/// The summary to print: the counts and the rate, the task, the reference robot's verdict
/// and the ten smallest admissible robots.
fn summary(
    st: &SynthTask,
    kind: RobotKind,
    source: &str,
    found: &[Candidate],
    best: &[&Candidate],
    seconds: f64,
) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "synth ({kind:?}, task {source}): {} robots scanned, {} admissible, {:.1} s ({:.1} robots/s)",
        found.len(),
        best.len(),
        seconds,
        found.len() as f64 / seconds.max(1e-9)
    );
    let [bx, by, bz] = st.task.box_mm;
    let [nx, ny, nz] = st.task.grid;
    let _ = writeln!(
        text,
        "task: {bx} x {by} x {bz} mm box at [0, 0, hc] on a {nx} x {ny} x {nz} grid, platform parallel and {:+} deg about [1,1,0]",
        st.task.tilt_deg
    );
    if let Some(c) = reference_of(kind, found) {
        let _ = match &c.rejected {
            None => writeln!(text, "the reference robot is admissible"),
            Some(why) => writeln!(text, "the reference robot is NOT admissible: {why}"),
        };
    }
    for (k, c) in best.iter().enumerate().take(10) {
        let dims: Vec<String> = dim_names(kind)
            .iter()
            .zip(&c.dims_mm)
            .map(|(n, v)| format!("{n} {v}"))
            .collect();
        let _ = writeln!(
            text,
            "  {:>3}. {} ({:.0} cm^3)",
            k + 1,
            dims.join(", "),
            c.envelope_volume_cm3
        );
    }
    text
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
