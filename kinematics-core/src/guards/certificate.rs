//! Certified regions: one full guard evaluation at a pose c certifies every pose near it.
//!
//! For every stop-level guard g with margin m_g (positive inside, in the guard's unit) this
//! module bounds how fast the margin can change along a straight motion of the platform
//! (translation linear, rotation about a fixed world axis: the supervisor's segments and
//! braking paths): |dm_g/ds| ≤ a_g·|v| + b_g·|ω| for the twist [v; ω] of the motion, the
//! coefficients computed from the geometry in use, the limits and the values at c. Along
//! the straight motion from c to a pose x the twist is constant, |v| = |Δt| and |ω| = θ,
//! the rotation angle of R_x R_cᵀ, so
//!
//! ```text
//!     m_g(x) ≥ m_g(c) - (a_g |Δt| + b_g θ)                                  (1)
//! ```
//!
//! and the **certified region** of c is { x : a_g |Δt| + b_g θ < m_g(c) for every g }.
//!
//! The bounds hold wherever every stop-level guard holds (the safe set S: the stroke is
//! within its range, the platform within the task box and the tilt cone, ...) and where
//! the auxiliary bounds hold (the angle ψ ≤ ψ_max below, which keeps the serial measure
//! |Cn2| ≥ κ, the smallest singular value of the scaled Jtilde ≥ σ_lo, and two more,
//! themselves certified by (1) like guards). Why the
//! region lies in S (the first-exit argument): on the straight motion from c to a pose x of
//! the region, let y be the first pose where a guard or an auxiliary bound fails; before
//! y every bound below holds, so by (1) each margin at y is still positive; the margins are
//! continuous, so none fails at y either: there is no such y.
//!
//! Notation (per chain i; thesis chapter 6 and 7, CONVENTIONS.md): p the upper revolute
//! centre, b the spherical joint, l = |p - b| the leg, ŝ1 = (p - b)/l, ŝ2 = R r_i the upper
//! revolute axis, l_b = b - e (the rotating link, |l_b| = rb), θ the link angle, Cn2 =
//! (ŝ2 × z0)·l_b, written ŝ2·(z0 × l_b) (Eq. 7.21, 10.6), A the scaled Jtilde (moment
//! columns over rp, CONVENTIONS.md measures). The rates, with V_p = |v| + rp|ω|:
//!
//! - ṗ = v + ω × (p - t): |ṗ| ≤ V_p.
//! - θ̇ from the second row of each chain of Jtilde (Eq. 7.16-7.21): Cn2·θ̇ = ŝ2·(v + ω ×
//!   (b - t)), |b - t| ≤ β (auxiliary: β = |b - t| at c + 10 mm, never above l_max + rp,
//!   the bound |b - t| ≤ |b - p| + |p - t|; |d|b - t|| ≤ |ḃ| + |v|), so |θ̇| ≤ Θ = (|v| +
//!   β|ω|)/κ.
//! - ḃ = θ̇ u, u = z0 × l_b: |ḃ| ≤ rb Θ. l̇ ≤ |ṗ - ḃ| ≤ V_p + rb Θ (stroke).
//! - u across ŝ2: with ψ the angle between u and ŝ2 (as lines), Cn2 = ŝ2·u = ±|u| cos ψ
//!   and u = Cn2 ŝ2 + w⊥ with |w⊥| = |u| sin ψ; |u| ≤ rb is constant (l_b turns about z0).
//!   ψ changes at most at |dŝ2| + |du/|u|| ≤ |ω| + Θ. The auxiliary bound ψ ≤ ψ_max =
//!   ψ_c + 0.1 rad (ψ_c the largest over the chains at c; ψ_max < π/2) gives |Cn2| ≥ κ =
//!   |u|_min cos ψ_max and |w⊥|/|Cn2| = tan ψ ≤ k = tan ψ_max, √(1 + k²) = 1/cos ψ_max
//!   (k = tan 0.1 rad ≈ 0.1 where ψ_c = 0, as at the central configuration).
//! - ŝ1 = (p - b)/l: dŝ1 = (I - ŝ1ŝ1ᵀ)(ṗ - ḃ)/l. The leg is normal to the upper revolute
//!   axis (ŝ2·(p - b) = 0, the constraint whose derivative gives θ̇ above), so (ŝ1, ŝ2,
//!   n = ŝ1 × ŝ2) is orthonormal. The ŝ2 part of ṗ - ḃ is -ṡ2·(p - b) = l ω·n (ṡ2 = ω ×
//!   ŝ2); the n part is γ = n·ṗ - θ̇ n·w⊥ = (n - (n·w⊥/Cn2) ŝ2)·v + n·(ω × (p - t)) -
//!   (n·w⊥/Cn2) ŝ2·(ω × (b - t)), and as n ⊥ ŝ2, |γ| ≤ √(1 + k²)|v| + (rp + kβ)|ω| =
//!   |v|/cos ψ_max + (rp + kβ)|ω|. So |dŝ1| ≤ |(|ω|, |γ|/l_min)| (Minkowski, below: the
//!   bound (V_p + rb Θ)/l_min of the triangle inequality is up to 2.7x larger at the
//!   centre). ŝ2 = R r_i: |dŝ2| ≤ |ω|.
//! - the spherical-joint tilt, the angle between ŝ1 and the socket axis fixed to the link
//!   (turning at θ̇ about z0): ≤ |dŝ1| + Θ. The link angle: Θ.
//! - the collision radius (section 11.4), |P_xy| with P = b + ŝ1 (h - b_z)/ŝ1_z (b moves
//!   on a horizontal circle: b_z is constant): |Ṗ| ≤ |ḃ| + 2|h - b_z| |dŝ1|/ŝ1_z², where
//!   ŝ1_z ≥ (p_z,min - b_z)/l_max on S, p_z,min the lowest platform point the task box and
//!   tilt cone allow.
//! - the serial measure Cn2 (Eq. 10.6): |d Cn2| ≤ rb|ω| + rb Θ (relative: over rb).
//! - the task box: |v| per axis; the tilt cone: |ω|.
//! - reach: the inverse kinematics of Eq. 6.22 has a real root while its discriminant is
//!   positive, and the discriminant vanishes exactly where the leg plane touches the link
//!   circle, i.e. where Cn2 = 0 (the circle's tangent z0 × l_b lies in the plane of normal
//!   ŝ2). With |Cn2| ≥ κ > 0 on the motion the root persists (and stays the same branch).
//! - the parallel measure (inverse condition number of A): the rows of A change at most
//!   at r1 = |(|dŝ1|, |ω| + |dŝ1|)| (the ŝ1 lines through p: the direction and the
//!   moment (p - t) × ŝ1 / rp, with |ṗ - v| ≤ rp|ω|) and r2 = |(|ω|, (|v|/cos ψ_max +
//!   (1 + k)β|ω|)/rp)| (the ŝ2 lines through b: the moment (b - t) × ŝ2 / rp changes at
//!   ((ḃ - v) × ŝ2 + (b - t) × ṡ2)/rp, where ḃ × ŝ2 = θ̇ w⊥ × ŝ2 and v × ŝ2 = v⊥ × ŝ2 for
//!   v = v∥ ŝ2 + v⊥: |(ŝ2·v/Cn2) w⊥ × ŝ2 - v⊥ × ŝ2| ≤ k|v∥| + |v⊥| ≤ √(1 + k²)|v|), each
//!   the norm of a pair of rate bounds by the Minkowski inequality (see the efforts
//!   below), so ‖A(x) - A(c)‖_F ≤
//!   δ, the integral of √3·√(r1² + r2²). By Weyl's inequality σ_min(x) ≥ σ_min(c) - δ
//!   and σ_max(x) ≤ σ_max(c) + δ, so the measure stays ≥ the stop level p while
//!   δ ≤ σ_max(c)(ic - p)/(1 + p), ic the measure at c; σ_max(c) is the SVD's (the one that gave ic), and never less
//!   than the largest row norm of A(c), a lower bound of it (≥ 1: each row has a unit
//!   direction part).
//! - the actuator efforts of the declared payload (Eq. 7.10, 7.15, 7.16, 7.20): the line
//!   forces f = A⁻ᵀ D s_e (D s_e = [f_e; m_e/rp]), τ_leg = f1_i, τ_link = a12 f1_i + a22 f2_i
//!   (|a12|, |a22| ≤ rb). With |f| ≤ F (auxiliary, F = 1.5|f(c)| + 1 N) and σ_min(A) ≥
//!   σ_lo = 0.8 σ_min(c) (auxiliary): |ḟ| ≤ (|D ṡ_e| + ‖Ȧ‖ F)/σ_lo, |D ṡ_e| ≤ |ω| |c_p| |f_e|/rp
//!   for a payload force f_e through the platform point c_p. Per chain, τ̇_link = ȧ12 f1 +
//!   ȧ22 f2 + a12 ḟ1 + a22 ḟ2, and by Cauchy-Schwarz on each pair |τ̇_link| ≤
//!   |(ȧ12, ȧ22)| F + √2 rb |ḟ| (|(a12, a22)| ≤ √2 rb, |(ḟ1, ḟ2)| ≤ |ḟ|,
//!   |(f1, f2)| ≤ F), with |ȧ12| ≤ rb(|dŝ1| + Θ), |ȧ22| ≤ rb(|ω| + Θ); the norm of the
//!   pair of rate bounds a·|v| + b·|ω| is bounded by the Minkowski inequality:
//!   |(a1, a2)|·|v| + |(b1, b2)|·|ω|.
//!
//! ψ_max is ψ_c + 0.1 rad and σ_lo 0.8 × the smallest singular value bound at c: each
//! auxiliary bound is one more constraint of the region, with the rest as margin.
//!
//! The bounds are derived for the RSPR chain (a rotating link about z0 on the base plane, a
//! prismatic leg, a revolute joint on the platform); [`Guards::certify`] gives no region
//! for other mechanisms. Rounding: the margins are those the evaluation computed; no
//! allowance is made for the rounding of the evaluation itself (f32 on the MCU: 1e-7
//! relative, far inside the 5 % the supervisor keeps in hand of each region).

use crate::chain::Chain;
use crate::ik::Solution;
use crate::jacobian::Jacobians;
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::{rotation_angle, Pose};
use crate::scalar::{dot3, larger, lit, norm3, smaller, sqrt, sub3, Real};
use crate::statics::Statics;
use nalgebra::Rotation3;

use super::limits::Limits;
use super::readings::Guard;
use super::setup::Guards;

/// Constraints of one certified region: one per stop-level guard and auxiliary bound.
pub const CONSTRAINTS: usize = 14;

/// The share of each margin a region uses (5 % kept in hand).
pub const MARGIN_SHARE: f64 = 0.95;

/// How far ψ, the angle between z0 × l_b and ŝ2, may grow beyond its largest value at
/// the centre in a region, rad (auxiliary: it bounds |Cn2| from below and the part of
/// z0 × l_b across ŝ2).
const PSI_SLACK: f64 = 0.1;
/// cos and sin of [`PSI_SLACK`] (written out: no trigonometry in `no_std` constants).
const PSI_SLACK_COS: f64 = 0.995_004_165_278_025_8;
const PSI_SLACK_SIN: f64 = 0.099_833_416_646_828_15;

/// σ_lo as a share of its value at the centre.
const AUX_SHARE: f64 = 0.8;
/// β = |b - t| at the centre plus this, m.
const BT_SLACK: f64 = 0.01;
/// F = this × |f(c)| + 1 N.
const F_GROWTH: f64 = 1.5;

/// A bound a·|v| + b·|ω| on a rate of change along a straight motion of twist [v; ω].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rate<T: Real> {
    /// Per m/s of the platform centre's speed.
    pub v: T,
    /// Per rad/s of the angular speed.
    pub w: T,
}

impl<T: Real> Rate<T> {
    fn new(v: T, w: T) -> Self {
        Rate { v, w }
    }
    fn plus(self, o: Self) -> Self {
        Rate::new(self.v + o.v, self.w + o.w)
    }
    fn times(self, k: T) -> Self {
        Rate::new(self.v * k, self.w * k)
    }
    /// The bound over a straight motion of |Δt| and θ.
    pub fn over(&self, dt: T, dtheta: T) -> T {
        self.v * dt + self.w * dtheta
    }
}

/// One constraint of a region: the guard (or auxiliary bound) it keeps, its margin at the
/// centre and the bound on the margin's rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constraint<T: Real> {
    /// The guard; None for the auxiliary bounds (ψ ≤ ψ_max, |b - t| ≤ β, σ_min ≥ σ_lo,
    /// |f| ≤ F).
    pub guard: Option<Guard>,
    /// The margin at the centre, in the guard's unit.
    pub margin: T,
    /// The bound on its rate of change.
    pub rate: Rate<T>,
}

/// The region certified by one full evaluation at `center`: every pose x with, for each
/// constraint, rate.over(|Δt|, θ) < [`MARGIN_SHARE`] × margin, violates no stop-level
/// guard (see the module documentation). Stored normalised: x is inside when a·|Δt| +
/// b·θ < 1 for every (a, b) of `scaled`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Certificate<T: Real> {
    /// The pose evaluated.
    pub center: Pose<T>,
    /// (a, b) of each constraint: the rate over [`MARGIN_SHARE`] × the margin.
    pub scaled: [(T, T); CONSTRAINTS],
    /// The largest translation certified at no rotation, m (the smallest 0.95 m/a).
    pub reach_t: T,
    /// The largest rotation certified at no translation, rad.
    pub reach_r: T,
    /// A warn level of the parallel measure or the payload efforts was reached at the
    /// centre: the guard.
    pub warn: Option<Guard>,
}

impl<T: Real> Certificate<T> {
    /// Whether a pose |Δt| and θ from the centre is inside.
    pub fn contains_offset(&self, dt: T, dtheta: T) -> bool {
        self.scaled
            .iter()
            .all(|(a, b)| *a * dt + *b * dtheta < T::one())
    }

    /// Whether `pose` is inside (with [`angle_bound`] for the rotation: conservative).
    pub fn contains(&self, pose: &Pose<T>) -> bool {
        let dt = norm3(&sub3(&pose.t, &self.center.t));
        self.contains_offset(dt, angle_bound(&pose.r, &self.center.r))
    }

    /// Whether every pose of a straight motion `from` → `to` (translation and rotation
    /// each linear, at any relative pace: a segment of the supervisor or a braking path,
    /// whose translation and rotation may end at different times) is inside. Uses
    /// |Δt(s)| ≤ max(|Δt_from|, |Δt_to|) (the norm is convex) and θ(s) ≤ max(θ_from,
    /// θ_to): the rotation about a fixed world axis is a geodesic of SO(3), and a ball of
    /// SO(3) of radius below π is geodesically convex. (With unit quaternions q(s) on the
    /// great-circle arc from q_from to q_to, of length θ_from,to/2 < π/2, and the centre's
    /// q_c, signs chosen so that q_c·q > 0 at the ends: q_c·q(s) = K cos(s - s₀) is
    /// positive at both ends of an interval shorter than π, so positive and concave on
    /// it, and its least value, the largest angle θ = 2 acos(q_c·q), is at an end.) The
    /// angles are bounded from above ([`angle_bound`]), so the test is conservative. Ends
    /// θ ≥ π/2 from the centre are refused outright: below that the signs above exist
    /// (the two ends are then within π of each other, their arc shorter than π/2).
    pub fn contains_motion(&self, from: &Pose<T>, to: &Pose<T>) -> bool {
        let ta = norm3(&sub3(&from.t, &self.center.t));
        let tb = norm3(&sub3(&to.t, &self.center.t));
        let ra = angle_bound(&from.r, &self.center.r);
        let rb = angle_bound(&to.r, &self.center.r);
        // (A NaN or infinite end is refused: `larger` alone would pass over a NaN.)
        if !(ta + tb + ra + rb).is_finite() {
            return false;
        }
        let r = larger(ra, rb);
        r < lit(core::f64::consts::FRAC_PI_2) && self.contains_offset(larger(ta, tb), r)
    }
}

/// An upper bound of the angle of the rotation a·bᵀ, cheap (no product of the matrices,
/// no trigonometry): with cos θ = (tr(a·bᵀ) - 1)/2 and tr(a·bᵀ) = Σ a_ij b_ij,
/// 2·tan(θ/2) = 2·√((1 - cos θ)/(1 + cos θ)) ≥ θ on [0, π) (relative excess θ²/12: 0.1 %
/// at 6 deg); infinite from 179 deg on (nothing is certified that far) and for a matrix
/// with a NaN.
pub fn angle_bound<T: Real>(a: &Rotation3<T>, b: &Rotation3<T>) -> T {
    let (ma, mb) = (a.matrix(), b.matrix());
    let mut tr = T::zero();
    for (x, y) in ma.iter().zip(mb.iter()) {
        tr += *x * *y;
    }
    let one = T::one();
    let c = smaller((tr - one) * lit::<T>(0.5), one);
    if !(c > lit(-0.9998)) {
        return T::max_value().unwrap_or(one / T::default_epsilon());
    }
    lit::<T>(2.0) * sqrt((one - c) / (one + c))
}

/// |Δt| and the rotation angle of `pose` from `center`.
pub fn offset<T: Real>(center: &Pose<T>, pose: &Pose<T>) -> (T, T) {
    (
        norm3(&sub3(&pose.t, &center.t)),
        rotation_angle(&(pose.r * center.r.inverse())),
    )
}

/// The smallest margin of each guard in one full evaluation (the readings' margins:
/// positive inside, in the guard's unit), for [`Guards::certify`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuardMinima<T: Real>(pub [T; 19]);

impl<T: Real> GuardMinima<T> {
    /// No reading yet (every margin infinite).
    pub fn new() -> Self {
        GuardMinima([T::max_value().unwrap_or(T::one() / T::default_epsilon()); 19])
    }
    /// Records a reading's margin (NaN counts as beyond the limit).
    pub fn record(&mut self, guard: Guard, margin: T) {
        let Some(slot) = self.0.get_mut(guard_index(guard)) else {
            return;
        };
        if !(margin >= *slot) {
            *slot = if margin.is_finite() {
                margin
            } else {
                -T::one()
            };
        }
    }
    /// The smallest margin of `guard` seen.
    pub fn get(&self, guard: Guard) -> T {
        self.0.get(guard_index(guard)).copied().unwrap_or(-T::one())
    }
}

impl<T: Real> Default for GuardMinima<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// The guard's place in [`Guard::ALL`] (its declaration order).
fn guard_index(g: Guard) -> usize {
    g as usize
}

/// What a full evaluation computed at its pose, for [`Guards::certify`].
#[derive(Clone, Copy, Debug)]
pub struct FullEvaluation<'a, T: Real> {
    /// The inverse-kinematics solution.
    pub sol: &'a Solution<T>,
    /// Its Jacobians.
    pub jac: &'a Jacobians<T>,
    /// The parallel measure (inverse condition number of the scaled Jtilde).
    pub inv_cond: T,
    /// The largest singular value of the scaled Jtilde, from the same SVD (0 if unknown:
    /// the largest row norm is used then).
    pub sigma_max: T,
    /// The payload statics.
    pub statics: &'a Statics<T>,
    /// The smallest margin of each guard.
    pub minima: &'a GuardMinima<T>,
    /// A warn level of the parallel measure, the force or the torque was reached.
    pub warn: Option<Guard>,
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// The region a full evaluation without a stop-level violation certifies (see the
    /// module documentation), or None: not an RSPR, a margin not positive, a bound not
    /// finite.
    pub fn certify(&self, e: &FullEvaluation<'_, T>) -> Option<Certificate<T>> {
        let cons = self.certificate_constraints(e);
        let cons = cons.as_ref()?;
        let zero = T::zero();
        let share = lit::<T>(MARGIN_SHARE);
        let mut scaled = [(zero, zero); CONSTRAINTS];
        // The largest coefficients: the reaches are their reciprocals (the smallest
        // 1/a of the constraints, as 1/x is monotone also in rounding).
        let (mut a_max, mut b_max) = (zero, zero);
        for (s, c) in scaled.iter_mut().zip(cons.iter()) {
            // (Also refuses a NaN: a comparison with NaN is false.)
            if !(c.margin > zero && c.rate.v >= zero && c.rate.w >= zero) {
                return None;
            }
            let usable = c.margin * share;
            *s = (c.rate.v / usable, c.rate.w / usable);
            a_max = larger(a_max, s.0);
            b_max = larger(b_max, s.1);
        }
        // Every coefficient is ≥ 0 and not NaN, so all are finite when the largest are.
        if !(a_max.is_finite() && b_max.is_finite()) {
            return None;
        }
        let reach = |m: T| {
            if m > zero {
                Some(T::one() / m)
            } else {
                T::max_value()
            }
        };
        Some(Certificate {
            center: e.sol.pose,
            scaled,
            reach_t: reach(a_max)?,
            reach_r: reach(b_max)?,
            warn: e.warn,
        })
    }

    /// The constraints of the region [`Guards::certify`] gives, unscaled: each guard's (and
    /// auxiliary bound's) margin at the centre and the bound on its rate (for the
    /// certificate, tests and reports); None for another mechanism than the RSPR or a
    /// degenerate evaluation.
    pub fn certificate_constraints(
        &self,
        e: &FullEvaluation<'_, T>,
    ) -> Option<[Constraint<T>; CONSTRAINTS]> {
        use JointKind::{Angular, Linear};
        if self.robot.joint_kinds() != [Linear, Linear, Linear, Angular, Angular, Angular] {
            return None;
        }
        let g = CentreGeometry::of(e)?;
        let r = Rates::new(&g, &self.limits)?;
        let collision = self.collision_constraint(&g, &r, e.minima)?;
        let p = parallel_bounds(e, &g, &r);
        let f = effort_bounds(e, &g, &r, &p, &self.limits);
        let m = e.minima;
        let c = |g: Guard, rate: Rate<T>| Constraint {
            guard: Some(g),
            margin: m.get(g),
            rate,
        };
        let aux = |margin: T, rate: Rate<T>| Constraint {
            guard: None,
            margin,
            rate,
        };
        let one = T::one();
        let stop = self.limits.parallel.stop;
        Some([
            c(Guard::Workspace, r.vel),
            c(Guard::TiltCone, r.omega),
            c(Guard::Stroke, r.legdot),
            c(Guard::LinkAngle, r.theta),
            c(Guard::Tilt, r.s1dot.plus(r.theta)),
            collision,
            c(Guard::SerialSingularity, r.cn2dot),
            aux(lit(PSI_SLACK), r.cn2dot),
            aux(r.beta - g.bt, r.bdot.plus(r.vel)),
            Constraint {
                guard: Some(Guard::ParallelSingularity),
                margin: p.sigma_c * (e.inv_cond - stop) / (one + stop),
                rate: p.delta,
            },
            aux(p.sigma_min - p.sigma_lo, p.delta),
            aux(f.big_f - f.fc, f.fdot),
            c(Guard::Force, f.fdot),
            c(Guard::Torque, f.torque),
        ])
    }

    /// The collision radius's constraint (section 11.4; a constraint that never binds when
    /// the collision guard is off); None when the legs may stand horizontal on S.
    fn collision_constraint(
        &self,
        g: &CentreGeometry<T>,
        r: &Rates<T>,
        minima: &GuardMinima<T>,
    ) -> Option<Constraint<T>> {
        let l = &self.limits;
        let zero = T::zero();
        if !(l.collision_radius > zero) {
            return Some(Constraint {
                guard: None,
                margin: T::one(),
                rate: Rate::new(zero, zero),
            });
        }
        // The lowest point of the platform's revolute centres on S.
        let pz_min = self.robot.hc()
            - l.box_half.z
            - l.box_margin
            - g.rp * crate::scalar::sin_cos(l.tilt_cone).0;
        let s1z = (pz_min - g.bz_hi) / l.stroke[1];
        if !(s1z > zero) {
            return None;
        }
        let lever = larger(
            (l.collision_plane_height - g.bz_lo).abs(),
            (l.collision_plane_height - g.bz_hi).abs(),
        );
        Some(Constraint {
            guard: Some(Guard::Collision),
            margin: minima.get(Guard::Collision),
            rate: r
                .bdot
                .plus(r.s1dot.times(lit::<T>(2.0) * lever / (s1z * s1z))),
        })
    }
}

/// What the bounds are built from, read off the solution at the centre: the extremes
/// over the three chains.
struct CentreGeometry<T: Real> {
    /// rb = |l_b|.
    rb: T,
    /// rp = |p - t|.
    rp: T,
    /// The lowest and the highest spherical-joint centre, b_z.
    bz_lo: T,
    bz_hi: T,
    /// The smallest |u|, u = z0 × l_b.
    u_min: T,
    /// cos ψ_c, ψ_c the largest angle between u and ŝ2 (|Cn2| = |u| cos ψ; |u| is
    /// constant: l_b turns about z0).
    cos_c: T,
    /// The largest |b - t|.
    bt: T,
}

impl<T: Real> CentreGeometry<T> {
    fn of(e: &FullEvaluation<'_, T>) -> Option<Self> {
        let zero = T::zero();
        let sol = e.sol;
        let t = sol.pose.t;
        let (mut rb, mut rp) = (zero, zero);
        let (mut bz_lo, mut bz_hi) = (T::max_value()?, -T::max_value()?);
        let (mut u_min, mut cos_c) = (T::max_value()?, T::one());
        let mut bt = zero;
        for c in Chain::ALL {
            let ch = &sol.chains[c];
            rb = larger(rb, norm3(&ch.lb));
            rp = larger(rp, norm3(&sub3(&ch.p, &t)));
            bz_lo = smaller(bz_lo, ch.b.z);
            bz_hi = larger(bz_hi, ch.b.z);
            let u = sqrt(ch.lb.x * ch.lb.x + ch.lb.y * ch.lb.y);
            u_min = smaller(u_min, u);
            cos_c = smaller(cos_c, e.jac.serial[c].a22.abs() / u);
            bt = larger(bt, norm3(&sub3(&ch.b, &t)));
        }
        Some(CentreGeometry {
            rb,
            rp,
            bz_lo,
            bz_hi,
            u_min,
            cos_c,
            bt,
        })
    }
}

/// The bounds on the rates of the motion's quantities over the region (the module
/// documentation derives each).
struct Rates<T: Real> {
    /// |v| and |ω|.
    vel: Rate<T>,
    omega: Rate<T>,
    /// Θ ≥ |θ̇|.
    theta: Rate<T>,
    /// |ḃ| and |l̇|.
    bdot: Rate<T>,
    legdot: Rate<T>,
    /// |dŝ1|.
    s1dot: Rate<T>,
    /// The serial measure's (and ψ's) rate: |ω| + Θ.
    cn2dot: Rate<T>,
    /// β ≥ |b - t| (auxiliary), k = tan ψ_max and 1/cos ψ_max.
    beta: T,
    k: T,
    sec: T,
}

impl<T: Real> Rates<T> {
    fn new(g: &CentreGeometry<T>, l: &Limits<T>) -> Option<Self> {
        let (one, zero) = (T::one(), T::zero());
        let (lmin, lmax) = (l.stroke[0], l.stroke[1]);
        if !(g.rp > zero && g.rb > zero && lmin > zero && g.cos_c > zero && g.u_min > zero) {
            return None;
        }
        // ψ ≤ ψ_max = ψ_c + PSI_SLACK (auxiliary): cos and sin of the sum, no trigonometry.
        let sin_c = sqrt(larger(one - g.cos_c * g.cos_c, zero));
        let (cd, sd) = (lit::<T>(PSI_SLACK_COS), lit::<T>(PSI_SLACK_SIN));
        let cos_max = g.cos_c * cd - sin_c * sd;
        let sin_max = sin_c * cd + g.cos_c * sd;
        if !(cos_max > zero) {
            return None;
        }
        // |Cn2| ≥ κ and |w⊥|/|Cn2| = tan ψ ≤ k on the region.
        let kappa = g.u_min * cos_max;
        let k = sin_max / cos_max;
        let sec = one / cos_max;
        // |b - t| ≤ β (auxiliary; ≤ l_max + rp always).
        let beta = smaller(g.bt + lit(BT_SLACK), lmax + g.rp);
        // Θ = (|v| + β|ω|)/κ bounds |θ̇|.
        let theta = Rate::new(one / kappa, beta / kappa);
        let vp = Rate::new(one, g.rp);
        let bdot = theta.times(g.rb);
        let omega = Rate::new(zero, one);
        // dŝ1 = (ω·n) ŝ2 + (γ/l) n, n = ŝ1 × ŝ2, |γ| ≤ √(1 + k²)|v| + (rp + kβ)|ω|.
        let s1dot = hyp(omega, Rate::new(sec, g.rp + k * beta).times(one / lmin));
        Some(Rates {
            vel: Rate::new(one, zero),
            omega,
            theta,
            bdot,
            legdot: vp.plus(bdot),
            s1dot,
            cn2dot: omega.plus(theta),
            beta,
            k,
            sec,
        })
    }
}

/// The norm of a pair of rate bounds (Minkowski: |v·a + w·b| ≤ |v||a| + |w||b|).
fn hyp<T: Real>(x: Rate<T>, y: Rate<T>) -> Rate<T> {
    Rate::new(sqrt(x.v * x.v + y.v * y.v), sqrt(x.w * x.w + y.w * y.w))
}

/// The parallel measure's bounds: δ bounds the rate of ‖A(x) - A(c)‖_F; σ_max(c) and
/// σ_min(c) of the scaled Jtilde A, and σ_lo ≤ σ_min on the region (auxiliary).
struct ParallelBounds<T: Real> {
    delta: Rate<T>,
    sigma_c: T,
    sigma_min: T,
    sigma_lo: T,
}

fn parallel_bounds<T: Real>(
    e: &FullEvaluation<'_, T>,
    g: &CentreGeometry<T>,
    r: &Rates<T>,
) -> ParallelBounds<T> {
    let one = T::one();
    // Each row's direction part and moment part (over rp); the ŝ2 rows' moment changes at
    // most at |v|/cos ψ_max + (1 + k)β|ω|.
    let row1 = hyp(r.s1dot, r.s1dot.plus(r.omega));
    let row2 = hyp(
        r.omega,
        Rate::new(r.sec, (one + r.k) * r.beta).times(one / g.rp),
    );
    let delta = hyp(row1, row2).times(sqrt(lit(3.0)));
    // σ_max(c): the SVD's, at least the largest row norm (a lower bound of it, ≥ 1).
    let sigma_c = larger(
        larger(largest_row_norm(&e.jac.jtilde, g.rp), one),
        e.sigma_max,
    );
    let sigma_min = e.inv_cond * sigma_c;
    ParallelBounds {
        delta,
        sigma_c,
        sigma_min,
        sigma_lo: sigma_min * lit(AUX_SHARE),
    }
}

/// The payload efforts' bounds (Eq. 7.10): |f| at the centre, F ≥ |f| on the region
/// (auxiliary), and the rates of the line forces and the link torques.
struct EffortBounds<T: Real> {
    fc: T,
    big_f: T,
    fdot: Rate<T>,
    torque: Rate<T>,
}

fn effort_bounds<T: Real>(
    e: &FullEvaluation<'_, T>,
    g: &CentreGeometry<T>,
    r: &Rates<T>,
    p: &ParallelBounds<T>,
    l: &Limits<T>,
) -> EffortBounds<T> {
    let one = T::one();
    let f = e.statics;
    let fc = sqrt(dot3(&f.f1, &f.f1) + dot3(&f.f2, &f.f2));
    let big_f = fc * lit(F_GROWTH) + one;
    let fe = &l.payload;
    let fe_norm = sqrt(fe.x * fe.x + fe.y * fe.y + fe.z * fe.z);
    let se_dot = Rate::new(T::zero(), norm3(&l.payload_lever) * fe_norm / g.rp);
    let fdot = se_dot.plus(p.delta.times(big_f)).times(one / p.sigma_lo);
    let a12dot = r.s1dot.plus(r.theta).times(g.rb);
    let a22dot = r.omega.plus(r.theta).times(g.rb);
    let torque = hyp(a12dot, a22dot)
        .times(big_f)
        .plus(fdot.times(sqrt(lit::<T>(2.0)) * g.rb));
    EffortBounds {
        fc,
        big_f,
        fdot,
        torque,
    }
}

/// The largest row norm of Jtilde with its moment columns over rp (a lower bound of
/// σ_max of the scaled Jtilde).
fn largest_row_norm<T: Real>(jtilde: &nalgebra::Matrix6<T>, rp: T) -> T {
    let mut rows = [T::zero(); 6];
    for (j, col) in jtilde.data.0.iter().enumerate() {
        let k = if j >= 3 { T::one() / rp } else { T::one() };
        for (r, x) in rows.iter_mut().zip(col.iter()) {
            *r += (*x * k) * (*x * k);
        }
    }
    sqrt(rows.iter().fold(T::zero(), |a, x| larger(a, *x)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written-out cosine and sine of the ψ slack are those of the slack.
    #[test]
    fn psi_slack_constants() {
        let (sin, cos) = crate::scalar::sin_cos(PSI_SLACK);
        assert!((cos - PSI_SLACK_COS).abs() < 1e-16);
        assert!((sin - PSI_SLACK_SIN).abs() < 1e-16);
    }
}
