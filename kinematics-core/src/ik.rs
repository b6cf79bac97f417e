//! Inverse kinematics, generic over the robot: all 8 branches (thesis 6.2 and 6.3).

use crate::branch::Branch;
use crate::chain::{Chain, PerChain};
use crate::mechanism::{ChainSolution, IkFailure, Mechanism, PlatformChain};
use crate::pose::Pose;
use crate::scalar::Real;
use crate::vectors::Joints;
use core::fmt;

/// An inverse-kinematics failure, naming the chain and the reason.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IkError {
    /// The chain that failed (chain 1 for a non-finite pose).
    pub chain: Chain,
    /// Why.
    pub reason: IkFailure,
}

impl fmt::Display for IkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.chain, self.reason)
    }
}

/// A full inverse-kinematics solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution<T: Real> {
    /// The pose solved for.
    pub pose: Pose<T>,
    /// The branch solved on.
    pub branch: Branch,
    /// Per-chain solutions.
    pub chains: PerChain<ChainSolution<T>>,
}

impl<T: Real> Solution<T> {
    /// An all-zero placeholder (identity rotation) to be filled by [`inverse_into`].
    pub fn zeroed(branch: Branch) -> Self {
        let z = ChainSolution::zeroed();
        Solution {
            pose: Pose::central(T::zero()),
            branch,
            chains: PerChain([z, z, z]),
        }
    }
    /// The joint vector in q order: `[qa_1, qa_2, qa_3, qb_1, qb_2, qb_3]`.
    pub fn q(&self) -> Joints<T> {
        let [c1, c2, c3] = &self.chains.0;
        Joints::new(c1.qa, c2.qa, c3.qa, c1.qb, c2.qb, c3.qb)
    }
}

/// The platform-side quantities of a chain at a pose (Eq. 6.1-6.7), as the robot defines
/// them ([`Mechanism::platform_chain`]).
#[inline]
pub fn platform_chain<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    pose: &Pose<T>,
    chain: Chain,
) -> PlatformChain<T> {
    m.platform_chain(pose, chain)
}

/// Inverse kinematics on one branch. Fails with the chain and the reason; never returns
/// non-finite joints.
pub fn inverse<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    pose: &Pose<T>,
    branch: Branch,
) -> Result<Solution<T>, IkError> {
    let mut sol = Solution::zeroed(branch);
    inverse_into(m, pose, branch, &mut sol)?;
    Ok(sol)
}

/// [`inverse`] writing into `out` (on the control path: a solution is ~300 bytes, and
/// building it in place saves the copies a returned value costs on the Cortex-M4). On
/// failure `out` holds a partial solution that must not be used.
pub fn inverse_into<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    pose: &Pose<T>,
    branch: Branch,
    out: &mut Solution<T>,
) -> Result<(), IkError> {
    if !pose.is_finite() {
        return Err(IkError {
            chain: Chain::One,
            reason: IkFailure::NonFiniteInput,
        });
    }
    out.pose = *pose;
    out.branch = branch;
    for (chain, slot) in Chain::ALL.into_iter().zip(out.chains.0.iter_mut()) {
        let pc = platform_chain(m, pose, chain);
        m.chain_ik(chain, &pc, branch.is_set(chain), slot)
            .map_err(|reason| IkError { chain, reason })?;
        if !(slot.qa.is_finite() && slot.qb.is_finite() && slot.leg.is_finite()) {
            return Err(IkError {
                chain,
                reason: IkFailure::NonFiniteInput,
            });
        }
    }
    Ok(())
}
