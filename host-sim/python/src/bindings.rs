//! The Python module `rspr` over [`crate::analysis`]: sequences of numbers in (lists,
//! tuples, NumPy arrays: anything iterable), plain Python objects out (floats, lists,
//! dicts), each error a Python exception whose text is the Rust error's.
//!
//! A method that takes a pose takes one (six numbers) or many (an N x 6 array or a list of
//! rows) and answers one result or a list of N. With `errors="none"` a row that fails
//! gives None instead of raising.

use crate::analysis::{self, AnalysisError, CheckValues, SingularityValues};
use crate::design_tools::{self, CompareSettings, DesignToolError, WorkspaceSettings};
use design::ranges::quantity_names;
use design::synth::dim_names;
use kinematics_core::{Branch, Mechanism, Robot, RobotKind};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use pyo3::IntoPyObjectExt;
use robot_config::edge::joint_columns;
use robot_config::selection::{kind_name, BuiltinRobot, SelectedLimits, SelectedRobot};
use robot_config::verdict::Check;
use std::path::PathBuf;

pyo3::create_exception!(
    rspr,
    RsprError,
    PyValueError,
    "Base of the errors of `rspr`; its text is the Rust error's."
);
pyo3::create_exception!(
    rspr,
    InputError,
    RsprError,
    "An input that is not a pose, joints, wrench or branch (shape, NaN, range)."
);
pyo3::create_exception!(
    rspr,
    GeometryError,
    RsprError,
    "A robot or geometry file that is invalid."
);
pyo3::create_exception!(
    rspr,
    IkError,
    RsprError,
    "The pose has no inverse kinematics on the branch."
);
pyo3::create_exception!(
    rspr,
    FkError,
    RsprError,
    "The forward kinematics did not converge."
);
pyo3::create_exception!(
    rspr,
    JacobianError,
    RsprError,
    "The Jacobian cannot be formed (serial singularity) or conditioned."
);
pyo3::create_exception!(
    rspr,
    ForcesError,
    RsprError,
    "The actuator forces are unbounded (parallel singularity) or the wrench is invalid."
);
pyo3::create_exception!(
    rspr,
    SingularityError,
    RsprError,
    "The singularity analysis did not converge."
);
pyo3::create_exception!(
    rspr,
    DesignError,
    RsprError,
    "A design tool (workspace, synthesis, comparison) cannot run: its settings, task file, \
     robot or limits."
);

fn to_py(e: AnalysisError) -> PyErr {
    let text = e.to_string();
    match e {
        AnalysisError::Input(_) => InputError::new_err(text),
        AnalysisError::Guards(_) => GeometryError::new_err(text),
        AnalysisError::Design(_) => DesignError::new_err(text),
        AnalysisError::Ik(_) => IkError::new_err(text),
        AnalysisError::Fk(_) => FkError::new_err(text),
        AnalysisError::Jacobian(_) | AnalysisError::Conditioning(_) => JacobianError::new_err(text),
        AnalysisError::Forces(_) => ForcesError::new_err(text),
        AnalysisError::Singularity(_) => SingularityError::new_err(text),
    }
}

/// The six numbers of `obj`, named `what` in messages.
fn six(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 6]> {
    let mut out = [0.0; 6];
    let mut n = 0usize;
    for item in obj.try_iter().map_err(|_| {
        InputError::new_err(format!(
            "{what}: expected 6 numbers, got {}",
            type_name(obj)
        ))
    })? {
        let item = item?;
        let v: f64 = item.extract().map_err(|_| {
            InputError::new_err(format!(
                "{what}: element {n} is not a number ({})",
                type_name(&item)
            ))
        })?;
        if let Some(slot) = out.get_mut(n) {
            *slot = v;
        }
        n += 1;
    }
    if n != 6 {
        return Err(InputError::new_err(format!(
            "{what}: expected 6 numbers, got {n}"
        )));
    }
    Ok(out)
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// One row of six numbers, or many: (rows, whether many were given).
fn rows(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<[f64; 6]>, bool)> {
    let items: Vec<Bound<'_, PyAny>> = obj
        .try_iter()
        .map_err(|_| {
            InputError::new_err(format!(
                "{what}: expected 6 numbers or rows of 6, got {}",
                type_name(obj)
            ))
        })?
        .collect::<PyResult<_>>()?;
    let many = items
        .first()
        .is_some_and(|first| first.extract::<f64>().is_err());
    if !many {
        return Ok((vec![six(obj, what)?], false));
    }
    let rows = items
        .iter()
        .enumerate()
        .map(|(i, row)| six(row, &format!("{what} row {i}")))
        .collect::<PyResult<_>>()?;
    Ok((rows, true))
}

/// Whether a failed row raises or gives None.
fn raises(errors: &str) -> PyResult<bool> {
    match errors {
        "raise" => Ok(true),
        "none" => Ok(false),
        other => Err(InputError::new_err(format!(
            "errors: expected \"raise\" or \"none\", got {other:?}"
        ))),
    }
}

fn branch(bits: i64) -> PyResult<Branch> {
    analysis::branch(bits).map_err(to_py)
}

/// One RSPR or USR robot: the built-in reference robots or a geometry file of the command
/// line (`host-sim/robot-config/geometry/`). Poses are x_mm, y_mm, z_mm, rx_deg, ry_deg,
/// rz_deg (rotation vector in degrees); joints in q order (RSPR l1_mm..l3_mm,
/// theta1_deg..theta3_deg; USR alpha1_deg..alpha3_deg, beta1_deg..beta3_deg); Jacobians,
/// wrenches and forces in SI.
#[pyclass(frozen, name = "Robot", module = "rspr")]
pub struct PyRobot {
    robot: Robot<f64>,
    source: String,
    limits: SelectedLimits,
    /// The guards of `robot` with `limits` on every branch.
    guards: Check,
}

fn design_err(e: DesignToolError) -> PyErr {
    to_py(e.into())
}

/// The limits of a file (the command line's `--limits`), else the reference limits.
fn limits_of(path: Option<PathBuf>) -> PyResult<SelectedLimits> {
    match path {
        Some(p) => SelectedLimits::from_file(&p).map_err(|e| GeometryError::new_err(e.to_string())),
        None => Ok(SelectedLimits::reference()),
    }
}

impl PyRobot {
    fn of(s: SelectedRobot, limits: SelectedLimits) -> Self {
        PyRobot {
            guards: analysis::guards(&s.robot, &limits.limits),
            robot: s.robot,
            source: s.source,
            limits,
        }
    }
}

impl PyRobot {
    /// Applies `f` to each pose row; one result or a list.
    fn each<'py, T>(
        &self,
        py: Python<'py>,
        poses: &Bound<'py, PyAny>,
        what: &str,
        errors: &str,
        f: impl Fn(&Robot<f64>, [f64; 6]) -> Result<T, AnalysisError>,
        out: impl Fn(Python<'py>, T) -> PyResult<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let raise = raises(errors)?;
        let (rows, many) = rows(poses, what)?;
        if !many {
            let [row] = rows.as_slice() else {
                return Err(InputError::new_err(format!("{what}: no row")));
            };
            return out(py, f(&self.robot, *row).map_err(to_py)?);
        }
        let list = PyList::empty(py);
        for (i, row) in rows.iter().enumerate() {
            match f(&self.robot, *row) {
                Ok(v) => list.append(out(py, v)?)?,
                Err(e) if raise => {
                    let text = format!("row {i}: {e}");
                    let err = to_py(e);
                    return Err(PyErr::from_type(err.get_type(py), text));
                }
                Err(_) => list.append(py.None())?,
            }
        }
        Ok(list.into_any())
    }
}

fn list6<'py>(py: Python<'py>, v: [f64; 6]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyList::new(py, v)?.into_any())
}

fn matrix<'py>(py: Python<'py>, m: [[f64; 6]; 6]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyList::new(py, m.iter().map(|r| r.to_vec()))?.into_any())
}

#[pymethods]
impl PyRobot {
    /// A built-in robot: "rspr" (the chapter 11 prototype: e 20, rb 90, rp 50, hc 160 mm)
    /// or "usr" (Appendix A: e 30, rp 30, l1 60, l2 80, hc 80 mm).
    /// `limits`: a limits file (TOML, the command line's `--limits`) for the guards; the
    /// reference limits when None.
    #[new]
    #[pyo3(signature = (kind = "rspr", limits = None))]
    fn new(kind: &str, limits: Option<PathBuf>) -> PyResult<Self> {
        let which = match kind {
            "rspr" => BuiltinRobot::Rspr,
            "usr" => BuiltinRobot::Usr,
            other => {
                return Err(GeometryError::new_err(format!(
                    "robot: expected \"rspr\" or \"usr\", got {other:?}"
                )))
            }
        };
        Ok(PyRobot::of(
            SelectedRobot::builtin(which),
            limits_of(limits)?,
        ))
    }

    /// The robot of a geometry file (TOML, mm; the command line's `--geometry`), with the
    /// limits of `limits` (the reference limits when None).
    #[staticmethod]
    #[pyo3(signature = (path, limits = None))]
    fn from_file(path: PathBuf, limits: Option<PathBuf>) -> PyResult<Self> {
        let s =
            SelectedRobot::from_file(&path).map_err(|e| GeometryError::new_err(e.to_string()))?;
        Ok(PyRobot::of(s, limits_of(limits)?))
    }

    /// Where the guards' limits came from.
    #[getter]
    fn limits_source(&self) -> &str {
        &self.limits.source
    }

    /// The robot's dimensions in mm (RSPR e, rb, rp, hc; USR e, rp, l1, l2, hc; a
    /// per-chain RSPR: rp and hc only), by name.
    #[getter]
    fn dims_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let mm = |x: f64| x * 1e3;
        match &self.robot {
            Robot::Rspr(g) => {
                for (k, v) in [
                    ("e_mm", g.e),
                    ("rb_mm", g.rb),
                    ("rp_mm", g.rp),
                    ("hc_mm", g.hc),
                ] {
                    d.set_item(k, mm(v))?;
                }
            }
            Robot::Usr(g) => {
                for (k, v) in [
                    ("e_mm", g.e),
                    ("rp_mm", g.rp),
                    ("l1_mm", g.l1),
                    ("l2_mm", g.l2),
                    ("hc_mm", g.hc),
                ] {
                    d.set_item(k, mm(v))?;
                }
            }
            other => {
                d.set_item("rp_mm", mm(other.rp()))?;
                d.set_item("hc_mm", mm(other.hc()))?;
            }
        }
        Ok(d)
    }

    /// "RSPR" or "USR".
    #[getter]
    fn kind(&self) -> &'static str {
        kind_name(self.robot.kind())
    }

    /// Where the robot came from.
    #[getter]
    fn source(&self) -> &str {
        &self.source
    }

    /// The joint names in q order, with their units.
    #[getter]
    fn joint_names(&self) -> Vec<&'static str> {
        joint_columns(self.robot.kind()).to_vec()
    }

    /// Platform radius rp in mm.
    #[getter]
    fn rp_mm(&self) -> f64 {
        self.robot.rp() * 1e3
    }

    /// Height of the central configuration hc in mm.
    #[getter]
    fn hc_mm(&self) -> f64 {
        self.robot.hc() * 1e3
    }

    fn __repr__(&self) -> String {
        format!("rspr.Robot({}: {})", self.kind(), self.source)
    }

    /// Inverse kinematics: the joints (mm, deg, q order) of a pose or of each of many
    /// poses on a branch 0..7 (one bit per chain, chain 1 in bit 0; 0 = all outer).
    #[pyo3(signature = (pose, branch = 0, errors = "raise"))]
    fn ik<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        branch: i64,
        errors: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self::branch(branch)?;
        self.each(
            py,
            pose,
            "pose",
            errors,
            |r, p| analysis::ik(r, p, b),
            list6,
        )
    }

    /// Inverse kinematics on every branch: {branch: joints} for the branches that solve
    /// the pose (`ik(pose, branch=b)` says why one does not).
    fn ik_branches<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let p = six(pose, "pose")?;
        let d = PyDict::new(py);
        for (b, r) in Branch::ALL
            .iter()
            .zip(analysis::ik_branches(&self.robot, p))
        {
            if let Ok(q) = r {
                d.set_item(b.bits(), q.to_vec())?;
            }
        }
        Ok(d)
    }

    /// Forward kinematics: {"pose": [x_mm..rz_deg], "iterations": n} of joints (mm, deg,
    /// q order) on a branch, by Newton's method from `initial` (a pose; default the
    /// central configuration).
    #[pyo3(signature = (joints, branch = 0, initial = None))]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        joints: &Bound<'py, PyAny>,
        branch: i64,
        initial: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let q = six(joints, "joints")?;
        let init = initial.map(|p| six(p, "initial")).transpose()?;
        let fk = analysis::fk(&self.robot, q, self::branch(branch)?, init).map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("pose", fk.pose.to_vec())?;
        d.set_item("iterations", fk.iterations)?;
        Ok(d)
    }

    /// The Jacobians: {"j": J = dq/dx (6 x 6, SI, rows in q order, columns [v; w]),
    /// "jtilde": the tripod Jacobian (Eq. 7.14, rows the Plücker lines), "inv_cond": the
    /// inverse condition number of jtilde with its moment columns over rp}.
    #[pyo3(signature = (pose, branch = 0, errors = "raise"))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        branch: i64,
        errors: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self::branch(branch)?;
        self.each(
            py,
            pose,
            "pose",
            errors,
            |r, p| analysis::jacobian(r, p, b),
            |py, v| {
                let d = PyDict::new(py);
                d.set_item("j", matrix(py, v.j)?)?;
                d.set_item("jtilde", matrix(py, v.jtilde)?)?;
                d.set_item("inv_cond", v.inv_cond)?;
                Ok(d.into_any())
            },
        )
    }

    /// The actuator efforts tau = J^-T s_e (SI, q order: RSPR f1_n..f3_n, t1_nm..t3_nm)
    /// that hold the wrench s_e = [fx_n, fy_n, fz_n, tx_nm, ty_nm, tz_nm] the platform
    /// exerts on its environment; refused (ForcesError) below `min_inv_cond`.
    #[pyo3(signature = (pose, wrench, branch = 0, min_inv_cond = analysis::MIN_INV_COND, errors = "raise"))]
    fn forces<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        wrench: &Bound<'py, PyAny>,
        branch: i64,
        min_inv_cond: f64,
        errors: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self::branch(branch)?;
        let se = six(wrench, "wrench")?;
        self.each(
            py,
            pose,
            "pose",
            errors,
            |r, p| analysis::forces(r, p, se, b, min_inv_cond),
            list6,
        )
    }

    /// The singularity analysis of thesis chapter 10, as `host-sim singularity` reports
    /// it: serial measures, the parallel measure, the rank of the six scaled lines, every
    /// circuit with its variety, the residual of each configuration S1..S13, the linear
    /// complex, the twists the platform gains and each chain's serial case.
    #[pyo3(signature = (pose, branch = 0, errors = "raise"))]
    fn singularity<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        branch: i64,
        errors: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self::branch(branch)?;
        let serial_key = match self.robot.kind() {
            RobotKind::Rspr => "serial_mm",
            RobotKind::Usr => "serial_mm2",
        };
        self.each(
            py,
            pose,
            "pose",
            errors,
            |r, p| analysis::singularity(r, p, b),
            |py, v| singularity_dict(py, serial_key, v),
        )
    }

    /// The guards' verdict at a pose or at each of many poses on a branch, as `host-sim
    /// check`: {"ok": no stop-level violation (the supervisor would accept the pose),
    /// "severity": "", "warn" or "stop", "violations": [{"guard", "subject", "value",
    /// "limit", "unit", "severity", "text"}] in the guard's edge unit, "verdict": the
    /// verdict in words (the `guards` column of `ik`)}. A pose without inverse kinematics
    /// is a `reach` violation, not an error.
    #[pyo3(signature = (pose, branch = 0, errors = "raise"))]
    fn check<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        branch: i64,
        errors: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self::branch(branch)?;
        self.each(
            py,
            pose,
            "pose",
            errors,
            |_, p| analysis::check(&self.guards, p, b),
            check_dict,
        )
    }

    /// The workspace scan's admissibility at a pose or at each of many poses on a branch
    /// (`host-sim workspace`: no stop-level violation, the workspace guard excluded): None
    /// when admissible, else the first violation as `guard:subject:value:limit unit`.
    #[pyo3(signature = (pose, branch = 0))]
    fn admissible<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        branch: i64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let adm = design_tools::admissible(&self.robot, &self.limits.limits, self::branch(branch)?)
            .map_err(design_err)?;
        self.each(
            py,
            pose,
            "pose",
            "raise",
            |_, p| {
                analysis::pose(p)?;
                Ok(adm
                    .violation(p)
                    .map(|r| design::workspace::describe_reading(&r)))
            },
            |py, v| v.into_bound_py_any(py),
        )
    }

    /// The workspace of `host-sim workspace`: for each section height hc + z (z_mm = (from,
    /// to, step), mm) at both task orientations (parallel, and tilt_deg about [1,1,0]), the
    /// largest admissible radius rho_max_mm in each direction phi_deg (march by step_mm,
    /// bisection to tol_mm, up to max_radius_mm), and whether the task box's footprint
    /// (box_mm) lies inside; and the verdict on the whole task box on a grid at most 2 mm
    /// apart. {"sections": [...], "task_box": {"inside", "points", "spacing_mm",
    /// "first_violation", "orientation_violations"}}.
    #[pyo3(signature = (z_mm = (-30.0, 30.0, 10.0), phi_step_deg = 5.0, step_mm = 1.0, tol_mm = 0.01, max_radius_mm = 150.0, box_mm = (40.0, 40.0, 20.0), tilt_deg = 20.0, branch = 0))]
    #[allow(clippy::too_many_arguments)]
    fn workspace<'py>(
        &self,
        py: Python<'py>,
        z_mm: (f64, f64, f64),
        phi_step_deg: f64,
        step_mm: f64,
        tol_mm: f64,
        max_radius_mm: f64,
        box_mm: (f64, f64, f64),
        tilt_deg: f64,
        branch: i64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let settings = WorkspaceSettings {
            z_mm: z_mm.into(),
            phi_step_deg,
            step_mm,
            tol_mm,
            max_radius_mm,
            box_mm: box_mm.into(),
            tilt_deg,
            branch: self::branch(branch)?,
        };
        let robot = self.robot;
        let limits = self.limits.limits;
        let w = py
            .detach(|| design_tools::workspace(&robot, &limits, &settings))
            .map_err(design_err)?;
        let d = PyDict::new(py);
        let sections = PyList::empty(py);
        for s in &w.sections {
            let e = PyDict::new(py);
            e.set_item("orientation", s.orientation)?;
            e.set_item("rotation_deg", s.rotation_deg.to_vec())?;
            e.set_item("z_mm", s.z_mm)?;
            e.set_item("phi_deg", s.phi_deg.clone())?;
            e.set_item("rho_max_mm", s.rho_max_mm.clone())?;
            e.set_item("footprint_rays_inside", s.footprint_rays_inside)?;
            e.set_item("footprint_violation", s.footprint_violation.clone())?;
            e.set_item("footprint_inside", s.footprint_inside())?;
            sections.append(e)?;
        }
        d.set_item("sections", sections)?;
        let v = &w.verdict;
        let t = PyDict::new(py);
        t.set_item("inside", v.inside())?;
        t.set_item("points", v.points)?;
        t.set_item("spacing_mm", v.spacing_mm.to_vec())?;
        t.set_item("first_violation", v.first_violation.clone())?;
        t.set_item("orientation_violations", v.orientation_violations.to_vec())?;
        d.set_item("task_box", t)?;
        Ok(d)
    }

    /// The RSPR against the RRPS of Alizade et al. along the thesis's diagonal, as `host-sim
    /// compare`: both with this robot's rb, rp and hc, the RSPR with eccentricity e_mm and
    /// the RRPS with rrps_e_mm (default e_mm), `samples` poses, the wrench, a branch.
    /// {"s", "poses", "rspr_tau", "rrps_tau" (None where a robot fails), "rspr_errors",
    /// "rrps_errors", "rspr_peaks", "rrps_peaks", "rotary_torque" and "leg_force": {"rspr":
    /// {"peak", "mean", "peak_to_peak"}, "rrps": {...}, "reduction": {...}}}; the reduction
    /// is 1 - RSPR/RRPS.
    #[pyo3(signature = (e_mm = 0.0, rrps_e_mm = None, samples = 101, wrench = None, branch = 0))]
    fn compare<'py>(
        &self,
        py: Python<'py>,
        e_mm: f64,
        rrps_e_mm: Option<f64>,
        samples: usize,
        wrench: Option<&Bound<'py, PyAny>>,
        branch: i64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let settings = CompareSettings {
            rspr_e_mm: e_mm,
            rrps_e_mm: rrps_e_mm.unwrap_or(e_mm),
            samples,
            wrench: match wrench {
                Some(w) => six(w, "wrench")?,
                None => CompareSettings::cli().wrench,
            },
            branch: self::branch(branch)?,
        };
        let robot = self.robot;
        let v = py
            .detach(|| design_tools::compare(&robot, &settings))
            .map_err(design_err)?;
        let c = &v.comparison;
        let d = PyDict::new(py);
        d.set_item("rspr_e_mm", settings.rspr_e_mm)?;
        d.set_item("rrps_e_mm", settings.rrps_e_mm)?;
        d.set_item("s", c.rspr.iter().map(|x| x.s).collect::<Vec<_>>())?;
        d.set_item(
            "poses",
            c.rspr.iter().map(|x| x.pose.to_vec()).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "rspr_tau",
            c.rspr
                .iter()
                .map(|x| x.tau.as_ref().ok().map(|t| t.to_vec()))
                .collect::<Vec<_>>(),
        )?;
        d.set_item(
            "rrps_tau",
            c.rrps
                .iter()
                .map(|x| x.tau.as_ref().ok().map(|t| t.to_vec()))
                .collect::<Vec<_>>(),
        )?;
        d.set_item(
            "rspr_errors",
            c.rspr
                .iter()
                .map(|x| x.tau.as_ref().err().map(|e| e.to_string()))
                .collect::<Vec<_>>(),
        )?;
        d.set_item(
            "rrps_errors",
            c.rrps
                .iter()
                .map(|x| x.tau.as_ref().err().map(|e| e.to_string()))
                .collect::<Vec<_>>(),
        )?;
        d.set_item("rspr_peaks", c.rspr_peaks.to_vec())?;
        d.set_item("rrps_peaks", c.rrps_peaks.to_vec())?;
        d.set_item("rotary_torque", group_dict(py, &v.rotary_torque)?)?;
        d.set_item("leg_force", group_dict(py, &v.leg_force)?)?;
        Ok(d)
    }
}

fn readings_dict<'py>(
    py: Python<'py>,
    r: &design::compare::Readings,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("peak", r.peak)?;
    d.set_item("mean", r.mean)?;
    d.set_item("peak_to_peak", r.peak_to_peak)?;
    Ok(d)
}

fn group_dict<'py>(
    py: Python<'py>,
    g: &design_tools::GroupReadings,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rspr", readings_dict(py, &g.rspr)?)?;
    d.set_item("rrps", readings_dict(py, &g.rrps)?)?;
    let [p, m, q] = g.reduction;
    let r = PyDict::new(py);
    r.set_item("peak", p)?;
    r.set_item("mean", m)?;
    r.set_item("peak_to_peak", q)?;
    d.set_item("reduction", r)?;
    Ok(d)
}

fn check_dict<'py>(py: Python<'py>, v: CheckValues) -> PyResult<Bound<'py, PyAny>> {
    let d = PyDict::new(py);
    d.set_item("ok", v.ok)?;
    d.set_item("severity", v.severity)?;
    let list = PyList::empty(py);
    for r in v.violations {
        let e = PyDict::new(py);
        e.set_item("guard", r.guard)?;
        e.set_item("subject", r.subject)?;
        e.set_item("value", r.value)?;
        e.set_item("limit", r.limit)?;
        e.set_item("unit", r.unit)?;
        e.set_item("severity", r.severity)?;
        e.set_item("text", r.text)?;
        list.append(e)?;
    }
    d.set_item("violations", list)?;
    d.set_item("verdict", v.verdict)?;
    Ok(d.into_any())
}

fn robot_kind(kind: &str) -> PyResult<RobotKind> {
    match kind {
        "rspr" => Ok(RobotKind::Rspr),
        "usr" => Ok(RobotKind::Usr),
        other => Err(InputError::new_err(format!(
            "kind: expected \"rspr\" or \"usr\", got {other:?}"
        ))),
    }
}

/// The dimensional synthesis of thesis section 8.2, as `host-sim synth`: every robot of
/// the task's scan ranges (or of `dims`, an N x k array of dimensions in mm: RSPR e, rb,
/// rp, hc; USR e, rp, l1, l2, hc) evaluated over the task against the requirements of
/// its kind, on `jobs` threads (0 = every core). `task`: a task file (TOML; default the
/// thesis's, embedded); e_mm .. hc_mm: (from, to, step) ranges overriding the file's;
/// `grid`: the task box's grid (nx, ny, nz). A list of candidates in scan order:
/// {"dims_mm": {name: mm}, "envelope_volume_cm3", "admissible", "rejected" (the first
/// unmet requirement, as synth.csv), "rank" (by size among the admissible, 1 the smallest,
/// as admissible.csv; None when rejected), "parallel_inv_cond_min", "serial_min",
/// "ranges": {quantity: [min, max]} over the task}.
#[pyfunction]
#[pyo3(signature = (kind = "rspr", dims = None, task = None, e_mm = None, rb_mm = None, rp_mm = None, l1_mm = None, l2_mm = None, hc_mm = None, grid = None, jobs = 0))]
#[allow(clippy::too_many_arguments)]
fn synth<'py>(
    py: Python<'py>,
    kind: &str,
    dims: Option<&Bound<'py, PyAny>>,
    task: Option<PathBuf>,
    e_mm: Option<(f64, f64, f64)>,
    rb_mm: Option<(f64, f64, f64)>,
    rp_mm: Option<(f64, f64, f64)>,
    l1_mm: Option<(f64, f64, f64)>,
    l2_mm: Option<(f64, f64, f64)>,
    hc_mm: Option<(f64, f64, f64)>,
    grid: Option<(usize, usize, usize)>,
    jobs: usize,
) -> PyResult<Bound<'py, PyList>> {
    let kind = robot_kind(kind)?;
    let names = dim_names(kind);
    let given = [
        ("e_mm", e_mm),
        ("rb_mm", rb_mm),
        ("rp_mm", rp_mm),
        ("l1_mm", l1_mm),
        ("l2_mm", l2_mm),
        ("hc_mm", hc_mm),
    ];
    let mut ranges = Vec::new();
    for (name, r) in given {
        let Some((a, b, c)) = r else { continue };
        if !names.contains(&name) {
            return Err(InputError::new_err(format!(
                "{name}: not a dimension of the {} (its dimensions: {})",
                kind_name(kind),
                names.join(", ")
            )));
        }
        ranges.push((name, [a, b, c]));
    }
    if let Some((a, b, c)) = grid {
        if a == 0 || b == 0 || c == 0 {
            return Err(InputError::new_err(format!(
                "grid: ({a}, {b}, {c}) needs at least 1 point along each axis"
            )));
        }
    }
    let st = design_tools::synth_task(kind, task.as_deref(), &ranges, grid.map(<[usize; 3]>::from))
        .map_err(design_err)?;
    let rows = match dims {
        Some(d) => {
            let items: Vec<Bound<'py, PyAny>> = d
                .try_iter()
                .map_err(|_| InputError::new_err("dims: expected rows of dimensions"))?
                .collect::<PyResult<_>>()?;
            let many = items.first().is_some_and(|f| f.extract::<f64>().is_err());
            let rows: Vec<Bound<'py, PyAny>> = if many { items } else { vec![d.clone()] };
            rows.iter()
                .enumerate()
                .map(|(i, r)| {
                    r.try_iter()
                        .and_then(|it| {
                            it.map(|x| x?.extract::<f64>())
                                .collect::<PyResult<Vec<f64>>>()
                        })
                        .map_err(|_| {
                            InputError::new_err(format!("dims row {i}: not a row of numbers"))
                        })
                })
                .collect::<PyResult<Vec<_>>>()?
        }
        None => design_tools::synth_grid(&st, kind),
    };
    let (found, rank) = py
        .detach(|| design_tools::synth(&st, kind, rows, jobs))
        .map_err(design_err)?;
    let quantities = quantity_names(kind);
    let out = PyList::empty(py);
    for (c, r) in found.iter().zip(rank) {
        let d = PyDict::new(py);
        let dm = PyDict::new(py);
        for (n, v) in names.iter().zip(&c.dims_mm) {
            dm.set_item(*n, *v)?;
        }
        d.set_item("dims_mm", dm)?;
        d.set_item("envelope_volume_cm3", c.envelope_volume_cm3)?;
        d.set_item("admissible", c.rejected.is_none())?;
        d.set_item("rejected", c.rejected.as_ref().map(|e| e.to_string()))?;
        d.set_item("rank", r)?;
        d.set_item(
            "parallel_inv_cond_min",
            c.ranges.as_ref().map(|g| g.parallel_inv_cond_min),
        )?;
        d.set_item(
            "serial_min",
            c.ranges.as_ref().map(|g| g.serial_relative_min),
        )?;
        let q = PyDict::new(py);
        if let Some(g) = &c.ranges {
            for n in &quantities {
                if let Some(x) = g.get(n, "task").filter(|x| x.poses > 0) {
                    q.set_item(n, vec![x.min, x.max])?;
                }
            }
        }
        d.set_item("ranges", q)?;
        out.append(d)?;
    }
    Ok(out)
}

fn singularity_dict<'py>(
    py: Python<'py>,
    serial_key: &str,
    v: SingularityValues,
) -> PyResult<Bound<'py, PyAny>> {
    let d = PyDict::new(py);
    d.set_item(serial_key, v.serial.to_vec())?;
    d.set_item("serial_frac", v.serial_frac.to_vec())?;
    d.set_item("parallel_inv_cond", v.parallel_inv_cond)?;
    d.set_item("det_sign", v.det_sign)?;
    d.set_item("nearest", v.nearest)?;
    d.set_item("rank", v.rank)?;
    d.set_item("relative_sigma", v.relative_sigma.to_vec())?;
    let circuits = PyList::empty(py);
    for c in v.circuits {
        let e = PyDict::new(py);
        e.set_item("variety", c.variety)?;
        e.set_item(
            "lines",
            c.lines.iter().map(|&l| u32::from(l)).collect::<Vec<_>>(),
        )?;
        circuits.append(e)?;
    }
    d.set_item("circuits", circuits)?;
    let residuals = PyList::empty(py);
    let holding = PyList::empty(py);
    for r in v.residuals {
        if r.holds {
            holding.append(&r.which)?;
        }
        let e = PyDict::new(py);
        e.set_item("configuration", r.configuration)?;
        e.set_item("residual", r.residual)?;
        e.set_item("which", r.which)?;
        e.set_item("holds", r.holds)?;
        residuals.append(e)?;
    }
    d.set_item("configurations", holding)?;
    d.set_item("residuals", residuals)?;
    d.set_item("complex", v.complex)?;
    let gained = PyList::empty(py);
    for g in v.gained {
        let e = PyDict::new(py);
        e.set_item("twist_scaled", g.twist_scaled.to_vec())?;
        e.set_item("pitch_mm", g.pitch_mm)?;
        e.set_item("axis_mm", g.axis_mm.map(|a| a.to_vec()))?;
        gained.append(e)?;
    }
    d.set_item("gained", gained)?;
    d.set_item("serial_cases", v.serial_cases.to_vec())?;
    Ok(d.into_any())
}

/// The kinematic analysis of the RSPR and USR parallel robots of Simaan's thesis: inverse
/// and forward kinematics, the Jacobians, the actuator forces, the line-geometry
/// singularity classification, the guards' verdict, the workspace, the dimensional
/// synthesis and the RSPR/RRPS comparison, the same code as the `host-sim` command line.
#[pymodule]
mod rspr {
    #[pymodule_export]
    use super::{
        synth, DesignError, FkError, ForcesError, GeometryError, IkError, InputError,
        JacobianError, PyRobot, RsprError, SingularityError,
    };
}
