//! Jacobians: the tripod Jacobian Jtilde whose rows are Plücker lines (Eq. 7.14), the serial
//! part Js (RSPR Eq. 7.21, USR B of Eq. 7.31) and J = Js⁻¹ Jtilde = dq/dx (Eq. 7.18).

use crate::chain::{Chain, PerChain};
use crate::ik::Solution;
use crate::mechanism::{Mechanism, SerialBlock};
use crate::scalar::{cross3, lit, sub3, Real};
use core::fmt;
use nalgebra::{Matrix6, Vector3};

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

/// A Plücker line [ŝ; m] as a row of Jtilde.
pub(crate) type Line<T> = [T; 6];

/// One Plücker line [ŝ; (x - o_p) × ŝ] with the moment taken about o_p (Eq. 7.13).
pub(crate) fn plucker<T: Real>(s: &Vector3<T>, through_minus_op: &Vector3<T>) -> Line<T> {
    let mo = cross3(through_minus_op, s);
    [s.x, s.y, s.z, mo.x, mo.y, mo.z]
}

/// The two Plücker lines of each chain (Eq. 7.14): ŝ1_i through p_i and ŝ2_i through b_i,
/// in {0}, moments about o_p.
fn chain_lines<T: Real>(sol: &Solution<T>) -> PerChain<(Line<T>, Line<T>)> {
    let t = sol.pose.t;
    sol.chains.map(|_, c| {
        (
            plucker(&c.s1, &sub3(&c.p, &t)),
            plucker(&c.s2, &sub3(&c.b, &t)),
        )
    })
}

/// The tripod Jacobian Jtilde (Eq. 7.14): rows 1..3 the lines ŝ1_i through p_i, rows 4..6
/// the lines ŝ2_i through b_i.
pub fn tripod_jacobian<T: Real>(sol: &Solution<T>) -> Matrix6<T> {
    let [(a1, b1), (a2, b2), (a3, b3)] = chain_lines(sol).0;
    // Column by column (the storage order), written out: no loops on the Cortex-M4.
    macro_rules! col {
        ($k:literal) => {
            [a1[$k], a2[$k], a3[$k], b1[$k], b2[$k], b3[$k]]
        };
    }
    Matrix6::from([col!(0), col!(1), col!(2), col!(3), col!(4), col!(5)])
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
/// Jtilde, Eq. 7.14) and the serial blocks B_i (Eq. 7.21 / 7.31); shared by the RSPR and
/// the USR.
fn compose_into<T: Real>(
    lines: &PerChain<(Line<T>, Line<T>)>,
    serial: &PerChain<SerialBlock<T>>,
    relative: &PerChain<T>,
    out: &mut Jacobians<T>,
) -> Result<(), JacobianError> {
    let tol = serial_singular_tolerance::<T>();
    // B_i⁻¹ of each chain, refusing a serial singularity (the first chain in order).
    let inv = PerChain::try_from_fn(|chain| {
        let blk = &serial[chain];
        let det = blk.det();
        if !(relative[chain] > tol) || !det.is_finite() {
            return Err(JacobianError::SerialSingular {
                chain,
                relative_det: crate::scalar::to_f64(relative[chain]),
            });
        }
        let inv = T::one() / det;
        Ok([blk.a22 * inv, -blk.a12 * inv, -blk.a21 * inv, blk.a11 * inv])
    })?;
    out.serial = *serial;
    // Chain by chain: [J_qa_i; J_qb_i] = B_i⁻¹ [Jt_i; Jt_{3+i}]; column by column (the
    // storage order), written out: nalgebra's row views and loops cost ~3x the arithmetic
    // on the Cortex-M4.
    let [(a1, b1), (a2, b2), (a3, b3)] = &lines.0;
    let [k1, k2, k3] = &inv.0;
    macro_rules! tilde {
        ($k:literal) => {
            [a1[$k], a2[$k], a3[$k], b1[$k], b2[$k], b3[$k]]
        };
    }
    macro_rules! full {
        ($k:literal) => {
            [
                k1[0] * a1[$k] + k1[1] * b1[$k],
                k2[0] * a2[$k] + k2[1] * b2[$k],
                k3[0] * a3[$k] + k3[1] * b3[$k],
                k1[2] * a1[$k] + k1[3] * b1[$k],
                k2[2] * a2[$k] + k2[3] * b2[$k],
                k3[2] * a3[$k] + k3[3] * b3[$k],
            ]
        };
    }
    out.jtilde = Matrix6::from([
        tilde!(0),
        tilde!(1),
        tilde!(2),
        tilde!(3),
        tilde!(4),
        tilde!(5),
    ]);
    out.j = Matrix6::from([full!(0), full!(1), full!(2), full!(3), full!(4), full!(5)]);
    Ok(())
}
