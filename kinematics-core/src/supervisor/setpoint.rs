//! The setpoint and one step of the motion from it: the profile's limits at the setpoint
//! (what the joints can follow, through its Jacobian), the candidate's kinematic guards,
//! its joint rates, the motion guards on the output, and a step scaled down where the
//! motion guards refuse it.
//!
//! Near serial singularities J̇·twist moves the joints at a constant twist: braking and
//! slowing down use the Cartesian deceleration the joints follow for that change
//! ([`profile::braking_accels`], [`profile::slowing_step`]), and a step the motion guards
//! still refuse is scaled down ([`profile::step_scales`]) before the supervisor holds.

use crate::guards::{Depth, Evaluation, Guard, Limits, MotionSample, Reading, Severity, Solved};
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::Pose;
use crate::scalar::{lit, norm3, wrap_angle, Real};
use crate::vectors::{Joints, Twist};
use nalgebra::{Matrix6, Vector3};

use super::profile::{self, ProfileLimits};
use super::state::Supervisor;

/// One tick's step: the candidate setpoint, its twist and joint rates, what its kinematic
/// check solved and the warn-level guard it reached.
pub(super) struct Step<T: Real> {
    pub pose: Pose<T>,
    pub twist: Twist<T>,
    pub qdot: Joints<T>,
    pub solved: Solved,
    pub warn: Option<Guard>,
}

/// What the kinematic check of a pose found: the first stop-level reading, the first
/// warn-level guard, and what was solved.
pub(super) type KinematicCheck<T> = (Option<Reading<T>>, Option<Guard>, Solved);

/// The motion limits scaled by (1 - 1000 ε).
fn shaved<T: Real>(l: &Limits<T>) -> Limits<T> {
    let k = T::one() - T::default_epsilon() * lit(1000.0);
    Limits {
        tip_speed: l.tip_speed * k,
        angular_speed: l.angular_speed * k,
        tip_accel: l.tip_accel * k,
        angular_accel: l.angular_accel * k,
        ..*l
    }
}

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// The setpoint moves (its twist is not zero).
    pub(super) fn moving(&self) -> bool {
        self.twist.iter().any(|x| *x != T::zero())
    }

    /// The setpoint's twist as its translational and angular velocities (v, ω).
    pub(super) fn twist_parts(&self) -> (Vector3<T>, Vector3<T>) {
        let t = &self.twist;
        (Vector3::new(t.x, t.y, t.z), Vector3::new(t.w, t.a, t.b))
    }

    /// The setpoint's Jacobian, when there is one (not at a serial singularity).
    fn setpoint_jacobian(&self) -> Option<&Matrix6<T>> {
        self.jacobians().map(|j| &j.j)
    }

    /// This tick's profile limits: the motion limits a hair inside (so that rounding
    /// never trips the motion guards that check the output), the accelerations within
    /// what the joints can follow at the setpoint ([`profile::joint_safe_accels`]).
    pub(super) fn profile_limits(&self) -> ProfileLimits<T> {
        let l = shaved(self.guards.limits());
        let (mut tip_accel, mut angular_accel) = (l.tip_accel, l.angular_accel);
        if let Some(j) = self.setpoint_jacobian() {
            (tip_accel, angular_accel) = profile::joint_safe_accels(
                j,
                &self.guards.robot().joint_kinds(),
                l.tip_accel,
                l.angular_accel,
                &l.joint_accel,
                self.cfg.joint_accel_headroom,
            );
        }
        ProfileLimits {
            tip_speed: l.tip_speed,
            angular_speed: l.angular_speed,
            tip_accel,
            angular_accel,
        }
    }

    /// One tick of the profile from the twist (`v0`, `w0`) towards the desired (`vd`,
    /// `wd`): each change limited to `l`'s accelerations (what the joints follow whatever
    /// the direction); while it slows down (neither speed grows), the full Cartesian
    /// accelerations scaled to what the joints follow for this change
    /// ([`profile::slowing_step`], never less), so that the profile keeps up with speed caps
    /// that fall as J grows towards a serial singularity. The speeds never grow faster than
    /// `l` allows, which the braking points assume, and slow at least as fast as `l` allows,
    /// which the braking curve assumes.
    pub(super) fn profile_step(
        &self,
        l: &ProfileLimits<T>,
        (v0, w0): (&Vector3<T>, &Vector3<T>),
        (vd, wd): (&Vector3<T>, &Vector3<T>),
    ) -> (Vector3<T>, Vector3<T>) {
        let dt = self.cfg.dt;
        let slowing = norm3(vd) <= norm3(v0) && norm3(wd) <= norm3(w0);
        match self.setpoint_jacobian() {
            Some(j) if slowing => {
                let full = shaved(self.guards.limits());
                profile::slowing_step(
                    j,
                    &self.guards.robot().joint_kinds(),
                    (v0, w0),
                    (vd, wd),
                    (l.tip_accel, l.angular_accel),
                    (full.tip_accel, full.angular_accel),
                    &full.joint_accel,
                    self.cfg.joint_accel_headroom,
                    dt,
                )
            }
            _ => (
                v0 + profile::limit_step(vd - v0, l.tip_accel, dt),
                w0 + profile::limit_step(wd - w0, l.angular_accel, dt),
            ),
        }
    }

    /// The profile limits of a controlled stop along the twist (`v0`, `w0`): the full
    /// (shaved) decelerations scaled to what the joints can follow in this direction
    /// ([`profile::braking_accels`]), never less than `l`'s.
    pub(super) fn braking_limits(
        &self,
        l: &ProfileLimits<T>,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> ProfileLimits<T> {
        let full = shaved(self.guards.limits());
        let Some(j) = self.setpoint_jacobian() else {
            return *l;
        };
        let (tip_accel, angular_accel) = profile::braking_accels(
            j,
            &self.guards.robot().joint_kinds(),
            v0,
            w0,
            full.tip_accel,
            full.angular_accel,
            &full.joint_accel,
            self.cfg.joint_accel_headroom,
        );
        ProfileLimits {
            tip_accel: tip_accel.max(l.tip_accel),
            angular_accel: angular_accel.max(l.angular_accel),
            ..*l
        }
    }

    /// Speed caps along the unit directions at the setpoint ([`profile::speed_caps`]).
    pub(super) fn speed_caps(
        &self,
        l: &ProfileLimits<T>,
        dir_v: &Vector3<T>,
        dir_w: &Vector3<T>,
    ) -> (T, T) {
        match self.setpoint_jacobian() {
            Some(j) => profile::speed_caps(
                j,
                &self.guards.robot().joint_kinds(),
                l,
                &self.guards.limits().joint_speed,
                self.cfg.joint_speed_headroom,
                dir_v,
                dir_w,
            ),
            None => (l.tip_speed, l.angular_speed),
        }
    }

    /// Evaluates the kinematic guards at `pose` into the spare of `self.evals`
    /// (the solution and its Jacobians; [`Self::keep_candidate`] makes it the setpoint's):
    /// the first stop-level reading, whether a warn level is reached, and what was solved.
    ///
    /// A pose inside a certified region violates no stop-level guard (the region's
    /// guarantee, [`crate::guards::certificate`]): there only what the setpoint needs is
    /// solved ([`crate::guards::Guards::solve_certified`]: the inverse kinematics, the
    /// serial measures' warn level, the Jacobians), which is the same outcome at less cost.
    pub(super) fn kinematic_check(&mut self, pose: &Pose<T>) -> KinematicCheck<T> {
        let mut stop = None;
        let mut warn = None;
        let mut visit = |r: &Reading<T>| match r.severity {
            Some(Severity::Stop) if stop.is_none() => stop = Some(*r),
            Some(Severity::Warn) if warn.is_none() => warn = Some(r.guard),
            _ => {}
        };
        let certified = self.in_certified_region(pose);
        if certified {
            self.counters.setpoints_certified += 1;
        }
        let cond = &mut self.cond_setpoint;
        let scratch = self.evals.spare_mut();
        let solved = if certified {
            self.guards.solve_certified(pose, &mut visit, scratch)
        } else {
            self.guards
                .evaluate_pose_into(pose, &mut visit, cond, scratch, Depth::Kinematic)
        };
        (stop, warn, solved)
    }

    /// The candidate's evaluation (see [`Self::kinematic_check`]).
    fn candidate(&self) -> &Evaluation<T> {
        self.evals.spare()
    }

    /// The candidate checked last becomes the setpoint: its pose, joints and Jacobians.
    pub(super) fn keep_candidate(&mut self, pose: &Pose<T>, solved: Solved) {
        self.q = self.candidate().sol.q();
        self.pose = *pose;
        self.jac_ok = solved == Solved::WithJacobian;
        self.evals.swap();
    }

    /// The joint rates of the candidate's twist: J·twist with the Jacobian its kinematic
    /// check computed, or finite differences from the setpoint's joints when J is singular
    /// (the serial guard stops long before).
    pub(super) fn candidate_rates(&self, twist: &Twist<T>, with_jacobian: bool) -> Joints<T> {
        let dt = self.cfg.dt;
        if with_jacobian {
            return Joints::from(profile::jac_times(
                &self.candidate().jac.j,
                &(*twist).into(),
            ));
        }
        let mut qd = (self.candidate().sol.q() - self.q) / dt;
        for (x, k) in qd.iter_mut().zip(self.guards.robot().joint_kinds().iter()) {
            if *k == JointKind::Angular {
                *x = wrap_angle(*x * dt) / dt;
            }
        }
        qd
    }

    /// The motion guards on the output itself (from the last output to this one): the
    /// first stop-level reading, if any.
    pub(super) fn motion_stop(&self, twist: &Twist<T>, qdot: &Joints<T>) -> Option<Reading<T>> {
        let dt = self.cfg.dt;
        let prev = MotionSample {
            twist: self.twist,
            qdot: self.qdot,
        };
        let cur = MotionSample {
            twist: *twist,
            qdot: *qdot,
        };
        if self.guards.motion_within_limits(&prev, &cur, dt) {
            return None;
        }
        // The readings, for the stop's reason.
        let mut motion_stop = None;
        self.guards.evaluate_motion(&prev, &cur, dt, &mut |r| {
            if r.severity == Some(Severity::Stop) && motion_stop.is_none() {
                motion_stop = Some(*r);
            }
        });
        motion_stop
    }

    /// A step the motion guards refused, scaled down by β ([`profile::step_scales`]) to
    /// keep every joint within its speed and acceleration limits: the candidate displaced
    /// by β·twist·dt, with its own kinematic check and joint rates. While braking the least
    /// β (the shortest stop), else the largest (the least slow-down); a slower step stays
    /// on the stretch the braking points checked. `Err(Some(reading))` when the rescaled
    /// candidate violates a stop level, `Err(None)` when no β keeps the limits (or the
    /// rescaled step still does not): the caller holds.
    pub(super) fn rescaled_step(&mut self, step: &Step<T>) -> Result<Step<T>, Option<Reading<T>>> {
        if step.solved != Solved::WithJacobian {
            return Err(None);
        }
        let l = shaved(self.guards.limits());
        let limits = profile::StepLimits {
            tip_accel: l.tip_accel,
            angular_accel: l.angular_accel,
            joint_speed: l.joint_speed,
            joint_accel: l.joint_accel,
        };
        let kinds = self.guards.robot().joint_kinds();
        let dt = self.cfg.dt;
        let (lo, hi) = profile::step_scales(
            &self.twist,
            &step.twist,
            &self.qdot,
            &step.qdot,
            &kinds,
            &limits,
            dt,
        )
        .ok_or(None)?;
        let beta = if self.activity.is_braking() { lo } else { hi };
        let twist = step.twist * beta;
        let (v, w) = (twist.fixed_rows::<3>(0), twist.fixed_rows::<3>(3));
        let pose = self.pose.displaced(&(v * dt), &(w * dt));
        let (stop, warn, solved) = self.kinematic_check(&pose);
        if let Some(r) = stop {
            return Err(Some(r));
        }
        if solved != Solved::WithJacobian {
            return Err(None);
        }
        let qdot = self.candidate_rates(&twist, true);
        if self.motion_stop(&twist, &qdot).is_some() {
            return Err(None);
        }
        self.counters.slowed += 1;
        Ok(Step {
            pose,
            twist,
            qdot,
            solved,
            warn: warn.or(self.ahead_warn),
        })
    }
}
