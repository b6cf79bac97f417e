//! The holding brakes at enable: the brake check (with the brakes still applied and the
//! drives on, a small torque against each closed brake must not move its joint), then the
//! release (the drives hold the robot under servo while the brakes open, for the release
//! time), then the robot follows. Applying them is the stop sequencer's ([`crate::stops`]).
//! Spring-applied brakes: unpowered = holding, so a dead board or a cut cable holds.

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
}

fn lit<S: Float>(x: f64) -> S {
    S::from(x).unwrap_or_else(S::zero)
}

impl<S: Float> Default for BrakeCheckConfig<S> {
    fn default() -> Self {
        let (dl, dr) = (lit::<S>(0.023), lit::<S>(0.018));
        let (ml, mr) = (lit::<S>(6e-6), lit::<S>(3.5e-4));
        BrakeCheckConfig {
            duty: [dl, dl, dl, dr, dr, dr],
            push_us: 40_000,
            max_motion: [ml, ml, ml, mr, mr, mr],
            release_us: 60_000,
        }
    }
}

/// Where an enable is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnablePhase<S> {
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
    /// Starts an enable at `now_us` with the joints at `q`.
    pub fn start(cfg: BrakeCheckConfig<S>, q: &[S; NUM_JOINTS], now_us: u64) -> Self {
        BrakeCheck {
            cfg,
            phase: EnablePhase::Checking {
                positive: true,
                since_us: now_us,
                start: *q,
            },
        }
    }

    /// The phase.
    pub fn phase(&self) -> EnablePhase<S> {
        self.phase
    }

    /// Whether the brakes may be released now (the check passed).
    pub fn brakes_released(&self) -> bool {
        !matches!(self.phase, EnablePhase::Checking { .. })
    }

    /// One step at `now_us` with the joints at `q`.
    pub fn step(&mut self, q: &[S; NUM_JOINTS], now_us: u64) -> EnableStep<S> {
        match self.phase {
            EnablePhase::Checking {
                positive,
                since_us,
                start,
            } => {
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
                if now_us.saturating_sub(since_us) >= self.cfg.push_us {
                    if positive {
                        self.phase = EnablePhase::Checking {
                            positive: false,
                            since_us: now_us,
                            start,
                        };
                    } else {
                        self.phase = EnablePhase::Releasing { since_us: now_us };
                        return EnableStep::Hold;
                    }
                }
                let sign = if matches!(self.phase, EnablePhase::Checking { positive: true, .. }) {
                    S::one()
                } else {
                    -S::one()
                };
                EnableStep::Push(self.cfg.duty.map(|d| d * sign))
            }
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
}
