//! What the supervisor's caller does with it: submit master targets, run the control
//! periods (the step, then the evaluation phase), brake, and clear a latched stop.

use crate::guards::Reading;
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;

use super::mode::Event;
use super::report::{Refusal, TickOutput};
use super::state::Supervisor;

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// Submits a master target stamped `stamp_us`, at clock time `now_us`. Accepted targets
    /// are verified over the next ticks; a refusal is returned (and counted) at once for
    /// non-finite, stale, out-of-order or too-distant targets, and while stopped.
    pub fn submit(
        &mut self,
        target: &Pose<T>,
        stamp_us: u64,
        now_us: u64,
    ) -> Result<(), Refusal<T>> {
        let t = self.admit(target, stamp_us, now_us)?;
        self.take_target(&t);
        Ok(())
    }

    /// One control period: the step ([`Self::step`]), then the evaluation phase
    /// ([`Self::evaluate`]). Callers that write the step's output to the drives before
    /// the evaluation call the two themselves.
    pub fn tick(&mut self) -> TickOutput<T> {
        let out = self.step();
        self.evaluate();
        out
    }

    /// Stops as soon as the limits allow, e.g. when the master falls silent: forgets the
    /// pending and queued targets and brakes along the current twist at full deceleration
    /// (within the stretch the braking points have checked); the goal becomes where the
    /// robot comes to rest. Not a latched stop: new targets are taken.
    pub fn brake(&mut self) {
        self.drop_pending();
        self.stream.reset();
        let event = if self.moving() {
            Event::Brake
        } else {
            Event::HoldAt { at: self.pose }
        };
        self.activity = self.activity.on(event);
    }

    /// Clears a latched stop when the current setpoint is safe again (e.g. after the
    /// limits were reviewed); the goal becomes the current setpoint.
    pub fn clear(&mut self) -> Result<(), Option<Reading<T>>> {
        let (verdict, _) = self.guards.check_pose(&self.pose);
        if verdict.is_stop() {
            return Err(verdict.first_stop().copied());
        }
        self.activity = self.activity.on(Event::Cleared { at: self.pose });
        self.drop_pending();
        self.stream.reset();
        if let Some(h) = &mut self.handoff {
            h.brake = false;
        }
        Ok(())
    }
}
