//! The line geometry of the parallel singularities (thesis 10.2): the rank of the six
//! Plücker lines of Jtilde (Eq. 7.14), every minimal linearly dependent subset of them
//! with the line variety its span belongs to (the varieties of thesis Fig. 9.3), and the
//! instantaneous motion the platform gains.
//!
//! **Coordinates.** Row k of Jtilde is the line l_k = [ŝ; m] (moment about o_p). The
//! analysis works on the scaled lines [ŝ; m / rp], each normalised to unit length: the
//! scaling makes the six coordinates dimensionless (CONVENTIONS.md, the parallel measure)
//! and neither it nor the normalisation changes which subsets are dependent.
//!
//! **Rank.** The numerical rank of the six scaled lines: the singular values above
//! `rank_tol · σ_max` (one-sided Jacobi, [`super::dense`]). A subset of lines is dependent
//! when its own rank is below its size with the same absolute threshold; by the
//! interlacing of singular values a subset's smallest singular value is at least that of
//! all six, so a robot of full rank has no dependent subset.
//!
//! **Varieties.** A minimal dependent subset (a circuit) of k lines spans a (k-1)-space;
//! the Klein form Ω(a, b) = ŝ_a·m_b + ŝ_b·m_a (the reciprocal product) restricted to that
//! space classifies it:
//! - k = 2: the two lines coincide (1a, a point of the Klein quadric);
//! - k = 3: a flat pencil (2b; three lines of a 2-space are dependent only when the
//!   space is a pencil: two skew lines span no third line);
//! - k = 4, the form on the 3-space: rank 3 a regulus (3A), rank 2 a union of two flat
//!   pencils (3B), zero a bundle (3C: all lines through a point) or a plane (3D: all
//!   lines in a plane). A bundle and a plane differ by their lines' directions: three
//!   independent lines through a finite point have independent directions (rank 3), three
//!   parallel ones (a bundle at infinity) rank 1; three independent lines of a finite
//!   plane span its two directions (rank 2), lines at infinity none. An odd rank is a
//!   bundle, an even one a plane;
//! - k = 5, the linear congruence: the form on the reciprocal 2-space W^⊥ (the lines that
//!   meet every line of the congruence are its points on the Klein quadric): indefinite,
//!   two real directrices, hyperbolic (4B); definite, elliptic (4A); rank 1, parabolic
//!   (4C); zero, degenerate (4D);
//! - k = 6, the linear complex: the reciprocal screw X = [X_s; X_m] (one dimension):
//!   X_s·X_m = 0 a special complex (5B, all lines meet the line X), else a general complex
//!   (5A) with axis along X_s and pitch X_s·X_m / |X_s|².
//!
//! **The motion gained.** A twist [v; ω] with Jtilde [v; ω] = 0 (thesis 10.1: with the
//! actuators locked the platform can move along it). It is reciprocal to every line: the
//! reciprocal screw of the complex at rank 5 is that twist, written [ω; v].

use super::dense::{decompose, Decomposition};
use crate::ik::Solution;
use crate::jacobian::tripod_jacobian;
use crate::scalar::{lit, sqrt, Real};
use crate::vectors::Twist;
use core::fmt;
use heapless::Vec as HVec;
use nalgebra::{Matrix6, Vector3};

/// The line varieties of the thesis (Fig. 9.3), named by its codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variety {
    /// 1a: two coincident lines.
    Coincident,
    /// 2b: a flat pencil (lines in one plane through one point).
    FlatPencil,
    /// 3A: a regulus.
    Regulus,
    /// 3B: the union of two flat pencils sharing a line.
    Union,
    /// 3C: a bundle (all lines through one point).
    Bundle,
    /// 3D: all lines of one plane.
    Plane,
    /// 4A: an elliptic linear congruence (no real directrix).
    EllipticCongruence,
    /// 4B: a hyperbolic linear congruence (two skew directrices).
    HyperbolicCongruence,
    /// 4C: a parabolic linear congruence (one directrix, counted twice).
    ParabolicCongruence,
    /// 4D: a degenerate linear congruence (a plane's lines and a point's lines).
    DegenerateCongruence,
    /// 5A: a general linear complex.
    GeneralComplex,
    /// 5B: a special linear complex (all lines meet one line).
    SpecialComplex,
    /// The numerical ranks did not fit any variety (only within the tolerance's reach of
    /// two cases; never seen away from it).
    Unclassified,
}

impl Variety {
    /// The thesis's code: "1a", "2b", "3A" .. "5B" ("?" unclassified).
    pub const fn code(self) -> &'static str {
        match self {
            Variety::Coincident => "1a",
            Variety::FlatPencil => "2b",
            Variety::Regulus => "3A",
            Variety::Union => "3B",
            Variety::Bundle => "3C",
            Variety::Plane => "3D",
            Variety::EllipticCongruence => "4A",
            Variety::HyperbolicCongruence => "4B",
            Variety::ParabolicCongruence => "4C",
            Variety::DegenerateCongruence => "4D",
            Variety::GeneralComplex => "5A",
            Variety::SpecialComplex => "5B",
            Variety::Unclassified => "?",
        }
    }
}

impl fmt::Display for Variety {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

/// A minimal dependent subset of the six lines and its variety.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Circuit {
    /// Bit k-1 set: line l_k (row k of Jtilde) belongs to the subset.
    pub lines: u8,
    /// The variety its span belongs to.
    pub variety: Variety,
}

impl Circuit {
    /// The line numbers 1..6 of the subset, in order.
    pub fn line_numbers(&self) -> impl Iterator<Item = u8> + '_ {
        (0u8..6)
            .filter(|k| self.lines & (1 << k) != 0)
            .map(|k| k + 1)
    }
    /// How many lines.
    pub fn size(&self) -> u32 {
        self.lines.count_ones()
    }
}

impl fmt::Display for Circuit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:", self.variety)?;
        for n in self.line_numbers() {
            write!(f, "{n}")?;
        }
        Ok(())
    }
}

/// One instantaneous motion the platform gains, as a screw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GainedMotion<T: Real> {
    /// The twist [v; ω] (v of o_p, {0}), scaled so that |[v; rp ω]| = 1.
    pub twist: Twist<T>,
    /// Pitch |v∥| / |ω| (m per rad) of its screw; None for a pure translation.
    pub pitch: Option<T>,
    /// The point of the screw axis nearest o_p, relative to o_p (m, {0}); zero for a pure
    /// translation.
    pub axis_point: Vector3<T>,
}

impl<T: Real> GainedMotion<T> {
    fn from_scaled(y: &[T; 6], rp: T, tol: T) -> Self {
        let [v0, v1, v2, w0, w1, w2] = *y;
        let v = Vector3::new(v0, v1, v2);
        let w = Vector3::new(w0 / rp, w1 / rp, w2 / rp);
        let twist = Twist::new(v0, v1, v2, w.x, w.y, w.z);
        // |rp ω| against the unit scaled twist: below the tolerance, a translation.
        if !(sqrt(w0 * w0 + w1 * w1 + w2 * w2) > tol) {
            return GainedMotion {
                twist,
                pitch: None,
                axis_point: Vector3::zeros(),
            };
        }
        let w2n = w.dot(&w);
        GainedMotion {
            twist,
            pitch: Some(w.dot(&v) / w2n),
            axis_point: w.cross(&v) / w2n,
        }
    }
}

/// The tolerances of the analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances<T: Real> {
    /// Relative singular value below which a direction counts as lost: σ ≤ rank · σ_max
    /// of the six scaled, normalised lines.
    pub rank: T,
    /// Relative residual of a geometric condition ([`super::configurations`]): lengths
    /// over rp, sines of angles.
    pub geometry: T,
}

impl<T: Real> Default for Tolerances<T> {
    /// 1e-6 for both, or 1000 machine epsilons where that is larger (f32: 1.2e-4).
    fn default() -> Self {
        let t = lit::<T>(1.0e-6).max(T::default_epsilon() * lit(1.0e3));
        Tolerances {
            rank: t,
            geometry: t,
        }
    }
}

/// Capacity for circuits: at most one per subset of six lines.
pub const MAX_CIRCUITS: usize = 63;

/// The line-geometry analysis of Jtilde at one configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct LineAnalysis<T: Real> {
    /// Numerical rank of the six lines (6: no parallel singularity).
    pub rank: u8,
    /// Singular values of the scaled, normalised lines over the largest, descending.
    pub relative_sigma: [T; 6],
    /// Every minimal dependent subset, smallest first, with its variety.
    pub circuits: HVec<Circuit, MAX_CIRCUITS>,
    /// A basis of the motions the platform gains (6 - rank of them).
    pub gained: HVec<GainedMotion<T>, 6>,
    /// At rank 5, the linear complex all six lines belong to (5A or 5B).
    pub complex: Option<Variety>,
}

/// The analysis failed: a non-finite Jtilde or platform radius.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotFinite;

impl fmt::Display for NotFinite {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the lines of Jtilde are not finite")
    }
}

/// The six scaled, normalised lines of Jtilde (rows).
pub(crate) fn scaled_lines<T: Real>(jtilde: &Matrix6<T>, rp: T) -> Option<[[T; 6]; 6]> {
    if !(rp > T::zero()) || !rp.is_finite() {
        return None;
    }
    let mut rows = [[T::zero(); 6]; 6];
    for (r, row) in rows.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            let v = jtilde.get((r, c)).copied()?;
            *x = if c < 3 { v } else { v / rp };
        }
        let n = sqrt(row.iter().fold(T::zero(), |a, &x| a + x * x));
        if !(n > T::zero()) || !n.is_finite() {
            return None;
        }
        for x in row.iter_mut() {
            *x /= n;
        }
    }
    Some(rows)
}

/// The rows of `lines` selected by `mask` (bit k: row k), the others zero; with `swap`,
/// each row as [m; ŝ] (the Klein form's partner: Ω(a, b) = a · swap(b)).
fn select<T: Real>(lines: &[[T; 6]; 6], mask: u8, swap: bool) -> [[T; 6]; 6] {
    let mut out = [[T::zero(); 6]; 6];
    for (k, (o, l)) in out.iter_mut().zip(lines.iter()).enumerate() {
        if mask & (1 << k) != 0 {
            *o = if swap { swapped(l) } else { *l };
        }
    }
    out
}

fn swapped<T: Real>(l: &[T; 6]) -> [T; 6] {
    let [a, b, c, d, e, f] = *l;
    [d, e, f, a, b, c]
}

/// The Klein form Ω(a, b) = a_s·b_m + a_m·b_s.
fn klein<T: Real>(a: &[T; 6], b: &[T; 6]) -> T {
    super::dot(a, &swapped(b))
}

/// The line-geometry analysis of the tripod at a solution (see the module documentation).
pub fn analyse<T: Real>(
    sol: &Solution<T>,
    rp: T,
    tol: &Tolerances<T>,
) -> Result<LineAnalysis<T>, NotFinite> {
    analyse_jtilde(&tripod_jacobian(sol), rp, tol)
}

/// [`analyse`] from Jtilde itself (rows the Plücker lines [ŝ; m], moments about o_p).
pub fn analyse_jtilde<T: Real>(
    jtilde: &Matrix6<T>,
    rp: T,
    tol: &Tolerances<T>,
) -> Result<LineAnalysis<T>, NotFinite> {
    let lines = scaled_lines(jtilde, rp).ok_or(NotFinite)?;
    let full = decompose(&lines).ok_or(NotFinite)?;
    let smax = full.sigma_max();
    let threshold = tol.rank * smax;
    let rank = full.rank(threshold);
    let mut relative_sigma = full.sigma;
    for s in relative_sigma.iter_mut() {
        *s /= smax;
    }
    sort_descending(&mut relative_sigma);

    let mut circuits: HVec<Circuit, MAX_CIRCUITS> = HVec::new();
    if rank < 6 {
        // Subsets by size, so that every circuit contained in a larger dependent subset
        // is known before it.
        for size in 2u32..=6 {
            for mask in 1u8..64 {
                if mask.count_ones() != size || circuits.iter().any(|c| c.lines & mask == c.lines) {
                    continue;
                }
                let d = decompose(&select(&lines, mask, false)).ok_or(NotFinite)?;
                if u32::from(d.rank(threshold)) < size {
                    let variety = classify(&lines, mask, &d, threshold, tol);
                    // (Capacity: one per subset, so this cannot fail.)
                    let _ = circuits.push(Circuit {
                        lines: mask,
                        variety,
                    });
                }
            }
        }
    }

    let (null, n_null) = full.null_space(threshold);
    let mut gained: HVec<GainedMotion<T>, 6> = HVec::new();
    for y in null.iter().take(n_null) {
        let _ = gained.push(GainedMotion::from_scaled(y, rp, tol.rank));
    }
    let complex = if n_null == 1 {
        null.first().map(|y| {
            // The reciprocal screw [X_s; X_m] = [rp ω; v] in the scaled coordinates.
            let [v0, v1, v2, w0, w1, w2] = *y;
            complex_kind(&[w0, w1, w2, v0, v1, v2], tol.rank)
        })
    } else {
        None
    };
    Ok(LineAnalysis {
        rank,
        relative_sigma,
        circuits,
        gained,
        complex,
    })
}

fn sort_descending<T: Real>(s: &mut [T; 6]) {
    for i in 1..6 {
        let mut j = i;
        while j > 0 {
            let (Some(&a), Some(&b)) = (s.get(j - 1), s.get(j)) else {
                break;
            };
            if a < b {
                s.swap(j - 1, j);
                j -= 1;
            } else {
                break;
            }
        }
    }
}

/// 5A or 5B from the unit reciprocal screw X = [X_s; X_m].
fn complex_kind<T: Real>(x: &[T; 6], tol: T) -> Variety {
    let [a0, a1, a2, b0, b1, b2] = *x;
    if (a0 * b0 + a1 * b1 + a2 * b2).abs() > tol {
        Variety::GeneralComplex
    } else {
        Variety::SpecialComplex
    }
}

/// The variety of a circuit: the lines of `mask`, whose decomposition is `d`.
fn classify<T: Real>(
    lines: &[[T; 6]; 6],
    mask: u8,
    d: &Decomposition<T>,
    threshold: T,
    tol: &Tolerances<T>,
) -> Variety {
    match mask.count_ones() {
        2 => Variety::Coincident,
        3 => Variety::FlatPencil,
        4 => {
            // The Klein form on an orthonormal basis Q of the span: G = Qᵀ K Q, |G| ≤ 1.
            let (q, r) = d.row_space(threshold);
            if r != 3 {
                return Variety::Unclassified;
            }
            let mut g = [[T::zero(); 6]; 6];
            for (a, row) in g.iter_mut().enumerate().take(3) {
                for (b, x) in row.iter_mut().enumerate().take(3) {
                    if let (Some(qa), Some(qb)) = (q.get(a), q.get(b)) {
                        *x = klein(qa, qb);
                    }
                }
            }
            let Some(gd) = decompose(&g) else {
                return Variety::Unclassified;
            };
            match gd.rank(tol.rank) {
                3 => Variety::Regulus,
                2 => Variety::Union,
                0 => {
                    // Bundle or plane: the rank of three independent lines' directions.
                    let mut dirs = [[T::zero(); 6]; 6];
                    let mut n = 0;
                    for (k, l) in lines.iter().enumerate() {
                        if mask & (1 << k) != 0 && n < 3 {
                            if let Some(row) = dirs.get_mut(n) {
                                let [a, b, c, ..] = *l;
                                *row = [a, b, c, T::zero(), T::zero(), T::zero()];
                            }
                            n += 1;
                        }
                    }
                    match decompose(&dirs).map(|dd| dd.rank(tol.rank)) {
                        Some(1 | 3) => Variety::Bundle,
                        Some(0 | 2) => Variety::Plane,
                        _ => Variety::Unclassified,
                    }
                }
                _ => Variety::Unclassified,
            }
        }
        5 => {
            // The reciprocal 2-space: the null space of the swapped rows.
            let Some(sd) = decompose(&select(lines, mask, true)) else {
                return Variety::Unclassified;
            };
            let (n, count) = sd.null_space(threshold);
            let (Some(x), Some(y), 2) = (n.first(), n.get(1), count) else {
                return Variety::Unclassified;
            };
            let (a, b, c) = (klein(x, x), klein(x, y), klein(y, y));
            // Eigenvalues of [[a, b], [b, c]].
            let mid = (a + c) / lit(2.0);
            let rad = sqrt(((a - c) / lit(2.0)) * ((a - c) / lit(2.0)) + b * b);
            let (l1, l2) = (mid + rad, mid - rad);
            let big = |l: T| l.abs() > tol.rank;
            match (big(l1), big(l2)) {
                (true, true) if (l1 > T::zero()) != (l2 > T::zero()) => {
                    Variety::HyperbolicCongruence
                }
                (true, true) => Variety::EllipticCongruence,
                (true, false) | (false, true) => Variety::ParabolicCongruence,
                (false, false) => Variety::DegenerateCongruence,
            }
        }
        6 => {
            let Some(sd) = decompose(&select(lines, mask, true)) else {
                return Variety::Unclassified;
            };
            let (n, count) = sd.null_space(threshold);
            match (n.first(), count) {
                (Some(x), 1) => complex_kind(x, tol.rank),
                _ => Variety::Unclassified,
            }
        }
        _ => Variety::Unclassified,
    }
}
