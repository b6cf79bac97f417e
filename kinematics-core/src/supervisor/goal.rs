//! The goal: a verified target becomes the goal of a robot at rest, or the next goal of a
//! moving one, which replaces the goal once the braking point towards it has been checked
//! (a braking-point check looks no farther than the goal it was computed towards).
//!
//! The braking point is where braking would stop if it began only when the check after
//! the one starting now has finished, the robot accelerating until then, but no farther
//! than the goal (see [`Supervisor::braking_point`]).

use crate::guards::MAX_STAGES;
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::{lit, Real};
use nalgebra::Vector3;

use super::mode::Event;
use super::path::Target;
use super::profile::{self, ProfileLimits};
use super::state::Supervisor;

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// A verified target: the goal, or the next goal while moving. Ends a controlled stop.
    pub(super) fn accept(&mut self, t: &Target<T>) {
        let moving = self.moving();
        self.activity = self.activity.on(Event::Accepted {
            target: t.to,
            moving,
        });
        self.counters.accepted += 1;
        if t.plain.is_some() {
            self.counters.led += 1;
        }
        self.try_take_over();
    }

    /// A braking-point check towards the next goal passed: the next goal becomes the goal.
    pub(super) fn next_goal_cleared(&mut self) {
        if self.activity.next_goal().is_some() {
            self.activity = self.activity.on(Event::NextGoalCleared);
        }
    }

    /// A verified target waiting to replace the goal takes over as soon as the braking
    /// stretch towards it lies in a certified region. Tried when the target is accepted
    /// and at the end of every evaluation phase, on the state the next step starts from
    /// (its pose, twist and profile limits): the same check as at the start of that step,
    /// off the real-time step, so that a led stream moves the goal on every tick.
    pub(super) fn try_take_over(&mut self) {
        let Some(next) = self.activity.next_goal().copied() else {
            return;
        };
        if !self.moving() || self.handoff.is_some_and(|h| h.brake) {
            return;
        }
        let l = match self.handoff.and_then(|h| h.limits) {
            Some(l) => l,
            None => self.profile_limits(),
        };
        let (v0, w0) = self.twist_parts();
        let a = self.braking_point(&l, &v0, &w0, &next);
        if let Some(warn) = self.certified(&self.pose, &a) {
            self.counters.ahead_certified += 1;
            self.ahead_warn = warn;
            self.next_goal_cleared();
        }
    }

    /// The braking point towards `towards` from the setpoint moving at (`v0`, `w0`).
    ///
    /// The braking point checked by a job that starts on this tick must cover what can
    /// happen until the next braking-point job has finished: a job takes at most L ticks
    /// (L = [`MAX_STAGES`] / `stages_per_tick`, rounded up) and the next one may wait for
    /// one path sample, so it finishes at most 3·L - 1 ticks after this one; until then the
    /// profile may accelerate, to v' = |v| + a·(3L - 1)·dt, and a violation found then
    /// starts braking from there. The point checked is where the robot, moving on for 3L
    /// ticks at v' along its current twist, would stop from v' ([`profile::braking_point`]:
    /// 3.7 mm ahead at 25 mm/s, 250 mm/s², L = 13), but no farther than `towards` (the goal,
    /// or the verified target waiting to replace it): the profile stops there with
    /// deceleration in hand, so a target next to a boundary is reached; the goal changes
    /// only after a check that looked past it.
    pub(super) fn braking_point(
        &self,
        l: &ProfileLimits<T>,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
        towards: &Pose<T>,
    ) -> Pose<T> {
        let per_job = MAX_STAGES.div_ceil(u32::from(self.cfg.stages_per_tick));
        let n = lit::<T>(f64::from(3 * per_job));
        profile::braking_point(&self.pose, v0, w0, towards, l, n, self.cfg.dt)
    }
}
