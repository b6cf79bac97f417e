//! The teleoperation mapping: master samples in, the robot's target out (CRTK
//! `servo_cp`) or "hold". Pure and deterministic: time comes only from the caller.
//!
//! # Semantics (dVRK / CRTK names)
//!
//! - **Following**: the operator is present, the clutch is released and the master is
//!   fresh. The target is the robot pose captured at engagement plus the master's motion
//!   since engagement, scaled: `p = p_r0 + s_t·C·(p_m − p_m0)`,
//!   `R = exp(s_r·C·log(R_m·R_m0⁻¹))·R_r0`, where `C` is the registration (tracker frame
//!   → robot frame {0}; rate masters already speak {0}). It then goes through the tremor
//!   filter and the velocity/acceleration limits, and is emitted as `servo_cp`.
//! - **Clutch** (indexing): pressed, the master is decoupled and the robot holds; the
//!   surgeon repositions the master. **Operator presence** (dead-man): released, the
//!   robot holds. **Master lost**: no sample for `master_timeout_s`, the robot holds.
//!   **Stream gap**: two ticks more than `max_tick_s` apart, the robot holds for that tick.
//!   Holding emits [`TeleopOutput::Hold`]: the host sends no new target (heartbeats go
//!   on), so the board stays at the last `servo_cp`.
//! - **Re-engaging** (any hold ending) captures a new offset: `p_m0, R_m0` = the master
//!   now, `p_r0, R_r0` = the pose held, the filter restarts from rest and the limiter
//!   from rest at the held pose. **Zero-jump property**: the first `servo_cp` after
//!   re-engaging equals the held pose exactly (bit for bit), whatever the master did
//!   while decoupled: the motion since engagement is exactly zero
//!   ([`crate::pose::rotation_increment`] is exactly zero for equal orientations), the
//!   filter maps zero to zero from rest, and the limiter stays exactly at a pose it is
//!   asked to hold.
//! - **Motion scaling** `s_t` (translation) and `s_r` (rotation), robot motion per master
//!   motion (1:5 is 0.2), change only while the master is decoupled (clutch pressed, or
//!   operator absent, or before the first engagement); while following they are refused
//!   with [`TeleopError::ScaleWhileFollowing`].
//! - **Rate masters** (SpaceMouse, keyboard) integrate their twist into a virtual master
//!   pose, `p_v += v·dt`, `R_v = exp(ω·dt)·R_v`, which then goes through the same
//!   mapping; a position master's pose is used as it is.

use crate::device::{MasterInput, MasterSample};
use crate::limits::{LimitsError, MotionLimits, PoseLimiter};
use crate::pose::{rotate, rotation_increment, CartesianPose};
use crate::tremor::{FilterDesignError, TremorFilter, TremorFilterConfig};
use nalgebra::{UnitQuaternion, Vector3};
use thiserror::Error;

/// Robot motion per master motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionScale {
    /// Translation factor (0.2 = 1:5).
    pub translation: f64,
    /// Rotation factor.
    pub rotation: f64,
}

/// Largest scale factor accepted (a master moving the robot 10× its own motion).
pub const MAX_SCALE: f64 = 10.0;

impl MotionScale {
    /// Checks both factors are in (0, [`MAX_SCALE`]].
    pub fn new(translation: f64, rotation: f64) -> Result<Self, TeleopError> {
        for (which, v) in [("translation", translation), ("rotation", rotation)] {
            if !(v.is_finite() && v > 0.0 && v <= MAX_SCALE) {
                return Err(TeleopError::Scale { which, value: v });
            }
        }
        Ok(MotionScale {
            translation,
            rotation,
        })
    }
}

impl Default for MotionScale {
    /// 1:1.
    fn default() -> Self {
        MotionScale {
            translation: 1.0,
            rotation: 1.0,
        }
    }
}

/// The mapping's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct TeleopConfig {
    /// Target stream rate, Hz (the tremor filter is designed for it).
    pub stream_rate_hz: f64,
    /// Motion scaling.
    pub scale: MotionScale,
    /// Position masters: rotation from the tracker frame to the robot frame {0}.
    pub registration: UnitQuaternion<f64>,
    /// The tremor filter (None: off).
    pub tremor: Option<TremorFilterConfig>,
    /// Master-side limits.
    pub limits: MotionLimits,
    /// The master is lost when its newest sample is older than this, s.
    pub master_timeout_s: f64,
    /// Ticks further apart than this are a stream gap (hold, then re-engage), s.
    pub max_tick_s: f64,
}

impl Default for TeleopConfig {
    /// 100 Hz, 1:1, identity registration, the default tremor filter and limits, master
    /// timeout 0.1 s, stream gap 0.1 s.
    fn default() -> Self {
        TeleopConfig {
            stream_rate_hz: 100.0,
            scale: MotionScale::default(),
            registration: UnitQuaternion::identity(),
            tremor: Some(TremorFilterConfig::default()),
            limits: MotionLimits::default(),
            master_timeout_s: 0.1,
            max_tick_s: 0.1,
        }
    }
}

/// Why the robot holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HoldReason {
    /// [`Teleop::start`] not called yet.
    NotStarted,
    /// No master sample yet.
    NoMaster,
    /// The newest master sample is too old.
    MasterLost,
    /// The dead-man is released.
    OperatorAbsent,
    /// The clutch is pressed.
    Clutched,
    /// The stream stalled (ticks too far apart).
    StreamGap,
}

impl HoldReason {
    /// A stable name for recordings.
    pub fn as_str(self) -> &'static str {
        match self {
            HoldReason::NotStarted => "not_started",
            HoldReason::NoMaster => "no_master",
            HoldReason::MasterLost => "master_lost",
            HoldReason::OperatorAbsent => "operator_absent",
            HoldReason::Clutched => "clutched",
            HoldReason::StreamGap => "stream_gap",
        }
    }
}

/// The mapping's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TeleopState {
    /// Coupled: targets are streamed.
    Following,
    /// Decoupled: the robot holds.
    Holding(HoldReason),
}

/// What to do this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TeleopOutput {
    /// Send this target (CRTK `servo_cp`).
    ServoCp {
        /// The target.
        pose: CartesianPose,
        /// A velocity or acceleration limit acted on it.
        limited: bool,
    },
    /// Send nothing new: the robot holds at the last target.
    Hold(HoldReason),
}

/// What went wrong.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum TeleopError {
    /// A scale factor out of range.
    #[error("motion scale: {which} factor {value} is not in (0, 10]")]
    Scale {
        /// Translation or rotation.
        which: &'static str,
        /// The value.
        value: f64,
    },
    /// The scale was changed while following.
    #[error("motion scale can change only while the master is decoupled (press the clutch); it is following")]
    ScaleWhileFollowing,
    /// The tremor filter could not be designed.
    #[error(transparent)]
    Filter(#[from] FilterDesignError),
    /// The limits are not usable.
    #[error(transparent)]
    Limits(#[from] LimitsError),
    /// A setting out of range.
    #[error("teleop: {field} = {value} is not positive and finite")]
    Setting {
        /// The field.
        field: &'static str,
        /// The value.
        value: f64,
    },
    /// Time did not advance.
    #[error("teleop: tick at {now_s} s is not after the previous one at {previous_s} s")]
    TimeNotIncreasing {
        /// Previous tick, s.
        previous_s: f64,
        /// This tick, s.
        now_s: f64,
    },
    /// A non-finite time.
    #[error("teleop: tick time {0} is not finite")]
    NonFiniteTime(f64),
    /// A sample with non-finite numbers.
    #[error("teleop: master sample at {t_s} s has non-finite values")]
    NonFiniteSample {
        /// The sample's time.
        t_s: f64,
    },
    /// A non-finite robot pose given to start or resync.
    #[error("teleop: the robot pose given is not finite")]
    NonFinitePose,
}

/// Counters over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TeleopStats {
    /// Ticks.
    pub ticks: u64,
    /// Ticks that emitted `servo_cp`.
    pub following: u64,
    /// Of those, ticks where a limit acted.
    pub limited: u64,
    /// Engagements (offset captures).
    pub engagements: u64,
    /// Hold ticks by reason: master lost, operator absent, clutched, stream gap, no master.
    pub hold_master_lost: u64,
    /// Operator absent.
    pub hold_operator_absent: u64,
    /// Clutched.
    pub hold_clutched: u64,
    /// Stream gap.
    pub hold_stream_gap: u64,
    /// No master yet.
    pub hold_no_master: u64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Anchor {
    master: CartesianPose,
    robot: CartesianPose,
    rate: bool,
}

/// The teleoperation mapping.
#[derive(Clone, Debug)]
pub struct Teleop {
    config: TeleopConfig,
    filter: Option<TremorFilter>,
    limiter: PoseLimiter,
    last_t: Option<f64>,
    latest: Option<MasterSample>,
    virtual_master: CartesianPose,
    held: CartesianPose,
    anchor: Option<Anchor>,
    state: TeleopState,
    stats: TeleopStats,
    commanded: Option<CartesianPose>,
}

impl Teleop {
    /// Checks the settings and designs the filter.
    pub fn new(config: TeleopConfig) -> Result<Self, TeleopError> {
        for (field, value) in [
            ("stream_rate_hz", config.stream_rate_hz),
            ("master_timeout_s", config.master_timeout_s),
            ("max_tick_s", config.max_tick_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(TeleopError::Setting { field, value });
            }
        }
        MotionScale::new(config.scale.translation, config.scale.rotation)?;
        let filter = config
            .tremor
            .as_ref()
            .map(|t| TremorFilter::design(t, config.stream_rate_hz))
            .transpose()?;
        let limiter = PoseLimiter::new(&config.limits, CartesianPose::identity())?;
        Ok(Teleop {
            config,
            filter,
            limiter,
            last_t: None,
            latest: None,
            virtual_master: CartesianPose::identity(),
            held: CartesianPose::identity(),
            anchor: None,
            state: TeleopState::Holding(HoldReason::NotStarted),
            stats: TeleopStats::default(),
            commanded: None,
        })
    }

    /// Starts at `t_s` with the robot at `robot_pose` (its measured or commanded pose):
    /// the robot holds there until the operator engages.
    pub fn start(&mut self, t_s: f64, robot_pose: CartesianPose) -> Result<(), TeleopError> {
        if !t_s.is_finite() {
            return Err(TeleopError::NonFiniteTime(t_s));
        }
        self.resync(robot_pose)?;
        self.last_t = Some(t_s);
        self.state = TeleopState::Holding(HoldReason::NoMaster);
        Ok(())
    }

    /// The robot is at `robot_pose` (e.g. after the board refused a target): hold there
    /// and capture a new offset at the next engaged tick.
    pub fn resync(&mut self, robot_pose: CartesianPose) -> Result<(), TeleopError> {
        if !robot_pose.is_finite() {
            return Err(TeleopError::NonFinitePose);
        }
        self.held = robot_pose;
        self.anchor = None;
        self.limiter.reset(robot_pose);
        if self.state == TeleopState::Following {
            self.state = TeleopState::Holding(HoldReason::NoMaster);
        }
        Ok(())
    }

    /// Changes the motion scale; only while decoupled.
    pub fn set_scale(&mut self, scale: MotionScale) -> Result<(), TeleopError> {
        let scale = MotionScale::new(scale.translation, scale.rotation)?;
        if self.state == TeleopState::Following {
            return Err(TeleopError::ScaleWhileFollowing);
        }
        self.config.scale = scale;
        Ok(())
    }

    /// The settings.
    pub fn config(&self) -> &TeleopConfig {
        &self.config
    }

    /// The state after the last tick.
    pub fn state(&self) -> TeleopState {
        self.state
    }

    /// Where the robot holds or was last sent (the last `servo_cp`, or the start pose).
    pub fn held_pose(&self) -> CartesianPose {
        self.held
    }

    /// The rate masters' virtual master pose.
    pub fn virtual_master(&self) -> CartesianPose {
        self.virtual_master
    }

    /// Counters.
    pub fn stats(&self) -> TeleopStats {
        self.stats
    }

    /// What the operator commanded at the last following tick: the pose held at
    /// engagement plus the scaled master motion, before the tremor filter and the limits
    /// (`None` while holding). The latency figures measure from it.
    pub fn commanded(&self) -> Option<CartesianPose> {
        self.commanded
    }

    /// The tremor filter, when on.
    pub fn filter(&self) -> Option<&TremorFilter> {
        self.filter.as_ref()
    }

    fn hold(&mut self, reason: HoldReason) -> TeleopOutput {
        self.anchor = None;
        self.commanded = None;
        self.state = TeleopState::Holding(reason);
        let s = &mut self.stats;
        match reason {
            HoldReason::MasterLost => s.hold_master_lost += 1,
            HoldReason::OperatorAbsent => s.hold_operator_absent += 1,
            HoldReason::Clutched => s.hold_clutched += 1,
            HoldReason::StreamGap => s.hold_stream_gap += 1,
            HoldReason::NoMaster | HoldReason::NotStarted => s.hold_no_master += 1,
        }
        TeleopOutput::Hold(reason)
    }

    /// One stream tick at `t_s` (master clock), with the master's new sample if any.
    pub fn step(
        &mut self,
        t_s: f64,
        sample: Option<&MasterSample>,
    ) -> Result<TeleopOutput, TeleopError> {
        if !t_s.is_finite() {
            return Err(TeleopError::NonFiniteTime(t_s));
        }
        let Some(previous_s) = self.last_t else {
            return Ok(TeleopOutput::Hold(HoldReason::NotStarted));
        };
        if t_s <= previous_s {
            return Err(TeleopError::TimeNotIncreasing {
                previous_s,
                now_s: t_s,
            });
        }
        if let Some(s) = sample {
            let finite = s.t_s.is_finite()
                && match &s.input {
                    MasterInput::Twist(t) => t.is_finite(),
                    MasterInput::Pose(p) => p.is_finite(),
                };
            if !finite {
                return Err(TeleopError::NonFiniteSample { t_s: s.t_s });
            }
            self.latest = Some(*s);
        }
        self.last_t = Some(t_s);
        self.stats.ticks += 1;
        let dt = t_s - previous_s;
        let Some(latest) = self.latest else {
            return Ok(self.hold(HoldReason::NoMaster));
        };
        let fresh = t_s - latest.t_s <= self.config.master_timeout_s;
        if let (MasterInput::Twist(tw), true) = (&latest.input, fresh) {
            let v = &mut self.virtual_master;
            v.position_m += tw.linear_m_s * dt;
            v.orientation = rotate(&v.orientation, &(tw.angular_rad_s * dt));
        }
        if let Some(r) = self.hold_reason(&latest, fresh, dt) {
            return Ok(self.hold(r));
        }
        let (master, rate) = match latest.input {
            MasterInput::Twist(_) => (self.virtual_master, true),
            MasterInput::Pose(p) => (p, false),
        };
        let anchor = self.engaged(master, rate);
        Ok(self.follow(&anchor, &master, rate, dt))
    }

    /// Why the robot holds this tick, if it does: the master silent too long (not
    /// `fresh`), the operator absent, the clutch engaged, or a tick of `dt` too long.
    fn hold_reason(&self, latest: &MasterSample, fresh: bool, dt: f64) -> Option<HoldReason> {
        if !fresh {
            Some(HoldReason::MasterLost)
        } else if !latest.buttons.operator_present {
            Some(HoldReason::OperatorAbsent)
        } else if latest.buttons.clutch {
            Some(HoldReason::Clutched)
        } else if dt > self.config.max_tick_s {
            Some(HoldReason::StreamGap)
        } else {
            None
        }
    }

    /// The anchor of the engagement: the current one, or a new one at `master` and the
    /// held robot pose (the tremor filter and the limiter restarting from there) when not
    /// engaged yet or the master's kind changed (`rate`).
    fn engaged(&mut self, master: CartesianPose, rate: bool) -> Anchor {
        match self.anchor {
            Some(a) if a.rate == rate => a,
            _ => {
                let a = Anchor {
                    master,
                    robot: self.held,
                    rate,
                };
                if let Some(f) = &mut self.filter {
                    f.reset();
                }
                self.limiter.reset(self.held);
                self.stats.engagements += 1;
                self.anchor = Some(a);
                a
            }
        }
    }

    /// Follows the master over a tick of `dt`: its motion since `anchor` (registered into
    /// the robot's frame for a position master) scaled, filtered and limited, from the
    /// robot's pose at the anchor.
    fn follow(
        &mut self,
        anchor: &Anchor,
        master: &CartesianPose,
        rate: bool,
        dt: f64,
    ) -> TeleopOutput {
        let mut dp = master.position_m - anchor.master.position_m;
        let mut dr = rotation_increment(&anchor.master.orientation, &master.orientation);
        if !rate {
            dp = self.config.registration * dp;
            dr = self.config.registration * dr;
        }
        let dp = dp * self.config.scale.translation;
        let dr = dr * self.config.scale.rotation;
        self.commanded = Some(CartesianPose {
            position_m: anchor.robot.position_m + dp,
            orientation: rotate(&anchor.robot.orientation, &dr),
        });
        let u = [dp.x, dp.y, dp.z, dr.x, dr.y, dr.z];
        let y = match &mut self.filter {
            Some(f) => f.step(u),
            None => u,
        };
        let [x, yy, z, rx, ry, rz] = y;
        let desired = CartesianPose {
            position_m: anchor.robot.position_m + Vector3::new(x, yy, z),
            orientation: rotate(&anchor.robot.orientation, &Vector3::new(rx, ry, rz)),
        };
        let (pose, limited) = self.limiter.step(&desired, dt);
        self.held = pose;
        self.state = TeleopState::Following;
        self.stats.following += 1;
        if limited {
            self.stats.limited += 1;
        }
        TeleopOutput::ServoCp { pose, limited }
    }
}
