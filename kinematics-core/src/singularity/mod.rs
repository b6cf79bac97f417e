//! Singularity measures (CONVENTIONS.md, "Measures"; thesis chapter 10).

use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::jacobian::tripod_jacobian;
use crate::mechanism::Mechanism;
use crate::scalar::{lit, sqrt, Real};
use core::fmt;
use nalgebra::Matrix6;

pub mod configurations;
mod dense;
pub mod lines;
pub mod serial_cases;

/// Which singularity the configuration is nearest to, comparing the dimensionless measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Nearest {
    /// A serial singularity of this chain (Eq. 10.6 / 10.11).
    Serial(Chain),
    /// A parallel singularity of the tripod (chapter 10.2).
    Parallel,
}

impl fmt::Display for Nearest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Nearest::Serial(c) => write!(f, "serial:{}", c.number()),
            Nearest::Parallel => f.write_str("parallel"),
        }
    }
}

/// The SVD of Jtilde did not converge (only for non-finite or absurd input).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SvdDidNotConverge;

impl fmt::Display for SvdDidNotConverge {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("singular-value decomposition of Jtilde did not converge")
    }
}

/// Singularity measures at one configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measures<T: Real> {
    /// Serial measure per chain in SI: RSPR |Cn2_i| (m, Eq. 10.6); USR
    /// |Cn1_i Cr2_i - Cr1_i Cn2_i| (m², Eq. 10.11).
    pub serial: PerChain<T>,
    /// The same made dimensionless: RSPR |Cn2_i| / rb; USR over l1².
    pub serial_relative: PerChain<T>,
    /// Parallel measure: inverse condition number (σ_min/σ_max) of Jtilde with its moment
    /// columns divided by rp.
    pub parallel_inv_cond: T,
    /// Sign of det(Jtilde): -1, 0 or +1. A change of sign along a path crosses a parallel
    /// singularity.
    pub parallel_det_sign: i8,
    /// The nearest singularity.
    pub nearest: Nearest,
}

/// Inverse condition number σ_min / σ_max of the scaled Jtilde (CONVENTIONS.md, the
/// parallel measure; 0 at a parallel singularity, 1 at isotropy), from a cold start.
///
/// See [`ConditionEstimator`] for the method; on the control path keep one estimator per
/// stream of nearby poses so that each call starts warm.
pub fn parallel_inv_cond<T: Real>(jtilde: &Matrix6<T>, rp: T) -> Result<T, SvdDidNotConverge> {
    ConditionEstimator::new().inv_cond(jtilde, rp)
}

/// The singular values of the scaled Jtilde by one-sided (Hestenes) Jacobi rotations,
/// warm-started from the right singular vectors of the previous call.
///
/// Why not nalgebra's SVD: it is accurate and general, but it starts from scratch
/// (bidiagonalisation and implicit QR: about 25,000 instructions on the Cortex-M4 for a
/// 6x6 f32 matrix). Consecutive control ticks evaluate poses a few micrometres apart,
/// whose singular vectors barely move: applying the previous right singular vectors V
/// first leaves W = A V nearly column-orthogonal, and one sweep of rotations (most of
/// them skipped) plus one confirming sweep converge. From a cold start (V = I) four or five
/// sweeps are needed, as for any cyclic Jacobi method. [`ConditionEstimator::begin`] and
/// [`ConditionEstimator::sweep`] spread one decomposition over several calls, one sweep
/// each (about 2,000 instructions on the Cortex-M4), for the staged guard evaluations.
///
/// Method (Golub & Van Loan, "Matrix Computations", section 8.6.3): for each pair of
/// columns (i, j) of W with α = |w_i|², β = |w_j|², γ = w_i·w_j, rotate both columns (and
/// the same columns of V) by the angle that makes them orthogonal, unless
/// |γ| ≤ tol·√(αβ) already. When a whole sweep rotates nothing, the column norms of W are
/// the singular values (to a relative error of order tol², tol = 64 ε). V is
/// re-orthonormalised (modified Gram-Schmidt) at the start of every call, so rounding
/// cannot accumulate over millions of ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConditionEstimator<T: Real> {
    /// Right singular vectors of the last call, by column.
    v: [[T; 6]; 6],
    /// W = A V of the decomposition in progress (see [`ConditionEstimator::begin`]).
    w: [[T; 6]; 6],
    /// Squared column norm below which a column of W counts as zero.
    floor: T,
    sweeps: u8,
    /// The largest singular value of the last decomposition that converged (0 before).
    sigma_max: T,
    /// A decomposition was begun and has not finished.
    running: bool,
}

impl<T: Real> Default for ConditionEstimator<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// Sweeps allowed before giving up: a cold start needs 4 (f32) or 5 (f64) on the
/// reference robot's task box (measured over 5,000 poses), a warm start 1 or 2.
pub const MAX_SWEEPS: u8 = 10;

impl<T: Real> ConditionEstimator<T> {
    /// A cold estimator (V = I).
    pub fn new() -> Self {
        ConditionEstimator {
            v: identity(),
            w: [[T::zero(); 6]; 6],
            floor: T::zero(),
            sweeps: 0,
            sigma_max: T::zero(),
            running: false,
        }
    }

    /// The largest singular value of the scaled Jtilde of the last decomposition that
    /// converged to a finite, nonzero inverse condition number (0 before the first).
    pub fn sigma_max(&self) -> T {
        self.sigma_max
    }

    /// Sweeps the last call needed (the confirming sweep included).
    pub fn last_sweeps(&self) -> u8 {
        self.sweeps
    }

    /// Forgets the warm start.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The inverse condition number of the scaled `jtilde` ([`parallel_inv_cond`]),
    /// warm-started from the previous call. On failure (non-finite input, no convergence)
    /// the estimator is reset and the error returned. The same as [`Self::begin`], then
    /// [`Self::sweep`] until it gives the result.
    pub fn inv_cond(&mut self, jtilde: &Matrix6<T>, rp: T) -> Result<T, SvdDidNotConverge> {
        self.begin(jtilde, rp)?;
        for _ in 0..=MAX_SWEEPS {
            if let Some(result) = self.sweep() {
                return result;
            }
        }
        // (Unreachable: `sweep` gives up after MAX_SWEEPS.)
        self.reset();
        Err(SvdDidNotConverge)
    }

    /// Begins a decomposition of the scaled `jtilde` that [`Self::sweep`] carries on one
    /// sweep per call (so that a caller with a fixed budget per control tick can spread
    /// it): scales the columns, re-orthonormalises the warm start V and forms W = A V.
    /// Fails (and resets the estimator) on a non-finite input.
    pub fn begin(&mut self, jtilde: &Matrix6<T>, rp: T) -> Result<(), SvdDidNotConverge> {
        // The columns of the scaled Jtilde (CONVENTIONS.md: angular columns over rp).
        let mut a: [[T; 6]; 6] = (*jtilde).into();
        for col in a.iter_mut().skip(3) {
            for x in col.iter_mut() {
                *x /= rp;
            }
        }
        let mut norm2 = T::zero();
        for col in a.iter() {
            norm2 += dot(col, col);
        }
        if !norm2.is_finite() || !rp.is_finite() {
            self.reset();
            return Err(SvdDidNotConverge);
        }
        if !self.orthonormalise() {
            self.v = identity();
        }
        // W = A V, column by column (plain arrays: no view overhead on the Cortex-M4).
        self.w = [[T::zero(); 6]; 6];
        for (wc, vc) in self.w.iter_mut().zip(self.v.iter()) {
            for (ac, vk) in a.iter().zip(vc.iter()) {
                axpy(*vk, ac, wc);
            }
        }
        // A column at the rounding level of A is a zero singular value: rotating it against
        // the others would only shuffle rounding errors and never converge.
        let noise = T::default_epsilon() * lit(8.0) * sqrt(norm2);
        self.floor = noise * noise;
        self.sweeps = 0;
        self.running = true;
        Ok(())
    }

    /// One sweep of the decomposition begun by [`Self::begin`]: None while it has not
    /// converged, then the inverse condition number (or the failure, after
    /// [`MAX_SWEEPS`] sweeps, which resets the estimator). Without a decomposition in
    /// progress, a failure.
    pub fn sweep(&mut self) -> Option<Result<T, SvdDidNotConverge>> {
        if !self.running {
            return Some(Err(SvdDidNotConverge));
        }
        let tol = T::default_epsilon() * lit(64.0);
        self.sweeps += 1;
        // The largest squared off-diagonal ratio or rotation sine of the sweep.
        let mut largest = T::zero();
        // Squared column norms, fresh each sweep and updated exactly by each rotation.
        let mut norms = [T::zero(); 6];
        for (n, col) in norms.iter_mut().zip(self.w.iter()) {
            *n = dot(col, col);
        }
        for i in 0..5 {
            for j in (i + 1)..6 {
                let r = rotate_pair(
                    &mut self.w,
                    &mut self.v,
                    &mut norms,
                    (i, j),
                    tol,
                    self.floor,
                );
                if r > largest {
                    largest = r;
                }
            }
        }
        // Converged when nothing needed a rotation, or when every rotation of the sweep
        // was small (off-diagonal ratio and sine below √tol): the off-diagonal terms those
        // rotations leave or re-create are then below ~tol, so a further sweep would rotate
        // nothing (the classical quadratic convergence of cyclic Jacobi; a cluster of
        // singular values makes the sines large and keeps sweeping).
        if !(largest < tol) {
            if self.sweeps >= MAX_SWEEPS {
                self.reset();
                return Some(Err(SvdDidNotConverge));
            }
            return None;
        }
        self.running = false;
        let (mut max, mut min) = (T::zero(), T::max_value().unwrap_or(T::one()));
        for col in self.w.iter() {
            let s = sqrt(dot(col, col));
            if s > max {
                max = s;
            }
            if s < min {
                min = s;
            }
        }
        if max > T::zero() && min.is_finite() {
            self.sigma_max = max;
            Some(Ok(min / max))
        } else if max == T::zero() {
            Some(Ok(T::zero()))
        } else {
            self.reset();
            Some(Err(SvdDidNotConverge))
        }
    }

    fn orthonormalise(&mut self) -> bool {
        let v = &mut self.v;
        for k in 0..6 {
            let (done, rest) = v.split_at_mut(k);
            let Some(ck) = rest.first_mut() else {
                return false;
            };
            for cj in done.iter() {
                axpy(-dot(cj, ck), cj, ck);
            }
            let n = sqrt(dot(ck, ck));
            if !(n > lit(0.5)) || !n.is_finite() {
                return false;
            }
            for x in ck.iter_mut() {
                *x /= n;
            }
        }
        true
    }
}

fn identity<T: Real>() -> [[T; 6]; 6] {
    let mut m = [[T::zero(); 6]; 6];
    for (k, col) in m.iter_mut().enumerate() {
        if let Some(x) = col.get_mut(k) {
            *x = T::one();
        }
    }
    m
}

// The 6-element kernels are written out: at opt-level "s" (the firmware's) loops over
// six elements are not unrolled, and the loop overhead was three times the arithmetic.

#[inline]
fn dot<T: Real>(a: &[T; 6], b: &[T; 6]) -> T {
    let [a0, a1, a2, a3, a4, a5] = *a;
    let [b0, b1, b2, b3, b4, b5] = *b;
    a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 + a4 * b4 + a5 * b5
}

/// y += k x.
#[inline]
fn axpy<T: Real>(k: T, x: &[T; 6], y: &mut [T; 6]) {
    let [x0, x1, x2, x3, x4, x5] = *x;
    let [y0, y1, y2, y3, y4, y5] = y;
    *y0 += k * x0;
    *y1 += k * x1;
    *y2 += k * x2;
    *y3 += k * x3;
    *y4 += k * x4;
    *y5 += k * x5;
}

/// Columns i < j of a column array, both mutable.
#[inline]
fn pair_mut<T>(m: &mut [[T; 6]; 6], i: usize, j: usize) -> Option<(&mut [T; 6], &mut [T; 6])> {
    let (lo, hi) = m.split_at_mut(j);
    Some((lo.get_mut(i)?, hi.first_mut()?))
}

/// Rotates columns a and b by (c, s): a' = c a - s b, b' = s a + c b.
#[inline]
fn rotate<T: Real>(a: &mut [T; 6], b: &mut [T; 6], c: T, s: T) {
    let (p, q) = (*a, *b);
    let [a0, a1, a2, a3, a4, a5] = a;
    let [b0, b1, b2, b3, b4, b5] = b;
    let [p0, p1, p2, p3, p4, p5] = p;
    let [q0, q1, q2, q3, q4, q5] = q;
    (*a0, *b0) = (c * p0 - s * q0, s * p0 + c * q0);
    (*a1, *b1) = (c * p1 - s * q1, s * p1 + c * q1);
    (*a2, *b2) = (c * p2 - s * q2, s * p2 + c * q2);
    (*a3, *b3) = (c * p3 - s * q3, s * p3 + c * q3);
    (*a4, *b4) = (c * p4 - s * q4, s * p4 + c * q4);
    (*a5, *b5) = (c * p5 - s * q5, s * p5 + c * q5);
}

/// One Jacobi rotation of columns i < j of W (and of V). Returns 0 when none was needed,
/// else the larger of the squared off-diagonal ratio γ²/(αβ) and the squared sine. Columns
/// whose squared norm is at most `floor` count as zero.
#[inline]
fn rotate_pair<T: Real>(
    w: &mut [[T; 6]; 6],
    v: &mut [[T; 6]; 6],
    norms: &mut [T; 6],
    (i, j): (usize, usize),
    tol: T,
    floor: T,
) -> T {
    let Some((wi, wj)) = pair_mut(w, i, j) else {
        return T::zero();
    };
    let Some((ni, nj)) = pair_mut_1(norms, i, j) else {
        return T::zero();
    };
    let (alpha, beta, gamma) = (*ni, *nj, dot(wi, wj));
    let (g2, ab) = (gamma * gamma, alpha * beta);
    if !(g2 > tol * tol * ab) || alpha <= floor || beta <= floor {
        return T::zero();
    }
    // The rotation that zeroes γ: tan(2θ) = 2γ / (β - α), the smaller root of
    // t² + 2ζt - 1 = 0 (|θ| ≤ 45 deg).
    let zeta = (beta - alpha) / (gamma + gamma);
    let t = if zeta == T::zero() {
        T::one()
    } else {
        let t = T::one() / (zeta.abs() + sqrt(T::one() + zeta * zeta));
        if zeta < T::zero() {
            -t
        } else {
            t
        }
    };
    let c = T::one() / sqrt(T::one() + t * t);
    let s = c * t;
    rotate(wi, wj, c, s);
    if let Some((vi, vj)) = pair_mut(v, i, j) {
        rotate(vi, vj, c, s);
    }
    // |w_i'|² = α - tγ, |w_j'|² = β + tγ (the rotation's exact effect on the norms).
    *ni = alpha - t * gamma;
    *nj = beta + t * gamma;
    let ratio2 = g2 / ab;
    let s2 = s * s;
    if ratio2 > s2 {
        ratio2
    } else {
        s2
    }
}

/// Elements i < j of an array, both mutable.
#[inline]
fn pair_mut_1<T>(m: &mut [T; 6], i: usize, j: usize) -> Option<(&mut T, &mut T)> {
    let (lo, hi) = m.split_at_mut(j);
    Some((lo.get_mut(i)?, hi.first_mut()?))
}

fn sign<T: Real>(x: T) -> i8 {
    if x > T::zero() {
        1
    } else if x < T::zero() {
        -1
    } else {
        0
    }
}

/// All singularity measures at a solution.
pub fn measures<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    sol: &Solution<T>,
) -> Result<Measures<T>, SvdDidNotConverge> {
    let jtilde = tripod_jacobian(sol);
    let both = sol.chains.map(|_, c| m.serial_measure(c));
    let serial = both.map(|_, b| b.0);
    let serial_relative = both.map(|_, b| b.1);
    let parallel_inv_cond = parallel_inv_cond(&jtilde, m.rp())?;
    let mut nearest = Nearest::Parallel;
    let mut smallest = parallel_inv_cond;
    for (chain, &r) in serial_relative.iter() {
        if r < smallest {
            smallest = r;
            nearest = Nearest::Serial(chain);
        }
    }
    Ok(Measures {
        serial,
        serial_relative,
        parallel_inv_cond,
        parallel_det_sign: sign(jtilde.determinant()),
        nearest,
    })
}
