//! The park move after homing: from where the homing left the joints (legs just off their
//! switches, links just off their hard stops) to the park joints (the central
//! configuration by default), along the straight line in joint space.
//!
//! **The path passes the guards before the robot moves.** The move is checked at
//! [`ParkConfig::samples`] points along the line, one per control tick (a forward
//! kinematics warm-started from the last sample and a full pose evaluation of the guards):
//! the homed pose lies at the mechanics' extremes, so it is usually outside the task box,
//! and a guard that is violated *at the start* may stay violated along the path only while
//! the path recovers from it: its margin may never shrink from one sample to the next. Any
//! other stop-level violation, a violation at the park pose itself, or a point without a
//! pose refuses the move (the homing fails, its stop applies).
//!
//! **Then the move runs with a smooth profile**: the quintic `s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`,
//! zero speed and acceleration at both ends, its duration the shortest that keeps every
//! joint within its park speed (peak `1.875·Δq/T`) and acceleration (peak `5.77·Δq/T²`).

use kinematics_core::fk::{forward, FkConfig};
use kinematics_core::guards::{Guard, Guards, Reading, Severity, Subject};
use kinematics_core::{Branch, Joints, Mechanism, Pose};
use num_traits::Float;
use servo::NUM_JOINTS;

use crate::scalar::lit;
use crate::scalar::Scalar;

/// Park move settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParkConfig<S> {
    /// Largest joint speeds, m/s and rad/s (default 10 mm/s, 0.2 rad/s).
    pub speed: [S; NUM_JOINTS],
    /// Largest joint accelerations, m/s² and rad/s² (default 50 mm/s², 1 rad/s²).
    pub accel: [S; NUM_JOINTS],
    /// Points of the path checked before the move (default 32, one per tick).
    pub samples: u16,
    /// The move's end: every joint within this of the park joints (default 0.1 mm,
    /// 2 mrad), or the homing fails after `settle_us` more.
    pub tolerance: [S; NUM_JOINTS],
    /// Time allowed after the profile's end to settle within the tolerance, µs
    /// (default 500 ms).
    pub settle_us: u64,
}

impl<S: Float> Default for ParkConfig<S> {
    fn default() -> Self {
        let (vl, vr) = (lit::<S>(0.010), lit::<S>(0.2));
        let (al, ar) = (lit::<S>(0.050), lit::<S>(1.0));
        let (tl, tr) = (lit::<S>(0.1e-3), lit::<S>(2e-3));
        ParkConfig {
            speed: [vl, vl, vl, vr, vr, vr],
            accel: [al, al, al, ar, ar, ar],
            samples: 32,
            tolerance: [tl, tl, tl, tr, tr, tr],
            settle_us: 500_000,
        }
    }
}

/// Why the park move was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParkRefusal<S: Scalar> {
    /// A guard is violated along the path (not a recovery from the start) or at the park
    /// pose: the sample (0 = start) and the reading.
    Guard {
        /// The sample, 0 ..= samples.
        sample: u16,
        /// The violation.
        reading: Reading<S>,
    },
    /// A point of the path has no pose (forward kinematics failed).
    NoPose {
        /// The sample.
        sample: u16,
    },
    /// Invalid settings or joints (non-finite, not positive).
    Invalid,
    /// The robot did not settle at the park joints in time (joint, error).
    NotSettled {
        /// The joint furthest off.
        joint: usize,
        /// Its error, m or rad.
        error: S,
    },
}

/// What one step of the park move asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParkStep<S: Scalar> {
    /// Still checking the path: hold where the robot is.
    Checking {
        /// Samples checked so far.
        checked: u16,
    },
    /// Follow this joint setpoint (position, speed).
    Move {
        /// Joint setpoint.
        q: [S; NUM_JOINTS],
        /// Its speed.
        qdot: [S; NUM_JOINTS],
    },
    /// At the park joints: the controller takes over.
    Arrived,
    /// Refused or failed.
    Refused(ParkRefusal<S>),
}

/// Most guard readings followed as recoveries.
const MAX_RECOVERIES: usize = 16;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase<S: Scalar> {
    Checking { sample: u16, guess: Pose<S> },
    Moving { since_us: u64 },
    Done(ParkStep<S>),
}

/// The park move: [`ParkMove::step`] once per control tick.
#[derive(Clone, Debug)]
pub struct ParkMove<S: Scalar, M: Mechanism<S>> {
    cfg: ParkConfig<S>,
    guards: Guards<S, M>,
    fk: FkConfig<S>,
    from: [S; NUM_JOINTS],
    to: [S; NUM_JOINTS],
    duration_s: S,
    phase: Phase<S>,
    /// The guards violated at the start and their last margins.
    recovering: heapless::Vec<(Guard, Subject, S), MAX_RECOVERIES>,
}

impl<S: Scalar, M: Mechanism<S>> ParkMove<S, M> {
    /// A park move of `robot` on `branch` under `guards`, from the joints `from` (the
    /// measured pose `pose` there) to `to`.
    pub fn new(
        guards: Guards<S, M>,
        fk: FkConfig<S>,
        cfg: ParkConfig<S>,
        from: [S; NUM_JOINTS],
        pose: Pose<S>,
        to: [S; NUM_JOINTS],
    ) -> Self {
        let mut duration = S::zero();
        let mut valid = cfg.samples > 0;
        for j in 0..NUM_JOINTS {
            let (Some(a), Some(b), Some(v), Some(acc)) =
                (from.get(j), to.get(j), cfg.speed.get(j), cfg.accel.get(j))
            else {
                valid = false;
                continue;
            };
            let d = Float::abs(*b - *a);
            let ok = |x: S| x.is_finite() && x > S::zero();
            valid &= d.is_finite() && ok(*v) && ok(*acc);
            // Peak speed 15/8 Δ/T, peak acceleration 10/√3 Δ/T² of the quintic.
            let t_speed = lit::<S>(1.875) * d / *v;
            let t_accel = Float::sqrt(lit::<S>(5.773_502_7) * d / *acc);
            duration = Float::max(Float::max(duration, t_speed), t_accel);
        }
        let phase = if valid && duration.is_finite() && pose.is_finite() {
            Phase::Checking {
                sample: 0,
                guess: pose,
            }
        } else {
            Phase::Done(ParkStep::Refused(ParkRefusal::Invalid))
        };
        ParkMove {
            cfg,
            guards,
            fk,
            from,
            to,
            duration_s: duration,
            phase,
            recovering: heapless::Vec::new(),
        }
    }

    /// The move's duration once checked, s.
    pub fn duration_s(&self) -> S {
        self.duration_s
    }

    /// The joints at the fraction `s` of the path.
    fn at(&self, s: S) -> [S; NUM_JOINTS] {
        core::array::from_fn(|j| {
            let (a, b) = (
                self.from.get(j).copied().unwrap_or_else(S::zero),
                self.to.get(j).copied().unwrap_or_else(S::zero),
            );
            a + (b - a) * s
        })
    }

    /// Checks sample `k` (pose guess `guess`); the pose found, or the refusal.
    fn check(&mut self, k: u16, guess: &Pose<S>) -> Result<Pose<S>, ParkRefusal<S>> {
        let n = self.cfg.samples;
        let s = S::from(k).unwrap_or_else(S::zero) / S::from(n).unwrap_or_else(S::one);
        let q = Joints::from(self.at(s));
        let Ok(fk) = forward(
            self.guards.robot(),
            &q,
            self.guards.branch(),
            guess,
            &self.fk,
        ) else {
            return Err(ParkRefusal::NoPose { sample: k });
        };
        let mut refusal = None;
        let recovering = &mut self.recovering;
        let last = k == n;
        self.guards.evaluate_pose(&fk.pose, &mut |r: &Reading<S>| {
            if refusal.is_some() {
                return;
            }
            let key = recovering
                .iter()
                .position(|e| e.0 == r.guard && e.1 == r.subject);
            let stop = r.severity == Some(Severity::Stop);
            match (stop, key.and_then(|i| recovering.get_mut(i))) {
                // At the start, every violation is one the path must recover from.
                (true, None) if k == 0 => {
                    if recovering.push((r.guard, r.subject, r.margin)).is_err() {
                        refusal = Some(*r);
                    }
                }
                // Recovering: the margin may not shrink (nor be NaN); the park pose itself
                // must be clear. (A guard the path has cleared has the margin +inf: it
                // must stay clear.)
                (true, Some(entry)) => {
                    if last || !(r.margin >= entry.2) {
                        refusal = Some(*r);
                    } else {
                        entry.2 = r.margin;
                    }
                }
                (true, None) => refusal = Some(*r),
                (false, Some(entry)) => entry.2 = S::infinity(),
                (false, None) => {}
            }
        });
        match refusal {
            Some(reading) => Err(ParkRefusal::Guard { sample: k, reading }),
            None => Ok(fk.pose),
        }
    }

    /// One step at `now_us` with the measured joints `q`: a path sample while checking,
    /// then the profile's setpoint, then `Arrived` once within the tolerance.
    pub fn step(&mut self, q: &[S; NUM_JOINTS], now_us: u64) -> ParkStep<S> {
        match self.phase {
            Phase::Checking { sample, guess } => match self.check(sample, &guess) {
                Err(r) => {
                    self.phase = Phase::Done(ParkStep::Refused(r));
                    ParkStep::Refused(r)
                }
                Ok(_) if sample >= self.cfg.samples => {
                    self.phase = Phase::Moving { since_us: now_us };
                    self.step(q, now_us)
                }
                Ok(pose) => {
                    self.phase = Phase::Checking {
                        sample: sample + 1,
                        guess: pose,
                    };
                    ParkStep::Checking {
                        checked: sample + 1,
                    }
                }
            },
            Phase::Moving { since_us } => {
                let t = lit::<S>(now_us.saturating_sub(since_us) as f64 * 1e-6);
                let big_t = self.duration_s;
                let tau = if big_t > S::zero() {
                    Float::min(t / big_t, S::one())
                } else {
                    S::one()
                };
                // s = 10τ³ − 15τ⁴ + 6τ⁵, ds/dτ = 30τ² − 60τ³ + 30τ⁴.
                let t2 = tau * tau;
                let s = t2 * tau * (lit::<S>(10.0) - lit::<S>(15.0) * tau + lit::<S>(6.0) * t2);
                let ds = lit::<S>(30.0) * t2 * (S::one() - tau) * (S::one() - tau);
                let setpoint = self.at(s);
                let rate = if big_t > S::zero() {
                    ds / big_t
                } else {
                    S::zero()
                };
                let qdot = core::array::from_fn(|j| {
                    let d = self.to.get(j).copied().unwrap_or_else(S::zero)
                        - self.from.get(j).copied().unwrap_or_else(S::zero);
                    d * rate
                });
                if tau >= S::one() {
                    // The profile is over: arrived once every joint is within tolerance.
                    let mut worst = (0usize, S::zero());
                    let mut settled = true;
                    for (j, ((x, p), tol)) in q
                        .iter()
                        .zip(self.to.iter())
                        .zip(self.cfg.tolerance.iter())
                        .enumerate()
                    {
                        let e = Float::abs(*x - *p);
                        settled &= e <= *tol;
                        if !(e <= worst.1) {
                            worst = (j, e);
                        }
                    }
                    let late = now_us.saturating_sub(since_us)
                        > (big_t.to_f64().unwrap_or(0.0) * 1e6) as u64 + self.cfg.settle_us;
                    if settled {
                        self.phase = Phase::Done(ParkStep::Arrived);
                        return ParkStep::Arrived;
                    }
                    if late {
                        let r = ParkStep::Refused(ParkRefusal::NotSettled {
                            joint: worst.0,
                            error: worst.1,
                        });
                        self.phase = Phase::Done(r);
                        return r;
                    }
                }
                ParkStep::Move { q: setpoint, qdot }
            }
            Phase::Done(step) => step,
        }
    }

    /// The branch the move is checked on.
    pub fn branch(&self) -> Branch {
        self.guards.branch()
    }
}
