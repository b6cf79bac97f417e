//! The real-time step of a period, by phase: the evaluation phase's handoff and the
//! stream; the plan (arrive at the goal, rest on it, follow the profile towards it, or
//! brake); the candidate setpoint's kinematic guards; the motion guards on the output
//! (the step scaled down where they refuse it); and the setpoint kept, or held with the
//! stop latched.

use crate::guards::{Guard, Reading, Solved};
use crate::mechanism::Mechanism;
use crate::pose::{rotation_vector, Pose};
use crate::scalar::{norm3, Real};
use crate::vectors::{Joints, Twist};
use nalgebra::Vector3;

use super::mode::{Activity, Event};
use super::path::Target;
use super::profile::{self, ProfileLimits};
use super::report::TickOutput;
use super::setpoint::Step;
use super::state::Supervisor;

/// Why a step ends without a new setpoint.
enum Halt<T: Real> {
    /// A stop-level violation: hold and latch it.
    Stop(Reading<T>),
    /// No solution without a stop-level violation (unreachable: no solution is a stop):
    /// keep the setpoint, reporting this warn-level guard.
    Keep(Option<Guard>),
}

/// What a step does.
enum Plan<T: Real> {
    /// Snap onto the goal and stop (`at_goal`: the setpoint is on it already).
    Arrive { goal: Pose<T>, at_goal: bool },
    /// Stay at rest on the goal.
    Rest,
    /// Move to the candidate setpoint `pose` at the twist (`v`, `w`).
    Move {
        pose: Pose<T>,
        v: Vector3<T>,
        w: Vector3<T>,
    },
}

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// The real-time step of a period: the profile's step towards the goal or a
    /// controlled stop ([`profile`]), the candidate setpoint's kinematic guards and the
    /// motion guards on the output. It acts on the verdicts of the evaluation phase
    /// before it; when that phase did not run (a scheduling fault), a moving robot brakes
    /// on the stretch checked before.
    pub fn step(&mut self) -> TickOutput<T> {
        let Some((l, brake)) = self.begin_step() else {
            return self.output(None);
        };
        let (v0, w0) = self.twist_parts();
        let (pose, v1, w1) = match self.plan(&l, &v0, &w0, brake) {
            Plan::Move { pose, v, w } => (pose, v, w),
            Plan::Arrive { goal, at_goal } => return self.arrive(&goal, at_goal),
            Plan::Rest => {
                self.twist = Twist::zeros();
                self.qdot = Joints::zeros();
                return self.output(self.warning);
            }
        };
        let (solved, warn) = match self.check_candidate(&pose) {
            Ok(checked) => checked,
            Err(halt) => return self.halt(halt),
        };
        // The guards computed the candidate's Jacobians already (in the scratch): reuse them.
        let twist = Twist::new(v1.x, v1.y, v1.z, w1.x, w1.y, w1.z);
        let mut step = Step {
            pose,
            twist,
            qdot: self.candidate_rates(&twist, solved == Solved::WithJacobian),
            solved,
            warn,
        };
        if let Err(halt) = self.within_motion_limits(&mut step, &l, &v0, &w0) {
            return self.halt(halt);
        }
        self.take_step(&step)
    }

    /// The start of a step: the profile limits the evaluation phase computed at the
    /// setpoint and whether to brake (a braking point found unsafe, or the phase missed
    /// while moving); a stream fallen silent; a next goal at rest. None while stopped.
    fn begin_step(&mut self) -> Option<(ProfileLimits<T>, bool)> {
        if self.activity.latched().is_some() {
            // (The handoff stays: whether the evaluation phase ran counts at the first
            // step after a clear.)
            return None;
        }
        let moving = self.moving();
        let handoff = self.handoff.take();
        let l = handoff
            .and_then(|h| h.limits)
            .unwrap_or_else(|| self.profile_limits());
        let mut brake = handoff.is_some_and(|h| h.brake);
        if handoff.is_none() {
            // The braking points' horizon assumes the phase runs every period.
            self.counters.evaluations_missed += 1;
            brake |= moving;
        }
        // A stream fallen silent after a led target: back to the master's newest target.
        if let Some(plain) = self.stream.tick(self.dt_us) {
            self.take_target(&Target::plain(&plain, self.last_stamp_us.unwrap_or(0)));
        }
        // Standing still, a verified target waiting for a braking-point check takes over
        // at once (there is no motion to look past the goal).
        if !moving {
            self.next_goal_cleared();
        }
        Some((l, brake))
    }

    /// What this step does: while following, arrive when within a tick of the goal, rest
    /// on it, or (unless told to brake) the profile's step towards it; else brake.
    fn plan(
        &mut self,
        l: &ProfileLimits<T>,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
        brake: bool,
    ) -> Plan<T> {
        let Activity::Following { goal, .. } = &self.activity else {
            return self.braking_step(l, v0, w0);
        };
        // Towards the goal (world frame), with the braking profile.
        let e_t = goal.t - self.pose.t;
        let e_r = rotation_vector(&(goal.r * self.pose.r.inverse()));
        let (d, a) = (norm3(&e_t), norm3(&e_r));
        if self.pending.is_none() && profile::arrived(d, a, v0, w0, l, self.cfg.dt) {
            let at_goal = d + a == T::zero();
            return Plan::Arrive {
                goal: *goal,
                at_goal,
            };
        }
        // At rest on the goal (e.g. while a new target is being verified): the setpoint
        // stays, and it was checked when it became the setpoint.
        if d + a == T::zero() && !self.moving() {
            return Plan::Rest;
        }
        if brake {
            return self.braking_step(l, v0, w0);
        }
        let dir = |e: &Vector3<T>, n: T| {
            if n > T::zero() {
                e / n
            } else {
                Vector3::zeros()
            }
        };
        let (dir_v, dir_w) = (dir(&e_t, d), dir(&e_r, a));
        let dt = self.cfg.dt;
        let (vcap, wcap) = self.speed_caps(l, &dir_v, &dir_w);
        let vd = profile::desired_velocity(&dir_v, d, vcap, l.tip_accel, dt);
        let wd = profile::desired_velocity(&dir_w, a, wcap, l.angular_accel, dt);
        let (v, w) = self.profile_step(l, (v0, w0), (&vd, &wd));
        let pose = self.pose.displaced(&(v * dt), &(w * dt));
        Plan::Move { pose, v, w }
    }

    /// A step of the controlled stop, on the stretch checked before: decelerate along the
    /// current twist, at the full deceleration on every tick until the robot stands.
    /// Targets in verification are dropped; the goal is where the robot comes to rest.
    fn braking_step(&mut self, l: &ProfileLimits<T>, v0: &Vector3<T>, w0: &Vector3<T>) -> Plan<T> {
        if !self.activity.is_braking() {
            self.counters.brakes += 1;
        }
        self.drop_pending();
        let dt = self.cfg.dt;
        let b = self.braking_limits(l, v0, w0);
        let v = profile::step_braking(v0, b.tip_accel, dt);
        let w = profile::step_braking(w0, b.angular_accel, dt);
        let pose = self.pose.displaced(&(v * dt), &(w * dt));
        let stop = profile::stop_point(&v, &w, &pose, &b);
        self.activity = self.activity.on(Event::Braked { stop });
        Plan::Move { pose, v, w }
    }

    /// The candidate setpoint's kinematic guards: what was solved and the warn-level guard
    /// to report.
    fn check_candidate(&mut self, pose: &Pose<T>) -> Result<(Solved, Option<Guard>), Halt<T>> {
        let (stop, warn, solved) = self.kinematic_check(pose);
        // A warn level of the parallel measure or a payload effort reached at the braking
        // point is reported as well (those are only evaluated there while moving).
        let warn = warn.or(self.ahead_warn);
        match (stop, solved) {
            (Some(r), _) => Err(Halt::Stop(r)),
            (None, Solved::No) => Err(Halt::Keep(warn)),
            _ => Ok((solved, warn)),
        }
    }

    /// The motion guards on the output: a step they refuse is scaled down in place
    /// ([`Self::rescaled_step`]; while braking, the stop point moves with it), or the
    /// supervisor holds.
    fn within_motion_limits(
        &mut self,
        step: &mut Step<T>,
        l: &ProfileLimits<T>,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> Result<(), Halt<T>> {
        let Some(r) = self.motion_stop(&step.twist, &step.qdot) else {
            return Ok(());
        };
        *step = self
            .rescaled_step(step)
            .map_err(|reason| Halt::Stop(reason.unwrap_or(r)))?;
        if self.activity.is_braking() {
            let (v, w) = (step.twist.fixed_rows::<3>(0), step.twist.fixed_rows::<3>(3));
            let b = self.braking_limits(l, v0, w0);
            let stop = profile::stop_point(&v.into(), &w.into(), &step.pose, &b);
            self.activity = self.activity.on(Event::Braked { stop });
        }
        Ok(())
    }

    /// The step's candidate becomes the setpoint; a braking robot that stands follows
    /// again, with the setpoint as its goal.
    fn take_step(&mut self, step: &Step<T>) -> TickOutput<T> {
        self.keep_candidate(&step.pose, step.solved);
        self.qdot = step.qdot;
        self.twist = step.twist;
        self.warning = step.warn;
        if step.warn.is_some() {
            self.counters.warn_ticks += 1;
        }
        if self.activity.is_braking() && !self.moving() {
            self.activity = self.activity.on(Event::Stood { at: self.pose });
        }
        self.output(step.warn)
    }

    /// Snaps onto the (verified) goal and stops: its kinematic check first (the goal was
    /// checked in full: the end of its path, first of all).
    fn arrive(&mut self, goal: &Pose<T>, at_goal: bool) -> TickOutput<T> {
        if !at_goal {
            let (stop, warn, solved) = self.kinematic_check(goal);
            if stop.is_none() && solved != Solved::No {
                self.keep_candidate(goal, solved);
                self.warning = warn;
            }
        }
        self.twist = Twist::zeros();
        self.qdot = Joints::zeros();
        self.output(self.warning)
    }

    /// The output of a step that ends without a new setpoint.
    fn halt(&mut self, halt: Halt<T>) -> TickOutput<T> {
        match halt {
            Halt::Stop(reason) => self.hold(reason),
            Halt::Keep(warning) => self.output(warning),
        }
    }

    /// A stop-level violation at the setpoint: holds the last safe setpoint and latches
    /// `reason` until [`Self::clear`]; targets and the stream are forgotten.
    fn hold(&mut self, reason: Reading<T>) -> TickOutput<T> {
        self.activity = self.activity.on(Event::Violation { reason });
        self.stream.reset();
        self.counters.stops += 1;
        self.twist = Twist::zeros();
        self.qdot = Joints::zeros();
        self.drop_pending();
        self.output(None)
    }

    /// The tick's output, with `warning` as its warn-level guard.
    fn output(&self, warning: Option<Guard>) -> TickOutput<T> {
        TickOutput {
            pose: self.pose,
            q: self.q,
            qdot: self.qdot,
            twist: self.twist,
            mode: self.activity.report(self.pending.is_some(), self.moving()),
            warning: warning.is_some(),
            warn_guard: warning,
            stop: self.activity.latched().copied(),
        }
    }
}
