//! The RSPR chain: a rotating link on the base (revolute about z0 at e_i, length rb), a
//! spherical joint b_i, a prismatic leg of length l_i, a revolute joint at p_i on the
//! platform (thesis 6.2 and 7.3.2).

use crate::chain::Chain;
use crate::geometry::RsprGeometry;
use crate::mechanism::{ChainSolution, IkFailure};
use crate::mechanism::{JointKind, Mechanism, PlatformChain, SerialBlock};
use crate::scalar::{dot3, lit, norm3, sqrt, sub3, Real};
use nalgebra::Vector3;

/// Signed angle about +z0 from `from` to `to` (both horizontal), in (-π, π].
pub(crate) fn yaw_from<T: Real>(from: &Vector3<T>, to: &Vector3<T>) -> T {
    let cross = from.x * to.y - from.y * to.x;
    let dot = from.x * to.x + from.y * to.y;
    cross.atan2(dot)
}

/// z0 × v: the velocity of the tip of v when it turns about +z0 at unit rate.
pub(crate) fn z_cross<T: Real>(v: &Vector3<T>) -> Vector3<T> {
    Vector3::new(-v.y, v.x, T::zero())
}

impl<T: Real> Mechanism<T> for RsprGeometry<T> {
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
        use JointKind::*;
        [Linear, Linear, Linear, Angular, Angular, Angular]
    }
    fn length_scale(&self) -> T {
        self.rb
    }

    #[inline]
    fn chain_ik(
        &self,
        _chain: Chain,
        pc: &PlatformChain<T>,
        inner: bool,
        out: &mut ChainSolution<T>,
    ) -> Result<(), IkFailure> {
        let eps = T::default_epsilon() * lit(64.0);
        let n = pc.n;
        // The leg moves in the plane P_i through p_i with normal m = R r_i. Its trace on the
        // base plane is the line v_i (Eq. 6.13-6.17); direction z0 × m, horizontal.
        let v_len = sqrt(pc.m.x * pc.m.x + pc.m.y * pc.m.y);
        if n.z.abs() <= eps || v_len <= eps {
            return Err(IkFailure::DegeneratePlane);
        }
        let (mut vx, mut vy) = (-pc.m.y / v_len, pc.m.x / v_len);
        // Eq. 6.18: v_i points along the base-plane projection of R pp_i.
        if vx * pc.u.x + vy * pc.u.y < T::zero() {
            (vx, vy) = (-vx, -vy);
        }
        // Eq. 6.8-6.10: d_i, where the line through p_i along n pierces the base plane
        // (its z is 0).
        let k = pc.p.z / n.z;
        let (dx, dy) = (pc.p.x - n.x * k, pc.p.y - n.y * k);
        // Eq. 6.19-6.21 with a = |v|² = 1: t² + 2 h t + c = 0.
        let (dex, dey) = (dx - pc.e.x, dy - pc.e.y);
        let h = dex * vx + dey * vy;
        let c = dex * dex + dey * dey - self.rb * self.rb;
        let disc = h * h - c;
        if !(disc >= T::zero()) {
            return Err(IkFailure::NoRealRoot);
        }
        // Eq. 6.22: the plus root is "outer" (bit clear), the minus root "inner".
        let root = sqrt(disc);
        let t = if inner { -h - root } else { -h + root };
        let b = Vector3::new(dx + t * vx, dy + t * vy, T::zero());
        let lb = sub3(&b, &pc.e);
        let s1_vec = sub3(&pc.p, &b);
        let leg = norm3(&s1_vec);
        if !(leg > eps * self.rb) {
            return Err(IkFailure::ZeroLengthLeg);
        }
        *out = ChainSolution {
            e: pc.e,
            b,
            p: pc.p,
            lb,
            s1: Vector3::new(s1_vec.x / leg, s1_vec.y / leg, s1_vec.z / leg),
            leg,
            s2: pc.m,
            axis: Vector3::new(T::zero(), T::zero(), T::one()),
            qa: leg,
            // θ_i: angle of the rotating link about +z0 from the radial direction (Fig. 6.3).
            qb: yaw_from(&pc.radial, &lb),
            gamma: T::zero(),
        };
        Ok(())
    }

    fn serial_block(&self, s: &ChainSolution<T>) -> SerialBlock<T> {
        // Eq. 7.19-7.21: ŝ_n = z0, Cn1 = (ŝ1 × ŝn)·l_b, Cn2 = (ŝ2 × ŝn)·l_b.
        let tip = z_cross(&s.lb);
        SerialBlock {
            a11: T::one(),
            a12: dot3(&s.s1, &tip),
            a21: T::zero(),
            a22: dot3(&s.s2, &tip),
        }
    }

    fn serial_measure(&self, s: &ChainSolution<T>) -> (T, T) {
        // Eq. 10.6: the chain is singular when Cn2_i = 0.
        let cn2 = self.serial_block(s).a22.abs();
        (cn2, cn2 / self.rb)
    }
}
