//! `host-sim synth`: the dimensional synthesis scan of thesis section 8.2. Every robot of a
//! grid of characteristic dimensions (RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc) is
//! evaluated over the task with [`super::ranges::evaluate`] and kept when it meets the
//! design requirements: every task pose solved with the forces computed (no singularity),
//! actuator forces/torques within bounds (RSPR 30 N and 1 N m, USR 2 N m), the
//! spherical-joint tilt within bounds, optionally the RSPR actuator's minimal length and
//! stroke, and on the USR -90 < alpha < 90, 0 < gamma < 90, 0 < delta < 180 deg.
//! The robots are evaluated on worker threads; the output keeps the scan order.

use super::ranges::{evaluate, quantity_names, Ranges};
use super::{out_dir, write_csv};
use crate::task_box::{numbers, TaskBox};
use crate::units::{fixed, mm_to_m};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kinematics_core::{Branch, Robot, RobotKind, RsprGeometry, UsrGeometry};
use std::io::IsTerminal;
use std::path::PathBuf;

/// `host-sim synth`.
#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Eccentricity e: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP", default_value = "10,30,10")]
    pub e_mm: String,
    /// RSPR rotating-link radius rb: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP", default_value = "60,100,10")]
    pub rb_mm: String,
    /// Platform radius rp: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP", default_value = "30,60,10")]
    pub rp_mm: String,
    /// USR lower link l1: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP", default_value = "60,80,10")]
    pub l1_mm: String,
    /// USR upper link l2: from, to, step, mm.
    #[arg(long, value_name = "FROM,TO,STEP", default_value = "60,80,10")]
    pub l2_mm: String,
    /// Central height hc: from, to, step, mm [default: RSPR 120,200,20; USR 60,110,10].
    #[arg(long, value_name = "FROM,TO,STEP")]
    pub hc_mm: Option<String>,
    /// Task grid points along x, y, z.
    #[arg(long, value_name = "NX,NY,NZ", default_value = "5,5,3")]
    pub grid: String,
    /// Largest prismatic force, N (RSPR).
    #[arg(long, value_name = "N", default_value_t = 30.0)]
    pub max_force_n: f64,
    /// Largest actuator torque, N m [default: RSPR 1.0, USR 2.0].
    #[arg(long, value_name = "NM")]
    pub max_torque_nm: Option<f64>,
    /// Largest spherical-joint tilt, deg [default: RSPR 30, USR unbounded].
    #[arg(long, value_name = "DEG")]
    pub max_tilt_deg: Option<f64>,
    /// RSPR: shortest admissible prismatic length over the task, mm (0 = no bound).
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub min_length_mm: f64,
    /// RSPR: largest admissible prismatic stroke (span over the task), mm (0 = no bound).
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub max_stroke_mm: f64,
    /// Smallest inverse condition number of the scaled Jtilde accepted in the task.
    #[arg(long, value_name = "X", default_value_t = 1e-3)]
    pub min_inv_cond: f64,
    /// Worker threads [default: the available parallelism].
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Output directory [default: target/design/synth].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// The design requirements (edge units).
#[derive(Clone, Debug, PartialEq)]
pub struct Requirements {
    pub max_force_n: f64,
    pub max_torque_nm: f64,
    pub max_tilt_deg: f64,
    pub min_length_mm: f64,
    pub max_stroke_mm: f64,
    pub min_inv_cond: f64,
}

impl Requirements {
    /// The thesis's bounds for a robot kind (section 8.2).
    pub fn thesis(kind: RobotKind) -> Self {
        Requirements {
            max_force_n: 30.0,
            max_torque_nm: if kind == RobotKind::Rspr { 1.0 } else { 2.0 },
            max_tilt_deg: if kind == RobotKind::Rspr {
                30.0
            } else {
                f64::INFINITY
            },
            min_length_mm: 0.0,
            max_stroke_mm: 0.0,
            min_inv_cond: 1e-3,
        }
    }
}

/// One scanned robot.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// The dimensions in mm: RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc.
    pub dims_mm: Vec<f64>,
    /// The ranges over the task, when the robot could be evaluated.
    pub ranges: Option<Ranges>,
    /// The first unmet requirement; None when admissible.
    pub rejected: Option<String>,
}

/// The values from, from + step, ... <= to.
pub fn steps(flag: &str, text: &str) -> Result<Vec<f64>, String> {
    let [from, to, step]: [f64; 3] = numbers(flag, text)?;
    if !(step > 0.0 && to >= from && (to - from) / step <= 1000.0) {
        return Err(format!(
            "{flag}: need FROM <= TO and 0 < STEP, at most 1000 values"
        ));
    }
    let n = ((to - from) / step + 1e-9).floor() as usize + 1;
    Ok((0..n).map(|k| from + step * k as f64).collect())
}

/// The dimension names of a robot kind, in `dims_mm` order.
pub fn dim_names(kind: RobotKind) -> &'static [&'static str] {
    match kind {
        RobotKind::Rspr => &["e_mm", "rb_mm", "rp_mm", "hc_mm"],
        RobotKind::Usr => &["e_mm", "rp_mm", "l1_mm", "l2_mm", "hc_mm"],
    }
}

fn robot_of(kind: RobotKind, d: &[f64]) -> Result<Robot<f64>, String> {
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

/// The first unmet requirement of evaluated ranges; None when all are met.
pub fn check(kind: RobotKind, r: &Ranges, req: &Requirements) -> Option<String> {
    if let Some(f) = r.failures.first() {
        return Some(format!("task pose failed: {f}"));
    }
    let t = |q: &str| r.get(q, "task");
    for name in quantity_names(kind) {
        let Some(q) = t(&name) else { continue };
        let abs = q.min.abs().max(q.max.abs());
        let bad = if name.starts_with("f") && name.ends_with("_n") {
            (abs > req.max_force_n).then(|| format!("|{name}| {abs:.2} > {}", req.max_force_n))
        } else if name.ends_with("_nm") {
            (abs > req.max_torque_nm).then(|| format!("|{name}| {abs:.3} > {}", req.max_torque_nm))
        } else if name.starts_with("tilt") {
            (q.max > req.max_tilt_deg)
                .then(|| format!("{name} {:.2} > {}", q.max, req.max_tilt_deg))
        } else if name.starts_with('l') && name.ends_with("_mm") {
            if req.min_length_mm > 0.0 && q.min < req.min_length_mm {
                Some(format!("{name} min {:.2} < {}", q.min, req.min_length_mm))
            } else if req.max_stroke_mm > 0.0 && q.span() > req.max_stroke_mm {
                Some(format!(
                    "{name} span {:.2} > {}",
                    q.span(),
                    req.max_stroke_mm
                ))
            } else {
                None
            }
        } else if kind == RobotKind::Usr {
            let open = |lo: f64, hi: f64| {
                (q.min <= lo || q.max >= hi)
                    .then(|| format!("{name} {:.1}..{:.1} outside ({lo}, {hi})", q.min, q.max))
            };
            if name.starts_with("alpha") {
                open(-90.0, 90.0)
            } else if name.starts_with("gamma") {
                open(0.0, 90.0)
            } else if name.starts_with("delta") {
                open(0.0, 180.0)
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
    None
}

/// Evaluates one robot.
pub fn candidate(
    kind: RobotKind,
    dims_mm: Vec<f64>,
    task: &TaskBox,
    req: &Requirements,
) -> Candidate {
    let wrench = [7.0, 7.0, 7.0, 0.7, 0.7, 0.7];
    let evaluated = robot_of(kind, &dims_mm)
        .and_then(|robot| evaluate(&robot, task, wrench, Branch::OUTER, req.min_inv_cond));
    match evaluated {
        Ok(r) => Candidate {
            rejected: check(kind, &r, req),
            ranges: Some(r),
            dims_mm,
        },
        Err(e) => Candidate {
            dims_mm,
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

/// Evaluates every robot on `jobs` threads; the result keeps the order of `dims`.
pub fn scan(
    kind: RobotKind,
    dims: Vec<Vec<f64>>,
    task: &TaskBox,
    req: &Requirements,
    jobs: usize,
    bar: &ProgressBar,
) -> Vec<Candidate> {
    let jobs = jobs.max(1);
    let chunk = dims.len().div_ceil(jobs).max(1);
    let chunks: Vec<Vec<Vec<f64>>> = dims.chunks(chunk).map(|c| c.to_vec()).collect();
    std::thread::scope(|s| {
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|c| {
                s.spawn(move || {
                    c.into_iter()
                        .map(|d| {
                            let r = candidate(kind, d, task, req);
                            bar.inc(1);
                            r
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .collect()
    })
}

/// Runs `synth` for the kind of the selected robot.
pub fn run(args: &SynthArgs, kind: RobotKind) -> Result<(), String> {
    let hc_default = match kind {
        RobotKind::Rspr => "120,200,20",
        RobotKind::Usr => "60,110,10",
    };
    let hc = steps("--hc-mm", args.hc_mm.as_deref().unwrap_or(hc_default))?;
    let e = steps("--e-mm", &args.e_mm)?;
    let rp = steps("--rp-mm", &args.rp_mm)?;
    let axes = match kind {
        RobotKind::Rspr => vec![e, steps("--rb-mm", &args.rb_mm)?, rp, hc],
        RobotKind::Usr => vec![
            e,
            rp,
            steps("--l1-mm", &args.l1_mm)?,
            steps("--l2-mm", &args.l2_mm)?,
            hc,
        ],
    };
    let mut req = Requirements::thesis(kind);
    req.max_force_n = args.max_force_n;
    if let Some(t) = args.max_torque_nm {
        req.max_torque_nm = t;
    }
    if let Some(t) = args.max_tilt_deg {
        req.max_tilt_deg = t;
    }
    req.min_length_mm = args.min_length_mm;
    req.max_stroke_mm = args.max_stroke_mm;
    req.min_inv_cond = args.min_inv_cond;
    let task = TaskBox::from_flags(&args.grid, "40,40,20", "20")?;
    let dims = grid(&axes);
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
        ProgressStyle::with_template("synth [{bar:40}] {pos}/{len} robots, eta {eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let found = scan(kind, dims, &task, &req, jobs, &bar);
    bar.finish_and_clear();
    let names = quantity_names(kind);
    let mut header: Vec<String> = dim_names(kind).iter().map(|s| s.to_string()).collect();
    header.push("admissible".into());
    header.push("rejected".into());
    for n in &names {
        header.push(format!("{n}_min"));
        header.push(format!("{n}_max"));
    }
    let rows: Vec<Vec<String>> = found
        .iter()
        .map(|c| {
            let mut r: Vec<String> = c.dims_mm.iter().map(|&x| fixed(x, 3)).collect();
            r.push(c.rejected.is_none().to_string());
            r.push(c.rejected.clone().unwrap_or_default());
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
    let p = dir.join("synth.csv");
    write_csv(&p, &header, &rows)?;
    let ok: Vec<&Candidate> = found.iter().filter(|c| c.rejected.is_none()).collect();
    println!(
        "synth ({kind:?}): {} robots scanned, {} admissible (scan order; all in {})",
        found.len(),
        ok.len(),
        p.display()
    );
    for c in ok.iter().take(25) {
        let dims: Vec<String> = dim_names(kind)
            .iter()
            .zip(&c.dims_mm)
            .map(|(n, v)| format!("{n} {v}"))
            .collect();
        println!("  {}", dims.join(", "));
    }
    Ok(())
}
