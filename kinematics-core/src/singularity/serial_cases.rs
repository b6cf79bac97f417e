//! The serial singularities of each chain by their geometric case (thesis 10.3).
//!
//! **RSPR (Eq. 10.6-10.7):** Cn2_i = (ŝ2_i × ŝn_i)·l_bi = 0, in four cases: a, ŝ2 in the
//! plane of l_b and ŝn (the general case, Cn2 = 0 itself); b, ŝ2 ∥ ŝn; c, l_b ∥ ŝ2; d,
//! l_b ∥ ŝn (impossible on the RSPR: ŝn is the rotating link's axis, perpendicular to it).
//!
//! **USR (Eq. 10.8-10.11):** with Cn = ŝ·(ŝn × l_b) and Cr = ŝ·(ŝr × l_b) (ŝn the yaw
//! axis z0, ŝr the pitch axis): A, Cn1 = Cn2 = 0 (ŝ1 and ŝ2 in the plane of ŝn and l_b);
//! B, l_b ∥ ŝn; C, ŝ1 ∥ l_b (the links collinear); D, ŝ2 ∥ l_b (the inverse kinematics'
//! branches meet); E, Cr1 = Cr2 = 0 (ŝ1 and ŝ2 in the plane of ŝr and l_b); F, Cn1 Cr2 -
//! Cr1 Cn2 = 0, the general condition, which A..E imply.
//!
//! Residuals are dimensionless: the C terms over |l_b| (sines), parallelism as the sine
//! of the angle, F over |l_b|².

use super::lines::Tolerances;
use crate::chain::PerChain;
use crate::ik::Solution;
use crate::mechanism::{ChainSolution, Mechanism};
use crate::robot::{Robot, RobotKind};
use crate::scalar::Real;
use nalgebra::Vector3;

/// Which of the cases hold, one bit per case: bit 0 the first letter (RSPR a, USR A).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Cases {
    pub bits: u8,
    /// The architecture whose letters the bits mean.
    pub rspr: bool,
}

impl Cases {
    /// No serial singularity.
    pub fn is_empty(&self) -> bool {
        self.bits == 0
    }
    /// Whether the case with this letter (RSPR 'a'..'d', USR 'A'..'F') holds.
    pub fn has(&self, letter: char) -> bool {
        let base = if self.rspr { 'a' } else { 'A' };
        let k = (letter as u32).wrapping_sub(base as u32);
        k < 8 && self.bits & (1 << k) != 0
    }
    /// The letters of the cases that hold ("" for none), e.g. "a+c".
    pub fn letters(&self) -> heapless::String<12> {
        let mut s = heapless::String::new();
        let base = if self.rspr { b'a' } else { b'A' };
        for k in 0..6u8 {
            if self.bits & (1 << k) != 0 {
                if !s.is_empty() {
                    let _ = s.push('+');
                }
                let _ = s.push(char::from(base + k));
            }
        }
        s
    }
}

fn sine<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> T {
    let d = a.norm() * b.norm();
    if d > T::zero() {
        a.cross(b).norm() / d
    } else {
        T::zero()
    }
}

/// The cases of an RSPR chain (a..d).
pub fn rspr_cases<T: Real>(c: &ChainSolution<T>, tol: &Tolerances<T>) -> Cases {
    let lb = c.lb.norm();
    let small = |x: T| !(x > tol.geometry);
    let cn2 = if lb > T::zero() {
        c.s2.cross(&c.axis).dot(&c.lb) / lb // Eq. 10.6
    } else {
        T::zero()
    };
    let flags = [
        small(cn2.abs()),
        small(sine(&c.s2, &c.axis)),
        small(sine(&c.lb, &c.s2)),
        small(sine(&c.lb, &c.axis)),
    ];
    Cases {
        bits: pack(&flags),
        rspr: true,
    }
}

/// The cases of a USR chain (A..F), from its serial block (Cn1, Cr1; Cn2, Cr2).
pub fn usr_cases<T: Real, M: Mechanism<T> + ?Sized>(
    m: &M,
    c: &ChainSolution<T>,
    tol: &Tolerances<T>,
) -> Cases {
    let blk = m.serial_block(c);
    let lb = c.lb.norm();
    let small = |x: T| !(x > tol.geometry);
    let (cn1, cr1, cn2, cr2, det) = if lb > T::zero() {
        (
            blk.a11 / lb,
            blk.a12 / lb,
            blk.a21 / lb,
            blk.a22 / lb,
            blk.det() / (lb * lb),
        )
    } else {
        (T::zero(), T::zero(), T::zero(), T::zero(), T::zero())
    };
    let flags = [
        small(cn1.abs()) && small(cn2.abs()),
        small(sine(&c.lb, &c.axis)),
        small(sine(&c.s1, &c.lb)),
        small(sine(&c.s2, &c.lb)),
        small(cr1.abs()) && small(cr2.abs()),
        small(det.abs()),
    ];
    Cases {
        bits: pack(&flags),
        rspr: false,
    }
}

fn pack(flags: &[bool]) -> u8 {
    flags
        .iter()
        .enumerate()
        .fold(0u8, |acc, (k, &f)| if f { acc | (1 << k) } else { acc })
}

/// The cases of every chain of a robot at a solution.
pub fn cases<T: Real>(robot: &Robot<T>, sol: &Solution<T>, tol: &Tolerances<T>) -> PerChain<Cases> {
    match robot.kind() {
        RobotKind::Rspr => sol.chains.map(|_, c| rspr_cases(c, tol)),
        RobotKind::Usr => sol.chains.map(|_, c| usr_cases(robot, c, tol)),
    }
}
