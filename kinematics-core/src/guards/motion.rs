//! The motion guards: speeds and accelerations of the platform (tip and angular) and of
//! every joint, between two samples one control period apart.

use crate::mechanism::{JointKind, Mechanism};
use crate::scalar::Real;
use crate::vectors::{Joints, Twist};

use super::readings::{stop_only, upper, Guard, Reading, Subject};
use super::setup::Guards;

/// One platform motion sample for the motion guards.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSample<T: Real> {
    /// Platform twist [v; ω] (m/s, rad/s).
    pub twist: Twist<T>,
    /// Joint rates in q order.
    pub qdot: Joints<T>,
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// Evaluates the motion guards between two samples `dt` apart (speeds of `cur`,
    /// accelerations from `prev` to `cur`).
    pub fn evaluate_motion(
        &self,
        prev: &MotionSample<T>,
        cur: &MotionSample<T>,
        dt: T,
        visit: &mut impl FnMut(&Reading<T>),
    ) {
        let l = &self.limits;
        let [v, w, a, alpha] = platform_motion(prev, cur, dt);
        let r = Subject::Robot;
        visit(&upper(Guard::TipSpeed, r, v, stop_only(l.tip_speed)));
        visit(&upper(
            Guard::AngularSpeed,
            r,
            w,
            stop_only(l.angular_speed),
        ));
        visit(&upper(Guard::TipAccel, r, a, stop_only(l.tip_accel)));
        visit(&upper(
            Guard::AngularAccel,
            r,
            alpha,
            stop_only(l.angular_accel),
        ));
        let kinds = self.robot.joint_kinds();
        for (j, ((qd, qd0), kind)) in cur
            .qdot
            .iter()
            .zip(prev.qdot.iter())
            .zip(kinds.iter())
            .enumerate()
        {
            let (vmax, amax) = self.joint_motion_limits(*kind);
            let s = Subject::Joint(j as u8 + 1);
            visit(&upper(Guard::JointSpeed, s, qd.abs(), stop_only(vmax)));
            visit(&upper(
                Guard::JointAccel,
                s,
                ((*qd - *qd0) / dt).abs(),
                stop_only(amax),
            ));
        }
    }

    /// Whether [`Guards::evaluate_motion`] would give no stop-level reading (the same
    /// values against the same limits, a NaN beyond them), without building the
    /// readings: the control path's check, which needs the readings only on a stop.
    pub fn motion_within_limits(
        &self,
        prev: &MotionSample<T>,
        cur: &MotionSample<T>,
        dt: T,
    ) -> bool {
        let l = &self.limits;
        let [v, w, a, alpha] = platform_motion(prev, cur, dt);
        let mut ok = v <= l.tip_speed
            && w <= l.angular_speed
            && a <= l.tip_accel
            && alpha <= l.angular_accel;
        // Over plain arrays (nalgebra's iterators cost several times the arithmetic on the
        // Cortex-M4).
        let ([qd], [qd0]) = (cur.qdot.data.0, prev.qdot.data.0);
        let kinds = self.robot.joint_kinds();
        for ((v, v0), kind) in qd.iter().zip(qd0.iter()).zip(kinds.iter()) {
            let (vmax, amax) = self.joint_motion_limits(*kind);
            ok &= v.abs() <= vmax && ((*v - *v0) / dt).abs() <= amax;
        }
        ok
    }

    /// The speed and acceleration limits of a joint of `kind`.
    fn joint_motion_limits(&self, kind: JointKind) -> (T, T) {
        let l = &self.limits;
        match kind {
            JointKind::Linear => (l.joint_speed[0], l.joint_accel[0]),
            JointKind::Angular => (l.joint_speed[1], l.joint_accel[1]),
        }
    }
}

/// Tip speed, angular speed, tip acceleration and angular acceleration of a motion sample
/// (the accelerations from `prev`, `dt` earlier).
fn platform_motion<T: Real>(prev: &MotionSample<T>, cur: &MotionSample<T>, dt: T) -> [T; 4] {
    let (c, p) = (&cur.twist, &prev.twist);
    let norm = |x: T, y: T, z: T| crate::scalar::sqrt(x * x + y * y + z * z);
    [
        norm(c.x, c.y, c.z),
        norm(c.w, c.a, c.b),
        norm((c.x - p.x) / dt, (c.y - p.y) / dt, (c.z - p.z) / dt),
        norm((c.w - p.w) / dt, (c.a - p.a) / dt, (c.b - p.b) / dt),
    ]
}
