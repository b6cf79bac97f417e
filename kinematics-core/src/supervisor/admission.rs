//! Admission of master targets: the checks a target passes when it is submitted (not
//! stopped, finite, fresh, in order, not too far from the setpoint), the lead along the
//! master's stream ([`super::lead`]), and the refusals with their counters. An admitted
//! target goes to the path check ([`super::verification`]).

use crate::guards::{Depth, Evaluation, Reading, Severity};
use crate::mechanism::Mechanism;
use crate::pose::{rotation_angle, Pose};
use crate::scalar::{lit, norm3, Real};
use crate::singularity::ConditionEstimator;

use super::path::Target;
use super::profile::BRAKING_SHARE;
use super::report::Refusal;
use super::state::Supervisor;

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// Counts and records a refusal, and returns it as the error.
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

    /// The checks at submission of a master target stamped `stamp_us`, at clock time
    /// `now_us`: the target to verify (led along the stream, see [`super::lead`], when
    /// the led target is within the longest segment), or the refusal (counted).
    pub(super) fn admit(
        &mut self,
        target: &Pose<T>,
        stamp_us: u64,
        now_us: u64,
    ) -> Result<Target<T>, Refusal<T>> {
        if self.activity.latched().is_some() {
            self.refuse(Refusal::Latched)?;
        }
        if !target.is_finite() {
            self.refuse(Refusal::NonFinite)?;
        }
        let age = now_us as i128 - stamp_us as i128;
        if age.unsigned_abs() > u128::from(self.cfg.stale_after_us) {
            let age_us = age.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64;
            self.refuse(Refusal::Stale { age_us })?;
        }
        if self.last_stamp_us.is_some_and(|last| stamp_us <= last) {
            self.refuse(Refusal::OutOfOrder)?;
        }
        self.check_distance(target)?;
        self.last_stamp_us = Some(stamp_us);
        self.stream.observe(target, stamp_us);
        let delay_s = lit::<T>(now_us.saturating_sub(stamp_us) as f64 * 1e-6);
        Ok(match self.led(target, delay_s) {
            Some(led) if self.within_segment(&led) => {
                self.stream.lead_taken();
                Target {
                    to: led,
                    plain: Some(*target),
                    stamp_us,
                }
            }
            _ => Target::plain(target, stamp_us),
        })
    }

    /// `target`, arrived `delay_s` after its stamp, led along the master's stream, when the
    /// lead is on, the robot is not braking and the stream moves.
    fn led(&self, target: &Pose<T>, delay_s: T) -> Option<Pose<T>> {
        if !self.cfg.lead || self.activity.is_braking() {
            return None;
        }
        let l = self.profile_limits();
        self.stream.led(
            target,
            l.tip_speed,
            l.tip_accel * lit::<T>(BRAKING_SHARE),
            self.cfg.dt,
            delay_s,
        )
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

    /// Refuses a target too far from the current setpoint, naming the first stop-level
    /// kinematic guard the target itself breaks, if any (a target far outside the
    /// workspace is refused for the workspace, not for its distance).
    pub(super) fn check_distance(&mut self, target: &Pose<T>) -> Result<(), Refusal<T>> {
        let (distance, angle, within) = self.segment_from_setpoint(target);
        if !within {
            let breaks = self.first_breach(target);
            self.refuse(Refusal::TooFar {
                distance,
                angle,
                breaks,
            })?;
        }
        Ok(())
    }

    /// The first stop-level reading of the kinematic guards at `pose` (workspace first,
    /// then reach, joint ranges, tilt, collision, serial singularity), as people read it.
    fn first_breach(&self, pose: &Pose<T>) -> Option<Reading<T>> {
        let mut first: Option<Reading<T>> = None;
        let mut eval = Evaluation::new(self.guards.branch());
        self.guards.evaluate_pose_into(
            pose,
            &mut |r| {
                if first.is_none() && r.severity == Some(Severity::Stop) {
                    first = Some(*r);
                }
            },
            &mut ConditionEstimator::new(),
            &mut eval,
            Depth::Kinematic,
        );
        first.map(|r| self.guards.in_world(&r, pose))
    }
}
