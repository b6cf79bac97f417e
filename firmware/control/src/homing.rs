//! Homing: the incremental encoders find their reference, joint by joint, against a
//! switch or a hard stop, then the robot parks.
//!
//! Each tick the runtime's sensing has read the encoders; [`Homing::step`] reads the
//! joints and counts through [`JointReferences`], with the switches and the currents, sets
//! the reference of a joint through it and drives the outputs.

use hal::{CurrentSense, LimitSwitches, MotorOutputs};
use num_traits::Float;
use servo::config::ConfigError;
use servo::joint_servo::JointServo;
use servo::{ServoConfig, NUM_JOINTS};

/// The encoders as the homing sees them (the runtime's sensing): this tick's joints and
/// counts, and the reference of a joint.
pub trait JointReferences<S> {
    /// This tick's joint positions (relative for the joints not referenced yet).
    fn joints(&self) -> [S; NUM_JOINTS];
    /// This tick's extended counts.
    fn counts(&self) -> [i64; NUM_JOINTS];
    /// Joint `joint` is at `q` now (its count is kept); false outside `0..6`.
    fn set_reference(&mut self, joint: usize, q: S) -> bool;
}

/// How a joint finds its reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeMethod {
    /// Drive to the home switch; a stall before it is a failure.
    Switch,
    /// Drive into the mechanical stop under the current/duty limit; the stall is the
    /// reference.
    HardStop,
}

/// Homing of one joint. Joint units: m (legs), rad (links); currents in A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointHoming<S> {
    /// Switch or hard stop.
    pub method: HomeMethod,
    /// Approach towards `+q` (else towards `-q`).
    pub towards_positive: bool,
    /// Joint position at the switch point or the stop.
    pub home_position: S,
    /// |duty| while approaching (slow), within the duty limit.
    pub approach_duty: S,
    /// |duty| while backing off.
    pub backoff_duty: S,
    /// Distance to back off from the reference.
    pub backoff_distance: S,
    /// Largest travel while searching before giving up.
    pub max_travel: S,
    /// Above this |current| the duty is cut for the tick (the current limit); lasting
    /// for the stall time it counts as a stall. Infinite disables it.
    pub current_limit: S,
}

/// Homing settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingConfig<S> {
    /// Per joint.
    pub joints: [JointHoming<S>; NUM_JOINTS],
    /// Joints in the order they are homed (each index once).
    pub order: [u8; NUM_JOINTS],
    /// Largest |duty| of any homing move.
    pub duty_limit: S,
    /// No motion of at least `stall_counts` for this long while driving is a stall, µs.
    pub stall_time_us: u64,
    /// Counts that make "motion".
    pub stall_counts: i64,
    /// Longest time of one phase of one joint, µs.
    pub phase_timeout_us: u64,
    /// After homing, move in joint space to these positions (e.g. the central
    /// configuration), or stay where the last back-off ended.
    pub park: Option<[S; NUM_JOINTS]>,
    /// Park move speed per joint (m/s, rad/s).
    pub park_speed: [S; NUM_JOINTS],
    /// Park done when every |error| is within this (m, rad).
    pub park_tolerance: [S; NUM_JOINTS],
}

impl<S: Float> HomingConfig<S> {
    /// Placeholder settings for the reference robot (to be confirmed on the mechanics):
    /// legs home on a switch at the short end of the stroke (150 mm), links against a
    /// hard stop 60 deg below the central angle (`link_centre` is the central θ of each
    /// link, rad); park at `park`.
    pub fn reference(link_centre: [S; 3], park: Option<[S; NUM_JOINTS]>) -> Self {
        let lit = |x: f64| S::from(x).unwrap_or_else(S::zero);
        let leg = JointHoming {
            method: HomeMethod::Switch,
            towards_positive: false,
            home_position: lit(0.150),
            approach_duty: lit(0.03),
            backoff_duty: lit(0.04),
            backoff_distance: lit(0.002),
            max_travel: lit(0.080),
            current_limit: lit(3.0),
        };
        let link = |centre: S| JointHoming {
            method: HomeMethod::HardStop,
            towards_positive: false,
            home_position: centre - lit(60f64.to_radians()),
            approach_duty: lit(0.02),
            backoff_duty: lit(0.03),
            backoff_distance: lit(0.05),
            max_travel: lit(3.5),
            current_limit: lit(0.6),
        };
        let [c1, c2, c3] = link_centre;
        HomingConfig {
            joints: [leg, leg, leg, link(c1), link(c2), link(c3)],
            order: [0, 1, 2, 3, 4, 5],
            duty_limit: lit(0.3),
            stall_time_us: 150_000,
            stall_counts: 4,
            phase_timeout_us: 30_000_000,
            park,
            park_speed: [
                lit(0.005),
                lit(0.005),
                lit(0.005),
                lit(0.1),
                lit(0.1),
                lit(0.1),
            ],
            park_tolerance: [
                lit(0.2e-3),
                lit(0.2e-3),
                lit(0.2e-3),
                lit(0.005),
                lit(0.005),
                lit(0.005),
            ],
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<(), HomingError> {
        let bad = |joint: usize| Err(HomingError::Config { joint });
        let mut seen = [false; NUM_JOINTS];
        for j in self.order {
            match seen.get_mut(usize::from(j)) {
                Some(s) if !*s => *s = true,
                _ => return bad(usize::from(j)),
            }
        }
        let pos = |x: S| x.is_finite() && x > S::zero();
        if !(pos(self.duty_limit) && self.duty_limit <= S::one()) || self.stall_time_us == 0 {
            return bad(0);
        }
        for (j, h) in self.joints.iter().enumerate() {
            let ok = h.home_position.is_finite()
                && pos(h.approach_duty)
                && pos(h.backoff_duty)
                && pos(h.backoff_distance)
                && pos(h.max_travel)
                && h.current_limit > S::zero()
                && !h.current_limit.is_nan();
            if !ok {
                return bad(j);
            }
        }
        for j in 0..NUM_JOINTS {
            let speed = self.park_speed.get(j).copied().unwrap_or_else(S::zero);
            let tol = self.park_tolerance.get(j).copied().unwrap_or_else(S::zero);
            let park_ok = match self.park {
                Some(p) => p.get(j).is_some_and(|x| x.is_finite()),
                None => true,
            };
            if !(pos(speed) && pos(tol) && park_ok) {
                return bad(j);
            }
        }
        Ok(())
    }
}

/// Why homing failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingError {
    /// A setting is invalid (the joint it concerns).
    Config {
        /// Joint.
        joint: usize,
    },
    /// A phase took longer than `phase_timeout_us`.
    Timeout {
        /// Joint.
        joint: usize,
    },
    /// Travelled `max_travel` without finding the reference.
    NotFound {
        /// Joint.
        joint: usize,
    },
    /// Stalled before reaching its switch (obstacle, jam).
    StalledBeforeSwitch {
        /// Joint.
        joint: usize,
    },
    /// The switch stayed actuated after backing off.
    SwitchStuck {
        /// Joint.
        joint: usize,
    },
    /// The park move tripped the tracking monitor or did not settle.
    Park,
}

/// The homing procedure's phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingPhase {
    /// Not started.
    Idle,
    /// Driving off a switch that was already actuated at the start.
    LeaveSwitch {
        /// Joint.
        joint: usize,
    },
    /// Driving slowly towards the switch or stop.
    Approach {
        /// Joint.
        joint: usize,
    },
    /// Backing off from the reference.
    BackOff {
        /// Joint.
        joint: usize,
    },
    /// Joint-space move to the park position.
    Park,
    /// Finished.
    Done,
    /// Failed.
    Failed(HomingError),
}

/// What one homing step reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingStatus {
    /// Still going.
    Running(HomingPhase),
    /// Homed: every joint's encoder has its reference (the sensing's joints are
    /// absolute from now on).
    Done,
    /// Failed; every output is off.
    Failed(HomingError),
}

/// The homing procedure, one [`Homing::step`] per control tick.
#[derive(Clone, Debug)]
pub struct Homing<S> {
    cfg: HomingConfig<S>,
    servo: JointServo<S>,
    phase: HomingPhase,
    /// Index into `order`.
    index: usize,
    phase_start_us: u64,
    phase_start_q: S,
    motion_count: i64,
    motion_us: u64,
    over_current_since: Option<u64>,
    /// Current limiting: the factor on the commanded duty.
    duty_scale: S,
    park_from: [S; NUM_JOINTS],
    park_duration_s: S,
    park_start_us: u64,
    last_us: u64,
    /// The joints at the last step.
    q: [S; NUM_JOINTS],
    /// The extended counts at the last step.
    counts: [i64; NUM_JOINTS],
    /// First step of the phase.
    fresh: bool,
}

fn joint_of<S>(cfg: &HomingConfig<S>, index: usize) -> Option<usize> {
    cfg.order.get(index).map(|j| usize::from(*j))
}

impl<S: Float> Homing<S> {
    /// A homing procedure (validates `cfg`; the servo settings are for the park move).
    pub fn new(cfg: &HomingConfig<S>, servo: &ServoConfig<S>) -> Result<Self, HomingSetupError> {
        cfg.validate().map_err(HomingSetupError::Homing)?;
        Ok(Homing {
            cfg: *cfg,
            servo: JointServo::new(servo).map_err(HomingSetupError::Servo)?,
            phase: HomingPhase::Idle,
            index: 0,
            phase_start_us: 0,
            phase_start_q: S::zero(),
            motion_count: 0,
            motion_us: 0,
            over_current_since: None,
            duty_scale: S::one(),
            park_from: [S::zero(); NUM_JOINTS],
            park_duration_s: S::zero(),
            park_start_us: 0,
            last_us: 0,
            q: [S::zero(); NUM_JOINTS],
            counts: [0; NUM_JOINTS],
            fresh: false,
        })
    }

    /// The settings.
    pub fn config(&self) -> &HomingConfig<S> {
        &self.cfg
    }
    /// The phase.
    pub fn phase(&self) -> HomingPhase {
        self.phase
    }
    /// Starts homing from the joints `q` and counts `counts` the sensing reads now.
    pub fn start(&mut self, q: &[S; NUM_JOINTS], counts: &[i64; NUM_JOINTS], now_us: u64) {
        self.q = *q;
        self.counts = *counts;
        self.index = 0;
        self.last_us = now_us;
        match joint_of(&self.cfg, 0) {
            Some(j) => self.enter(HomingPhase::Approach { joint: j }, now_us),
            None => self.phase = HomingPhase::Failed(HomingError::Config { joint: 0 }),
        }
    }

    /// Aborts: the phase becomes `Idle` (the caller turns the outputs off).
    pub fn abort(&mut self) {
        self.phase = HomingPhase::Idle;
    }

    fn enter(&mut self, phase: HomingPhase, now_us: u64) {
        self.phase = phase;
        self.fresh = true;
        self.phase_start_us = now_us;
        self.motion_us = now_us;
        self.over_current_since = None;
        self.duty_scale = S::one();
        if let HomingPhase::LeaveSwitch { joint }
        | HomingPhase::Approach { joint }
        | HomingPhase::BackOff { joint } = phase
        {
            self.phase_start_q = self.q.get(joint).copied().unwrap_or_else(S::zero);
            self.motion_count = self.counts.get(joint).copied().unwrap_or(0);
        }
    }

    fn fail<H: MotorOutputs<S>>(&mut self, hw: &mut H, e: HomingError) -> HomingStatus {
        hw.set_duties(&[S::zero(); NUM_JOINTS]);
        hw.disable();
        self.phase = HomingPhase::Failed(e);
        HomingStatus::Failed(e)
    }

    fn next_joint(&mut self, now_us: u64) {
        self.index += 1;
        match joint_of(&self.cfg, self.index) {
            Some(j) => self.enter(HomingPhase::Approach { joint: j }, now_us),
            None => match self.cfg.park {
                Some(_) => self.start_park(now_us),
                None => self.phase = HomingPhase::Done,
            },
        }
    }

    fn start_park(&mut self, now_us: u64) {
        let q = self.q;
        self.park_from = q;
        self.servo.reset(&q);
        let mut t = S::zero();
        if let Some(park) = self.cfg.park {
            for ((p, q0), v) in park.iter().zip(q.iter()).zip(self.cfg.park_speed.iter()) {
                t = t.max((*p - *q0).abs() / *v);
            }
        }
        self.park_duration_s = t;
        self.park_start_us = now_us;
        self.enter(HomingPhase::Park, now_us);
    }

    /// One step on the tick's measurements (`sensing`, updated at the start of the
    /// tick): reads the switches and currents, sets references, drives the outputs.
    pub fn step<H, R>(&mut self, hw: &mut H, sensing: &mut R, now_us: u64) -> HomingStatus
    where
        H: MotorOutputs<S> + LimitSwitches + CurrentSense<S>,
        R: JointReferences<S>,
    {
        let dt_us = now_us.saturating_sub(self.last_us);
        self.last_us = now_us;
        let (q, counts) = (sensing.joints(), sensing.counts());
        self.q = q;
        self.counts = counts;
        let switches = hw.switches();
        let currents = hw.currents();
        let elapsed = now_us.saturating_sub(self.phase_start_us);
        let mut duty = [S::zero(); NUM_JOINTS];
        match self.phase {
            HomingPhase::Idle => {
                hw.set_duties(&duty);
                return HomingStatus::Running(HomingPhase::Idle);
            }
            HomingPhase::Failed(e) => return self.fail(hw, e),
            HomingPhase::Done => {
                hw.set_duties(&duty);
                return HomingStatus::Done;
            }
            HomingPhase::LeaveSwitch { joint }
            | HomingPhase::Approach { joint }
            | HomingPhase::BackOff { joint } => {
                let (Some(h), Some(&qj), Some(&cj), Some(&sw), Some(&ij)) = (
                    self.cfg.joints.get(joint).copied(),
                    q.get(joint),
                    counts.get(joint),
                    switches.get(joint),
                    currents.get(joint),
                ) else {
                    return self.fail(hw, HomingError::Config { joint });
                };
                let fresh = core::mem::replace(&mut self.fresh, false);
                if elapsed > self.cfg.phase_timeout_us {
                    return self.fail(hw, HomingError::Timeout { joint });
                }
                // Motion / stall tracking.
                if (cj - self.motion_count).abs() >= self.cfg.stall_counts {
                    self.motion_count = cj;
                    self.motion_us = now_us;
                }
                // Current limit: scale the duty down while above it, relax back
                // slowly; running at (90 % of) the limit for the stall time is a stall.
                let i_abs = ij.abs();
                if i_abs > h.current_limit {
                    self.duty_scale = (self.duty_scale * h.current_limit / i_abs).min(S::one());
                } else {
                    let relax = S::from(1.05).unwrap_or_else(S::one);
                    self.duty_scale = (self.duty_scale * relax).min(S::one());
                }
                let near = S::from(0.9).unwrap_or_else(S::one);
                if i_abs >= h.current_limit * near {
                    self.over_current_since.get_or_insert(now_us);
                } else {
                    self.over_current_since = None;
                }
                let stalled = now_us.saturating_sub(self.motion_us) >= self.cfg.stall_time_us
                    || self
                        .over_current_since
                        .is_some_and(|t| now_us.saturating_sub(t) >= self.cfg.stall_time_us);
                let scale = self.duty_scale;
                let travel = (qj - self.phase_start_q).abs();
                let sign = if h.towards_positive {
                    S::one()
                } else {
                    -S::one()
                };
                let limit = self.cfg.duty_limit;
                match self.phase {
                    HomingPhase::Approach { .. } => {
                        if h.method == HomeMethod::Switch && sw && fresh {
                            // Already on the switch at the start: leave it first.
                            self.enter(HomingPhase::LeaveSwitch { joint }, now_us);
                        } else if h.method == HomeMethod::Switch && sw {
                            // The reference: the position where the switch closes.
                            sensing.set_reference(joint, h.home_position);
                            self.q = sensing.joints();
                            self.enter(HomingPhase::BackOff { joint }, now_us);
                        } else if stalled {
                            if h.method == HomeMethod::HardStop {
                                sensing.set_reference(joint, h.home_position);
                                self.q = sensing.joints();
                                self.enter(HomingPhase::BackOff { joint }, now_us);
                            } else {
                                return self.fail(hw, HomingError::StalledBeforeSwitch { joint });
                            }
                        } else if travel > h.max_travel {
                            return self.fail(hw, HomingError::NotFound { joint });
                        } else {
                            set(&mut duty, joint, sign * h.approach_duty.min(limit) * scale);
                        }
                    }
                    HomingPhase::LeaveSwitch { .. } => {
                        if !sw {
                            self.enter(HomingPhase::Approach { joint }, now_us);
                        } else if travel > h.max_travel || stalled {
                            return self.fail(hw, HomingError::SwitchStuck { joint });
                        } else {
                            set(&mut duty, joint, -sign * h.backoff_duty.min(limit) * scale);
                        }
                    }
                    _ => {
                        // Back off.
                        if travel >= h.backoff_distance {
                            if h.method == HomeMethod::Switch && sw {
                                return self.fail(hw, HomingError::SwitchStuck { joint });
                            }
                            self.next_joint(now_us);
                        } else if stalled {
                            return self.fail(hw, HomingError::Timeout { joint });
                        } else {
                            set(&mut duty, joint, -sign * h.backoff_duty.min(limit) * scale);
                        }
                    }
                }
            }
            HomingPhase::Park => {
                let Some(park) = self.cfg.park else {
                    self.phase = HomingPhase::Done;
                    hw.set_duties(&duty);
                    return HomingStatus::Running(self.phase);
                };
                let us = S::from(1e-6).unwrap_or_else(S::zero);
                let t =
                    S::from(now_us.saturating_sub(self.park_start_us)).unwrap_or_else(S::zero) * us;
                let total = self.park_duration_s;
                let s = if total > S::zero() {
                    (t / total).min(S::one())
                } else {
                    S::one()
                };
                let mut sp = [S::zero(); NUM_JOINTS];
                let mut spd = [S::zero(); NUM_JOINTS];
                for j in 0..NUM_JOINTS {
                    let (Some(a), Some(b)) = (self.park_from.get(j), park.get(j)) else {
                        continue;
                    };
                    set(&mut sp, j, *a + (*b - *a) * s);
                    if s < S::one() && total > S::zero() {
                        set(&mut spd, j, (*b - *a) / total);
                    }
                }
                let dt = S::from(dt_us.max(1)).unwrap_or_else(S::one) * us;
                let out = self.servo.update(&sp, &spd, &q, dt);
                if out.fault.is_some() {
                    return self.fail(hw, HomingError::Park);
                }
                let settled = park
                    .iter()
                    .zip(q.iter())
                    .zip(self.cfg.park_tolerance.iter())
                    .all(|((p, m), tol)| (*p - *m).abs() <= *tol);
                if s >= S::one() && settled {
                    self.phase = HomingPhase::Done;
                    hw.set_duties(&duty);
                    return HomingStatus::Done;
                }
                if elapsed > self.cfg.phase_timeout_us {
                    return self.fail(hw, HomingError::Park);
                }
                for (d, o) in duty.iter_mut().zip(out.duty.iter()) {
                    *d = o.max(-self.cfg.duty_limit).min(self.cfg.duty_limit);
                }
            }
        }
        hw.set_duties(&duty);
        match self.phase {
            HomingPhase::Done => HomingStatus::Done,
            p => HomingStatus::Running(p),
        }
    }
}

fn set<S: Copy>(a: &mut [S; NUM_JOINTS], j: usize, v: S) {
    if let Some(x) = a.get_mut(j) {
        *x = v;
    }
}

/// Why a [`Homing`] or [`Runtime`] cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingSetupError {
    /// Homing settings.
    Homing(HomingError),
    /// Servo or encoder settings.
    Servo(ConfigError),
}
