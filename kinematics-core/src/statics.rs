//! Static forces: τ = J⁻ᵀ s_e (Eq. 7.10), computed as Jtildeᵀ f = s_e (Eq. 7.15) by an LU
//! factorisation and τ = Jsᵀ f (Eq. 7.16, 7.20), never with an explicit inverse.

use crate::chain::PerChain;
use crate::jacobian::Jacobians;
use crate::lu::Lu6;
use crate::mechanism::SerialBlock;
use crate::scalar::Real;
use crate::singularity::{parallel_inv_cond, SvdDidNotConverge};
use crate::vectors::{Joints, Wrench};
use core::fmt;
use nalgebra::Vector3;

/// Why the actuator forces cannot be computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ForceError {
    /// The wrench has a non-finite component.
    NonFiniteWrench,
    /// Jtilde is singular or too ill-conditioned: the forces would be unbounded.
    ParallelSingular {
        /// The measured inverse condition number.
        inv_cond: f64,
        /// The smallest accepted.
        limit: f64,
    },
    /// The singular-value decomposition did not converge.
    Svd(SvdDidNotConverge),
}

impl fmt::Display for ForceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ForceError::NonFiniteWrench => f.write_str("the wrench has a non-finite component"),
            ForceError::ParallelSingular { inv_cond, limit } => write!(
                f,
                "parallel singularity: inverse condition number {inv_cond:.3e} below {limit:.3e}"
            ),
            ForceError::Svd(e) => write!(f, "{e}"),
        }
    }
}

/// Forces at the actuators and at the spherical joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Statics<T: Real> {
    /// Actuator forces and torques in q order: RSPR [f1_1..3 (N); t_n1..3 (N m)], USR
    /// [t_α1..3; t_β1..3] (N m). f1_i > 0 pushes the platform away from b_i.
    pub tau: Joints<T>,
    /// Force intensities along ŝ1_i (f1 of Eq. 7.15), N.
    pub f1: Vector3<T>,
    /// Force intensities along ŝ2_i (f2 of Eq. 7.15), N.
    pub f2: Vector3<T>,
    /// Inverse condition number of the scaled Jtilde at which they were computed.
    pub inv_cond: T,
}

/// τ = J⁻ᵀ s_e for the wrench `se` the platform exerts on its environment (moment about
/// o_p, in {0}). Refuses configurations whose scaled Jtilde has an inverse condition
/// number below `min_inv_cond`.
pub fn actuator_forces<T: Real>(
    jac: &Jacobians<T>,
    rp: T,
    se: &Wrench<T>,
    min_inv_cond: T,
) -> Result<Statics<T>, ForceError> {
    if !se.iter().all(|x| x.is_finite()) {
        return Err(ForceError::NonFiniteWrench);
    }
    let inv_cond = parallel_inv_cond(&jac.jtilde, rp).map_err(ForceError::Svd)?;
    forces_with_inv_cond(jac, se, inv_cond, min_inv_cond)
}

/// [`actuator_forces`] when the inverse condition number of the scaled Jtilde is already
/// known (the guards compute it once for the singularity measure and the forces; pass
/// `inv_cond` 1 and `min_inv_cond` 0 for a hint that needs no conditioning check, such as
/// the flank a known load presses the lead screws against).
pub fn forces_with_inv_cond<T: Real>(
    jac: &Jacobians<T>,
    se: &Wrench<T>,
    inv_cond: T,
    min_inv_cond: T,
) -> Result<Statics<T>, ForceError> {
    if !se.iter().all(|x| x.is_finite()) {
        return Err(ForceError::NonFiniteWrench);
    }
    let singular = || ForceError::ParallelSingular {
        inv_cond: crate::scalar::to_f64(inv_cond),
        limit: crate::scalar::to_f64(min_inv_cond),
    };
    if !(inv_cond >= min_inv_cond) {
        return Err(singular());
    }
    EffortMap::new(jac)
        .forces(se, inv_cond)
        .ok_or_else(singular)
}

/// Jtilde factorised once, with the serial blocks, for the forces of several wrenches at
/// (nearly) one configuration: each is then one solve (Eq. 7.15) and τ = Jsᵀ f (Eq. 7.16,
/// 7.20). The control path factorises on one tick and solves on the next, so that no
/// tick pays for both (e.g. the flanks a tool's weight presses the lead screws against).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffortMap<T: Real> {
    lu: Option<Lu6<T>>,
    serial: PerChain<SerialBlock<T>>,
}

impl<T: Real> EffortMap<T> {
    /// Factorises Jtilde of `jac` (no conditioning check: see [`actuator_forces`]); the
    /// forces are then a transposed solve.
    pub fn new(jac: &Jacobians<T>) -> Self {
        EffortMap {
            lu: Lu6::new(&jac.jtilde),
            serial: jac.serial,
        }
    }

    /// The forces for the wrench `se` (the moment about o_p, in {0}), recorded with the
    /// inverse condition number `inv_cond` the caller measured; None when Jtilde is
    /// singular, or `se` or the result is not finite.
    pub fn forces(&self, se: &Wrench<T>, inv_cond: T) -> Option<Statics<T>> {
        if !se.iter().all(|x| x.is_finite()) {
            return None;
        }
        let f = self.lu.as_ref()?.solve_transposed(se);
        if !f.iter().all(|x| x.is_finite()) {
            return None;
        }
        // Eq. 7.16/7.20: τ = Jsᵀ [f1; f2], chain by chain.
        let [b1, b2, b3] = &self.serial.0;
        let tau = |blk: &SerialBlock<T>, fa: T, fb: T| {
            (blk.a11 * fa + blk.a21 * fb, blk.a12 * fa + blk.a22 * fb)
        };
        let ((a1, c1), (a2, c2), (a3, c3)) =
            (tau(b1, f.x, f.w), tau(b2, f.y, f.a), tau(b3, f.z, f.b));
        Some(Statics {
            tau: Joints::new(a1, a2, a3, c1, c2, c3),
            f1: Vector3::new(f.x, f.y, f.z),
            f2: Vector3::new(f.w, f.a, f.b),
            inv_cond,
        })
    }
}
