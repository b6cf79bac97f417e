//! Jacobians: the tripod Jacobian Jtilde whose rows are Plücker lines (Eq. 7.14), the serial
//! part Js (RSPR Eq. 7.21, USR B of Eq. 7.31) and J = Js⁻¹ Jtilde = dq/dx (Eq. 7.18).

use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::mechanism::{Mechanism, SerialBlock};
use crate::scalar::{lit, Real};
use core::fmt;
use nalgebra::{Matrix6, RowVector6, Vector3};

/// Why J = Js⁻¹ Jtilde does not exist.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JacobianError {
    /// The serial block of a chain is singular (RSPR Cn2_i = 0, Eq. 10.6; USR Eq. 10.11):
    /// finite platform twists need infinite joint rates.
    SerialSingular {
        chain: Chain,
        /// The chain's dimensionless serial measure (RSPR |Cn2|/rb, USR |det|/l1²).
        relative_det: f64,
    },
}

impl fmt::Display for JacobianError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JacobianError::SerialSingular {
                chain,
                relative_det,
            } => write!(
                f,
                "{chain} is at a serial singularity (relative |det| {relative_det:.3e})"
            ),
        }
    }
}

/// One Plücker line [ŝ; (x - o_p) × ŝ] with the moment taken about o_p (Eq. 7.13).
pub(crate) fn plucker<T: Real>(s: &Vector3<T>, through_minus_op: &Vector3<T>) -> RowVector6<T> {
    let mo = through_minus_op.cross(s);
    RowVector6::new(s.x, s.y, s.z, mo.x, mo.y, mo.z)
}

/// The two Plücker lines of each chain (Eq. 7.14): ŝ1_i through p_i and ŝ2_i through b_i,
/// in {0}, moments about o_p.
fn chain_lines<T: Real>(sol: &Solution<T>) -> PerChain<(RowVector6<T>, RowVector6<T>)> {
    let t = sol.pose.t;
    sol.chains
        .map(|_, c| (plucker(&c.s1, &(c.p - t)), plucker(&c.s2, &(c.b - t))))
}

fn stack<T: Real>(top: &PerChain<RowVector6<T>>, bottom: &PerChain<RowVector6<T>>) -> Matrix6<T> {
    let [a1, a2, a3] = top.0;
    let [b1, b2, b3] = bottom.0;
    Matrix6::from_rows(&[a1, a2, a3, b1, b2, b3])
}

/// The tripod Jacobian Jtilde (Eq. 7.14): rows 1..3 the lines ŝ1_i through p_i, rows 4..6
/// the lines ŝ2_i through b_i.
pub fn tripod_jacobian<T: Real>(sol: &Solution<T>) -> Matrix6<T> {
    let lines = chain_lines(sol);
    stack(&lines.map(|_, l| l.0), &lines.map(|_, l| l.1))
}

/// All the Jacobians at one solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jacobians<T: Real> {
    /// Tripod Jacobian Jtilde (Eq. 7.14), the instantaneous direct kinematics matrix A.
    pub jtilde: Matrix6<T>,
    /// Per-chain blocks of the serial Jacobian Js (Eq. 7.21 / B of Eq. 7.31).
    pub serial: PerChain<SerialBlock<T>>,
    /// J = Js⁻¹ Jtilde = dq/dx (Eq. 7.18): rows in q order, columns [v; ω], SI.
    pub j: Matrix6<T>,
}

/// Smallest dimensionless serial measure (see [`Mechanism::serial_measure`]) for which J is
/// still formed; below it the chain counts as serially singular.
pub fn serial_singular_tolerance<T: Real>() -> T {
    (T::default_epsilon() * lit(1.0e3)).max(lit(1.0e-9))
}

/// The Jacobians at an inverse-kinematics solution.
pub fn jacobian<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    sol: &Solution<T>,
) -> Result<Jacobians<T>, JacobianError> {
    let serial = sol.chains.map(|_, c| m.serial_block(c));
    let relative = sol.chains.map(|_, c| m.serial_measure(c).1);
    compose(chain_lines(sol), serial, relative)
}

/// J = Js⁻¹ Jtilde (Eq. 7.18) from each chain's two Plücker lines, its serial block and its
/// dimensionless serial measure (below [`serial_singular_tolerance`]: singular).
pub(crate) fn compose<T: Real>(
    lines: PerChain<(RowVector6<T>, RowVector6<T>)>,
    serial: PerChain<SerialBlock<T>>,
    relative: PerChain<T>,
) -> Result<Jacobians<T>, JacobianError> {
    let tol = serial_singular_tolerance::<T>();
    // Chain by chain: [J_qa_i; J_qb_i] = B_i⁻¹ [Jt_i; Jt_{3+i}].
    let rows = PerChain::try_from_fn(|chain| {
        let blk = &serial[chain];
        let det = blk.det();
        if !(relative[chain] > tol) || !det.is_finite() {
            return Err(JacobianError::SerialSingular {
                chain,
                relative_det: crate::geometry::to_f64(relative[chain]),
            });
        }
        let (r1, r2) = lines[chain];
        Ok((
            (r1 * blk.a22 - r2 * blk.a12) / det,
            (r2 * blk.a11 - r1 * blk.a21) / det,
        ))
    })?;
    Ok(Jacobians {
        jtilde: stack(&lines.map(|_, l| l.0), &lines.map(|_, l| l.1)),
        serial,
        j: stack(&rows.map(|_, r| r.0), &rows.map(|_, r| r.1)),
    })
}
