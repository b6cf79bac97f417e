//! Linear least squares with the covariance of the estimate.
//!
//! For rows `y_i = a_i . theta + e_i` with independent errors of one variance, the estimate
//! is `theta = (A^T A)^-1 A^T y`, the error variance `s^2 = |y - A theta|^2 / (n - p)` and
//! the covariance of the estimate `s^2 (A^T A)^-1` (Gauss-Markov). The columns are scaled
//! to unit norm before the solve (the unknowns of one problem differ by many orders of
//! magnitude: kg next to N next to N s/m) and the solve is an SVD, so a rank-deficient
//! design is refused rather than answered with huge numbers.

use nalgebra::{DMatrix, DVector};

use crate::error::IdentifyError;

/// An estimate and its standard deviation (one sigma), in the unit of the quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The estimated value.
    pub value: f64,
    /// Its standard deviation.
    pub std: f64,
}

impl Estimate {
    /// The standard deviation over the magnitude of the value (infinite at 0).
    pub fn relative_std(&self) -> f64 {
        self.std / self.value.abs()
    }

    /// `c` times the estimate (its deviation scales by `|c|`).
    pub fn scaled(&self, c: f64) -> Estimate {
        Estimate {
            value: c * self.value,
            std: c.abs() * self.std,
        }
    }

    /// The product of two independent estimates, the deviation to first order.
    pub fn times(&self, other: &Estimate) -> Estimate {
        Estimate {
            value: self.value * other.value,
            std: ((self.std * other.value).powi(2) + (other.std * self.value).powi(2)).sqrt(),
        }
    }
}

/// The solution of one least-squares problem.
#[derive(Debug, Clone)]
pub struct Solution {
    /// The estimates, in the order of the columns.
    pub theta: Vec<Estimate>,
    /// Their covariance.
    pub covariance: DMatrix<f64>,
    /// The rms residual, in the unit of the rows.
    pub rms_residual: f64,
    /// Rows used.
    pub rows: usize,
}

/// Solves `rows` (each `(a_i, y_i)`) for `names.len()` unknowns; `what` names the problem
/// in errors, `names` the unknowns.
pub fn solve(
    what: &'static str,
    names: &[&'static str],
    rows: &[(Vec<f64>, f64)],
) -> Result<Solution, IdentifyError> {
    let p = names.len();
    let n = rows.len();
    if n < p + 2 {
        return Err(IdentifyError::TooFewRows {
            what,
            rows: n,
            needed: p + 2,
        });
    }
    let mut a = DMatrix::<f64>::zeros(n, p);
    let mut y = DVector::<f64>::zeros(n);
    for (i, (row, yi)) in rows.iter().enumerate() {
        if row.len() != p || !yi.is_finite() || row.iter().any(|v| !v.is_finite()) {
            return Err(IdentifyError::BadRow { what, row: i });
        }
        for (j, v) in row.iter().enumerate() {
            a[(i, j)] = *v;
        }
        y[i] = *yi;
    }
    // Unit-norm columns: theta_j = theta_scaled_j / norm_j.
    let mut norms = vec![0.0; p];
    for (j, norm) in norms.iter_mut().enumerate() {
        let c = a.column(j).norm();
        if c == 0.0 {
            return Err(IdentifyError::Unidentifiable {
                what,
                unknown: names[j],
            });
        }
        *norm = c;
        a.column_mut(j).scale_mut(1.0 / c);
    }
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    // 1e-9 of the largest: beyond it the rows do not tell the unknowns apart.
    if smin <= 1e-9 * smax {
        let weakest = svd
            .v_t
            .as_ref()
            .and_then(|vt| {
                let k = svd.singular_values.imin();
                names.get(vt.row(k).iamax_full().1).copied()
            })
            .unwrap_or(names[0]);
        return Err(IdentifyError::Unidentifiable {
            what,
            unknown: weakest,
        });
    }
    let theta_s = svd
        .solve(&y, 0.0)
        .map_err(|_| IdentifyError::Unidentifiable {
            what,
            unknown: names[0],
        })?;
    let residual = &y - &a * &theta_s;
    let dof = (n - p) as f64;
    let s2 = residual.norm_squared() / dof;
    // (A^T A)^-1 = V S^-2 V^T.
    let vt = svd.v_t.ok_or(IdentifyError::Unidentifiable {
        what,
        unknown: names[0],
    })?;
    let mut inv = DMatrix::<f64>::zeros(p, p);
    for k in 0..p {
        let s = svd.singular_values[k];
        let v = vt.row(k).transpose();
        inv += (&v * v.transpose()) / (s * s);
    }
    let mut cov = inv * s2;
    for i in 0..p {
        for j in 0..p {
            cov[(i, j)] /= norms[i] * norms[j];
        }
    }
    let theta = (0..p)
        .map(|j| Estimate {
            value: theta_s[j] / norms[j],
            std: cov[(j, j)].max(0.0).sqrt(),
        })
        .collect();
    Ok(Solution {
        theta,
        covariance: cov,
        rms_residual: (residual.norm_squared() / n as f64).sqrt(),
        rows: n,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A line through noisy points: the estimate lands within a few sigma of the truth and
    /// the reported sigma matches the textbook formula for the slope.
    #[test]
    fn a_line_and_its_slope_deviation() {
        let xs: Vec<f64> = (0..200).map(|i| i as f64 * 0.01).collect();
        // A deterministic, zero-mean "noise" of known rms (a fast sine): rms 0.1/sqrt 2.
        let rows: Vec<(Vec<f64>, f64)> = xs
            .iter()
            .enumerate()
            .map(|(i, x)| (vec![1.0, *x], 3.0 + 2.0 * x + 0.1 * (i as f64 * 2.7).sin()))
            .collect();
        let s = solve("line", &["a", "b"], &rows).unwrap();
        let sigma = 0.1 / 2f64.sqrt();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let sxx: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
        let slope_std = sigma / sxx.sqrt();
        assert!((s.theta[1].value - 2.0).abs() < 4.0 * slope_std);
        assert!(
            (s.theta[1].std / slope_std - 1.0).abs() < 0.1,
            "{:?}",
            s.theta[1]
        );
    }

    #[test]
    fn collinear_columns_are_refused() {
        let rows: Vec<(Vec<f64>, f64)> = (0..10)
            .map(|i| (vec![i as f64, 2.0 * i as f64], i as f64))
            .collect();
        assert!(matches!(
            solve("twins", &["a", "b"], &rows),
            Err(IdentifyError::Unidentifiable { .. })
        ));
    }
}
