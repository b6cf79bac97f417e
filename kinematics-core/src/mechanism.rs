//! What a robot must provide so that the generic solvers work on it: the per-chain inverse
//! kinematics and the per-chain block of the serial Jacobian.

use crate::chain::Chain;
use crate::pose::Pose;
use crate::scalar::{axpy3, lit, Real};
use core::fmt;
use nalgebra::Vector3;

/// Whether a joint is a length (m) or an angle (rad); residuals of angles are wrapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Prismatic joint, metres.
    Linear,
    /// Revolute joint, radians.
    Angular,
}

/// The 2×2 block of the serial (instantaneous inverse kinematics) matrix of one chain.
///
/// With `qa` the chain's first joint (RSPR l_i, USR α_i) and `qb` its second (θ_i, β_i):
/// `[ŝ1·ṗ_rel; ŝ2·ṗ_rel] = [[a11, a12], [a21, a22]] [q̇a; q̇b]`, i.e. the rows of
/// Jtilde times the twist equal this block times the joint rates (Eq. 7.16-7.21 for
/// RSPR, Eq. 7.29-7.31 for USR).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SerialBlock<T: Real> {
    pub a11: T,
    pub a12: T,
    pub a21: T,
    pub a22: T,
}

impl<T: Real> SerialBlock<T> {
    /// Determinant of the block; zero at a serial singularity of the chain.
    pub fn det(&self) -> T {
        self.a11 * self.a22 - self.a12 * self.a21
    }
}

/// The platform-side quantities of one chain at a pose, computed once by the generic code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlatformChain<T: Real> {
    /// Upper revolute centre p_i = t + R pp_i (Eq. 6.7).
    pub p: Vector3<T>,
    /// Unit radial direction of the chain on the platform, R pp_i / rp.
    pub u: Vector3<T>,
    /// Unit axis of the upper revolute joint in {0}, R r_i (Eq. 6.4).
    pub m: Vector3<T>,
    /// Platform normal n = R z (Eq. 6.6).
    pub n: Vector3<T>,
    /// Base pivot e_i (Eq. 6.2).
    pub e: Vector3<T>,
    /// Unit radial direction of the chain on the base, [cos ξ_i, sin ξ_i, 0].
    pub radial: Vector3<T>,
}

/// Unit radial direction [cos ξ_i, sin ξ_i, 0] of a chain (Eq. 6.1-6.3).
pub fn radial<T: Real>(chain: Chain) -> Vector3<T> {
    // ξ_i = 0, 120, 240 deg: constants, so that no IK call pays for sin and cos (on the
    // Cortex-M4 libm computes them in software).
    const HALF_SQRT_3: f64 = 0.866_025_403_784_438_6;
    let (c, s) = match chain.xi_thirds() {
        0 => (1.0, 0.0),
        1 => (-0.5, HALF_SQRT_3),
        _ => (-0.5, -HALF_SQRT_3),
    };
    Vector3::new(lit(c), lit(s), T::zero())
}

/// The platform-side quantities of a chain of the symmetric robot of platform radius `rp`
/// and eccentricity `e` at a pose (Eq. 6.1-6.7): the default of
/// [`Mechanism::platform_chain`].
#[inline]
pub fn symmetric_platform_chain<T: Real>(
    rp: T,
    e: T,
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
    PlatformChain {
        p: axpy3(&pose.t, &u, rp), // Eq. 6.7
        u,
        m: m_axis,
        n,                                                      // Eq. 6.6
        e: Vector3::new(radial.x * e, radial.y * e, T::zero()), // Eq. 6.2
        radial,
    }
}

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
    /// Unit axis ŝn_i of the chain's first base joint in {0} (Eq. 7.19): +z0 on the
    /// symmetric RSPR and for the USR's yaw; the rotating link's own axis on a per-chain
    /// geometry ([`crate::chain_geometry`]), whose serial block needs it.
    pub axis: Vector3<T>,
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
            axis: z,
            qa: T::zero(),
            qb: T::zero(),
            gamma: T::zero(),
        }
    }
}

/// A robot of the thesis's class (Fig. 5.14): a tripod of SR dyads on top of three serial
/// chains. Implementors supply only the per-chain pieces.
pub trait Mechanism<T: Real> {
    /// Platform radius rp (m).
    fn rp(&self) -> T;
    /// Eccentricity e (m): distance of the base pivots from the base centre.
    fn e(&self) -> T;
    /// Central height hc (m) of the central configuration.
    fn hc(&self) -> T;
    /// Kinds of the six joints, in q order.
    fn joint_kinds(&self) -> [JointKind; 6];
    /// A characteristic length (m) used to scale tolerances (e.g. rb or l1).
    fn length_scale(&self) -> T;
    /// The platform-side quantities of one chain at a pose (Eq. 6.1-6.7), which
    /// [`Mechanism::chain_ik`] receives. The default is the symmetric robot's, from
    /// [`Mechanism::rp`] and [`Mechanism::e`]; a geometry with per-chain platform joints
    /// and base pivots ([`crate::chain_geometry`]) supplies its own.
    #[inline]
    fn platform_chain(&self, pose: &Pose<T>, chain: Chain) -> PlatformChain<T> {
        symmetric_platform_chain(self.rp(), self.e(), pose, chain)
    }
    /// Inverse kinematics of one chain on the chosen root (`bit_set` = the branch bit),
    /// written into `out` (in place: on the Cortex-M4 a returned solution costs copies
    /// worth more than the computation). On failure `out` must not be used.
    fn chain_ik(
        &self,
        chain: Chain,
        pc: &PlatformChain<T>,
        bit_set: bool,
        out: &mut ChainSolution<T>,
    ) -> Result<(), IkFailure>;
    /// The chain's block of the serial Jacobian at a solution.
    fn serial_block(&self, s: &ChainSolution<T>) -> SerialBlock<T>;
    /// The serial-singularity measure of a chain and its dimensionless form
    /// (RSPR |Cn2_i| in m and as a fraction of rb, Eq. 10.6; USR |Cn1 Cr2 - Cr1 Cn2| in m²
    /// and over l1², Eq. 10.11).
    fn serial_measure(&self, s: &ChainSolution<T>) -> (T, T);
}
