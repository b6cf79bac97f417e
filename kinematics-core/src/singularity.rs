//! Singularity measures (CONVENTIONS.md, "Measures"; thesis chapter 10).

use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::jacobian::tripod_jacobian;
use crate::mechanism::Mechanism;
use crate::scalar::Real;
use core::fmt;
use nalgebra::linalg::SVD;
use nalgebra::Matrix6;

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

/// Inverse condition number of Jtilde with its moment columns (4..6) divided by rp.
pub fn parallel_inv_cond<T: Real>(jtilde: &Matrix6<T>, rp: T) -> Result<T, SvdDidNotConverge> {
    let mut scaled = *jtilde;
    for mut col in scaled.column_iter_mut().skip(3) {
        col /= rp;
    }
    let svd =
        SVD::try_new(scaled, false, false, T::default_epsilon(), 200).ok_or(SvdDidNotConverge)?;
    let sv = svd.singular_values;
    let (max, min) = (sv.max(), sv.min());
    if max > T::zero() && min.is_finite() {
        Ok(min / max)
    } else if max == T::zero() {
        Ok(T::zero())
    } else {
        Err(SvdDidNotConverge)
    }
}

/// Sign of a determinant, with exact zero kept.
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
