//! The singular values and right singular vectors of a matrix of at most six rows and six
//! columns, for the line-geometry analysis ([`super::lines`], [`super::configurations`]):
//! the same one-sided Jacobi rotations as [`super::ConditionEstimator`], run from a cold
//! start to convergence and returning V as well. Rows beyond the matrix's own are zero.

use super::{dot, rotate_pair};
use crate::scalar::{lit, sqrt, Real};

/// Sweeps allowed: a cold cyclic Jacobi decomposition of a 6x6 matrix converges in 5 to 7
/// (quadratic convergence once the off-diagonal terms are small); 30 leaves a wide margin.
const SWEEPS: u8 = 30;

/// A = W Vᵀ with the columns of W orthogonal: σ_j = |w_j| and v_j the right singular
/// vectors, in no particular order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Decomposition<T: Real> {
    /// Singular values (the column norms of W), one per column of V.
    pub sigma: [T; 6],
    /// Right singular vectors, by column.
    pub v: [[T; 6]; 6],
}

impl<T: Real> Decomposition<T> {
    /// The largest singular value.
    pub fn sigma_max(&self) -> T {
        self.sigma
            .iter()
            .fold(T::zero(), |a, &s| if s > a { s } else { a })
    }

    /// How many singular values exceed `threshold`.
    pub fn rank(&self, threshold: T) -> u8 {
        self.sigma.iter().filter(|&&s| s > threshold).count() as u8
    }

    /// The right singular vectors whose singular value is at most `threshold` (an
    /// orthonormal basis of the null space), with the count.
    pub fn null_space(&self, threshold: T) -> ([[T; 6]; 6], usize) {
        let mut out = [[T::zero(); 6]; 6];
        let mut n = 0;
        for (s, v) in self.sigma.iter().zip(self.v.iter()) {
            if !(*s > threshold) {
                if let Some(slot) = out.get_mut(n) {
                    *slot = *v;
                    n += 1;
                }
            }
        }
        (out, n)
    }

    /// The right singular vectors whose singular value exceeds `threshold` (an orthonormal
    /// basis of the row space), with the count.
    pub fn row_space(&self, threshold: T) -> ([[T; 6]; 6], usize) {
        let mut out = [[T::zero(); 6]; 6];
        let mut n = 0;
        for (s, v) in self.sigma.iter().zip(self.v.iter()) {
            if *s > threshold {
                if let Some(slot) = out.get_mut(n) {
                    *slot = *v;
                    n += 1;
                }
            }
        }
        (out, n)
    }
}

/// The decomposition of the matrix whose rows are `rows`; None for a non-finite input or
/// (never seen) no convergence.
pub(crate) fn decompose<T: Real>(rows: &[[T; 6]; 6]) -> Option<Decomposition<T>> {
    // W starts as A itself, by columns; V = I.
    let mut w = [[T::zero(); 6]; 6];
    let mut norm2 = T::zero();
    for (r, row) in rows.iter().enumerate() {
        for (c, &x) in row.iter().enumerate() {
            if let Some(slot) = w.get_mut(c).and_then(|col| col.get_mut(r)) {
                *slot = x;
            }
            norm2 += x * x;
        }
    }
    if !norm2.is_finite() {
        return None;
    }
    let mut v = super::identity::<T>();
    if norm2 == T::zero() {
        return Some(Decomposition {
            sigma: [T::zero(); 6],
            v,
        });
    }
    let noise = T::default_epsilon() * lit(8.0) * sqrt(norm2);
    let floor = noise * noise;
    let tol = T::default_epsilon() * lit(64.0);
    for _ in 0..SWEEPS {
        let mut norms = [T::zero(); 6];
        for (n, col) in norms.iter_mut().zip(w.iter()) {
            *n = dot(col, col);
        }
        let mut largest = T::zero();
        for i in 0..5 {
            for j in (i + 1)..6 {
                let r = rotate_pair(&mut w, &mut v, &mut norms, (i, j), tol, floor);
                if r > largest {
                    largest = r;
                }
            }
        }
        if largest < tol {
            let mut sigma = [T::zero(); 6];
            for (s, col) in sigma.iter_mut().zip(w.iter()) {
                *s = sqrt(dot(col, col));
            }
            return Some(Decomposition { sigma, v });
        }
    }
    None
}
