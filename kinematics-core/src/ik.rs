//! Inverse kinematics, generic over the robot: all 8 branches (thesis 6.2 and 6.3).

use crate::branch::Branch;
use crate::chain::{Chain, PerChain};
use crate::mechanism::{radial, Mechanism, PlatformChain};
use crate::pose::Pose;
use crate::scalar::{axpy3, Real};
use crate::Joints;
use core::fmt;
use nalgebra::Vector3;

/// Why one chain has no inverse-kinematics solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkFailure {
    /// The pose has a non-finite component.
    NonFiniteInput,
    /// No real root: the chain cannot reach the platform point (negative discriminant of
    /// Eq. 6.22, or |c| > sqrt(a² + b²) in Eq. 6.32).
    NoRealRoot,
    /// The plane P_i of the leg is parallel to the base plane or the platform stands
    /// perpendicular to the base, so the line v_i of Eq. 6.14 is undefined (RSPR).
    DegeneratePlane,
    /// The coefficients of Eq. 6.28 vanish: every γ_i or none solves the chain (USR).
    DegenerateEquation,
    /// The lower link points straight up or down, so its yaw α_i is undefined (USR).
    YawUndefined,
    /// The spherical joint coincides with the revolute centre (zero-length leg).
    ZeroLengthLeg,
}

impl fmt::Display for IkFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            IkFailure::NonFiniteInput => "non-finite pose",
            IkFailure::NoRealRoot => "no real root (pose out of reach)",
            IkFailure::DegeneratePlane => "degenerate leg plane (platform perpendicular to base)",
            IkFailure::DegenerateEquation => "degenerate chain equation",
            IkFailure::YawUndefined => "lower link vertical, yaw undefined",
            IkFailure::ZeroLengthLeg => "zero-length leg",
        };
        f.write_str(s)
    }
}

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

/// The solution of one chain, with the intermediate points the guards and plots need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainSolution<T: Real> {
    /// Base pivot e_i.
    pub e: Vector3<T>,
    /// Spherical-joint centre b_i.
    pub b: Vector3<T>,
    /// Upper revolute centre p_i.
    pub p: Vector3<T>,
    /// Lower link l_bi = b_i - e_i (RSPR rotating link, USR lower link l_i1).
    pub lb: Vector3<T>,
    /// Unit vector ŝ1_i = (p_i - b_i)/|p_i - b_i| along the tripod link.
    pub s1: Vector3<T>,
    /// |p_i - b_i|: the RSPR prismatic length l_i, or l2 on the USR.
    pub leg: T,
    /// Unit axis ŝ2_i of the upper revolute joint in {0} (the line through b_i).
    pub s2: Vector3<T>,
    /// The chain's first joint: RSPR l_i (m), USR α_i (rad).
    pub qa: T,
    /// The chain's second joint: RSPR θ_i, USR β_i (rad).
    pub qb: T,
    /// USR: rotation γ_i of the upper link about r_i (Eq. 6.25); zero on the RSPR.
    pub gamma: T,
}

impl<T: Real> ChainSolution<T> {
    /// All zero (a placeholder, not a solution).
    pub fn zeroed() -> Self {
        let z = Vector3::zeros();
        ChainSolution {
            e: z,
            b: z,
            p: z,
            lb: z,
            s1: z,
            leg: T::zero(),
            s2: z,
            qa: T::zero(),
            qb: T::zero(),
            gamma: T::zero(),
        }
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

/// The platform-side quantities of a chain at a pose (Eq. 6.1-6.7).
#[inline]
pub fn platform_chain<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    pose: &Pose<T>,
    chain: Chain,
) -> PlatformChain<T> {
    let radial = radial::<T>(chain);
    // r_i = [cos(ξ+π/2), sin(ξ+π/2), 0] = z × radial (Eq. 6.4).
    let r_axis = Vector3::new(-radial.y, radial.x, T::zero());
    // R·radial and R·r_i from the columns of R (both vectors lie in the xy plane); written
    // out because nalgebra's generic product costs ~150 instructions each on the M4.
    let r = pose.r.matrix();
    let col = |a: T, b: T| {
        Vector3::new(
            r.m11 * a + r.m12 * b,
            r.m21 * a + r.m22 * b,
            r.m31 * a + r.m32 * b,
        )
    };
    let u = col(radial.x, radial.y);
    let m_axis = col(r_axis.x, r_axis.y);
    let n = Vector3::new(r.m13, r.m23, r.m33);
    let (rp, e) = (m.rp(), m.e());
    PlatformChain {
        p: axpy3(&pose.t, &u, rp), // Eq. 6.7
        u,
        m: m_axis,
        n,                                                      // Eq. 6.6
        e: Vector3::new(radial.x * e, radial.y * e, T::zero()), // Eq. 6.2
        radial,
    }
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
