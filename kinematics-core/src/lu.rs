//! The 6×6 linear systems of the control path: LU factorisation with partial pivoting
//! (Golub & Van Loan, "Matrix Computations", algorithm 3.4.1), written out.
//!
//! The systems are Jtilde Δx = Js Δq (each step of the forward kinematics, Eq. 7.17-7.18)
//! and Jtildeᵀ f = s_e (the statics, Eq. 7.15); one factorisation serves both directions
//! ([`Lu6::solve`], [`Lu6::solve_transposed`]), so the statics need no transposed copy.
//!
//! Why not nalgebra's LU: the algorithm is the same, but at the firmware's opt-level "s"
//! its generic loops cost several times the arithmetic on the Cortex-M4: about 1,000 to
//! 1,300 instructions to factorise and 550 to solve, against about 500 and 150 here, where
//! every loop over the six rows and columns is written out (`firmware/cortex-m/on-target`;
//! the same code with loops is no faster than nalgebra's). `tests/lu.rs` checks it
//! against nalgebra's LU.

use crate::scalar::Real;
use nalgebra::{Matrix6, Vector6};

/// The factors of a 6×6 matrix A, taken as P B = L U with B = Aᵀ: nalgebra stores A by
/// columns, which are the rows of Aᵀ, so the factorisation works on A's storage as it is.
/// L is unit lower triangular (its multipliers stored below the diagonal), U upper
/// triangular (on and above it), P the row permutation. A x = b is then Uᵀ Lᵀ P x = b,
/// and Aᵀ x = b is L U x = P b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lu6<T: Real> {
    /// L and U by rows (the rows of B = Aᵀ, i.e. A's columns).
    a: [[T; 6]; 6],
    /// Row k of P B is row `perm[k]` of B (bytes: the factors are copied on the control
    /// path, and 16 bytes fewer are 16 fewer to copy).
    perm: [u8; 6],
}

/// Elimination step `k`: partial pivoting over the rows listed, then the rows below the
/// pivot reduced over the columns listed (the same indices, k+1..6).
macro_rules! eliminate {
    ($a:ident, $perm:ident, $k:literal, [$($i:literal)*], $cols:tt) => {{
        // The largest magnitude in column k on or below the diagonal comes to row k (the
        // first of equal ones stays).
        $(
            if $a[$i][$k].abs() > $a[$k][$k].abs() {
                $a.swap($k, $i);
                $perm.swap($k, $i);
            }
        )*
        let pivot = $a[$k][$k];
        if !(pivot.abs() > T::zero() && pivot.is_finite()) {
            return None;
        }
        #[allow(unused_variables)] // (the last step has no row below)
        let inv = T::one() / pivot;
        $( reduce_row!($a, $k, $i, inv, $cols); )*
    }};
}

/// Row i minus f times row k over the columns listed, f = a[i][k] / pivot stored as L's
/// multiplier.
macro_rules! reduce_row {
    ($a:ident, $k:literal, $i:literal, $inv:ident, [$($j:literal)*]) => {{
        let f = $a[$i][$k] * $inv;
        $a[$i][$k] = f;
        $( $a[$i][$j] -= f * $a[$k][$j]; )*
    }};
}

/// Σ m[i][j]·v[j] over the j listed (row i of a triangle times v).
macro_rules! row_sum {
    ($m:ident, $v:ident, $i:literal, [$($j:literal)*]) => {
        T::zero() $( + $m[$i][$j] * $v[$j] )*
    };
}

/// Σ m[j][i]·v[j] over the j listed (column i of a triangle times v: the transposed).
macro_rules! col_sum {
    ($m:ident, $v:ident, $i:literal, [$($j:literal)*]) => {
        T::zero() $( + $m[$j][$i] * $v[$j] )*
    };
}

impl<T: Real> Lu6<T> {
    /// Factorises `m`; None when a pivot is zero or not finite (the matrix is singular to
    /// working precision, or not finite).
    pub fn new(m: &Matrix6<T>) -> Option<Self> {
        let mut a = m.data.0;
        let mut perm: [u8; 6] = [0, 1, 2, 3, 4, 5];
        eliminate!(a, perm, 0, [1 2 3 4 5], [1 2 3 4 5]);
        eliminate!(a, perm, 1, [2 3 4 5], [2 3 4 5]);
        eliminate!(a, perm, 2, [3 4 5], [3 4 5]);
        eliminate!(a, perm, 3, [4 5], [4 5]);
        eliminate!(a, perm, 4, [5], [5]);
        eliminate!(a, perm, 5, [], []);
        Some(Lu6 { a, perm })
    }

    /// x with A x = b: Uᵀ y = b (forward), Lᵀ z = y (backward), x = Pᵀ z.
    pub fn solve(&self, b: &Vector6<T>) -> Vector6<T> {
        let a = &self.a;
        let [mut z] = b.data.0;
        z[0] /= a[0][0];
        z[1] = (z[1] - col_sum!(a, z, 1, [0])) / a[1][1];
        z[2] = (z[2] - col_sum!(a, z, 2, [0 1])) / a[2][2];
        z[3] = (z[3] - col_sum!(a, z, 3, [0 1 2])) / a[3][3];
        z[4] = (z[4] - col_sum!(a, z, 4, [0 1 2 3])) / a[4][4];
        z[5] = (z[5] - col_sum!(a, z, 5, [0 1 2 3 4])) / a[5][5];
        z[4] -= col_sum!(a, z, 4, [5]);
        z[3] -= col_sum!(a, z, 3, [4 5]);
        z[2] -= col_sum!(a, z, 2, [3 4 5]);
        z[1] -= col_sum!(a, z, 1, [2 3 4 5]);
        z[0] -= col_sum!(a, z, 0, [1 2 3 4 5]);
        let mut x = [T::zero(); 6];
        for (zi, p) in z.iter().zip(self.perm.iter()) {
            if let Some(xp) = x.get_mut(usize::from(*p)) {
                *xp = *zi;
            }
        }
        Vector6::from(x)
    }

    /// x with Aᵀ x = b: L y = P b (forward), U x = y (backward).
    pub fn solve_transposed(&self, b: &Vector6<T>) -> Vector6<T> {
        let a = &self.a;
        let [b] = &b.data.0;
        let mut x = [T::zero(); 6];
        for (xi, p) in x.iter_mut().zip(self.perm.iter()) {
            *xi = b.get(usize::from(*p)).copied().unwrap_or_else(T::zero);
        }
        x[1] -= row_sum!(a, x, 1, [0]);
        x[2] -= row_sum!(a, x, 2, [0 1]);
        x[3] -= row_sum!(a, x, 3, [0 1 2]);
        x[4] -= row_sum!(a, x, 4, [0 1 2 3]);
        x[5] -= row_sum!(a, x, 5, [0 1 2 3 4]);
        x[5] /= a[5][5];
        x[4] = (x[4] - row_sum!(a, x, 4, [5])) / a[4][4];
        x[3] = (x[3] - row_sum!(a, x, 3, [4 5])) / a[3][3];
        x[2] = (x[2] - row_sum!(a, x, 2, [3 4 5])) / a[2][2];
        x[1] = (x[1] - row_sum!(a, x, 1, [2 3 4 5])) / a[1][1];
        x[0] = (x[0] - row_sum!(a, x, 0, [1 2 3 4 5])) / a[0][0];
        Vector6::from(x)
    }
}
