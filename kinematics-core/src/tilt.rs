//! Spherical-joint tilt (CONVENTIONS.md, "Measures"): the socket is fixed to the lower link
//! (it turns with θ_i on the RSPR, with α_i and β_i on the USR). Its axis is the leg
//! direction ŝ1_i at the central configuration of the same branch, expressed in the link's
//! frame; the tilt is the angle between the current ŝ1_i and that axis, both seen from the
//! link: the physical ball-in-socket angle.

use crate::branch::Branch;
use crate::chain::{Chain, PerChain};
use crate::ik::{inverse, platform_chain, IkError, Solution};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::{cross3, dot3, Real};
use nalgebra::Vector3;

/// Components of `v` in the frame of the lower link `lb`: x along the link, y = z0 × x
/// (horizontal), z = x × y. Defined whenever the link is not vertical, which the inverse
/// kinematics guarantees (the RSPR link is horizontal; a vertical USR link fails IK).
fn in_link_frame<T: Real>(lb: &Vector3<T>, v: &Vector3<T>) -> Option<Vector3<T>> {
    let unit = |v: Vector3<T>| {
        let n = crate::scalar::norm3(&v);
        (n > T::default_epsilon()).then(|| Vector3::new(v.x / n, v.y / n, v.z / n))
    };
    let x = unit(*lb)?;
    let y = unit(Vector3::new(-x.y, x.x, T::zero()))?;
    let z = cross3(&x, &y);
    Some(Vector3::new(dot3(v, &x), dot3(v, &y), dot3(v, &z)))
}

/// The socket axes of a robot: for each chain, the axis on the bit-clear and on the
/// bit-set root, in the link frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SocketAxes<T: Real>(pub PerChain<[Vector3<T>; 2]>);

/// The socket axis of one chain on one root: ŝ1_i at the central configuration, in the link
/// frame.
pub fn socket_axis<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    chain: Chain,
    bit_set: bool,
) -> Result<Vector3<T>, IkError> {
    let central = Pose::central(m.hc());
    let pc = platform_chain(m, &central, chain);
    let mut s = crate::mechanism::ChainSolution::zeroed();
    m.chain_ik(chain, &pc, bit_set, &mut s)
        .map_err(|reason| IkError { chain, reason })?;
    in_link_frame(&s.lb, &s.s1).ok_or(IkError {
        chain,
        reason: crate::mechanism::IkFailure::YawUndefined,
    })
}

impl<T: Real> SocketAxes<T> {
    /// Computes the six axes from the central configuration.
    pub fn new<M: Mechanism<T> + ?Sized>(m: &M) -> Result<Self, IkError> {
        // Validates that the whole central configuration exists on every branch too.
        inverse(m, &Pose::central(m.hc()), Branch::OUTER)?;
        Ok(SocketAxes(PerChain::try_from_fn(|c| {
            Ok([socket_axis(m, c, false)?, socket_axis(m, c, true)?])
        })?))
    }
}

/// Tilt of each spherical joint (rad, in [0, π]) at a solution. A chain whose link frame
/// is undefined reports π, the worst tilt, so a guard can never pass it.
pub fn tilt_angles<T: Real>(sol: &Solution<T>, axes: &SocketAxes<T>) -> PerChain<T> {
    PerChain::from_fn(|c| {
        let s = &sol.chains[c];
        let [clear, set] = axes.0[c];
        let axis = if sol.branch.is_set(c) { set } else { clear };
        match in_link_frame(&s.lb, &s.s1) {
            Some(v) => crate::scalar::norm3(&cross3(&v, &axis)).atan2(dot3(&v, &axis)),
            None => T::pi(),
        }
    })
}
