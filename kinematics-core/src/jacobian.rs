//! Jacobians: the tripod Jacobian Jtilde whose rows are Plücker lines (Eq. 7.14), the serial
//! part Js (RSPR Eq. 7.21, USR B of Eq. 7.31) and J = Js⁻¹ Jtilde = dq/dx (Eq. 7.18).

use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::mechanism::{Mechanism, SerialBlock};
use crate::scalar::{cross3, lit, sub3, Real};
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
    let mo = cross3(through_minus_op, s);
    RowVector6::new(s.x, s.y, s.z, mo.x, mo.y, mo.z)
}

/// The two Plücker lines of each chain (Eq. 7.14): ŝ1_i through p_i and ŝ2_i through b_i,
/// in {0}, moments about o_p.
fn chain_lines<T: Real>(sol: &Solution<T>) -> PerChain<(RowVector6<T>, RowVector6<T>)> {
    let t = sol.pose.t;
    sol.chains.map(|_, c| {
        (
            plucker(&c.s1, &sub3(&c.p, &t)),
            plucker(&c.s2, &sub3(&c.b, &t)),
        )
    })
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

impl<T: Real> Jacobians<T> {
    /// All zero (a placeholder to be filled by [`jacobian_into`]).
    pub fn zeroed() -> Self {
        let b = SerialBlock {
            a11: T::zero(),
            a12: T::zero(),
            a21: T::zero(),
            a22: T::zero(),
        };
        Jacobians {
            jtilde: Matrix6::zeros(),
            serial: PerChain([b, b, b]),
            j: Matrix6::zeros(),
        }
    }
}

/// Smallest dimensionless serial measure (see [`Mechanism::serial_measure`]) for which J is
/// still formed; below it the chain counts as serially singular.
pub fn serial_singular_tolerance<T: Real>() -> T {
    (T::default_epsilon() * lit(1.0e3)).max(lit(1.0e-9))
}

/// The full Jacobian J = Js⁻¹ Jtilde (q̇ = J [v; ω]) with its factors. Fails at a serial
/// singularity of a chain (Eq. 10.6 / 10.11).
pub fn jacobian<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    sol: &Solution<T>,
) -> Result<Jacobians<T>, JacobianError> {
    let mut out = Jacobians::zeroed();
    jacobian_into(m, sol, &mut out)?;
    Ok(out)
}

/// [`jacobian`] writing into `out` (the control path's form, without the copies of a
/// returned value). On failure `out` must not be used.
pub fn jacobian_into<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    sol: &Solution<T>,
    out: &mut Jacobians<T>,
) -> Result<(), JacobianError> {
    let serial = sol.chains.map(|_, c| m.serial_block(c));
    let relative = sol.chains.map(|_, c| m.serial_measure(c).1);
    compose_into(&chain_lines(sol), &serial, &relative, out)
}

/// J from the Plücker lines of each chain's two actuated directions (rows i and 3+i of
/// Jtilde, Eq. 7.14) and the serial blocks B_i (Eq. 7.21 / 7.31); shared by every
/// mechanism of the class (RSPR, USR, RRPS).
pub(crate) fn compose<T: Real>(
    lines: PerChain<(RowVector6<T>, RowVector6<T>)>,
    serial: PerChain<SerialBlock<T>>,
    relative: PerChain<T>,
) -> Result<Jacobians<T>, JacobianError> {
    let mut out = Jacobians::zeroed();
    compose_into(&lines, &serial, &relative, &mut out)?;
    Ok(out)
}

fn compose_into<T: Real>(
    lines: &PerChain<(RowVector6<T>, RowVector6<T>)>,
    serial: &PerChain<SerialBlock<T>>,
    relative: &PerChain<T>,
    out: &mut Jacobians<T>,
) -> Result<(), JacobianError> {
    let tol = serial_singular_tolerance::<T>();
    out.serial = *serial;
    for (chain, (r1, r2)) in lines.iter() {
        let i = chain.index();
        // Chain by chain: [J_qa_i; J_qb_i] = B_i⁻¹ [Jt_i; Jt_{3+i}].
        let blk = &serial[chain];
        let det = blk.det();
        if !(relative[chain] > tol) || !det.is_finite() {
            return Err(JacobianError::SerialSingular {
                chain,
                relative_det: crate::geometry::to_f64(relative[chain]),
            });
        }
        // Element by element over the (column-major) storage: nalgebra's row views and
        // temporaries cost ~3x the arithmetic on the Cortex-M4.
        let inv = T::one() / det;
        let (k11, k12, k21, k22) = (blk.a22 * inv, -blk.a12 * inv, -blk.a21 * inv, blk.a11 * inv);
        let columns = out
            .jtilde
            .as_mut_slice()
            .chunks_exact_mut(6)
            .zip(out.j.as_mut_slice().chunks_exact_mut(6));
        for ((ct, cj), (x1, x2)) in columns.zip(r1.iter().zip(r2.iter())) {
            let (t_top, t_bottom) = ct.split_at_mut(3);
            let (j_top, j_bottom) = cj.split_at_mut(3);
            if let (Some(t1), Some(t2), Some(j1), Some(j2)) = (
                t_top.get_mut(i),
                t_bottom.get_mut(i),
                j_top.get_mut(i),
                j_bottom.get_mut(i),
            ) {
                (*t1, *t2) = (*x1, *x2);
                (*j1, *j2) = (k11 * *x1 + k12 * *x2, k21 * *x1 + k22 * *x2);
            }
        }
    }
    Ok(())
}
