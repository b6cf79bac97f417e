//! What the supervisor is doing, as one value: following its goal, braking to a stop, or
//! stopped by a stop-level violation. Each variant holds the data that is valid in it (the
//! goal and the verified target waiting to replace it, where braking comes to rest, the
//! latched reason), and every change goes through [`Activity::on`], the whole transition
//! table in one place.
//!
//! Standing at the goal is following with a zero twist, and verifying a target happens in
//! any activity but the stop: both are read off the setpoint and the path check, not kept
//! here a second time ([`Activity::report`] combines them into the reported [`Mode`]).

use crate::guards::Reading;
use crate::pose::Pose;
use crate::scalar::Real;

use super::report::Mode;

/// What the supervisor is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Activity<T: Real> {
    /// Heading for `goal`, a verified pose, with the speed- and acceleration-limited
    /// profile that stops there (or standing on it). `next` is a target verified while
    /// moving: it replaces the goal once a braking-point check has looked past the goal
    /// towards it (the checks before looked no farther than the goal).
    Following {
        goal: Pose<T>,
        next: Option<Pose<T>>,
    },
    /// A controlled stop: full deceleration along the current twist on every tick, within
    /// the stretch the braking points have checked. `stop` is where the robot comes to
    /// rest (the goal it followed until the first braking step computes it).
    Braking { stop: Pose<T> },
    /// Stopped by a stop-level violation of the setpoint: the last safe setpoint holds and
    /// `reason` stays latched until cleared.
    Stopped { reason: Reading<T> },
}

/// What changes the activity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Event<T: Real> {
    /// A target passed its path check (or lies in a certified region): the goal of a robot
    /// at rest, the next goal of a moving one. Ends a controlled stop.
    Accepted { target: Pose<T>, moving: bool },
    /// The braking stretch towards the next goal was checked, or the robot stands: the
    /// next goal becomes the goal.
    NextGoalCleared,
    /// Told to stop while moving ([`super::Supervisor::brake`]).
    Brake,
    /// A braking step: the robot comes to rest at `stop`. Also how a step starts braking,
    /// on an unsafe braking point or a missed evaluation phase.
    Braked { stop: Pose<T> },
    /// The braking robot stands at `at`.
    Stood { at: Pose<T> },
    /// Told to stop while standing at `at`: the setpoint becomes the goal.
    HoldAt { at: Pose<T> },
    /// A stop-level violation at the setpoint.
    Violation { reason: Reading<T> },
    /// The latched stop was cleared at the safe setpoint `at` (or a clear while running).
    Cleared { at: Pose<T> },
}

impl<T: Real> Activity<T> {
    /// Standing at `at`, which becomes the goal.
    pub(super) fn holding(at: &Pose<T>) -> Self {
        Activity::Following {
            goal: *at,
            next: None,
        }
    }

    /// The transition table: the activity after `event` (`t` the target, `-` no next
    /// goal).
    ///
    /// - From any activity: `Violation { r }` → `Stopped { r }`; `Cleared { at }` →
    ///   `Following { at, - }`.
    /// - `Following { goal, next }`: `Accepted` → `Following { goal, t }` while moving,
    ///   `Following { t, next }` at rest; `NextGoalCleared` → `Following { next, - }`
    ///   (unchanged without a next goal); `Brake` → `Braking { goal }`; `Braked { s }` →
    ///   `Braking { s }`; `HoldAt { at }` → `Following { at, - }`; `Stood` → unchanged.
    /// - `Braking { stop }`: `Accepted` → `Following { stop, t }` while moving,
    ///   `Following { t, - }` at rest; `Braked { s }` → `Braking { s }`; `Stood { at }` →
    ///   `Following { at, - }`; `HoldAt { at }` → `Braking { at }`; `Brake` and
    ///   `NextGoalCleared` → unchanged.
    /// - `Stopped { reason }`: unchanged by every other event (a stopped supervisor takes
    ///   no targets and does not move).
    pub(super) fn on(self, event: Event<T>) -> Self {
        use Activity::{Braking, Following, Stopped};
        match (self, event) {
            (_, Event::Violation { reason }) => Stopped { reason },
            (_, Event::Cleared { at }) => Activity::holding(&at),
            (Stopped { .. }, _) => self,
            (Following { goal, next }, Event::Accepted { target, moving }) => {
                if moving {
                    Following {
                        goal,
                        next: Some(target),
                    }
                } else {
                    Following { goal: target, next }
                }
            }
            (Braking { stop }, Event::Accepted { target, moving }) => {
                if moving {
                    Following {
                        goal: stop,
                        next: Some(target),
                    }
                } else {
                    Activity::holding(&target)
                }
            }
            (
                Following {
                    next: Some(next), ..
                },
                Event::NextGoalCleared,
            ) => Activity::holding(&next),
            (Following { goal, .. }, Event::Brake) => Braking { stop: goal },
            (_, Event::Braked { stop }) => Braking { stop },
            (Braking { .. }, Event::Stood { at }) => Activity::holding(&at),
            (Following { .. }, Event::HoldAt { at }) => Activity::holding(&at),
            (Braking { .. }, Event::HoldAt { at }) => Braking { stop: at },
            (_, Event::NextGoalCleared | Event::Brake | Event::Stood { .. }) => self,
        }
    }

    /// The next goal, if a verified target waits to replace the goal.
    pub(super) fn next_goal(&self) -> Option<&Pose<T>> {
        match self {
            Activity::Following { next, .. } => next.as_ref(),
            _ => None,
        }
    }

    /// Where the robot is heading: the next goal, else the goal, or where braking stops.
    pub(super) fn heading(&self) -> Option<&Pose<T>> {
        match self {
            Activity::Following { goal, next } => Some(next.as_ref().unwrap_or(goal)),
            Activity::Braking { stop } => Some(stop),
            Activity::Stopped { .. } => None,
        }
    }

    /// Whether braking to a stop.
    pub(super) fn is_braking(&self) -> bool {
        matches!(self, Activity::Braking { .. })
    }

    /// The latched stop reason, if stopped.
    pub(super) fn latched(&self) -> Option<&Reading<T>> {
        match self {
            Activity::Stopped { reason } => Some(reason),
            _ => None,
        }
    }

    /// The mode reported with each tick: the activity, with following told apart by
    /// whether a target is being verified and whether the setpoint moves.
    pub(super) fn report(&self, verifying: bool, moving: bool) -> Mode {
        match self {
            Activity::Stopped { .. } => Mode::Stopped,
            Activity::Braking { .. } => Mode::Braking,
            Activity::Following { .. } if verifying => Mode::Verifying,
            Activity::Following { .. } if moving => Mode::Moving,
            Activity::Following { .. } => Mode::Holding,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guards::{Guard, Severity, Subject};
    use nalgebra::{Rotation3, Vector3};

    fn at(x_mm: f64) -> Pose<f64> {
        Pose {
            t: Vector3::new(x_mm * 1e-3, 0.0, 0.16),
            r: Rotation3::identity(),
        }
    }

    fn reading(value: f64) -> Reading<f64> {
        Reading {
            guard: Guard::Workspace,
            subject: Subject::Axis(0),
            value,
            limit: 0.0,
            margin: -value,
            severity: Some(Severity::Stop),
        }
    }

    /// Every (activity, event) pair against the table of [`Activity::on`]: the activity
    /// after the event, and the data it holds.
    #[test]
    fn the_transition_table() {
        use Activity::{Braking, Following, Stopped};
        let (goal, next, target, stop, here) = (at(1.0), at(2.0), at(3.0), at(4.0), at(5.0));
        let reason = reading(1.0);
        let following = |goal: Pose<f64>, next: Option<Pose<f64>>| Following { goal, next };
        let states = [
            ("following", following(goal, None)),
            ("following, next goal waiting", following(goal, Some(next))),
            ("braking", Braking { stop }),
            ("stopped", Stopped { reason }),
        ];
        let events = [
            Event::Accepted {
                target,
                moving: true,
            },
            Event::Accepted {
                target,
                moving: false,
            },
            Event::NextGoalCleared,
            Event::Brake,
            Event::Braked { stop: here },
            Event::Stood { at: here },
            Event::HoldAt { at: here },
            Event::Violation {
                reason: reading(2.0),
            },
            Event::Cleared { at: here },
        ];
        // Rows: the states above; columns: the events above.
        let table: [[Activity<f64>; 9]; 4] = [
            [
                following(goal, Some(target)),
                following(target, None),
                following(goal, None),
                Braking { stop: goal },
                Braking { stop: here },
                following(goal, None),
                following(here, None),
                Stopped {
                    reason: reading(2.0),
                },
                following(here, None),
            ],
            [
                following(goal, Some(target)),
                following(target, Some(next)),
                following(next, None),
                Braking { stop: goal },
                Braking { stop: here },
                following(goal, Some(next)),
                following(here, None),
                Stopped {
                    reason: reading(2.0),
                },
                following(here, None),
            ],
            [
                following(stop, Some(target)),
                following(target, None),
                Braking { stop },
                Braking { stop },
                Braking { stop: here },
                following(here, None),
                Braking { stop: here },
                Stopped {
                    reason: reading(2.0),
                },
                following(here, None),
            ],
            [
                Stopped { reason },
                Stopped { reason },
                Stopped { reason },
                Stopped { reason },
                Stopped { reason },
                Stopped { reason },
                Stopped { reason },
                Stopped {
                    reason: reading(2.0),
                },
                following(here, None),
            ],
        ];
        for ((name, state), row) in states.iter().zip(table.iter()) {
            for (event, expected) in events.iter().zip(row.iter()) {
                assert_eq!(state.on(*event), *expected, "{name} on {event:?}");
            }
        }
    }

    #[test]
    fn what_each_activity_holds_and_reports() {
        let (goal, next, stop) = (at(1.0), at(2.0), at(4.0));
        let following = Activity::Following {
            goal,
            next: Some(next),
        };
        assert_eq!(following.next_goal(), Some(&next));
        assert_eq!(following.heading(), Some(&next));
        assert_eq!(Activity::holding(&goal).heading(), Some(&goal));
        let braking = Activity::Braking { stop };
        assert_eq!(braking.next_goal(), None);
        assert_eq!(braking.heading(), Some(&stop));
        assert!(braking.is_braking() && !following.is_braking());
        let stopped = Activity::Stopped {
            reason: reading(1.0),
        };
        assert_eq!(stopped.heading(), None);
        assert_eq!(stopped.latched(), Some(&reading(1.0)));
        assert_eq!(following.latched(), None);
        // The reported mode: the stop and braking first, then verification, then motion.
        for verifying in [false, true] {
            for moving in [false, true] {
                assert_eq!(stopped.report(verifying, moving), Mode::Stopped);
                assert_eq!(braking.report(verifying, moving), Mode::Braking);
            }
            assert_eq!(following.report(true, verifying), Mode::Verifying);
        }
        assert_eq!(following.report(false, true), Mode::Moving);
        assert_eq!(following.report(false, false), Mode::Holding);
    }
}
