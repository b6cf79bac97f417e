//! The synthesis task file: the task box, and per robot kind the scan ranges of the
//! characteristic dimensions and the bounds a candidate must meet. A file's keys are laid
//! over the thesis's task (`host-sim/design/tasks/thesis.toml`, embedded) with the one
//! overlay of `robot-config` (unknown keys and values of the wrong type are rejected),
//! then validated; every error names the field (`rspr.max_torque_nm: ...`).

use kinematics_core::RobotKind;
use robot_config::overlay::{overlay, OverlayError};
use robot_config::task_box::{TaskBox, TaskBoxError};
use robot_config::toml_error::TomlError;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A scan range `[from, to, step]` that does not give values.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum RangeError {
    #[error("{field}: every value must be a finite number")]
    NotFinite { field: String },
    #[error("{field}: from = {from} mm must be >= 0")]
    NegativeFrom { field: String, from: f64 },
    #[error("{field}: need [from, to, step] with from <= to and step > 0, at most 1001 values")]
    Shape { field: String },
}

/// A task file (or its text) that cannot be used; names the field.
#[derive(Debug, Error)]
pub enum SynthTaskError {
    /// The embedded thesis task (a defect of the build, not of the user's file).
    #[error("the embedded thesis task: {0}")]
    Thesis(Box<SynthTaskError>),
    /// Not TOML.
    #[error(transparent)]
    Toml(#[from] TomlError),
    /// An unknown key, a value of the wrong type or length.
    #[error(transparent)]
    Overlay(#[from] OverlayError),
    /// The keys do not fit the task's layout.
    #[error("{0}")]
    Layout(toml::de::Error),
    #[error(transparent)]
    Range(#[from] RangeError),
    /// A bound that must be a number > 0 (or >= 0 when `zero_ok`).
    #[error("{field}: {value} is not a number {} 0", if *zero_ok { ">=" } else { ">" })]
    Bound {
        field: &'static str,
        value: f64,
        zero_ok: bool,
    },
    #[error("{field}: need [low, high] with low < high, deg")]
    OpenRange { field: &'static str },
    #[error("task.box_mm[{index}]: {value} is not a length >= 0 mm")]
    BoxLength { index: usize, value: f64 },
    #[error("task.tilt_deg: {0} is not a number")]
    Tilt(f64),
    #[error("task.wrench: every component must be a finite number")]
    Wrench,
    #[error(transparent)]
    Grid(#[from] TaskBoxError),
    #[error("cannot read the task file {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("task file {}: {error}", path.display())]
    InFile {
        path: PathBuf,
        error: Box<SynthTaskError>,
    },
}

/// The thesis's task file, `host-sim/design/tasks/thesis.toml`: the defaults of every task
/// file.
pub const THESIS_TASK_TOML: &str = include_str!("../../tasks/thesis.toml");

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
    /// Open ranges (quantity over the chains as in [`crate::ranges::Ranges::table_columns`], low, high)
    /// that the joint angles must stay strictly inside, deg.
    pub open_ranges_deg: Vec<(String, f64, f64)>,
}

impl Requirements {
    /// The thesis's requirements of a kind: those of `host-sim/design/tasks/thesis.toml`.
    pub fn thesis(kind: RobotKind) -> Result<Self, SynthTaskError> {
        Ok(SynthTask::thesis()?.kind(kind).requirements.clone())
    }
}

/// The scan of one kind: the dimension axes and the requirements.
#[derive(Clone, Debug, PartialEq)]
pub struct KindTask {
    /// The values of each dimension, mm, in [`super::dim_names`] order.
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

/// The values from, from + step, ... <= to of a `[from, to, step]` range.
/// `field` names the range in the error (a task file's key, a flag).
pub fn range_values(field: &str, [from, to, step]: [f64; 3]) -> Result<Vec<f64>, RangeError> {
    let field = || field.to_string();
    if !(from.is_finite() && to.is_finite() && step.is_finite()) {
        return Err(RangeError::NotFinite { field: field() });
    }
    if from < 0.0 {
        return Err(RangeError::NegativeFrom {
            field: field(),
            from,
        });
    }
    if !(step > 0.0 && to >= from && (to - from) / step <= 1000.0) {
        return Err(RangeError::Shape { field: field() });
    }
    let n = ((to - from) / step + 1e-9).floor() as usize + 1;
    Ok((0..n).map(|k| from + step * k as f64).collect())
}

/// A bound that must be a number > 0 (or >= 0 when `zero_ok`), infinity allowed.
fn bound(field: &'static str, v: f64, zero_ok: bool) -> Result<f64, SynthTaskError> {
    let ok = !v.is_nan() && if zero_ok { v >= 0.0 } else { v > 0.0 };
    if ok {
        Ok(v)
    } else {
        Err(SynthTaskError::Bound {
            field,
            value: v,
            zero_ok,
        })
    }
}

/// An open range `[low, high]` with low < high.
fn open_range(field: &'static str, [lo, hi]: [f64; 2]) -> Result<(f64, f64), SynthTaskError> {
    if lo.is_finite() && hi.is_finite() && lo < hi {
        Ok((lo, hi))
    } else {
        Err(SynthTaskError::OpenRange { field })
    }
}

impl SynthTask {
    /// The thesis's task (`host-sim/design/tasks/thesis.toml`).
    pub fn thesis() -> Result<Self, SynthTaskError> {
        Self::parse(THESIS_TASK_TOML).map_err(|e| SynthTaskError::Thesis(Box::new(e)))
    }

    /// A task from the text of a task file: its keys over the thesis's, then validated.
    /// Messages name the field (`rspr.max_torque_nm: ...`).
    pub fn parse(text: &str) -> Result<Self, SynthTaskError> {
        let table = |text: &str| {
            toml::from_str::<toml::Table>(text).map_err(|e| TomlError::located(text, &e))
        };
        let mut base = table(THESIS_TASK_TOML)
            .map_err(|e| SynthTaskError::Thesis(Box::new(SynthTaskError::Toml(e))))?;
        // Every array of the task has the length of the thesis's.
        overlay(&mut base, table(text)?, &[])?;
        let f: TaskFile = base.try_into().map_err(SynthTaskError::Layout)?;
        Self::from_file(f)
    }

    /// Loads and validates a task file; messages name the file and the field.
    pub fn load(path: &Path) -> Result<Self, SynthTaskError> {
        let text = std::fs::read_to_string(path).map_err(|source| SynthTaskError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text).map_err(|e| SynthTaskError::InFile {
            path: path.to_path_buf(),
            error: Box::new(e),
        })
    }

    fn from_file(f: TaskFile) -> Result<Self, SynthTaskError> {
        let t = &f.task;
        for (i, b) in t.box_mm.iter().enumerate() {
            if !(b.is_finite() && *b >= 0.0) {
                return Err(SynthTaskError::BoxLength {
                    index: i,
                    value: *b,
                });
            }
        }
        if !t.tilt_deg.is_finite() {
            return Err(SynthTaskError::Tilt(t.tilt_deg));
        }
        if t.wrench.iter().any(|w| !w.is_finite()) {
            return Err(SynthTaskError::Wrench);
        }
        let grid = TaskBox::grid_from("task.grid", t.grid)?;
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
