//! The holding brakes at enable: the brake check (with the brakes still applied and the
//! drives on, a small torque against each closed brake must not move its joint), then the
//! release (the drives hold the robot under servo while the brakes open, for the release
//! time), then the robot follows. Applying them is the stop sequencer's ([`crate::stops`]).
//! Spring-applied brakes: unpowered = holding, so a dead board or a cut cable holds.

use crate::scalar::lit;
use num_traits::Float;
use servo::NUM_JOINTS;

/// Brake check settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakeCheckConfig<S> {
    /// The check's duty per joint, in the +q direction, then in -q (default about 30 % of
    /// each joint's continuous rating at stall: 0.023 on the legs, 0.018 on the links).
    pub duty: [S; NUM_JOINTS],
    /// How long each direction is pushed, µs (default 40 ms).
    pub push_us: u64,
    /// Largest motion a holding brake allows, m or rad (default 4 counts: 6 µm on the
    /// legs, 3.5e-4 rad on the links).
    pub max_motion: [S; NUM_JOINTS],
    /// Release time of the brakes: the drives hold this long before following, µs
    /// (default 60 ms).
    pub release_us: u64,
    /// Engage time of the brakes, µs (default 30 ms: twice the reference brake's 15 ms):
    /// an enable that starts sooner after the brakes were applied waits this long from
    /// their application before it pushes against them, so a brake still closing is not
    /// taken for a failed one. A brake that closed on a moving joint may slip a little
    /// longer: after the engage time the check also waits until every joint has moved less
    /// than half its `max_motion` over 10 ms, for at most `settle_max_us` from the
    /// application (default 300 ms); then it pushes whatever the joints do, so a slipping
    /// brake fails the check.
    pub engage_us: u64,
    /// Longest wait for the joints to settle on the applied brakes, µs.
    pub settle_max_us: u64,
}

/// The window over which the joints must be still before the check pushes, µs.
const STILL_WINDOW_US: u64 = 10_000;

impl<S: Float> Default for BrakeCheckConfig<S> {
    fn default() -> Self {
        let (dl, dr) = (lit::<S>(0.023), lit::<S>(0.018));
        let (ml, mr) = (lit::<S>(6e-6), lit::<S>(3.5e-4));
        BrakeCheckConfig {
            duty: [dl, dl, dl, dr, dr, dr],
            push_us: 40_000,
            max_motion: [ml, ml, ml, mr, mr, mr],
            release_us: 60_000,
            engage_us: 30_000,
            settle_max_us: 300_000,
        }
    }
}

/// Where an enable is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnablePhase<S> {
    /// The brakes were applied less than their engage time ago, or the joints still move
    /// on them: nothing is pushed.
    Engaging {
        /// End of the engage time, µs.
        until_us: u64,
        /// End of the longest wait, µs.
        deadline_us: u64,
        /// The joints at the start of the current still window, and its start.
        window_q: [S; NUM_JOINTS],
        /// Start of the current still window, µs.
        window_us: u64,
    },
    /// Pushing against the closed brakes towards +q (`true`) or -q, since `since_us`,
    /// from the joints `start`.
    Checking {
        /// Towards +q.
        positive: bool,
        /// Start of this push, µs.
        since_us: u64,
        /// Joints at the start of the check.
        start: [S; NUM_JOINTS],
    },
    /// The check passed; the brakes open while the drives hold, since `since_us`.
    Releasing {
        /// Start of the release, µs.
        since_us: u64,
    },
    /// Released: the robot follows.
    Released,
}

/// What one step of an enable asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnableStep<S> {
    /// Apply these duties (open loop) with the brakes applied.
    Push([S; NUM_JOINTS]),
    /// Hold under servo with the brakes released.
    Hold,
    /// Done: follow.
    Released,
    /// A joint moved against its closed brake: (joint, motion).
    Failed {
        /// The joint.
        joint: usize,
        /// How far it moved, m or rad.
        motion: S,
    },
}

/// The enable sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakeCheck<S> {
    cfg: BrakeCheckConfig<S>,
    phase: EnablePhase<S>,
}

impl<S: Float> BrakeCheck<S> {
    /// Starts an enable at `now_us` with the joints at `q`; the brakes were last applied
    /// at `applied_at_us` (`None`: not since boot, they hold since power-up).
    pub fn start(
        cfg: BrakeCheckConfig<S>,
        q: &[S; NUM_JOINTS],
        now_us: u64,
        applied_at_us: Option<u64>,
    ) -> Self {
        let phase = match applied_at_us {
            Some(t) if t.saturating_add(cfg.engage_us) > now_us => EnablePhase::Engaging {
                until_us: t.saturating_add(cfg.engage_us),
                deadline_us: t.saturating_add(cfg.settle_max_us.max(cfg.engage_us)),
                window_q: *q,
                window_us: now_us,
            },
            _ => EnablePhase::Checking {
                positive: true,
                since_us: now_us,
                start: *q,
            },
        };
        BrakeCheck { cfg, phase }
    }

    /// The phase.
    pub fn phase(&self) -> EnablePhase<S> {
        self.phase
    }

    /// Whether the brakes may be released now (the check passed).
    pub fn brakes_released(&self) -> bool {
        matches!(
            self.phase,
            EnablePhase::Releasing { .. } | EnablePhase::Released
        )
    }

    /// One step at `now_us` with the joints at `q`.
    pub fn step(&mut self, q: &[S; NUM_JOINTS], now_us: u64) -> EnableStep<S> {
        if let EnablePhase::Engaging {
            until_us,
            deadline_us,
            window_q,
            window_us,
        } = self.phase
        {
            if self.engaging(q, now_us, until_us, deadline_us, window_q, window_us) {
                return EnableStep::Push([S::zero(); NUM_JOINTS]);
            }
            self.phase = EnablePhase::Checking {
                positive: true,
                since_us: now_us,
                start: *q,
            };
        }
        match self.phase {
            EnablePhase::Engaging { .. } => EnableStep::Push([S::zero(); NUM_JOINTS]),
            EnablePhase::Checking {
                positive,
                since_us,
                start,
            } => self.checking(q, now_us, positive, since_us, start),
            EnablePhase::Releasing { since_us } => {
                if now_us.saturating_sub(since_us) >= self.cfg.release_us {
                    self.phase = EnablePhase::Released;
                    EnableStep::Released
                } else {
                    EnableStep::Hold
                }
            }
            EnablePhase::Released => EnableStep::Released,
        }
    }

    /// While the brakes engage: true while it must still wait (the engage time, then
    /// until the joints have stood still for `STILL_WINDOW_US`, at most until the
    /// deadline); the window restarts whenever they moved.
    fn engaging(
        &mut self,
        q: &[S; NUM_JOINTS],
        now_us: u64,
        until_us: u64,
        deadline_us: u64,
        window_q: [S; NUM_JOINTS],
        window_us: u64,
    ) -> bool {
        let restart = EnablePhase::Engaging {
            until_us,
            deadline_us,
            window_q: *q,
            window_us: now_us,
        };
        if now_us < until_us {
            self.phase = restart;
            return true;
        }
        if now_us >= deadline_us {
            return false;
        }
        if now_us.saturating_sub(window_us) < STILL_WINDOW_US {
            return true;
        }
        let half = lit::<S>(0.5);
        let still = q
            .iter()
            .zip(window_q.iter())
            .zip(self.cfg.max_motion.iter())
            .all(|((x, w), m)| (*x - *w).abs() <= *m * half);
        if !still {
            self.phase = restart;
        }
        !still
    }

    /// The check's push against the closed brakes, one way then the other: a joint that
    /// moves more than its limit fails it.
    fn checking(
        &mut self,
        q: &[S; NUM_JOINTS],
        now_us: u64,
        positive: bool,
        since_us: u64,
        start: [S; NUM_JOINTS],
    ) -> EnableStep<S> {
        for (j, ((x, s), m)) in q
            .iter()
            .zip(start.iter())
            .zip(self.cfg.max_motion.iter())
            .enumerate()
        {
            let motion = (*x - *s).abs();
            if !(motion <= *m) {
                return EnableStep::Failed { joint: j, motion };
            }
        }
        let mut positive = positive;
        if now_us.saturating_sub(since_us) >= self.cfg.push_us {
            if positive {
                positive = false;
                self.phase = EnablePhase::Checking {
                    positive,
                    since_us: now_us,
                    start,
                };
            } else {
                self.phase = EnablePhase::Releasing { since_us: now_us };
                return EnableStep::Hold;
            }
        }
        let sign = if positive { S::one() } else { -S::one() };
        EnableStep::Push(self.cfg.duty.map(|d| d * sign))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    type Bc = BrakeCheck<f64>;

    fn run(
        bc: &mut Bc,
        q: impl Fn(u64) -> [f64; NUM_JOINTS],
        from: u64,
        to: u64,
    ) -> Vec<(u64, EnableStep<f64>)> {
        (from..to)
            .step_by(1000)
            .map(|t| (t, bc.step(&q(t), t)))
            .collect()
    }

    /// Property: brakes applied long ago (or never released since boot) are checked at
    /// once: the first step pushes towards +q.
    #[test]
    fn settled_brakes_are_checked_at_once() {
        let cfg = BrakeCheckConfig::<f64>::default();
        for applied in [None, Some(0u64), Some(1_000_000)] {
            let mut bc = Bc::start(cfg, &[0.0; NUM_JOINTS], 1_030_000, applied);
            assert!(matches!(
                bc.phase(),
                EnablePhase::Checking { positive: true, .. }
            ));
            assert_eq!(
                bc.step(&[0.0; NUM_JOINTS], 1_030_000),
                EnableStep::Push(cfg.duty)
            );
        }
    }

    /// Property: within the engage time of the brakes' application, nothing is pushed and
    /// the brakes stay applied; the check starts at the engage time when the joints are
    /// still, from the joints at that time (a sag while engaging is no failure).
    #[test]
    fn an_enable_right_after_a_stop_waits_for_the_engage_time() {
        let cfg = BrakeCheckConfig::<f64>::default();
        let sag = |t: u64| [if t < 20_000 { t as f64 * 1e-9 } else { 2e-5 }; NUM_JOINTS];
        let mut bc = Bc::start(cfg, &sag(1000), 1000, Some(0));
        let steps = run(&mut bc, sag, 1000, 29_000 + 1000);
        for (t, s) in &steps {
            assert_eq!(*s, EnableStep::Push([0.0; NUM_JOINTS]), "at {t} µs");
        }
        assert!(!bc.brakes_released());
        assert_eq!(
            bc.step(&sag(30_000), 30_000),
            EnableStep::Push([0.0; NUM_JOINTS])
        );
        // The still window (10 ms, from the last step within the engage time), then the push.
        let steps = run(&mut bc, sag, 31_000, 45_000);
        let first = steps
            .iter()
            .find(|(_, s)| *s != EnableStep::Push([0.0; NUM_JOINTS]))
            .unwrap();
        assert_eq!(first, &(39_000, EnableStep::Push(cfg.duty)));
        assert!(!bc.brakes_released());
    }

    /// Property: joints that keep moving on the applied brakes delay the push until the
    /// longest wait; then the check pushes and a joint still moving fails it.
    #[test]
    fn a_slipping_brake_fails_after_the_longest_wait() {
        let cfg = BrakeCheckConfig::<f64>::default();
        let slip = |t: u64| [t as f64 * 1e-9, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut bc = Bc::start(cfg, &slip(0), 0, Some(0));
        let steps = run(&mut bc, slip, 0, cfg.settle_max_us);
        assert!(steps
            .iter()
            .all(|(_, s)| *s == EnableStep::Push([0.0; NUM_JOINTS])));
        let steps = run(&mut bc, slip, cfg.settle_max_us, cfg.settle_max_us + 20_000);
        let failed = steps
            .iter()
            .find_map(|&(t, s)| match s {
                EnableStep::Failed { joint, motion } => Some((t, joint, motion)),
                _ => None,
            })
            .unwrap();
        assert_eq!(failed.1, 0);
        assert!(failed.2 > cfg.max_motion[0]);
        assert!(failed.0 <= cfg.settle_max_us + 8_000, "{failed:?}");
    }
}
