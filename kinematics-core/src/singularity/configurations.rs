//! The singular configurations S1..S13 of thesis Table 10.3: geometric conditions on the
//! platform plane P0 (through the revolute centres p_i, normal n), the tripod base plane
//! B0 (through the spherical-joint centres b_i), the planes pF_i of the constant flat
//! pencils F_i = (l_i, l_{i+3}) (through b_i, spanned by ŝ1_i and ŝ2_i) and the lines
//! l_1..l_6 of Jtilde (l_i along ŝ1_i through p_i, l_{i+3} along ŝ2_i through b_i).
//!
//! Each condition is measured by a residual, zero when it holds exactly: lengths over rp,
//! sines of angles, or the smallest singular value of unit-normalised rows (all
//! dimensionless); a condition holds when its residual is at most the geometric tolerance
//! ([`super::lines::Tolerances`]). Where the thesis states a condition for several index
//! sets, the residual is the smallest over them and the index set that gives it is kept.
//!
//! | S | condition measured | thesis |
//! | --- | --- | --- |
//! | S1 | every b_i in P0 (B0 = P0) | 10.4 |
//! | S2 | b_j, b_k in P0 and b_j = o_p | 10.5 |
//! | S3 | b_1 = b_2 = b_3 | 10.6 |
//! | S4 | p_j, p_k in B0 (pT_jk = B0) and b_i on l_j and l_k | 10.7 |
//! | S5 | b_j, b_{j±1} in P0: the same residual as S9 (pF_j = P0 exactly when b_j ∈ P0) | 10.8-9 |
//! | S6/S7 | B0 ∥ P0 and l_4, l_5, l_6 in one flat pencil | 10.10-11 |
//! | S8 | b_j = b_k | 10.12 |
//! | S9 | b_j, b_k in P0 (l_j, l_k in P0) | 10.15 |
//! | S10 | p_n in B0 (l_n ⊂ B0) and pF_j ∩ pF_k ∩ B0 on l_n, n ∈ 1..3 | 10.16 |
//! | S11 | ŝ2 of chain n-3 parallel to B0 (l_n ⊂ B0) and pF_j ∩ pF_k ∩ B0 on l_n, (j,k,n) ∈ {(1,2,6),(2,3,4),(3,1,5)} | 10.17 |
//! | S12 | pF_1, pF_2, pF_3 and B0 share a point: the smallest singular value of their four unit plane rows [n̂; -n̂·x / rp] | 10.19 |
//! | S13 | b_1, b_2, b_3 collinear: the triangle's smallest height over rp | 10.21 |
//!
//! S3 and S4 also ask r_i ∥ p_j p_k, which the symmetric platform satisfies by its
//! architecture (r_i = z_p × u_i is perpendicular to u_i, and so is u_j - u_k); it is
//! not measured. S6 and S7 are one condition in the thesis (two figures of it). S2, S5 are
//! special cases of S9; S4, S6/S7, S10, S11 of S12; S3, S8 of S13; the independent ones
//! are S1, S9, S12 and S13 (Table 10.3): at every parallel singularity one of them holds,
//! and S1 and S9 are themselves special cases of S12 (when b_j, b_k ∈ P0, the planes pF_j
//! = pF_k = P0 meet B0 along b_j b_k, which pF of the third chain crosses).

use super::dense::decompose;
use super::lines::Tolerances;
use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::scalar::{lit, sqrt, Real};
use core::fmt;
use nalgebra::{Matrix3, Vector3};

/// A singular configuration of Table 10.3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Configuration {
    S1,
    S2,
    S3,
    S4,
    S5,
    /// S6 and S7 (one condition).
    S6S7,
    S8,
    S9,
    S10,
    S11,
    S12,
    S13,
}

impl Configuration {
    /// Every configuration, in the thesis's order.
    pub const ALL: [Configuration; 12] = [
        Configuration::S1,
        Configuration::S2,
        Configuration::S3,
        Configuration::S4,
        Configuration::S5,
        Configuration::S6S7,
        Configuration::S8,
        Configuration::S9,
        Configuration::S10,
        Configuration::S11,
        Configuration::S12,
        Configuration::S13,
    ];

    /// The thesis's name ("S6/7" for S6 and S7).
    pub const fn name(self) -> &'static str {
        match self {
            Configuration::S1 => "S1",
            Configuration::S2 => "S2",
            Configuration::S3 => "S3",
            Configuration::S4 => "S4",
            Configuration::S5 => "S5",
            Configuration::S6S7 => "S6/7",
            Configuration::S8 => "S8",
            Configuration::S9 => "S9",
            Configuration::S10 => "S10",
            Configuration::S11 => "S11",
            Configuration::S12 => "S12",
            Configuration::S13 => "S13",
        }
    }

    /// One of the four independent configurations (S1, S9, S12, S13).
    pub const fn is_independent(self) -> bool {
        matches!(
            self,
            Configuration::S1 | Configuration::S9 | Configuration::S12 | Configuration::S13
        )
    }
}

impl fmt::Display for Configuration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The residual of one configuration's condition at a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual<T: Real> {
    pub configuration: Configuration,
    /// Dimensionless residual (module documentation); zero when the condition holds.
    pub residual: T,
    /// The chain or line numbers of the index set that gives it (0 = unused): S2, S8, S9
    /// and S5 the two chains j, k; S4 the chains j, k of the leg lines and the chain i of
    /// the spherical joint; S10, S11 the chains j, k of the planes and the line n.
    pub indices: [u8; 3],
}

impl<T: Real> Residual<T> {
    /// The condition holds within `tol`.
    pub fn holds(&self, tol: &Tolerances<T>) -> bool {
        !(self.residual > tol.geometry)
    }
}

impl<T: Real> fmt::Display for Residual<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.configuration.name())?;
        let used: [u8; 3] = self.indices;
        if used.iter().any(|&i| i != 0) {
            f.write_str("(")?;
            let mut first = true;
            for i in used.iter().filter(|&&i| i != 0) {
                if !first {
                    f.write_str(",")?;
                }
                write!(f, "{i}")?;
                first = false;
            }
            f.write_str(")")?;
        }
        Ok(())
    }
}

/// The residuals of all twelve conditions, in [`Configuration::ALL`]'s order.
pub type Residuals<T> = [Residual<T>; 12];

/// A plane through `x` with unit normal `n`.
#[derive(Clone, Copy, Debug)]
struct Plane<T: Real> {
    n: Vector3<T>,
    x: Vector3<T>,
}

impl<T: Real> Plane<T> {
    fn distance(&self, p: &Vector3<T>) -> T {
        self.n.dot(&(p - self.x)).abs()
    }
}

fn unit<T: Real>(v: &Vector3<T>) -> Option<Vector3<T>> {
    let n = v.norm();
    if n > T::zero() && n.is_finite() {
        Some(v / n)
    } else {
        None
    }
}

/// Distance from `x` to the line through `p` along the unit `s`.
fn line_distance<T: Real>(x: &Vector3<T>, p: &Vector3<T>, s: &Vector3<T>) -> T {
    (x - p).cross(s).norm()
}

/// The point common to three planes, None when they do not meet in one point.
fn meet<T: Real>(a: &Plane<T>, b: &Plane<T>, c: &Plane<T>) -> Option<Vector3<T>> {
    let m = Matrix3::from_rows(&[a.n.transpose(), b.n.transpose(), c.n.transpose()]);
    let rhs = Vector3::new(a.n.dot(&a.x), b.n.dot(&b.x), c.n.dot(&c.x));
    let x = m.lu().solve(&rhs)?;
    if x.iter().all(|v| v.is_finite()) {
        Some(x)
    } else {
        None
    }
}

const fn num(c: Chain) -> u8 {
    c.number()
}

/// The residuals of S1..S13 at a solution (module documentation). Infinite where a
/// condition's objects are undefined (B0 when the b_i are collinear, an intersection point
/// of planes that do not meet in one).
pub fn residuals<T: Real>(sol: &Solution<T>, rp: T) -> Residuals<T> {
    let inf = T::max_value().unwrap_or(lit(1.0e30));
    let op = sol.pose.t;
    let n = sol.pose.r * Vector3::z();
    let p0 = Plane { n, x: op };
    let ch = &sol.chains;
    let b = ch.map(|_, c| c.b);
    let p = ch.map(|_, c| c.p);
    let s1 = ch.map(|_, c| c.s1);
    let s2 = ch.map(|_, c| c.s2);
    let [b1, b2, b3] = b.0;
    let r = |x: T| x / rp;
    let mk = |configuration, residual, indices| Residual {
        configuration,
        residual,
        indices,
    };
    // Chain pairs (j, k) with the third chain i.
    let pairs = [
        (Chain::One, Chain::Two, Chain::Three),
        (Chain::Two, Chain::Three, Chain::One),
        (Chain::Three, Chain::One, Chain::Two),
    ];

    // S1: every b_i in P0.
    let in_p0 = b.map(|_, bi| r(p0.distance(bi)));
    let s1v = in_p0.0.iter().fold(T::zero(), |a, &x| a.max(x));
    // S9 / S5 / S2: two b's in P0 (and, S2, one of them at o_p).
    let mut s9 = (inf, [0u8; 3]);
    let mut s2v = (inf, [0u8; 3]);
    for (j, k, _) in pairs {
        let v = in_p0[j].max(in_p0[k]);
        if v < s9.0 {
            s9 = (v, [num(j), num(k), 0]);
        }
        for (a, c) in [(j, k), (k, j)] {
            let w = v.max(r((b[a] - op).norm()));
            if w < s2v.0 {
                s2v = (w, [num(a), num(c), 0]);
            }
        }
    }
    // S8 and S3: coincident spherical joints.
    let mut s8 = (inf, [0u8; 3]);
    let mut s3v = T::zero();
    for (j, k, _) in pairs {
        let d = r((b[j] - b[k]).norm());
        s3v = s3v.max(d);
        if d < s8.0 {
            s8 = (d, [num(j), num(k), 0]);
        }
    }
    // S13: the smallest height of the triangle b1 b2 b3 over rp.
    let longest = (b2 - b1).norm().max((b3 - b2).norm()).max((b1 - b3).norm());
    let twice_area = (b2 - b1).cross(&(b3 - b1)).norm();
    let s13 = if longest > T::zero() {
        r(twice_area / longest)
    } else {
        T::zero()
    };
    // B0 and the planes pF_i.
    let b0 = unit(&(b2 - b1).cross(&(b3 - b1))).map(|nb| Plane { n: nb, x: b1 });
    let pf: PerChain<Option<Plane<T>>> =
        ch.map(|_, c| unit(&c.s1.cross(&c.s2)).map(|nf| Plane { n: nf, x: c.b }));

    let (mut s4, mut s67, mut s10, mut s11, mut s12) =
        ((inf, [0u8; 3]), inf, (inf, [0u8; 3]), (inf, [0u8; 3]), inf);
    if let Some(b0) = b0 {
        // S4: l_j, l_k in B0 (their p's in it), b_i at their intersection.
        for (j, k, i) in pairs {
            let v = r(b0.distance(&p[j]))
                .max(r(b0.distance(&p[k])))
                .max(r(line_distance(&b[i], &p[j], &s1[j])))
                .max(r(line_distance(&b[i], &p[k], &s1[k])));
            if v < s4.0 {
                s4 = (v, [num(j), num(k), num(i)]);
            }
        }
        // S6/S7: B0 ∥ P0 and l4, l5, l6 in one flat pencil (rank 2).
        let parallel = b0.n.cross(&n).norm();
        let mut rows = [[T::zero(); 6]; 6];
        for (row, c) in rows.iter_mut().zip(ch.0.iter()) {
            let m = (c.b - op).cross(&c.s2) / rp;
            let l = [c.s2.x, c.s2.y, c.s2.z, m.x, m.y, m.z];
            let nl = sqrt(l.iter().fold(T::zero(), |a, &x| a + x * x));
            for (o, x) in row.iter_mut().zip(l.iter()) {
                *o = *x / nl;
            }
        }
        if let Some(d) = decompose(&rows) {
            let mut s = d.sigma;
            s.sort_unstable_by(|a, c| c.partial_cmp(a).unwrap_or(core::cmp::Ordering::Equal));
            s67 = parallel.max(s[2]);
        }
        // S10, S11: the point X = pF_j ∩ pF_k ∩ B0 on a line l_n of B0.
        for (j, k, i) in pairs {
            let (Some(fj), Some(fk)) = (pf[j], pf[k]) else {
                continue;
            };
            let Some(x) = meet(&fj, &fk, &b0) else {
                continue;
            };
            // S10: n = i (the third chain's leg line l_i, through p_i and b_i).
            let v10 = r(b0.distance(&p[i])).max(r(line_distance(&x, &b[i], &s1[i])));
            if v10 < s10.0 {
                s10 = (v10, [num(j), num(k), num(i)]);
            }
            // S11: (j, k, n) ∈ {(1,2,6),(2,3,4),(3,1,5)}: n = i + 3, the line along ŝ2_i
            // through b_i.
            let v11 =
                b0.n.dot(&s2[i])
                    .abs()
                    .max(r(line_distance(&x, &b[i], &s2[i])));
            if v11 < s11.0 {
                s11 = (v11, [num(j), num(k), num(i) + 3]);
            }
        }
        // S12: the four planes share a point.
        let mut rows = [[T::zero(); 6]; 6];
        let planes = [pf[Chain::One], pf[Chain::Two], pf[Chain::Three], Some(b0)];
        let mut ok = true;
        for (row, pl) in rows.iter_mut().zip(planes.iter()) {
            match pl {
                Some(pl) => {
                    let d = -pl.n.dot(&pl.x) / rp;
                    let nl = sqrt(T::one() + d * d);
                    *row = [
                        pl.n.x / nl,
                        pl.n.y / nl,
                        pl.n.z / nl,
                        d / nl,
                        T::zero(),
                        T::zero(),
                    ];
                }
                None => ok = false,
            }
        }
        if ok {
            if let Some(d) = decompose(&rows) {
                let mut s = d.sigma;
                s.sort_unstable_by(|a, c| c.partial_cmp(a).unwrap_or(core::cmp::Ordering::Equal));
                s12 = s[3];
            }
        }
    }
    [
        mk(Configuration::S1, s1v, [0; 3]),
        mk(Configuration::S2, s2v.0, s2v.1),
        mk(Configuration::S3, s3v, [0; 3]),
        mk(Configuration::S4, s4.0, s4.1),
        mk(Configuration::S5, s9.0, s9.1),
        mk(Configuration::S6S7, s67, [0; 3]),
        mk(Configuration::S8, s8.0, s8.1),
        mk(Configuration::S9, s9.0, s9.1),
        mk(Configuration::S10, s10.0, s10.1),
        mk(Configuration::S11, s11.0, s11.1),
        mk(Configuration::S12, s12, [0; 3]),
        mk(Configuration::S13, s13, [0; 3]),
    ]
}
