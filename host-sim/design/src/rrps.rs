//! The RRPS robot of Alizade, Tagiyev and Duffy (1994), which the thesis compares with the
//! RSPR (section 5.5.2; Appendix A section 4, Fig. 4.4): inverse kinematics, Jacobians and
//! statics, in the same conventions as the RSPR (CONVENTIONS.md). Only `host-sim compare`
//! needs it, so it lives here rather than in the controller's `kinematics-core`; it is
//! generic over the core's scalar like the core (its tests compare f32 with f64).
//!
//! # Geometry of chain i
//!
//! - A first revolute joint (actuated, angle θ_i) about +z0 through the base pivot
//!   e_i = e [cos ξ_i, sin ξ_i, 0]. It turns a horizontal link of length rb whose tip is
//!   b_i = e_i + rb û_i, û_i = [cos(ξ_i + θ_i), sin(ξ_i + θ_i), 0]. θ_i is measured about
//!   +z0 from the radial direction [cos ξ_i, sin ξ_i, 0], wrapped to (-π, π], like the
//!   RSPR's θ_i.
//! - A second revolute joint (passive) at b_i whose axis is horizontal and perpendicular to
//!   the link: â_i = z0 × û_i = [-sin(ξ_i + θ_i), cos(ξ_i + θ_i), 0]. (An axis along the
//!   link would put the leg in the vertical plane through b_i perpendicular to the link,
//!   which the platform points at radius rp < rb cannot reach with e = 0.)
//! - A prismatic leg (actuated, length l_i) from b_i, perpendicular to â_i, i.e. in the
//!   vertical plane through e_i and b_i.
//! - A spherical joint at p_i = t + R pp_i on the platform (pp_i as in CONVENTIONS.md).
//!
//! Joints q = [l_1, l_2, l_3, θ_1, θ_2, θ_3] (lengths first, as the RSPR).
//!
//! # Branches
//!
//! Bit clear ("outer"): the link points towards the horizontal projection of p_i - e_i, so
//! θ_i = 0 at the central configuration; bit set ("inner"): it points away (θ_i ≈ ±π).
//!
//! # Closure equations (per chain)
//!
//! - (R1) (p_i - b_i(θ_i)) · â_i(θ_i) = 0: the leg is perpendicular to the second axis.
//!   Since b_i - e_i = rb û_i ⊥ â_i, (R1) is (p_i - e_i) · â_i(θ_i) = 0: û_i is parallel
//!   to the horizontal part of p_i - e_i, two roots ±.
//! - (R2) l_i = |p_i - b_i|.
//!
//! Differentiating, with ȧ_i = -θ̇_i û_i, ḃ_i = θ̇_i rb â_i, ŝ_i = (p_i - b_i)/l_i and the
//! signed horizontal distance ρ_i = (p_i - e_i) · û_i of p_i from the first axis:
//! - (R1') â_i · ṗ_i = ρ_i θ̇_i,
//! - (R2') ŝ_i · ṗ_i = l̇_i (+ θ̇_i ŝ_i · (z0 × (p_i - e_i)), which is ρ_i ŝ_i · â_i = 0),
//!
//! with ṗ_i = v + ω × (p_i - t). So the tripod Jacobian has the Plücker lines ŝ_i and â_i,
//! both through p_i (the spherical joint transmits a force through p_i in the plane of ŝ_i
//! and â_i: the passive axis â_i through b_i takes no moment), and the serial block is
//! [[1, ŝ_i · (z0 × (p_i - e_i))], [0, â_i · (z0 × (p_i - e_i))]] = [[1, 0], [0, ρ_i]].
//! The chain is serially singular when ρ_i = 0 (p_i on the first axis).

// `!(x > limit)` is deliberate, as in `kinematics-core`: unlike `x <= limit` it is also
// true for NaN, so a NaN can never pass a check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use kinematics_core::jacobian::{serial_singular_tolerance, JacobianError, Jacobians};
use kinematics_core::mechanism::{radial, SerialBlock};
use kinematics_core::scalar::{cross3, lit, Real};
use kinematics_core::statics::{actuator_forces, Statics};
use kinematics_core::{Branch, Chain, ForceError, Joints, PerChain, Pose, Wrench};
use nalgebra::{Matrix6, Vector3};
use thiserror::Error;

/// RRPS dimensions, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RrpsGeometry<T: Real> {
    /// Eccentricity e: distance of the first revolute axes from the base centre (≥ 0).
    pub e: T,
    /// Length rb of the link between the two revolute joints.
    pub rb: T,
    /// Platform radius rp (radius of the circle through the spherical joints).
    pub rp: T,
    /// Central height hc.
    pub hc: T,
}

/// Why one RRPS chain has no inverse-kinematics solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RrpsFailure {
    /// The pose has a non-finite component, or a result was not finite.
    NonFinite,
    /// p_i lies on the first revolute axis: (R1) holds for every θ_i.
    OnPivotAxis,
    /// p_i coincides with the link tip b_i.
    ZeroLengthLeg,
}

impl RrpsFailure {
    /// The reason for people.
    fn describe(self) -> &'static str {
        match self {
            RrpsFailure::NonFinite => "non-finite pose or result",
            RrpsFailure::OnPivotAxis => "spherical joint on the first revolute axis",
            RrpsFailure::ZeroLengthLeg => "zero-length leg",
        }
    }
}

/// An RRPS inverse-kinematics failure, naming the chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Error)]
#[error("{chain}: {}", reason.describe())]
pub struct RrpsIkError {
    /// The chain that failed (chain 1 for a non-finite pose).
    pub chain: Chain,
    /// Why.
    pub reason: RrpsFailure,
}

/// An RRPS geometry that cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum RrpsGeometryError {
    /// A dimension is NaN or infinite.
    #[error("{field} is not finite")]
    NonFinite { field: &'static str },
    /// A dimension is not positive (e: negative).
    #[error("{field} must be positive, got {} mm", value_m * 1e3)]
    NotPositive { field: &'static str, value_m: f64 },
    /// The central configuration cannot be solved on some branch.
    #[error("cannot be assembled in the central configuration on branch {branch}: {error}")]
    NotAssemblable { branch: Branch, error: RrpsIkError },
}

impl<T: Real> RrpsGeometry<T> {
    /// A validated geometry: finite dimensions, e ≥ 0, the others > 0, and the central
    /// configuration solvable on all 8 branches.
    pub fn new(e: T, rb: T, rp: T, hc: T) -> Result<Self, RrpsGeometryError> {
        for (field, v, allow_zero) in [
            ("e", e, true),
            ("rb", rb, false),
            ("rp", rp, false),
            ("hc", hc, false),
        ] {
            if !v.is_finite() {
                return Err(RrpsGeometryError::NonFinite { field });
            }
            let ok = if allow_zero {
                v >= T::zero()
            } else {
                v > T::zero()
            };
            if !ok {
                return Err(RrpsGeometryError::NotPositive {
                    field,
                    value_m: to_f64(v),
                });
            }
        }
        let g = RrpsGeometry { e, rb, rp, hc };
        let central = Pose::central(hc);
        for branch in Branch::ALL {
            rrps_inverse(&g, &central, branch)
                .map_err(|error| RrpsGeometryError::NotAssemblable { branch, error })?;
        }
        Ok(g)
    }

    /// The RRPS of the thesis's comparison (Appendix A, Fig. 4.4): zero eccentricity and
    /// the RSPR prototype's rb = 90, rp = 50, hc = 160 mm. Validated by a test.
    pub fn comparison() -> Self {
        RrpsGeometry {
            e: T::zero(),
            rb: lit(0.090),
            rp: lit(0.050),
            hc: lit(0.160),
        }
    }
}

/// The solution of one RRPS chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RrpsChain<T: Real> {
    /// Base pivot e_i.
    pub e: Vector3<T>,
    /// Link tip b_i (centre of the second revolute joint).
    pub b: Vector3<T>,
    /// Spherical-joint centre p_i on the platform.
    pub p: Vector3<T>,
    /// Unit link direction û_i (horizontal).
    pub u: Vector3<T>,
    /// Unit axis â_i = z0 × û_i of the second revolute joint.
    pub a: Vector3<T>,
    /// Unit leg direction ŝ_i = (p_i - b_i)/l_i.
    pub s: Vector3<T>,
    /// Prismatic length l_i (m).
    pub l: T,
    /// Link angle θ_i (rad), in (-π, π].
    pub theta: T,
    /// Signed horizontal distance ρ_i = (p_i - e_i) · û_i of p_i from the first axis (m).
    pub rho: T,
}

/// A full RRPS inverse-kinematics solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RrpsSolution<T: Real> {
    /// The pose solved for.
    pub pose: Pose<T>,
    /// The branch solved on.
    pub branch: Branch,
    /// Per-chain solutions.
    pub chains: PerChain<RrpsChain<T>>,
}

impl<T: Real> RrpsSolution<T> {
    /// The joints q = [l_1, l_2, l_3, θ_1, θ_2, θ_3].
    pub fn q(&self) -> Joints<T> {
        let [c1, c2, c3] = &self.chains.0;
        Joints::new(c1.l, c2.l, c3.l, c1.theta, c2.theta, c3.theta)
    }
}

fn chain_ik<T: Real>(
    g: &RrpsGeometry<T>,
    pose: &Pose<T>,
    chain: Chain,
    inner: bool,
) -> Result<RrpsChain<T>, RrpsFailure> {
    let eps = T::default_epsilon() * lit(64.0);
    let radial = radial::<T>(chain);
    // Eq. 6.7: p_i = t + R pp_i; Eq. 6.2: e_i.
    let p = pose.t + pose.r * (radial * g.rp);
    let e = radial * g.e;
    let d = p - e;
    // (R1): û_i ∥ ±(horizontal part of p_i - e_i).
    let h = (d.x * d.x + d.y * d.y).sqrt();
    if !(h > eps * g.rb) {
        return Err(RrpsFailure::OnPivotAxis);
    }
    let sign = if inner { -T::one() } else { T::one() };
    let u = Vector3::new(d.x, d.y, T::zero()) * (sign / h);
    let a = z_cross(&u);
    let b = e + u * g.rb;
    // (R2): l_i = |p_i - b_i|.
    let leg = p - b;
    let l = leg.norm();
    if !(l > eps * g.rb) {
        return Err(RrpsFailure::ZeroLengthLeg);
    }
    let c = RrpsChain {
        e,
        b,
        p,
        u,
        a,
        s: leg / l,
        l,
        theta: yaw_from(&radial, &u),
        rho: d.dot(&u),
    };
    if c.l.is_finite() && c.theta.is_finite() && c.rho.is_finite() {
        Ok(c)
    } else {
        Err(RrpsFailure::NonFinite)
    }
}

/// RRPS inverse kinematics on one branch (closure equations R1, R2 in the module docs).
/// Never returns non-finite joints.
pub fn rrps_inverse<T: Real>(
    g: &RrpsGeometry<T>,
    pose: &Pose<T>,
    branch: Branch,
) -> Result<RrpsSolution<T>, RrpsIkError> {
    if !pose.is_finite() {
        return Err(RrpsIkError {
            chain: Chain::One,
            reason: RrpsFailure::NonFinite,
        });
    }
    let chains = PerChain::try_from_fn(|chain| {
        chain_ik(g, pose, chain, branch.is_set(chain))
            .map_err(|reason| RrpsIkError { chain, reason })
    })?;
    Ok(RrpsSolution {
        pose: *pose,
        branch,
        chains,
    })
}

/// Why the RRPS J = Js⁻¹ Jtilde does not exist: the class's error (serially singular when
/// ρ_i ≈ 0, p_i on the chain's first revolute axis; `relative_det` is |ρ_i|/rb).
pub type RrpsJacobianError = JacobianError;

/// The RRPS Jacobians have the shape of the class's: Jtilde (rows ŝ_i and â_i through
/// p_i), per-chain serial blocks [[1, ŝ·(z0×(p-e))], [0, â·(z0×(p-e))]] and J = Js⁻¹ Jtilde.
pub type RrpsJacobians<T> = Jacobians<T>;

/// The RRPS Jacobians (module docs, R1' and R2').
pub fn rrps_jacobian<T: Real>(
    g: &RrpsGeometry<T>,
    sol: &RrpsSolution<T>,
) -> Result<RrpsJacobians<T>, RrpsJacobianError> {
    let t = sol.pose.t;
    let lines = sol
        .chains
        .map(|_, c| (plucker(&c.s, &(c.p - t)), plucker(&c.a, &(c.p - t))));
    let serial = sol.chains.map(|_, c| {
        // Velocity of p_i when the chain turns about the first axis at unit rate.
        let tip = z_cross(&(c.p - c.e));
        SerialBlock {
            a11: T::one(),
            a12: c.s.dot(&tip),
            a21: T::zero(),
            a22: c.a.dot(&tip),
        }
    });
    let relative = serial.map(|_, b| b.det().abs() / g.rb);
    compose(&lines, &serial, &relative)
}

/// τ = J⁻ᵀ s_e (Eq. 7.10) for the RRPS: the same factorisation as the class's statics
/// ([`kinematics_core::statics::actuator_forces`]: Jtildeᵀ f = s_e by LU, τ = Jsᵀ f);
/// `f1` are the leg forces along ŝ_i, `f2` the forces along â_i.
pub fn rrps_actuator_forces<T: Real>(
    jac: &RrpsJacobians<T>,
    rp: T,
    se: &Wrench<T>,
    min_inv_cond: T,
) -> Result<Statics<T>, ForceError> {
    actuator_forces(jac, rp, se, min_inv_cond)
}

/// A Plücker line [ŝ; m] as a row of Jtilde.
type Line<T> = [T; 6];

/// One Plücker line [ŝ; (x - o_p) × ŝ] with the moment taken about o_p (Eq. 7.13).
fn plucker<T: Real>(s: &Vector3<T>, through_minus_op: &Vector3<T>) -> Line<T> {
    let mo = cross3(through_minus_op, s);
    [s.x, s.y, s.z, mo.x, mo.y, mo.z]
}

/// z0 × v.
fn z_cross<T: Real>(v: &Vector3<T>) -> Vector3<T> {
    Vector3::new(-v.y, v.x, T::zero())
}

/// The angle from `from` to `to` about +z0 (their horizontal parts), in (-π, π].
fn yaw_from<T: Real>(from: &Vector3<T>, to: &Vector3<T>) -> T {
    let cross = from.x * to.y - from.y * to.x;
    let dot = from.x * to.x + from.y * to.y;
    cross.atan2(dot)
}

/// Best-effort conversion to f64 for error messages.
fn to_f64<T: Real>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

/// J = Js⁻¹ Jtilde from the Plücker lines of each chain's two directions (rows i and 3+i of
/// Jtilde, Eq. 7.14) and the serial blocks B_i, refusing a serial singularity (a chain
/// whose dimensionless measure `relative` is at or below the core's tolerance) as the
/// core's Jacobian does.
fn compose<T: Real>(
    lines: &PerChain<(Line<T>, Line<T>)>,
    serial: &PerChain<SerialBlock<T>>,
    relative: &PerChain<T>,
) -> Result<Jacobians<T>, JacobianError> {
    let tol = serial_singular_tolerance::<T>();
    let inv = PerChain::try_from_fn(|chain| {
        let blk = &serial[chain];
        let det = blk.det();
        if !(relative[chain] > tol) || !det.is_finite() {
            return Err(JacobianError::SerialSingular {
                chain,
                relative_det: to_f64(relative[chain]),
            });
        }
        let inv = T::one() / det;
        Ok([blk.a22 * inv, -blk.a12 * inv, -blk.a21 * inv, blk.a11 * inv])
    })?;
    // Row i: [J_qa_i; J_qb_i] = B_i⁻¹ [Jt_i; Jt_{3+i}].
    let mut jtilde = Matrix6::zeros();
    let mut j = Matrix6::zeros();
    for (chain, (a, b)) in lines.iter() {
        let k = &inv[chain];
        let i = chain.index();
        for col in 0..6 {
            jtilde[(i, col)] = a[col];
            jtilde[(3 + i, col)] = b[col];
            j[(i, col)] = k[0] * a[col] + k[1] * b[col];
            j[(3 + i, col)] = k[2] * a[col] + k[3] * b[col];
        }
    }
    Ok(Jacobians {
        jtilde,
        serial: *serial,
        j,
    })
}
