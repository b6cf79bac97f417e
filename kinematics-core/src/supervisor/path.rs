//! The path check: the straight segment to an admitted target, sampled at `path_step` /
//! `path_step_angle` (the end point first), and the checker that runs the staged full
//! evaluations of the path samples and of the braking point in turn.

use crate::pose::{rotation_angle, rotation_vector, Pose};
use crate::scalar::{lit, norm3, scale3, sub3, Real};
use nalgebra::Vector3;

use super::admission::Refusal;
use super::{Job, Supervisor};
use crate::guards::{Guard, Reading};
use crate::mechanism::Mechanism;

/// A target to verify: the pose, and the master's plain target when the pose leads it
/// along the stream (see [`super::lead`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Target<T: Real> {
    pub to: Pose<T>,
    pub plain: Option<Pose<T>>,
}

impl<T: Real> Target<T> {
    /// The master's target as it came.
    pub fn plain(to: &Pose<T>) -> Self {
        Target {
            to: *to,
            plain: None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Pending<T: Real> {
    from: Pose<T>,
    to: Pose<T>,
    /// The master's plain target when `to` leads it.
    plain: Option<Pose<T>>,
    /// The whole segment ([`segment`]), computed once, not for every sample.
    dv: Vector3<T>,
    dw: Vector3<T>,
    samples: u16,
    /// Next sample to check; sample `samples` (the end) is checked first.
    next: u16,
    end_checked: bool,
}

/// Pose at fraction `s` of the straight segment a → b (translation linear, rotation about
/// the fixed world axis of b·aᵀ).
pub fn interpolate<T: Real>(a: &Pose<T>, b: &Pose<T>, s: T) -> Pose<T> {
    let (dv, dw) = segment(a, b);
    along(a, &dv, &dw, s)
}

/// The straight segment a → b: its translation and the rotation vector of b·aᵀ.
pub(super) fn segment<T: Real>(a: &Pose<T>, b: &Pose<T>) -> (Vector3<T>, Vector3<T>) {
    (sub3(&b.t, &a.t), rotation_vector(&(b.r * a.r.inverse())))
}

/// The pose at fraction `s` of the segment (`dv`, `dw`) from `from` ([`segment`]).
pub(super) fn along<T: Real>(from: &Pose<T>, dv: &Vector3<T>, dw: &Vector3<T>, s: T) -> Pose<T> {
    from.displaced(&scale3(dv, s), &scale3(dw, s))
}

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// Starts verifying the straight segment to `target` from whichever of the goal the
    /// robot is heading for (itself verified) and the setpoint is nearer to it, in path
    /// samples: a fast stream of targets is then verified in short steps from the goal
    /// however far the setpoint lags behind it, and a target back towards the setpoint
    /// from the setpoint. The motion from the setpoint to the new goal stays within the
    /// braking-point checks. While braking, from the setpoint.
    pub(super) fn start_pending(&mut self, t: &Target<T>) {
        if self.accept_certified(t) {
            return;
        }
        let target = &t.to;
        let (from, n) = self.path_start(target);
        let n = n.ceil().max(T::one());
        let samples = crate::scalar::to_f64(n) as u16;
        let (dv, dw) = segment(&from, target);
        self.pending = Some(Pending {
            from,
            to: *target,
            plain: t.plain,
            dv,
            dw,
            samples: samples.max(1),
            next: 1,
            end_checked: false,
        });
    }

    /// Where the path to `target` starts and how many samples it needs (unrounded): from
    /// whichever of the goal the robot is heading for and the setpoint is nearer to it
    /// (the setpoint while braking).
    fn path_start(&self, target: &Pose<T>) -> (Pose<T>, T) {
        let samples_from = |from: &Pose<T>| {
            let distance = norm3(&(target.t - from.t));
            let angle = rotation_angle(&(target.r * from.r.inverse()));
            (distance / self.cfg.path_step).max(angle / self.cfg.path_step_angle)
        };
        let goal = self.next_goal.unwrap_or(self.goal);
        let (at_goal, at_setpoint) = (samples_from(&goal), samples_from(&self.pose));
        // (The setpoint is within `max_segment` of the target: checked on submission.)
        if !self.braking && at_goal < at_setpoint {
            (goal, at_goal)
        } else {
            (self.pose, at_setpoint)
        }
    }

    /// Whether a certified region (the newest two) contains the whole straight motion
    /// `from` → `to`: then no pose of it violates a stop-level guard
    /// ([`crate::guards::certificate`]); the region's centre warning, if any.
    pub(super) fn certified(&self, from: &Pose<T>, to: &Pose<T>) -> Option<Option<Guard>> {
        self.certs
            .iter()
            .flatten()
            .find(|c| c.contains_motion(from, to))
            .map(|c| c.warn)
    }

    /// Accepts `target` at once when the segment its path check would sample lies in a
    /// certified region (not while braking): it becomes the goal, or the next goal while
    /// moving (which a braking-point check, itself certified or evaluated, promotes).
    pub(super) fn accept_certified(&mut self, t: &Target<T>) -> bool {
        if self.braking {
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

    /// A verified target: the goal, or the next goal while moving.
    fn accept(&mut self, t: &Target<T>) {
        if self.moving() {
            self.next_goal = Some(t.to);
        } else {
            self.goal = t.to;
        }
        self.braking = false;
        self.counters.accepted += 1;
        if t.plain.is_some() {
            self.counters.led += 1;
        }
        self.try_take_over();
    }

    /// A full evaluation without a stop-level violation: the region it certifies becomes
    /// the newest of the two kept.
    pub(super) fn keep_certificate(&mut self) {
        let cert = self.checker.full().and_then(|e| self.guards.certify(&e));
        if let Some(c) = cert {
            self.certs = [Some(c), self.certs[0]];
        }
    }

    /// Starts the queued target, if any, once the previous check is over.
    pub(super) fn start_queued(&mut self) {
        if let Some(q) = self.queued.take() {
            match q.plain {
                Some(_) if self.within_segment(&q.to) => self.start_pending(&q),
                Some(plain) => {
                    if self.check_distance(&plain).is_ok() {
                        self.start_pending(&Target::plain(&plain));
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
        self.next_goal = None;
        if matches!(self.job, Some(Job::Path | Job::PathEnd)) {
            self.job = None;
        }
    }

    /// Starts the checker's next job, if there is one: a sample of the pending path or
    /// the braking point `ahead` (while moving and not braking), in turn when both wait.
    /// With neither, the goal (or the next goal) is evaluated to certify the region around
    /// it, unless the newest region is centred there already.
    pub(super) fn start_job(&mut self, ahead: Option<&Pose<T>>) {
        match (self.pending, ahead) {
            (Some(p), None) => self.begin_path(&p),
            (Some(p), Some(_)) if self.path_turn => self.begin_path(&p),
            (_, Some(a)) => self.begin(a, Job::Ahead),
            (None, None) => {
                let goal = self.next_goal.unwrap_or(self.goal);
                if self.certs[0].is_none_or(|c| c.center != goal) {
                    self.begin(&goal, Job::Refresh);
                }
            }
        }
    }

    /// Starts on the pending path's next sample (its end first).
    pub(super) fn begin_path(&mut self, p: &Pending<T>) {
        let (k, job) = if p.end_checked {
            (p.next, Job::Path)
        } else {
            (p.samples, Job::PathEnd)
        };
        let s = lit::<T>(f64::from(k)) / lit(f64::from(p.samples));
        self.begin(&along(&p.from, &p.dv, &p.dw, s), job);
    }

    pub(super) fn begin(&mut self, pose: &Pose<T>, job: Job) {
        self.checker.start(pose);
        self.job = Some(job);
        self.path_turn = job == Job::Ahead;
    }

    /// Runs one stage of the checker's job; when it finishes, acts on its verdict. Returns
    /// whether a braking point was found unsafe.
    pub(super) fn run_stage(&mut self) -> bool {
        let Some(job) = self.job else { return false };
        let cond = match job {
            Job::Path => &mut self.cond_path,
            Job::PathEnd | Job::Refresh => &mut self.cond_path_end,
            Job::Ahead => &mut self.cond_ahead,
        };
        self.guards.advance(&mut self.checker, cond);
        if !self.checker.is_finished() {
            return false;
        }
        self.job = None;
        let stop = self.checker.stop().copied();
        if let Some(x) = self.checker.inv_cond() {
            self.parallel = x;
        }
        // The regions around the goal and the targets (not around every path sample and
        // braking point), certified in the tick of the evaluation's last stage (the
        // statics, the cheapest stage): a region a tick sooner is a region a tick fresher.
        // Not while braking: no target is accepted then, and the stop follows the
        // stretch checked before.
        let wanted = matches!(job, Job::Refresh | Job::PathEnd | Job::Ahead);
        if stop.is_none() && wanted && !self.braking {
            self.keep_certificate();
        }
        match job {
            Job::Refresh => false,
            Job::Ahead => {
                self.ahead_warn = self.checker.late_warn();
                if stop.is_none() && self.job_for_next {
                    if let Some(next) = self.next_goal.take() {
                        self.goal = next;
                    }
                }
                stop.is_some()
            }
            Job::Path | Job::PathEnd => {
                self.path_sample_checked(stop);
                false
            }
        }
    }

    /// The verdict on the pending path's current sample.
    pub(super) fn path_sample_checked(&mut self, stop: Option<Reading<T>>) {
        let Some(mut p) = self.pending else { return };
        if let Some(reading) = stop {
            let k = if p.end_checked { p.next } else { p.samples };
            self.pending = None;
            if let Some(plain) = p.plain {
                // The lead ran into a boundary the master's own target may not: no
                // refusal; the lead pauses and the plain target is verified instead
                // (unless a newer target waits).
                self.counters.lead_dropped += 1;
                self.stream.hold_off();
                if self.queued.is_some() {
                    self.start_queued();
                } else if self.check_distance(&plain).is_ok() {
                    self.start_pending(&Target::plain(&plain));
                }
                return;
            }
            let _ = self.refuse(Refusal::Path {
                fraction: lit::<T>(f64::from(k)) / lit(f64::from(p.samples)),
                reading,
            });
            self.start_queued();
            return;
        }
        if p.end_checked {
            p.next += 1;
        } else {
            p.end_checked = true;
        }
        if p.next >= p.samples {
            self.pending = None;
            self.accept(&Target {
                to: p.to,
                plain: p.plain,
            });
            self.start_queued();
            return;
        }
        self.pending = Some(p);
    }
}
