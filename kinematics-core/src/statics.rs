//! Static forces: τ = J⁻ᵀ s_e (Eq. 7.10), computed as Jtildeᵀ f = s_e (Eq. 7.15) by an LU
//! factorisation and τ = Jsᵀ f (Eq. 7.16, 7.20), never with an explicit inverse.

use crate::chain::PerChain;
use crate::jacobian::Jacobians;
use crate::scalar::Real;
use crate::singularity::{parallel_inv_cond, SvdDidNotConverge};
use crate::{Joints, Wrench};
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

/// τ = J⁻ᵀ s_e without the conditioning check, for hints such as the flank a known load
/// presses the lead screws against (still an error when Jtilde is exactly singular or the
/// result is not finite). Guards use [`actuator_forces`].
pub fn joint_efforts<T: Real>(
    jac: &Jacobians<T>,
    se: &Wrench<T>,
) -> Result<Statics<T>, ForceError> {
    forces_with_inv_cond(jac, se, T::one(), T::zero())
}

/// [`actuator_forces`] when the inverse condition number of the scaled Jtilde is already
/// known (the guards compute it once for the singularity measure and the forces).
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
        inv_cond: crate::geometry::to_f64(inv_cond),
        limit: crate::geometry::to_f64(min_inv_cond),
    };
    if !(inv_cond >= min_inv_cond) {
        return Err(singular());
    }
    // Eq. 7.15: [f1; f2] = Jtilde⁻ᵀ s_e, by LU of Jtildeᵀ.
    let f = jac.jtilde.transpose().lu().solve(se).ok_or_else(singular)?;
    if !f.iter().all(|x| x.is_finite()) {
        return Err(singular());
    }
    let f1 = PerChain([f.x, f.y, f.z]);
    let f2 = PerChain([f.w, f.a, f.b]);
    // Eq. 7.16/7.20: τ = Jsᵀ [f1; f2], chain by chain.
    let per = PerChain::from_fn(|c| {
        let blk = &jac.serial[c];
        let (fa, fb) = (f1[c], f2[c]);
        (blk.a11 * fa + blk.a21 * fb, blk.a12 * fa + blk.a22 * fb)
    });
    let [(a1, b1), (a2, b2), (a3, b3)] = per.0;
    Ok(Statics {
        tau: Joints::new(a1, a2, a3, b1, b2, b3),
        f1: Vector3::new(f.x, f.y, f.z),
        f2: Vector3::new(f.w, f.a, f.b),
        inv_cond,
    })
}
