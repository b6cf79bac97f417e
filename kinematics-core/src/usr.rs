//! The USR chain: an active universal joint at e_i (yaw α_i about z0, then pitch β_i), a
//! lower link of length l1, a spherical joint b_i, an upper link of length l2 and a revolute
//! joint at p_i on the platform (thesis 6.3 and 7.3.3).

use crate::chain::Chain;
use crate::geometry::UsrGeometry;
use crate::mechanism::{ChainSolution, IkFailure};
use crate::mechanism::{JointKind, Mechanism, PlatformChain, SerialBlock};
use crate::rspr::{yaw_from, z_cross};
use crate::scalar::{lit, wrap_angle, Real};
use nalgebra::Vector3;

/// ∂b/∂β: the velocity of the lower link's tip for a unit pitch rate (elevation grows).
fn pitch_tip<T: Real>(lb: &Vector3<T>) -> Vector3<T> {
    let rh = (lb.x * lb.x + lb.y * lb.y).sqrt();
    if rh > T::zero() {
        Vector3::new(-lb.z * lb.x / rh, -lb.z * lb.y / rh, rh)
    } else {
        Vector3::zeros()
    }
}

impl<T: Real> Mechanism<T> for UsrGeometry<T> {
    fn rp(&self) -> T {
        self.rp
    }
    fn e(&self) -> T {
        self.e
    }
    fn hc(&self) -> T {
        self.hc
    }
    fn joint_kinds(&self) -> [JointKind; 6] {
        [JointKind::Angular; 6]
    }
    fn length_scale(&self) -> T {
        self.l1
    }

    #[inline]
    fn chain_ik(
        &self,
        _chain: Chain,
        pc: &PlatformChain<T>,
        smaller_gamma: bool,
        out: &mut ChainSolution<T>,
    ) -> Result<(), IkFailure> {
        let eps = T::default_epsilon() * lit(64.0);
        let two = lit::<T>(2.0);
        let d = pc.p - pc.e;
        // Eq. 6.28-6.31: a cos γ + b sin γ = c.
        let a = -two * self.l2 * d.dot(&pc.n); // Eq. 6.29
        let b = two * self.l2 * d.dot(&pc.u); // Eq. 6.30
        let c = self.l1 * self.l1 - self.l2 * self.l2 - d.norm_squared(); // Eq. 6.31
        let rho2 = a * a + b * b;
        let scale = self.l1 * self.l2;
        if !(rho2.sqrt() > eps * scale) {
            return Err(IkFailure::DegenerateEquation);
        }
        let s2 = rho2 - c * c;
        if !(s2 >= T::zero()) {
            return Err(IkFailure::NoRealRoot);
        }
        // Eq. 6.32: γ = atan2(b, a) ± atan2(sqrt(a² + b² - c²), c).
        let phi = b.atan2(a);
        let half = s2.sqrt().atan2(c);
        let g_plus = wrap_angle(phi + half);
        let g_minus = wrap_angle(phi - half);
        let (larger, smaller) = if g_plus >= g_minus {
            (g_plus, g_minus)
        } else {
            (g_minus, g_plus)
        };
        let gamma = if smaller_gamma { smaller } else { larger };
        // Eq. 6.25: b_i = p_i + R pRCi [l2 sin γ, 0, -l2 cos γ].
        let bpt = pc.p + (pc.u * gamma.sin() - pc.n * gamma.cos()) * self.l2;
        let lb = bpt - pc.e; // Eq. 6.26
        let rh = (lb.x * lb.x + lb.y * lb.y).sqrt();
        if !(rh > eps * self.l1) {
            return Err(IkFailure::YawUndefined);
        }
        let s1_vec = pc.p - bpt;
        let leg = s1_vec.norm();
        if !(leg > eps * self.l2) {
            return Err(IkFailure::ZeroLengthLeg);
        }
        *out = ChainSolution {
            e: pc.e,
            b: bpt,
            p: pc.p,
            lb,
            s1: s1_vec / leg,
            leg,
            s2: pc.m,
            axis: Vector3::new(T::zero(), T::zero(), T::one()),
            // Eq. 6.35-6.37: yaw from the radial direction about +z0.
            qa: yaw_from(&pc.radial, &lb),
            // Elevation above the base plane (CONVENTIONS.md; Eq. 6.38 measures it from w_i).
            qb: lb.z.atan2(rh),
            gamma,
        };
        Ok(())
    }

    fn serial_block(&self, s: &ChainSolution<T>) -> SerialBlock<T> {
        // Eq. 7.31-7.33 with ŝn = z0 and ŝr the pitch axis: Cn = ŝ·(ŝn × l_b),
        // Cr = ŝ·(ŝr × l_b), where ŝn × l_b and ŝr × l_b are the tip velocities.
        let yaw_tip = z_cross(&s.lb);
        let pitch_tip = pitch_tip(&s.lb);
        SerialBlock {
            a11: s.s1.dot(&yaw_tip),   // Cn1
            a12: s.s1.dot(&pitch_tip), // Cr1
            a21: s.s2.dot(&yaw_tip),   // Cn2
            a22: s.s2.dot(&pitch_tip), // Cr2
        }
    }

    fn serial_measure(&self, s: &ChainSolution<T>) -> (T, T) {
        // Eq. 10.11: Cn1 Cr2 - Cr1 Cn2 = 0 at every serial singularity of the chain.
        let det = self.serial_block(s).det().abs();
        (det, det / (self.l1 * self.l1))
    }
}
