//! The evaluation phase of a period, after the step's outputs are written:
//! `stages_per_tick` stages of the checker's full evaluations ([`super::checker`]), which
//! take turns between the pending path's samples ([`super::verification`]) and the
//! braking point ([`Supervisor::braking_point`]); with neither waiting, the goal, to
//! certify the region around it so that the region follows the stream. The verdicts are
//! acted on here (a path sample) or by the next step (an unsafe braking point: it brakes).

use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;
use nalgebra::Vector3;

use super::checker::Job;
use super::path::Pending;
use super::profile::ProfileLimits;
use super::state::{Handoff, Supervisor};

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// The evaluation phase of a period, after its step: `stages_per_tick` stages of the
    /// checker. A braking point found unsafe is acted on by the next step, which also
    /// takes the profile limits computed here (the setpoint does not change in between).
    pub fn evaluate(&mut self) {
        // The phase ran, which the next step checks first (also while stopped: a clear
        // in between does not make the next step count a missed evaluation).
        let ran = *self.handoff.get_or_insert(Handoff::NOTHING);
        if self.activity.latched().is_some() {
            return;
        }
        let moving = self.moving();
        let l = self.profile_limits();
        let (v0, w0) = self.twist_parts();
        // Before the checker runs: a target it accepts tries to take over on them.
        self.handoff = Some(Handoff {
            limits: Some(l),
            ..ran
        });
        if self.run_checker(&l, moving, &v0, &w0) {
            self.handoff = Some(Handoff {
                brake: true,
                limits: Some(l),
            });
        }
        self.try_take_over();
    }

    /// Runs `stages_per_tick` stages of the checker: a path sample or the braking point in
    /// turn (the braking point only while moving and not braking). Returns whether a
    /// braking point was found unsafe.
    ///
    /// It runs in the evaluation phase after step k, on the state step k left, which is
    /// the state step k + 1 starts from: a verdict found here is acted on by step k + 1,
    /// as if the stage had run at its start.
    fn run_checker(
        &mut self,
        l: &ProfileLimits<T>,
        moving: bool,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> bool {
        let mut ahead_stop = false;
        for _ in 0..self.cfg.stages_per_tick {
            if self.checker.job.is_none() {
                let towards_next = self.activity.next_goal().is_some();
                let ahead = self.ahead_to_check(l, moving, v0, w0);
                self.start_job(ahead.as_ref(), towards_next);
            }
            if self.checker.job.is_none() {
                break;
            }
            ahead_stop |= self.run_stage();
        }
        ahead_stop
    }

    /// The braking point to check (while moving and not braking), unless its whole
    /// stretch from the setpoint lies in a certified region: then it passes at once, as a
    /// passed check would.
    fn ahead_to_check(
        &mut self,
        l: &ProfileLimits<T>,
        moving: bool,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> Option<Pose<T>> {
        if !moving || self.activity.is_braking() {
            return None;
        }
        let towards = *self.activity.heading()?;
        let a = self.braking_point(l, v0, w0, &towards);
        let Some(warn) = self.certified(&self.pose, &a) else {
            return Some(a);
        };
        self.counters.ahead_certified += 1;
        self.ahead_warn = warn;
        self.next_goal_cleared();
        None
    }

    /// Starts the checker's next job, if there is one: a sample of the pending path or
    /// the braking point `ahead` (computed towards the next goal when `towards_next`), in
    /// turn when both wait. With neither, the goal (or the next goal) is evaluated to
    /// certify the region around it, unless the newest region is centred there already.
    fn start_job(&mut self, ahead: Option<&Pose<T>>, towards_next: bool) {
        match (self.pending, ahead) {
            (Some(p), None) => self.begin_path(&p),
            (Some(p), Some(_)) if self.checker.path_turn => self.begin_path(&p),
            (_, Some(a)) => self.checker.begin(a, Job::Ahead { towards_next }),
            (None, None) => {
                let Some(goal) = self.activity.heading().copied() else {
                    return;
                };
                if self.certs[0].is_none_or(|c| c.center != goal) {
                    self.checker.begin(&goal, Job::Refresh);
                }
            }
        }
    }

    /// Starts on the pending path's next sample (its end first).
    fn begin_path(&mut self, p: &Pending<T>) {
        let job = if p.at_end() { Job::PathEnd } else { Job::Path };
        self.checker.begin(&p.sample(), job);
    }

    /// Runs one stage of the checker's job; when it finishes, acts on its verdict. Returns
    /// whether a braking point was found unsafe.
    fn run_stage(&mut self) -> bool {
        let Some(job) = self.checker.advance(&self.guards) else {
            return false;
        };
        let stop = self.checker.staged.stop().copied();
        if let Some(x) = self.checker.staged.inv_cond() {
            self.parallel = x;
        }
        // The regions around the goal and the targets (not around every path sample and
        // braking point), certified in the tick of the evaluation's last stage (the
        // statics, the cheapest stage): a region a tick sooner is a region a tick fresher.
        // Not while braking: no target is accepted then, and the stop follows the
        // stretch checked before.
        let wanted = matches!(job, Job::Refresh | Job::PathEnd | Job::Ahead { .. });
        if stop.is_none() && wanted && !self.activity.is_braking() {
            self.keep_certificate();
        }
        match job {
            Job::Refresh => false,
            Job::Ahead { towards_next } => {
                self.ahead_warn = self.checker.staged.late_warn();
                if stop.is_none() && towards_next {
                    self.next_goal_cleared();
                }
                stop.is_some()
            }
            Job::Path | Job::PathEnd => {
                self.path_sample_checked(stop);
                false
            }
        }
    }
}
