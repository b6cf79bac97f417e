//! The measurement model: what the tracker should see for a row's joints, given the
//! parameters, and its derivatives.
//!
//! For joints q the platform is at X = FK(q) of the robot's geometry; the tracker sees the
//! marker at `base_in_tracker · X · marker_in_platform`. The residual of a row is the
//! predicted minus the measured marker position divided by the tracker's position noise
//! and, for a full-pose row, the rotation vector of predicted · measuredᵀ divided by its
//! rotation noise: whitened, so that rows of either kind weigh by their information.
//!
//! Derivatives: the platform pose depends on the robot's parameters p implicitly through
//! IK_p(X) = q, so dX/dp = −J⁻¹ ∂IK/∂p (J = ∂q/∂x of `kinematics-core`, twist
//! coordinates); ∂IK/∂p and the derivatives of the composition are central differences
//! of closed-form expressions (no iteration inside them).

use crate::measurements::Measurement;
use crate::parameters::{self, Info, COUNT, MARKER, ROBOT, TRACKER};
use crate::rigid::Rigid;
use crate::CalibrationError;
use kinematics_core::{
    forward, inverse, jacobian, Branch, FkConfig, Joints, PerChainGeometry, Pose,
};
use nalgebra::{DMatrix, DVector, Vector3, Vector6};

/// The tracker's measurement noise (one standard deviation per axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    /// Position, m.
    pub position_m: f64,
    /// Orientation (each rotation-vector component), rad.
    pub rotation_rad: f64,
}

impl Default for Noise {
    /// 0.1 mm and 0.05 deg: a good optical tracker.
    fn default() -> Self {
        Noise {
            position_m: 0.1e-3,
            rotation_rad: 0.05f64.to_radians(),
        }
    }
}

/// The model of one set of measurements around a reference.
#[derive(Clone, Debug)]
pub struct Model<'a> {
    /// The robot the deviations are taken from (the nominal one).
    pub reference: PerChainGeometry<f64>,
    /// The reference base pose in the tracker's frame.
    pub base_in_tracker: Rigid,
    /// The reference marker pose in the platform's frame.
    pub marker_in_platform: Rigid,
    /// The tracker's noise (the residuals' weights).
    pub noise: Noise,
    /// The branch the robot runs on.
    pub branch: Branch,
    rows: &'a [Measurement],
    /// FK warm starts, one per row (the reference robot's FK).
    guesses: Vec<Pose<f64>>,
}

/// The robot moved by + and − a step in one of its parameters, and the step.
type MovedRobot = ([PerChainGeometry<f64>; 2], f64);

/// One row's residual, unwhitened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowResidual {
    /// |predicted − measured| marker position, m.
    pub position_m: f64,
    /// Angle of predicted · measuredᵀ, rad (full-pose rows).
    pub rotation_rad: Option<f64>,
}

impl<'a> Model<'a> {
    /// The model of `rows` around `reference`; fails when the reference's FK of a row's
    /// joints fails (the row cannot be from this robot).
    pub fn new(
        reference: PerChainGeometry<f64>,
        base_in_tracker: Rigid,
        marker_in_platform: Rigid,
        noise: Noise,
        rows: &'a [Measurement],
    ) -> Result<Self, CalibrationError> {
        let branch = Branch::OUTER;
        let central = Pose::central(reference.nominal().hc);
        let cfg = FkConfig::default();
        let guesses = rows
            .iter()
            .enumerate()
            .map(|(k, m)| {
                forward(&reference, &m.joints, branch, &central, &cfg)
                    .map(|s| s.pose)
                    .map_err(|error| CalibrationError::Fk { row: k + 1, error })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Model {
            reference,
            base_in_tracker,
            marker_in_platform,
            noise,
            branch,
            rows,
            guesses,
        })
    }

    /// The rows.
    pub fn rows(&self) -> &[Measurement] {
        self.rows
    }

    /// Residual rows in all.
    pub fn residual_count(&self) -> usize {
        self.rows.iter().map(Measurement::rows).sum()
    }

    /// The reference robot's FK pose of each row.
    pub fn reference_poses(&self) -> &[Pose<f64>] {
        &self.guesses
    }

    /// The robot and the two transforms at the deviations `delta`.
    pub fn at(
        &self,
        delta: &[f64],
    ) -> Result<(PerChainGeometry<f64>, Rigid, Rigid), CalibrationError> {
        let g = parameters::geometry(&self.reference, delta).map_err(CalibrationError::Geometry)?;
        Ok((
            g,
            parameters::transform(&self.base_in_tracker, delta, TRACKER),
            parameters::transform(&self.marker_in_platform, delta, MARKER),
        ))
    }

    /// The platform pose of every row at the robot `g` (FK from the warm starts).
    pub fn poses(&self, g: &PerChainGeometry<f64>) -> Result<Vec<Pose<f64>>, CalibrationError> {
        let cfg = FkConfig::default();
        self.rows
            .iter()
            .zip(&self.guesses)
            .enumerate()
            .map(|(k, (m, guess))| {
                forward(g, &m.joints, self.branch, guess, &cfg)
                    .map(|s| s.pose)
                    .map_err(|error| CalibrationError::Fk { row: k + 1, error })
            })
            .collect()
    }

    /// The whitened residual rows of one measurement for a platform pose.
    fn whitened(&self, m: &Measurement, a: &Rigid, x: &Rigid, b: &Rigid, out: &mut [f64]) {
        let p = a.then(x).then(b);
        let dp = (p.t - m.position) / self.noise.position_m;
        for (o, v) in out.iter_mut().zip(dp.iter()) {
            *o = *v;
        }
        if let Some(rot) = m.rotation {
            let measured = nalgebra::Rotation3::from_scaled_axis(rot);
            let dr = crate::rigid::rotation_vector(&(p.r * measured.inverse()))
                / self.noise.rotation_rad;
            for (o, v) in out.iter_mut().skip(3).zip(dr.iter()) {
                *o = *v;
            }
        }
    }

    /// The whitened residuals at `delta`, and the platform poses.
    pub fn residuals(
        &self,
        delta: &[f64],
    ) -> Result<(DVector<f64>, Vec<Pose<f64>>), CalibrationError> {
        let (g, a, b) = self.at(delta)?;
        let poses = self.poses(&g)?;
        let mut r = DVector::zeros(self.residual_count());
        let mut at = 0;
        for (m, x) in self.rows.iter().zip(&poses) {
            let n = m.rows();
            let mut buf = [0.0; 6];
            self.whitened(m, &a, &Rigid::from_pose(x), &b, &mut buf);
            for (k, v) in buf.iter().take(n).enumerate() {
                r[at + k] = *v;
            }
            at += n;
        }
        Ok((r, poses))
    }

    /// Each row's residual at `delta`, in SI.
    pub fn row_residuals(&self, delta: &[f64]) -> Result<Vec<RowResidual>, CalibrationError> {
        let (g, a, b) = self.at(delta)?;
        let poses = self.poses(&g)?;
        Ok(self
            .rows
            .iter()
            .zip(&poses)
            .map(|(m, x)| {
                let p = a.then(&Rigid::from_pose(x)).then(&b);
                RowResidual {
                    position_m: (p.t - m.position).norm(),
                    rotation_rad: m.rotation.map(|r| {
                        crate::rigid::angle(
                            &(p.r * nalgebra::Rotation3::from_scaled_axis(r).inverse()),
                        )
                    }),
                }
            })
            .collect())
    }

    /// The Jacobian of the whitened residuals with respect to the deviations (SI), at
    /// `delta` where the platform poses are `poses`.
    pub fn jacobian(
        &self,
        delta: &[f64],
        poses: &[Pose<f64>],
        infos: &[Info],
    ) -> Result<DMatrix<f64>, CalibrationError> {
        let (g, a, b) = self.at(delta)?;
        let moved = self.moved_robots(&g, delta, infos)?;
        let mut jac = DMatrix::zeros(self.residual_count(), COUNT);
        let mut at = 0;
        for (k, (m, x)) in self.rows.iter().zip(poses).enumerate() {
            let n = m.rows();
            let sol = inverse(&g, x, self.branch)
                .map_err(|error| CalibrationError::Ik { row: k + 1, error })?;
            let jx = jacobian(&g, &sol)
                .map_err(|_| CalibrationError::Singular { row: k + 1 })?
                .j;
            let lu = jx.lu();
            let (dr_dx, dr_dt) = self.residual_derivatives(m, x, &a, &b, delta);
            // dx/dp = −J⁻¹ ∂IK/∂p for each robot parameter.
            for (j, (pair, h)) in moved.iter().enumerate() {
                let dq = self.ik_derivative(pair, *h, x, k + 1)?;
                let dx = lu
                    .solve(&(-dq))
                    .ok_or(CalibrationError::Singular { row: k + 1 })?;
                for i in 0..n {
                    let mut s = 0.0;
                    for (c, row) in dr_dx.iter().enumerate() {
                        s += row[i] * dx[c];
                    }
                    jac[(at + i, j)] = s;
                }
            }
            for (c, row) in dr_dt.iter().enumerate() {
                for i in 0..n {
                    jac[(at + i, TRACKER + c)] = row[i];
                }
            }
            at += n;
        }
        Ok(jac)
    }

    /// The robot `g` (at `delta`) moved by ± a thousandth of each robot parameter's
    /// tolerance, with that step.
    fn moved_robots(
        &self,
        g: &PerChainGeometry<f64>,
        delta: &[f64],
        infos: &[Info],
    ) -> Result<Vec<MovedRobot>, CalibrationError> {
        let mut moved = Vec::with_capacity(ROBOT);
        for (j, info) in infos.iter().enumerate().take(ROBOT) {
            let h = info.scale * 1e-3;
            let mut d = delta.to_vec();
            let mut pair = [*g, *g];
            for (slot, sign) in pair.iter_mut().zip([1.0, -1.0]) {
                if let Some(x) = d.get_mut(j) {
                    *x = delta.get(j).copied().unwrap_or(0.0) + sign * h;
                }
                *slot = parameters::geometry(&self.reference, &d)
                    .map_err(CalibrationError::Geometry)?;
            }
            moved.push((pair, h));
        }
        Ok(moved)
    }

    /// The derivatives of row `m`'s whitened residuals at platform pose `x`, by central
    /// differences: with respect to the platform's twist (one row of six per twist
    /// coordinate), and to the tracker's and the marker's transforms (six each, in
    /// parameter order).
    fn residual_derivatives(
        &self,
        m: &Measurement,
        x: &Pose<f64>,
        a: &Rigid,
        b: &Rigid,
        delta: &[f64],
    ) -> ([[f64; 6]; 6], [[f64; 6]; 12]) {
        let xr = Rigid::from_pose(x);
        let eval = |a: &Rigid, x: &Rigid, b: &Rigid| {
            let mut buf = [0.0; 6];
            self.whitened(m, a, x, b, &mut buf);
            buf
        };
        let hx = 1e-6;
        let mut dr_dx = [[0.0; 6]; 6];
        let mut dr_dt = [[0.0; 6]; 12];
        for c in 0..6 {
            let mut d = Vector6::zeros();
            d[c] = hx;
            let (dv, dw) = (
                Vector3::new(d[0], d[1], d[2]),
                Vector3::new(d[3], d[4], d[5]),
            );
            let plus = x.displaced(&dv, &dw);
            let minus = x.displaced(&(-dv), &(-dw));
            let (rp, rm) = (
                eval(a, &Rigid::from_pose(&plus), b),
                eval(a, &Rigid::from_pose(&minus), b),
            );
            for i in 0..6 {
                dr_dx[c][i] = (rp[i] - rm[i]) / (2.0 * hx);
            }
            let mut dd = [0.0; 6];
            dd[c] = hx;
            let neg: [f64; 6] = dd.map(|v| -v);
            for (t, base, first) in [
                (0usize, &self.base_in_tracker, 0usize),
                (1, &self.marker_in_platform, 0),
            ] {
                let off = if t == 0 { TRACKER } else { MARKER };
                let cur = parameters::transform(base, delta, off);
                let plus = parameters::transform(&cur, &dd, first);
                let minus = parameters::transform(&cur, &neg, first);
                let (rp, rm) = if t == 0 {
                    (eval(&plus, &xr, b), eval(&minus, &xr, b))
                } else {
                    (eval(a, &xr, &plus), eval(a, &xr, &minus))
                };
                for i in 0..6 {
                    dr_dt[t * 6 + c][i] = (rp[i] - rm[i]) / (2.0 * hx);
                }
            }
        }
        (dr_dx, dr_dt)
    }

    /// ∂IK/∂p at platform pose `x` for one robot parameter, by central differences
    /// between the robots of `pair` (± `h`); the link angles' differences wrapped.
    fn ik_derivative(
        &self,
        pair: &[PerChainGeometry<f64>; 2],
        h: f64,
        x: &Pose<f64>,
        row: usize,
    ) -> Result<Joints<f64>, CalibrationError> {
        let angular = [false, false, false, true, true, true];
        let qp = inverse(&pair[0], x, self.branch).map(|s| s.q());
        let qm = inverse(&pair[1], x, self.branch).map(|s| s.q());
        let (Ok(qp), Ok(qm)) = (qp, qm) else {
            return Err(CalibrationError::Singular { row });
        };
        let mut dq: Joints<f64> = Joints::zeros();
        for i in 0..6 {
            let d = qp[i] - qm[i];
            dq[i] = if angular[i] {
                kinematics_core::scalar::wrap_angle(d)
            } else {
                d
            } / (2.0 * h);
        }
        Ok(dq)
    }
}

/// First estimates of the two transforms from the reference robot's poses: the base in
/// the tracker by fitting points (Kabsch), the marker on the platform by least squares,
/// alternately, starting from the marker's `marker_guess` (its drawing, or the identity).
pub fn initial_transforms(
    poses: &[Pose<f64>],
    rows: &[Measurement],
    marker_guess: Rigid,
) -> Result<(Rigid, Rigid), CalibrationError> {
    let full = rows.iter().all(|m| m.rotation.is_some());
    let mut b = marker_guess;
    let mut a = Rigid::identity();
    for _ in 0..20 {
        let predicted: Vec<Vector3<f64>> = poses.iter().map(|x| x.r * b.t + x.t).collect();
        let measured: Vec<Vector3<f64>> = rows.iter().map(|m| m.position).collect();
        a = crate::rigid::fit_points(&predicted, &measured).ok_or(CalibrationError::Degenerate)?;
        if full {
            // R_B: the chordal mean of (R_A R_X)ᵀ R_M.
            let mut sum = nalgebra::Matrix3::zeros();
            for (x, m) in poses.iter().zip(rows) {
                let rm = nalgebra::Rotation3::from_scaled_axis(m.rotation.unwrap_or_default());
                sum += ((a.r * x.r).inverse() * rm).matrix();
            }
            b.r = nalgebra::Rotation3::from_matrix(&sum);
        }
        // t_B: R_X t_B = R_Aᵀ (m − t_A) − t_X, least squares over the rows.
        let mut lhs = nalgebra::Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        for (x, m) in poses.iter().zip(rows) {
            let y = a.r.inverse() * (m.position - a.t) - x.t;
            let rx = x.r.matrix();
            lhs += rx.transpose() * rx;
            rhs += rx.transpose() * y;
        }
        b.t = lhs.lu().solve(&rhs).ok_or(CalibrationError::Degenerate)?;
    }
    Ok((a, b))
}
