//! The design tools the Python module exposes, in plain Rust over the `design` crate (the
//! functions `host-sim workspace`, `synth` and `compare` run): the workspace's sections
//! and the verdict on the task box, the dimensional synthesis scan, and the RSPR/RRPS
//! comparison along the thesis's diagonal. Settings in edge units (mm, deg, N, N m), as
//! the command line's flags; nothing here writes files or plots.

use design::compare::{compare_along, readings, reductions, Pair, PairError, Readings};
use design::forces_path::{PathSpec, THESIS_WRENCH};
use design::synth::{
    candidate, dim_names, grid, range_values, ranked, scan, Candidate, RangeError, SynthError,
    SynthTask, SynthTaskError,
};
use design::workspace::{
    scan_all, task_box_verdict, Admissible, BoxVerdict, Scan, ScanSettingError, Section,
    WorkspaceError,
};
use kinematics_core::guards::Limits;
use kinematics_core::{Branch, Mechanism, Robot, RobotKind};
use robot_config::task_box::TaskBox;
use robot_config::units::{m_to_mm, mm_to_m};
use std::path::Path;
use thiserror::Error;

/// Why a design tool cannot run: its settings, task file or robot.
#[derive(Debug, Error)]
pub enum DesignToolError {
    /// A workspace scan setting.
    #[error(transparent)]
    Scan(#[from] ScanSettingError),
    /// The workspace's guards.
    #[error("workspace: {0}")]
    Workspace(WorkspaceError),
    /// A scan range of the synthesis.
    #[error(transparent)]
    Range(#[from] RangeError),
    /// The synthesis's task file.
    #[error(transparent)]
    Task(#[from] SynthTaskError),
    /// The synthesis's dimensions of one robot.
    #[error("dims row {row}: expected {expected} dimensions ({names}), got {given}")]
    Dimensions {
        row: usize,
        expected: usize,
        names: String,
        given: usize,
    },
    /// The synthesis's worker threads.
    #[error(transparent)]
    Synth(#[from] SynthError),
    /// The robots of the comparison.
    #[error(transparent)]
    Pair(#[from] PairError),
    /// The comparison is of an RSPR (as `host-sim compare`).
    #[error("compare needs an RSPR geometry (its rb, rp and hc are used with e = 0)")]
    CompareNeedsRspr,
    /// Fewer than two samples along the path.
    #[error("samples: {0} is below 2")]
    Samples(usize),
    /// A value that must be finite.
    #[error(transparent)]
    Field(#[from] robot_config::fields::FieldError),
}

/// The settings of `host-sim workspace` (its flags' defaults in [`WorkspaceSettings::cli`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WorkspaceSettings {
    /// Section heights relative to hc: from, to, step, mm.
    pub z_mm: [f64; 3],
    pub phi_step_deg: f64,
    pub step_mm: f64,
    pub tol_mm: f64,
    pub max_radius_mm: f64,
    /// The task box's edges, mm, and its second orientation's tilt about [1,1,0], deg.
    pub box_mm: [f64; 3],
    pub tilt_deg: f64,
    pub branch: Branch,
}

impl WorkspaceSettings {
    /// The command line's defaults (`host-sim help workspace`).
    pub fn cli() -> Self {
        WorkspaceSettings {
            z_mm: [-30.0, 30.0, 10.0],
            phi_step_deg: 5.0,
            step_mm: 1.0,
            tol_mm: 0.01,
            max_radius_mm: 150.0,
            box_mm: [40.0, 40.0, 20.0],
            tilt_deg: 20.0,
            branch: Branch::OUTER,
        }
    }
}

/// The sections of the workspace at both task orientations and the verdict on the task box
/// (the 2 mm grid of `host-sim workspace`).
#[derive(Clone, Debug, PartialEq)]
pub struct WorkspaceValues {
    pub sections: Vec<Section>,
    pub verdict: BoxVerdict,
}

/// The task box of the settings (the grid is the scan's; `workspace` does not use it).
fn task_box(s: &WorkspaceSettings) -> TaskBox {
    TaskBox {
        grid: [1, 1, 1],
        box_mm: s.box_mm,
        tilt_deg: s.tilt_deg,
    }
}

/// `host-sim workspace` without its files: every section and the verdict.
pub fn workspace(
    robot: &Robot<f64>,
    limits: &Limits<f64>,
    s: &WorkspaceSettings,
) -> Result<WorkspaceValues, DesignToolError> {
    let hc_mm = m_to_mm(robot.hc());
    let task = task_box(s);
    robot_config::fields::finite("tilt_deg", s.tilt_deg)?;
    let scan = Scan::checked(
        hc_mm,
        s.z_mm,
        s.phi_step_deg,
        s.step_mm,
        s.tol_mm,
        s.max_radius_mm,
        &task,
    )?;
    let adm = admissible(robot, limits, s.branch)?;
    Ok(WorkspaceValues {
        sections: scan_all(&adm, &scan, &task),
        verdict: task_box_verdict(&adm, &task, hc_mm, 2.0),
    })
}

/// The workspace scan's admissibility test on a branch.
pub fn admissible(
    robot: &Robot<f64>,
    limits: &Limits<f64>,
    branch: Branch,
) -> Result<Admissible, DesignToolError> {
    Admissible::new(robot, branch, limits).map_err(DesignToolError::Workspace)
}

/// The synthesis's task: the thesis's (embedded) or a task file, with the scan ranges
/// and grid overridden as `host-sim synth`'s flags do (`ranges`: (name, [from, to,
/// step]) with names of [`dim_names`]).
pub fn synth_task(
    kind: RobotKind,
    file: Option<&Path>,
    ranges: &[(&'static str, [f64; 3])],
    task_grid: Option<[usize; 3]>,
) -> Result<SynthTask, DesignToolError> {
    let mut st = match file {
        Some(p) => SynthTask::load(p)?,
        None => SynthTask::thesis()?,
    };
    if let Some(g) = task_grid {
        st.task.grid = g;
    }
    let names = dim_names(kind);
    let k = st.kind_mut(kind);
    for (name, range) in ranges {
        if let Some(axis) = names
            .iter()
            .position(|n| n == name)
            .and_then(|i| k.axes.get_mut(i))
        {
            *axis = range_values(name, *range)?;
        }
    }
    Ok(st)
}

/// The robots of the task's scan ranges, in scan order (first dimension slowest).
pub fn synth_grid(st: &SynthTask, kind: RobotKind) -> Vec<Vec<f64>> {
    grid(&st.kind(kind).axes)
}

/// Every robot of `dims` (mm, [`dim_names`] order) evaluated over the task against its
/// requirements on `jobs` threads (0 = every core), in the order given; the admissible
/// ranked by size as `admissible.csv` ranks them (rank 1 the smallest).
pub fn synth(
    st: &SynthTask,
    kind: RobotKind,
    dims: Vec<Vec<f64>>,
    jobs: usize,
) -> Result<(Vec<Candidate>, Vec<Option<usize>>), DesignToolError> {
    let names = dim_names(kind);
    for (row, d) in dims.iter().enumerate() {
        if d.len() != names.len() {
            return Err(DesignToolError::Dimensions {
                row,
                expected: names.len(),
                names: names.join(", "),
                given: d.len(),
            });
        }
        for (n, v) in names.iter().zip(d) {
            robot_config::fields::finite(n, *v)?;
        }
    }
    let k = st.kind(kind);
    let found = if dims.len() == 1 {
        dims.into_iter()
            .map(|d| candidate(kind, d, &st.task, &k.requirements))
            .collect()
    } else {
        scan(kind, dims, &st.task, &k.requirements, jobs, &|| {})?
    };
    let mut rank = vec![None; found.len()];
    for (r, c) in ranked(&found).iter().enumerate() {
        if let Some(i) = found.iter().position(|x| std::ptr::eq(x, *c)) {
            if let Some(slot) = rank.get_mut(i) {
                *slot = Some(r + 1);
            }
        }
    }
    Ok((found, rank))
}

/// The settings of `host-sim compare`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareSettings {
    /// Eccentricity of the RSPR and of the RRPS, mm (`compare` prints e = 0 on both, and
    /// the robot's e on both and on the RSPR against the RRPS at 0).
    pub rspr_e_mm: f64,
    pub rrps_e_mm: f64,
    pub samples: usize,
    pub wrench: [f64; 6],
    pub branch: Branch,
}

impl CompareSettings {
    /// The command line's defaults: e = 0, 101 samples, the thesis's wrench, branch 0.
    pub fn cli() -> Self {
        CompareSettings {
            rspr_e_mm: 0.0,
            rrps_e_mm: 0.0,
            samples: 101,
            wrench: THESIS_WRENCH,
            branch: Branch::OUTER,
        }
    }
}

/// Peak, mean and peak-to-peak of one group of efforts on each robot, and the reductions
/// 1 - RSPR/RRPS of each.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupReadings {
    pub rspr: Readings,
    pub rrps: Readings,
    /// peak, mean, peak-to-peak.
    pub reduction: [f64; 3],
}

/// The comparison along the diagonal: the samples, the peaks per joint and the readings
/// of the rotary torques and the leg forces.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareValues {
    pub comparison: design::compare::Comparison,
    pub rotary_torque: GroupReadings,
    pub leg_force: GroupReadings,
}

/// `host-sim compare` without its files: the RSPR with `robot`'s rb, rp and hc against the
/// RRPS with the same, at the settings' eccentricities, along the thesis's diagonal.
pub fn compare(robot: &Robot<f64>, s: &CompareSettings) -> Result<CompareValues, DesignToolError> {
    let Robot::Rspr(g) = robot else {
        return Err(DesignToolError::CompareNeedsRspr);
    };
    if s.samples < 2 {
        return Err(DesignToolError::Samples(s.samples));
    }
    let wrench = robot_config::fields::finite_values(&robot_config::fields::WRENCH, s.wrench)?;
    let e_rspr = robot_config::fields::finite("rspr_e_mm", s.rspr_e_mm)?;
    let e_rrps = robot_config::fields::finite("rrps_e_mm", s.rrps_e_mm)?;
    let rspr = Pair::with_eccentricity(mm_to_m(e_rspr), g.rb, g.rp, g.hc)?.rspr;
    let rrps = Pair::with_eccentricity(mm_to_m(e_rrps), g.rb, g.rp, g.hc)?.rrps;
    let pair = Pair { rspr, rrps };
    let spec = PathSpec {
        samples: s.samples,
        wrench,
        branch: s.branch,
        ..PathSpec::thesis_diagonal()
    };
    let c = compare_along(&pair, &spec);
    let group = |range| {
        let (a, b) = readings(&c.rspr, &c.rrps, range);
        GroupReadings {
            rspr: a,
            rrps: b,
            reduction: reductions(&a, &b),
        }
    };
    Ok(CompareValues {
        rotary_torque: group(3..6),
        leg_force: group(0..3),
        comparison: c,
    })
}
