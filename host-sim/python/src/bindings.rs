//! The Python module `rspr` over [`crate::analysis`]: sequences of numbers in (lists,
//! tuples, NumPy arrays: anything iterable), plain Python objects out (floats, lists,
//! dicts), each error a Python exception whose text is the Rust error's.
//!
//! A method that takes a pose takes one (six numbers) or many (an N x 6 array or a list of
//! rows) and answers one result or a list of N. With `errors="none"` a row that fails
//! gives None instead of raising.

use crate::analysis::{self, AnalysisError, SingularityValues};
use kinematics_core::{Branch, Mechanism, Robot, RobotKind};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use robot_config::edge::joint_columns;
use robot_config::selection::{kind_name, BuiltinRobot, SelectedRobot};
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

fn to_py(e: AnalysisError) -> PyErr {
    let text = e.to_string();
    match e {
        AnalysisError::Pose(_) | AnalysisError::Joint { .. } | AnalysisError::Branch(_) => {
            InputError::new_err(text)
        }
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
    #[new]
    #[pyo3(signature = (kind = "rspr"))]
    fn new(kind: &str) -> PyResult<Self> {
        let which = match kind {
            "rspr" => BuiltinRobot::Rspr,
            "usr" => BuiltinRobot::Usr,
            other => {
                return Err(GeometryError::new_err(format!(
                    "robot: expected \"rspr\" or \"usr\", got {other:?}"
                )))
            }
        };
        let s = SelectedRobot::builtin(which);
        Ok(PyRobot {
            robot: s.robot,
            source: s.source,
        })
    }

    /// The robot of a geometry file (TOML, mm; the command line's `--geometry`).
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        let s =
            SelectedRobot::from_file(&path).map_err(|e| GeometryError::new_err(e.to_string()))?;
        Ok(PyRobot {
            robot: s.robot,
            source: s.source,
        })
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
/// and forward kinematics, the Jacobians, the actuator forces and the line-geometry
/// singularity classification, the same code as the `host-sim` command line.
#[pymodule]
mod rspr {
    #[pymodule_export]
    use super::{
        FkError, ForcesError, GeometryError, IkError, InputError, JacobianError, PyRobot,
        RsprError, SingularityError,
    };
}
