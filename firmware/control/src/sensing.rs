//! Sensing: the single owner of the measured joints and pose.
//!
//! Every control tick, in every state, starts with [`Sensing::read`]: the six raw
//! counters are read once, extended once (`servo::encoder`), converted to the motors'
//! positions, less the backlash compensation's offsets to the joints' positions. Once
//! the tick's outputs are written, [`Sensing::follow_pose`] makes the measured pose
//! follow those joints through the forward kinematics, once the robot is homed
//! ([`FkTracker`]: one Newton step per tick while the joints move, nothing while they
//! stand); nothing between the readings and the outputs uses it.
//!
//! The encoders sit on the motors. Where the backlash compensation holds a motor `o`
//! beyond its joint's setpoint to keep the lead screw's gap taken up (`servo::backlash`),
//! the joint is at the motor's position less `o`: the servo's offsets of the last tick
//! ([`Sensing::set_backlash`]) are what the sensing subtracts, and they stay while the
//! drives are off (the brakes hold the motors where they were, the gap does not change).
//! Without it the measured joints, the measured pose and every guard on them would move
//! by the offset (up to b/2 = 0.06 mm per leg) whenever the compensation takes up a gap,
//! though the platform does not move. Homing sets the encoders' reference through
//! [`Sensing::set_reference`]; the controller, the homing, the fault monitors and the
//! telemetry all read the tick's [`Measured`], never the hardware or a second estimate.
//!
//! Where the board has the second position channel (an absolute position sensor per
//! joint on the load side, `hal::AbsolutePositions`), [`Sensing::read_absolute`] reads it
//! once per tick too, through its calibration ([`ChannelCalibration`]): the monitors
//! check it against the encoders (`crate::absolute`), and homing takes the encoders'
//! references from it.

use hal::{AbsolutePositions, QuadratureCounter};
use kinematics_core::{
    Branch, FkConfig, FkError, FkTracker, Joints, Mechanism, Pose, Tracked, TrackerCounts,
};
use servo::config::ConfigError;
use servo::encoder::{EncoderConfig, Encoders};
use servo::NUM_JOINTS;

use crate::absolute::ChannelCalibration;
use crate::homing::JointReferences;
use crate::scalar::Scalar;

/// What the forward kinematics did on this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseStatus {
    /// Not homed: the encoders read relative positions, there is no pose.
    NotHomed,
    /// The estimate already matched the joints.
    Unchanged,
    /// Newton steps followed the joints (the number of steps).
    Stepped(u32),
    /// The full solver ran (its iterations).
    Solved(u32),
    /// The forward kinematics failed on this tick; the pose is the last good one.
    Failed(FkError),
}

/// The measurements of one tick: raw counters, motors, joints and pose (the extended
/// counts are the encoders': [`Sensing::encoders`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured<S: Scalar> {
    /// The raw 16-bit counters as read.
    pub raw: [u16; NUM_JOINTS],
    /// The motors' positions in joint units (m, rad): the encoders', relative until
    /// homed. The joint servos close their loops on these.
    pub motor: [S; NUM_JOINTS],
    /// The backlash compensation's offsets subtracted from the motors (m, rad): `motor - q`.
    pub backlash: [S; NUM_JOINTS],
    /// Joint positions (m, rad): the motors' less the backlash offsets, relative until
    /// homed. Everything else (pose, guards, monitors, telemetry) reads these.
    pub q: [S; NUM_JOINTS],
    /// The measured pose (the last good one after a failed tick), once homed.
    pub pose: Option<Pose<S>>,
    /// What the forward kinematics did on this tick.
    pub status: PoseStatus,
    /// The second channel's raw readings (None: no channel, or the read failed).
    pub absolute_raw: Option<[u16; NUM_JOINTS]>,
    /// The joint positions they stand for (m, rad; load side, absolute).
    pub absolute: Option<[S; NUM_JOINTS]>,
}

/// Counts kept by the sensing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensingCounters {
    /// Ticks sensed.
    pub ticks: u64,
    /// Ticks whose forward kinematics failed.
    pub fk_failures: u32,
    /// Consecutive failed ticks up to now.
    pub fk_failures_in_row: u32,
    /// Most Newton steps or iterations of one tick.
    pub fk_max_iterations: u32,
}

/// The encoders and the forward-kinematics tracker.
#[derive(Clone, Debug)]
pub struct Sensing<S: Scalar, M: Mechanism<S>> {
    robot: M,
    branch: Branch,
    fk_cfg: FkConfig<S>,
    encoder_cfg: EncoderConfig<S>,
    encoders: Encoders<S>,
    tracker: Option<FkTracker<S>>,
    measured: Measured<S>,
    counters: SensingCounters,
    /// The second channel's calibration (None: the application reads no channel).
    channel: Option<ChannelCalibration<S>>,
    /// The board has the channel fitted (read with it).
    channel_fitted: bool,
    /// References set since power-up (each moves the encoders' joints at once).
    references: u32,
}

/// Why the pose cannot be established after homing.
pub type ReferenceError = FkError;

/// Why a homed sensing cannot be set up ([`Sensing::homed_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensingError {
    /// An encoder setting.
    Config(ConfigError),
    /// The joints give no pose.
    Pose(FkError),
}

impl core::fmt::Display for SensingError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SensingError::Config(e) => write!(f, "encoders: {e}"),
            SensingError::Pose(e) => write!(f, "no pose at the homed joints: {e}"),
        }
    }
}

impl<S: Scalar, M: Mechanism<S>> Sensing<S, M> {
    /// Not homed; the counters read as zero until the first update.
    pub fn new(
        robot: M,
        branch: Branch,
        encoders: &EncoderConfig<S>,
        fk: FkConfig<S>,
    ) -> Result<Self, ConfigError> {
        let encoder_cfg = *encoders;
        let encoders = Encoders::new(&encoder_cfg)?;
        Ok(Sensing {
            robot,
            branch,
            fk_cfg: fk,
            encoder_cfg,
            measured: Measured {
                raw: [0; NUM_JOINTS],
                motor: encoders.positions(),
                backlash: [S::zero(); NUM_JOINTS],
                q: encoders.positions(),
                pose: None,
                status: PoseStatus::NotHomed,
                absolute_raw: None,
                absolute: None,
            },
            encoders,
            tracker: None,
            counters: SensingCounters::default(),
            channel: None,
            channel_fitted: false,
            references: 0,
        })
    }

    /// The sensing as the runtime has it after homing: the counters `raw` read the joints
    /// `q`, the pose solved once (for the host's simulation, tests and benchmarks that
    /// start homed).
    pub fn homed_at(
        robot: M,
        branch: Branch,
        encoders: &EncoderConfig<S>,
        fk: FkConfig<S>,
        raw: [u16; NUM_JOINTS],
        q: &[S; NUM_JOINTS],
    ) -> Result<Self, SensingError> {
        let mut s = Sensing::new(robot, branch, encoders, fk).map_err(SensingError::Config)?;
        s.boot(raw);
        for (j, qj) in q.iter().enumerate() {
            s.set_reference(j, *qj);
        }
        s.track_pose().map_err(SensingError::Pose)?;
        Ok(s)
    }

    /// Power-up: the counters as they are now become count zero (the encoders are
    /// incremental: relative until homed).
    pub fn boot(&mut self, raw: [u16; NUM_JOINTS]) {
        // (The configuration was validated by `new`: this cannot fail.)
        if let Ok(e) = Encoders::starting_at(&self.encoder_cfg, &raw) {
            self.encoders = e;
        }
        self.tracker = None;
        self.measured.raw = raw;
        self.measured.backlash = [S::zero(); NUM_JOINTS];
        self.measured.motor = self.encoders.positions();
        self.measured.q = self.measured.motor;
        self.measured.pose = None;
        self.measured.status = PoseStatus::NotHomed;
    }

    /// A whole tick's sensing: [`Sensing::read`], then [`Sensing::follow_pose`].
    pub fn update<H: QuadratureCounter + ?Sized>(&mut self, hw: &mut H) -> &Measured<S> {
        self.read(hw);
        self.follow_pose()
    }

    /// Reads the counters once and updates the joints: the start of every tick.
    pub fn read<H: QuadratureCounter + ?Sized>(&mut self, hw: &mut H) -> &Measured<S> {
        self.counters.ticks += 1;
        let raw = hw.counts();
        let motor = self.encoders.update(&raw);
        let m = &mut self.measured;
        m.raw = raw;
        m.motor = motor;
        m.q = minus(&motor, &m.backlash);
        &self.measured
    }

    /// The second channel's calibration: from now on [`Sensing::read_absolute`] reads the
    /// channel of a board that has it fitted.
    pub fn set_channel(&mut self, calibration: ChannelCalibration<S>) {
        self.channel = Some(calibration);
    }

    /// Reads the second channel once (a board with it fitted, and a calibration set):
    /// the raw readings and the positions they stand for; none otherwise, or when the read
    /// failed.
    pub fn read_absolute<H: AbsolutePositions + ?Sized>(&mut self, hw: &mut H) -> &Measured<S> {
        let m = &mut self.measured;
        self.channel_fitted = self.channel.is_some() && hw.absolute_fitted();
        m.absolute_raw = None;
        m.absolute = None;
        if let (true, Some(cal)) = (self.channel_fitted, self.channel.as_ref()) {
            m.absolute_raw = hw.absolute_counts();
            m.absolute = m.absolute_raw.as_ref().map(|r| cal.positions(r));
        }
        &self.measured
    }

    /// The board has the second channel fitted (and the application reads it).
    pub fn channel_fitted(&self) -> bool {
        self.channel_fitted
    }

    /// How many references were set since power-up (each moves the encoders' joints at
    /// once: a monitor that compares their motion starts over when it changes).
    pub fn reference_epoch(&self) -> u32 {
        self.references
    }

    /// The measured pose follows the joints of the last [`Sensing::read`] (once homed:
    /// a tracker update). The runtime calls it once the tick's outputs are written:
    /// nothing on the way from the readings to the outputs uses the pose (the servos
    /// close their loops on the joints); the monitors, the telemetry and the next
    /// controller's start do.
    pub fn follow_pose(&mut self) -> &Measured<S> {
        let m = &mut self.measured;
        let q = m.q;
        let Some(tracker) = self.tracker.as_mut() else {
            m.status = PoseStatus::NotHomed;
            return &self.measured;
        };
        m.status = match tracker.update(&self.robot, &Joints::from_row_slice(&q), &self.fk_cfg) {
            Ok(t) => {
                let (status, n) = match t {
                    Tracked::Unchanged => (PoseStatus::Unchanged, 0),
                    Tracked::Stepped { steps } => (PoseStatus::Stepped(steps), steps),
                    Tracked::Solved { iterations } => (PoseStatus::Solved(iterations), iterations),
                };
                self.counters.fk_max_iterations = self.counters.fk_max_iterations.max(n);
                self.counters.fk_failures_in_row = 0;
                status
            }
            Err(e) => {
                self.counters.fk_failures = self.counters.fk_failures.wrapping_add(1);
                self.counters.fk_failures_in_row =
                    self.counters.fk_failures_in_row.saturating_add(1);
                PoseStatus::Failed(e)
            }
        };
        // The estimate moved only when the tracker stepped or solved (a failed update
        // keeps the last good one).
        if matches!(m.status, PoseStatus::Stepped(_) | PoseStatus::Solved(_)) {
            m.pose = Some(*tracker.pose());
        }
        &self.measured
    }

    /// The homing procedure's reference: joint `joint` is at `q` now (its count is kept).
    /// Its motor is where the backlash offset the sensing holds puts it: `q + offset`
    /// (the homing's servo takes up the gap as it approaches the switch, so the motor
    /// leads the joint by b/2 in the approach's direction: the encoder is referred to
    /// the middle of the gap, as `servo::backlash` expects). The pose is not tracked
    /// until [`Sensing::track_pose`].
    pub fn set_reference(&mut self, joint: usize, q: S) -> bool {
        self.tracker = None;
        self.measured.pose = None;
        let offset = self
            .measured
            .backlash
            .get(joint)
            .copied()
            .unwrap_or_else(S::zero);
        let ok = self.encoders.set_position(joint, q + offset);
        self.references = self.references.wrapping_add(1);
        self.refresh_joints();
        ok
    }

    /// The backlash compensation's offsets of this tick (m, rad: motor setpoint less
    /// joint setpoint, [`servo::joint_servo::JointServo::backlash_offsets`]), subtracted
    /// from the motors from the next update on, and kept while no servo runs. Non-finite
    /// offsets are taken as 0.
    pub fn set_backlash(&mut self, offsets: &[S; NUM_JOINTS]) {
        for (o, n) in self.measured.backlash.iter_mut().zip(offsets) {
            *o = if n.is_finite() { *n } else { S::zero() };
        }
    }

    fn refresh_joints(&mut self) {
        let m = &mut self.measured;
        m.motor = self.encoders.positions();
        m.q = minus(&m.motor, &m.backlash);
    }

    /// Every joint is referenced: the pose is solved once from the current joints (the
    /// full solver, from the central pose) and tracked from then on.
    pub fn track_pose(&mut self) -> Result<&Pose<S>, ReferenceError> {
        let q = Joints::from_row_slice(&self.measured.q);
        let guess = Pose::central(self.robot.hc());
        let tracker = FkTracker::new(&self.robot, &q, self.branch, &guess, &self.fk_cfg)?;
        self.measured.pose = Some(*tracker.pose());
        self.measured.status = PoseStatus::Solved(0);
        self.counters.fk_failures_in_row = 0;
        Ok(self.tracker.insert(tracker).pose())
    }

    /// The reference is no longer trusted (a fault that may have moved the encoders'
    /// zero, a new homing run): no pose until homed again.
    /// The backlash offsets stay: the gaps have not changed.
    pub fn lose_reference(&mut self) {
        self.tracker = None;
        self.measured.pose = None;
        self.measured.status = PoseStatus::NotHomed;
    }

    /// This tick's measurements.
    pub fn measured(&self) -> &Measured<S> {
        &self.measured
    }
    /// The encoders (counts, positions, per-joint resolution).
    pub fn encoders(&self) -> &Encoders<S> {
        &self.encoders
    }
    /// The counters.
    pub fn counters(&self) -> &SensingCounters {
        &self.counters
    }
    /// What the forward-kinematics tracker did so far (None before homing).
    pub fn fk_counts(&self) -> Option<&TrackerCounts> {
        self.tracker.as_ref().map(|t| t.counts())
    }
    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The branch the robot is assembled on.
    pub fn branch(&self) -> Branch {
        self.branch
    }
}

impl<S: Scalar, M: Mechanism<S>> JointReferences<S> for Sensing<S, M> {
    fn joints(&self) -> [S; NUM_JOINTS] {
        self.measured.q
    }
    fn motors(&self) -> [S; NUM_JOINTS] {
        self.measured.motor
    }
    fn set_backlash(&mut self, offsets: &[S; NUM_JOINTS]) {
        Sensing::set_backlash(self, offsets)
    }
    fn counts(&self) -> [i64; NUM_JOINTS] {
        self.encoders.counts()
    }
    fn set_reference(&mut self, joint: usize, q: S) -> bool {
        Sensing::set_reference(self, joint, q)
    }
    fn absolute(&self) -> Option<[S; NUM_JOINTS]> {
        self.measured.absolute
    }
}

/// `a - b`, element by element.
pub(crate) fn minus<S: Scalar>(a: &[S; NUM_JOINTS], b: &[S; NUM_JOINTS]) -> [S; NUM_JOINTS] {
    let mut out = *a;
    for (o, y) in out.iter_mut().zip(b) {
        *o -= *y;
    }
    out
}
