//! Admission of master targets: the checks a target passes when it is submitted
//! (finite, fresh, in order, not too far from the setpoint), the refusals and the counters.
//! An admitted target goes to the path check ([`super::path`]).

use crate::pose::{rotation_angle, Pose};
use crate::scalar::{lit, norm3, Real};
use core::fmt;

use super::path::Target;
use super::Supervisor;
use crate::guards::Reading;
use crate::mechanism::Mechanism;

/// Why a target was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal<T: Real> {
    /// A component is NaN or infinite.
    NonFinite,
    /// The timestamp is older than `stale_after_us` (or from the future by as much).
    Stale { age_us: i64 },
    /// The timestamp is not newer than the last accepted one.
    OutOfOrder,
    /// Too far from the current setpoint (m, rad).
    TooFar { distance: T, angle: T },
    /// The straight path to it crosses a stop-level region at this fraction of the way.
    Path { fraction: T, reading: Reading<T> },
    /// The supervisor is stopped; clear it first.
    Latched,
}

impl<T: Real> fmt::Display for Refusal<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::NonFinite => f.write_str("target is not finite"),
            Refusal::Stale { age_us } => write!(f, "target is stale ({age_us} µs old)"),
            Refusal::OutOfOrder => f.write_str("target timestamp is not newer than the last"),
            Refusal::TooFar { distance, angle } => write!(
                f,
                "target too far from the setpoint ({:.1} mm, {:.1} deg)",
                crate::scalar::to_f64(*distance) * 1e3,
                crate::scalar::to_f64(*angle).to_degrees()
            ),
            Refusal::Path { fraction, reading } => write!(
                f,
                "path crosses {} at {:.0}% of the way",
                reading.guard,
                crate::scalar::to_f64(*fraction) * 100.0
            ),
            Refusal::Latched => f.write_str("supervisor is stopped; clear the fault first"),
        }
    }
}

/// Counts of what the supervisor refused or did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    pub accepted: u32,
    pub non_finite: u32,
    pub stale: u32,
    pub out_of_order: u32,
    pub too_far: u32,
    pub path_refused: u32,
    pub refused_latched: u32,
    pub superseded: u32,
    /// Targets accepted at once because their whole segment lies in a certified region
    /// (also counted in `accepted`).
    pub certified: u32,
    /// Braking-point checks answered by a certified region instead of a full evaluation.
    pub ahead_certified: u32,
    /// Targets accepted led along the master's stream (of `accepted`; see [`super::lead`]).
    pub led: u32,
    /// Led targets whose path check failed: the lead paused and the master's own target
    /// was verified instead (not a refusal).
    pub lead_dropped: u32,
    pub brakes: u32,
    pub stops: u32,
    pub warn_ticks: u32,
    /// Ticks whose step was scaled down to keep the joints within their speed and
    /// acceleration limits ([`super::profile::step_scales`]: J̇·twist near a serial
    /// singularity, which the Cartesian profile does not see).
    pub slowed: u32,
    /// Steps that found the evaluation phase had not run since the step before (a
    /// scheduling fault): a moving robot brakes on the stretch checked before.
    pub evaluations_missed: u32,
    /// Kinematic checks of a setpoint (the candidate, a rescaled step, the goal on
    /// arrival) answered inside a certified region ([`crate::guards::Guards::solve_certified`]).
    pub setpoints_certified: u32,
}

impl Counters {
    /// Every target refused, whatever the reason (saturating).
    pub fn refused(&self) -> u32 {
        [
            self.non_finite,
            self.stale,
            self.out_of_order,
            self.too_far,
            self.path_refused,
            self.refused_latched,
        ]
        .iter()
        .fold(0u32, |acc, x| acc.saturating_add(*x))
    }
}

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    pub(super) fn refuse(&mut self, r: Refusal<T>) -> Result<(), Refusal<T>> {
        let c = &mut self.counters;
        match r {
            Refusal::NonFinite => c.non_finite += 1,
            Refusal::Stale { .. } => c.stale += 1,
            Refusal::OutOfOrder => c.out_of_order += 1,
            Refusal::TooFar { .. } => c.too_far += 1,
            Refusal::Path { .. } => c.path_refused += 1,
            Refusal::Latched => c.refused_latched += 1,
        }
        self.last_refusal = Some(r);
        Err(r)
    }

    /// Submits a master target stamped `stamp_us`, at clock time `now_us`. Accepted targets
    /// are verified over the next ticks; a refusal is returned (and counted) at once for
    /// non-finite, stale, out-of-order or too-distant targets.
    pub fn submit(
        &mut self,
        target: &Pose<T>,
        stamp_us: u64,
        now_us: u64,
    ) -> Result<(), Refusal<T>> {
        if self.latched.is_some() {
            return self.refuse(Refusal::Latched);
        }
        if !target.is_finite() {
            return self.refuse(Refusal::NonFinite);
        }
        let age = now_us as i128 - stamp_us as i128;
        if age.unsigned_abs() > u128::from(self.cfg.stale_after_us) {
            let age_us = age.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64;
            return self.refuse(Refusal::Stale { age_us });
        }
        if self.last_stamp_us.is_some_and(|last| stamp_us <= last) {
            return self.refuse(Refusal::OutOfOrder);
        }
        self.check_distance(target)?;
        self.last_stamp_us = Some(stamp_us);
        self.stream.observe(target, stamp_us);
        // Led along the stream (see `lead`), within the longest segment.
        let delay_s = lit::<T>(now_us.saturating_sub(stamp_us) as f64 * 1e-6);
        let t = match self.led(target, delay_s) {
            Some(led) if self.within_segment(&led) => {
                self.stream.lead_taken();
                Target {
                    to: led,
                    plain: Some(*target),
                }
            }
            _ => Target::plain(target),
        };
        self.take_target(&t);
        Ok(())
    }

    /// `target`, arrived `delay_s` after its stamp, led along the master's stream, when the
    /// lead is on and the stream moves.
    fn led(&self, target: &Pose<T>, delay_s: T) -> Option<Pose<T>> {
        if !self.cfg.lead || self.braking {
            return None;
        }
        let l = self.profile_limits();
        self.stream.led(
            target,
            l.tip_speed,
            l.tip_accel * lit::<T>(super::profile::BRAKING_SHARE),
            self.cfg.dt,
            delay_s,
        )
    }

    /// A target accepted at once supersedes the path in verification and the queued one
    /// (both: a queued target left behind would be verified and taken after the newer one).
    fn supersede_pending(&mut self) {
        let (pending, queued) = (self.pending.take(), self.queued.take());
        if pending.is_some() || queued.is_some() {
            self.counters.superseded += 1;
        }
        if matches!(self.job, Some(super::Job::Path | super::Job::PathEnd)) {
            self.job = None;
        }
    }

    /// Takes a target that passed the checks at submission: accepted at once inside a
    /// certified region, else verified along its path (or queued behind the path in
    /// verification).
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

    /// The distance and rotation angle of `target` from the current setpoint, and whether
    /// both are within the longest segment.
    fn segment_from_setpoint(&self, target: &Pose<T>) -> (T, T, bool) {
        let distance = norm3(&(target.t - self.pose.t));
        let angle = rotation_angle(&(target.r * self.pose.r.inverse()));
        let within = distance <= self.cfg.max_segment && angle <= self.cfg.max_segment_angle;
        (distance, angle, within)
    }

    /// Whether `target` is within the longest segment from the current setpoint.
    pub(super) fn within_segment(&self, target: &Pose<T>) -> bool {
        self.segment_from_setpoint(target).2
    }

    /// Refuses a target too far from the current setpoint.
    pub(super) fn check_distance(&mut self, target: &Pose<T>) -> Result<(), Refusal<T>> {
        let (distance, angle, within) = self.segment_from_setpoint(target);
        if !within {
            self.refuse(Refusal::TooFar { distance, angle })?;
        }
        Ok(())
    }
}
