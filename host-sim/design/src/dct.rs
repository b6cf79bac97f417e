//! The planar circle-triangle mechanism of the double circular-triangular robot (thesis
//! Appendix A, sections 2.3 and 3.3, Fig. 3.2): a stationary circle, a moving triangle, and
//! three sliders whose pivots the actuators drive along the circle while the triangle's
//! sides slide through them. Inverse kinematics (two roots per slider), direct kinematics
//! (closed form, two assembly modes) and the planar Jacobian by virtual work.
//!
//! # Geometry (what the appendix leaves to its figure)
//!
//! - The circle: centre o_c at the origin of the mechanism's plane, radius `rc` (Table 4.1's
//!   Rb, Rp).
//! - The triangle: equilateral, side `side` (Table 4.1's Lb, Lp), centre o_t = p, turned
//!   by ψ. Side i has the outward unit normal n_i = [cos(ψ + ξ_i), sin(ψ + ξ_i)],
//!   ξ_i = 2π(i-1)/3, and lies at the inradius r = side/(2√3) from p; x_i = z × n_i runs
//!   along it.
//! - Slider i: a pivot at t_i = rc [cos φ_i, sin φ_i] on the circle, the actuated joint
//!   φ_i; side i slides through it, so t_i lies on side i's line:
//!   (t_i - p)·n_i = r.
//! - The actuator's coordinate is the arc length q_i = rc φ_i (m) and its effort τ_i the
//!   force along the circle (N), so that τ·q̇ is power.
//!
//! # Inverse kinematics
//!
//! rc cos(φ_i - ψ - ξ_i) = r + p·n_i, so φ_i = ψ + ξ_i ± acos((r + p·n_i)/rc): two roots
//! per slider; a clear branch bit takes +, a set one -.
//!
//! # Direct kinematics
//!
//! The three normals sum to zero, so the sum of the three constraints eliminates p:
//! Σ t_i·n_i = 3r, i.e. A cos ψ + B sin ψ = 3r/rc with A = Σ cos(φ_i - ξ_i),
//! B = Σ sin(φ_i - ξ_i): ψ = atan2(B, A) ± acos(3r / (rc √(A² + B²))), two assembly
//! modes; p then solves n_i·p = t_i·n_i - r (least squares over the three, consistent by
//! construction).
//!
//! # Jacobian (derived by virtual work; corrects Eq. 11)
//!
//! Differentiating the constraint with ṫ_i = φ̇_i z × t_i and ṅ_i = ψ̇ x_i:
//! s_i q̇_i = n_i·ṗ + a_i ψ̇, with s_i = n_i·(z × t̂_i) (the cosine between the side's
//! normal and the circle's tangent) and a_i = ((t_i - p) × n_i)·z. So
//! J̄ = dq/dx has rows [n_ix, n_iy, a_i] / s_i (x = [p; ψ]), and virtual work,
//! τ·q̇ = w·ẋ for the force and moment w = [f_t; T_t] the triangle exerts, gives
//! τ = J̄⁻ᵀ w (Eq. 12). The appendix's Eq. 11 reads c_i = (x̂_ti·x̂_0)(x̂_ti·(ẑ_0 × t̂_i)),
//! d_i = (x̂_ti·ŷ_0)(x̂_ti·(x̂_0 × t̂_i)), e_i = a_i x̂_ti·(ẑ_0 × t̂_i): with x̂_ti = n_i
//! (the direction a slider transmits force, perpendicular to the side) and P_ti = o_c - o_t
//! its a_i is the one above, but (1) d_i's second factor is identically zero (x̂_0 × t̂_i
//! is along ẑ_0, perpendicular to the plane), where it must be the same s_i as c_i's, and
//! (2) the rows are multiplied by s_i where virtual work divides by it. At s_i = 0 (the side
//! tangent to the circle, where the two roots of slider i meet) the slider is serially
//! singular. The tests check J̄ against finite differences of the inverse kinematics and
//! τ·q̇ = w·ẋ.

// `!(x <= limit)` is deliberate, as in `kinematics-core`: unlike `x > limit` it is also
// true for NaN, so a NaN can never pass a check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use nalgebra::{Matrix3, Vector2, Vector3};
use thiserror::Error;

/// The planar mechanism's dimensions, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Planar {
    /// Radius of the stationary circle.
    pub rc: f64,
    /// Side of the equilateral moving triangle.
    pub side: f64,
}

/// A pose of the triangle in its plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanarPose {
    /// Centre o_t (m).
    pub p: Vector2<f64>,
    /// Rotation ψ (rad).
    pub psi: f64,
}

/// Why the planar mechanism has no solution.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum PlanarError {
    #[error("circle radius {rc} m and triangle side {side} m must be finite and > 0")]
    Dimensions { rc: f64, side: f64 },
    #[error("non-finite pose or joints")]
    NonFinite,
    #[error("slider {slider}: side {slider} does not cross the circle (|cos| = {cos:.6} > 1)")]
    NoRoot { slider: usize, cos: f64 },
    #[error("slider {slider} is serially singular (side tangent to the circle, s = {s:.3e})")]
    SerialSingular { slider: usize, s: f64 },
    #[error("the sliders' positions admit no triangle (|cos| = {cos:.6} > 1)")]
    NoAssembly { cos: f64 },
    #[error("the planar Jacobian is singular (parallel singularity)")]
    ParallelSingular,
}

const XI: [f64; 3] = [
    0.0,
    2.0 * std::f64::consts::PI / 3.0,
    4.0 * std::f64::consts::PI / 3.0,
];

impl Planar {
    /// Checked dimensions.
    pub fn new(rc: f64, side: f64) -> Result<Self, PlanarError> {
        if rc.is_finite() && side.is_finite() && rc > 0.0 && side > 0.0 {
            Ok(Planar { rc, side })
        } else {
            Err(PlanarError::Dimensions { rc, side })
        }
    }

    /// The triangle's inradius side/(2√3).
    pub fn inradius(&self) -> f64 {
        self.side / (2.0 * 3f64.sqrt())
    }

    /// The outward normal of side i at rotation ψ.
    pub fn normal(psi: f64, i: usize) -> Vector2<f64> {
        let a = psi + XI[i % 3];
        Vector2::new(a.cos(), a.sin())
    }

    /// The slider pivot t_i at joint angle φ_i.
    pub fn pivot(&self, phi: f64) -> Vector2<f64> {
        Vector2::new(phi.cos(), phi.sin()) * self.rc
    }

    /// Inverse kinematics: the joint angles φ_i (rad) on a branch (bit i-1 set: the minus
    /// root of slider i).
    pub fn inverse(&self, x: &PlanarPose, branch: u8) -> Result<[f64; 3], PlanarError> {
        if !(x.p.iter().all(|v| v.is_finite()) && x.psi.is_finite()) {
            return Err(PlanarError::NonFinite);
        }
        let r = self.inradius();
        let mut phi = [0.0; 3];
        for (i, out) in phi.iter_mut().enumerate() {
            let n = Self::normal(x.psi, i);
            let cos = (r + x.p.dot(&n)) / self.rc;
            if !(cos.abs() <= 1.0) {
                return Err(PlanarError::NoRoot { slider: i + 1, cos });
            }
            let sign = if branch & (1 << i) == 0 { 1.0 } else { -1.0 };
            *out = x.psi + XI[i] + sign * cos.acos();
        }
        Ok(phi)
    }

    /// Direct kinematics: both assembly modes (ψ from the summed constraint, p by least
    /// squares over the three sides).
    pub fn direct(&self, phi: &[f64; 3]) -> Result<[PlanarPose; 2], PlanarError> {
        if !phi.iter().all(|v| v.is_finite()) {
            return Err(PlanarError::NonFinite);
        }
        let r = self.inradius();
        let (mut a, mut b) = (0.0, 0.0);
        for (f, xi) in phi.iter().zip(XI) {
            a += (f - xi).cos();
            b += (f - xi).sin();
        }
        let rho = a.hypot(b);
        let cos = 3.0 * r / (self.rc * rho);
        if !(cos.abs() <= 1.0) {
            return Err(PlanarError::NoAssembly { cos });
        }
        let base = b.atan2(a);
        let d = cos.acos();
        let pose_at = |psi: f64| {
            // Normal equations of n_i·p = t_i·n_i - r.
            let mut rhs = Vector2::zeros();
            for (i, f) in phi.iter().enumerate() {
                let n = Self::normal(psi, i);
                rhs += n * (self.pivot(*f).dot(&n) - r);
            }
            // Σ n nᵀ = 3/2 I for three unit normals 120 deg apart: always invertible.
            PlanarPose {
                p: rhs * (2.0 / 3.0),
                psi,
            }
        };
        Ok([pose_at(base + d), pose_at(base - d)])
    }

    /// The Jacobian J̄ = dq/dx (q the arc lengths rc φ_i, x = [p; ψ]) at a pose and its
    /// joints (module documentation).
    pub fn jacobian(&self, x: &PlanarPose, phi: &[f64; 3]) -> Result<Matrix3<f64>, PlanarError> {
        let mut j = Matrix3::zeros();
        for (i, f) in phi.iter().enumerate() {
            let n = Self::normal(x.psi, i);
            let t = self.pivot(*f);
            let tangent = Vector2::new(-f.sin(), f.cos());
            let s = n.dot(&tangent);
            if !(s.abs() > 1e-9) {
                return Err(PlanarError::SerialSingular { slider: i + 1, s });
            }
            let d = t - x.p;
            let a = d.x * n.y - d.y * n.x; // ((t_i - p) × n_i)·z
            let row = Vector3::new(n.x, n.y, a) / s;
            j.set_row(i, &row.transpose());
        }
        Ok(j)
    }

    /// The sliders' forces τ = J̄⁻ᵀ w for the force [fx, fy] (N) and moment T (N m) the
    /// triangle exerts (Eq. 12).
    pub fn efforts(
        &self,
        x: &PlanarPose,
        phi: &[f64; 3],
        w: &Vector3<f64>,
    ) -> Result<Vector3<f64>, PlanarError> {
        let j = self.jacobian(x, phi)?;
        j.transpose()
            .lu()
            .solve(w)
            .filter(|t| t.iter().all(|v| v.is_finite()))
            .ok_or(PlanarError::ParallelSingular)
    }
}
