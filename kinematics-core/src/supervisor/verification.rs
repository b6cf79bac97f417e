//! Verification of admitted targets: the straight segment to a target, from whichever of
//! the goal and the setpoint is nearer to it, is sampled at `path_step` /
//! `path_step_angle` ([`super::path`]), the end point first; the checker evaluates the
//! samples one after the other ([`super::evaluation`]). A stop-level violation anywhere
//! refuses the target (the robot keeps its goal); a path that passes makes the target the
//! goal ([`super::goal`]). A target whose segment lies in a certified region is accepted at
//! once. One target is verified at a time; the newest of those that arrive meanwhile waits.

use crate::guards::Reading;
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;

use super::path::{samples_between, Pending, Target};
use super::report::Refusal;
use super::state::Supervisor;

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// Takes an admitted target: accepted at once inside a certified region, else verified
    /// along its path (or queued behind the path in verification).
    pub(super) fn take_target(&mut self, t: &Target<T>) {
        // (Accepted at once there too when certified.)
        if self.pending.is_none() {
            self.start_pending(t);
            return;
        }
        // Inside a certified region: accepted at once, superseding the path in verification.
        if self.accept_certified(t) {
            self.supersede_pending();
            return;
        }
        if self.queued.is_some() {
            self.counters.superseded += 1;
        }
        self.queued = Some(*t);
    }

    /// A target accepted at once supersedes the path in verification and the queued one
    /// (both: a queued target left behind would be verified and taken after the newer one).
    fn supersede_pending(&mut self) {
        let (pending, queued) = (self.pending.take(), self.queued.take());
        if pending.is_some() || queued.is_some() {
            self.counters.superseded += 1;
        }
        self.checker.drop_path_job();
    }

    /// Starts verifying the straight segment to `target` from whichever of the goal the
    /// robot is heading for (itself verified) and the setpoint is nearer to it, in path
    /// samples: a fast stream of targets is then verified in short steps from the goal
    /// however far the setpoint lags behind it, and a target back towards the setpoint
    /// from the setpoint. The motion from the setpoint to the new goal stays within the
    /// braking-point checks. While braking, from the setpoint.
    fn start_pending(&mut self, t: &Target<T>) {
        if self.accept_certified(t) {
            return;
        }
        let (from, n) = self.path_start(&t.to);
        self.pending = Some(Pending::new(&from, t, n));
    }

    /// Where the path to `target` starts and how many samples it needs (unrounded): from
    /// whichever of the goal the robot is heading for and the setpoint is nearer to it
    /// (the setpoint while braking).
    fn path_start(&self, target: &Pose<T>) -> (Pose<T>, T) {
        let samples_from = |from: &Pose<T>| {
            samples_between(from, target, self.cfg.path_step, self.cfg.path_step_angle)
        };
        // (The setpoint is within `max_segment` of the target: checked on submission.)
        let at_setpoint = samples_from(&self.pose);
        if !self.activity.is_braking() {
            if let Some(goal) = self.activity.heading() {
                let at_goal = samples_from(goal);
                if at_goal < at_setpoint {
                    return (*goal, at_goal);
                }
            }
        }
        (self.pose, at_setpoint)
    }

    /// Accepts `target` at once when the segment its path check would sample lies in a
    /// certified region (not while braking): it becomes the goal, or the next goal while
    /// moving (which a braking-point check, itself certified or evaluated, promotes).
    fn accept_certified(&mut self, t: &Target<T>) -> bool {
        if self.activity.is_braking() {
            return false;
        }
        let (from, _) = self.path_start(&t.to);
        if self.certified(&from, &t.to).is_none() {
            return false;
        }
        self.accept(t);
        self.counters.certified += 1;
        true
    }

    /// Starts the queued target, if any, once the previous check is over.
    fn start_queued(&mut self) {
        if let Some(q) = self.queued.take() {
            match q.plain {
                Some(_) if self.within_segment(&q.to) => self.start_pending(&q),
                Some(plain) => {
                    if self.check_distance(&plain).is_ok() {
                        self.start_pending(&Target::plain(&plain, q.stamp_us));
                    }
                }
                None => {
                    if self.check_distance(&q.to).is_ok() {
                        self.start_pending(&q);
                    }
                }
            }
        }
    }

    /// Forgets the pending and the queued target (and a path check in progress).
    pub(super) fn drop_pending(&mut self) {
        self.pending = None;
        self.queued = None;
        self.checker.drop_path_job();
    }

    /// The verdict on the pending path's current sample: `stop`, its first stop-level
    /// reading, if any.
    pub(super) fn path_sample_checked(&mut self, stop: Option<Reading<T>>) {
        let Some(mut p) = self.pending else { return };
        if let Some(reading) = stop {
            self.pending = None;
            if let Some(plain) = p.target().plain {
                // The lead ran into a boundary the master's own target may not: no
                // refusal; the lead pauses and the plain target is verified instead
                // (unless a newer target waits).
                self.counters.lead_dropped += 1;
                self.stream.hold_off();
                if self.queued.is_some() {
                    self.start_queued();
                } else if self.check_distance(&plain).is_ok() {
                    self.start_pending(&Target::plain(&plain, p.target().stamp_us));
                }
                return;
            }
            let reading = self.guards.in_world(&reading, &p.sample());
            let _ = self.refuse(Refusal::Path {
                fraction: p.fraction(),
                reading,
                stamp_us: p.target().stamp_us,
            });
            self.start_queued();
            return;
        }
        if p.passed() {
            self.pending = None;
            self.accept(&p.target());
            self.start_queued();
            return;
        }
        self.pending = Some(p);
    }
}
