//! The guards that keep every setpoint safe (thesis 3.2 and 11.4).
//!
//! One [`Limits`] value holds every limit; [`Guards`] prepares it for one robot and branch
//! (socket axes, central joint values) and evaluates a pose. Every guard produces a
//! [`Reading`] with the measured value, the limit and the signed margin, so the same code
//! gives a [`Verdict`] (the violations, each with its severity) for the supervisor and the
//! worst margins for the design tools. Nothing here allocates or panics.

use crate::branch::Branch;
use crate::chain::{Chain, PerChain};
use crate::ik::{inverse, inverse_into, IkError, Solution};
use crate::jacobian::{jacobian_into, tripod_jacobian, Jacobians};
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::{rotation_angle, Pose};
use crate::scalar::{lit, wrap_angle, Real};
use crate::singularity::ConditionEstimator;
use crate::statics::forces_with_inv_cond;
use crate::tilt::{tilt_angles, SocketAxes};
use crate::{Joints, Twist, Wrench};
use core::fmt;
use nalgebra::Vector3;

/// How serious a violation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Continue, but raise the warning flag (e.g. approaching a singularity).
    Warn,
    /// Refuse the setpoint: hold the last safe one.
    Stop,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Severity::Warn => "warn",
            Severity::Stop => "stop",
        })
    }
}

/// The guards, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Guard {
    /// The pose has no inverse-kinematics solution on the branch.
    Reach,
    /// Prismatic stroke (RSPR l_i), m.
    Stroke,
    /// Rotating-link angle θ_i (RSPR) away from its central value, rad.
    LinkAngle,
    /// Lower-link yaw α_i (USR) away from its central value, rad.
    Yaw,
    /// Lower-link pitch β_i (USR) away from its central value, rad.
    Pitch,
    /// Spherical-joint tilt, rad (CONVENTIONS.md).
    Tilt,
    /// Piercing radius of the leg axis in the plane of the central motors' tops, m (11.4).
    Collision,
    /// Distance of the platform centre outside the task box plus margin, m (per axis).
    Workspace,
    /// Platform tilt (angle between n and z0), rad.
    TiltCone,
    /// Serial singularity measure, dimensionless (Eq. 10.6 / 10.11).
    SerialSingularity,
    /// Parallel singularity measure: inverse condition number of scaled Jtilde.
    ParallelSingularity,
    /// Prismatic actuator force for the declared payload wrench, N.
    Force,
    /// Revolute actuator torque for the declared payload wrench, N m.
    Torque,
    /// Speed of o_p, m/s.
    TipSpeed,
    /// Angular speed of the platform, rad/s.
    AngularSpeed,
    /// Acceleration of o_p, m/s².
    TipAccel,
    /// Angular acceleration of the platform, rad/s².
    AngularAccel,
    /// Joint speed, m/s or rad/s.
    JointSpeed,
    /// Joint acceleration, m/s² or rad/s².
    JointAccel,
}

impl Guard {
    /// Every guard, in report order.
    pub const ALL: [Guard; 19] = [
        Guard::Reach,
        Guard::Stroke,
        Guard::LinkAngle,
        Guard::Yaw,
        Guard::Pitch,
        Guard::Tilt,
        Guard::Collision,
        Guard::Workspace,
        Guard::TiltCone,
        Guard::SerialSingularity,
        Guard::ParallelSingularity,
        Guard::Force,
        Guard::Torque,
        Guard::TipSpeed,
        Guard::AngularSpeed,
        Guard::TipAccel,
        Guard::AngularAccel,
        Guard::JointSpeed,
        Guard::JointAccel,
    ];

    /// The name used at the edges (`guard:chain:value:limit`).
    pub const fn name(self) -> &'static str {
        match self {
            Guard::Reach => "reach",
            Guard::Stroke => "stroke",
            Guard::LinkAngle => "link_angle",
            Guard::Yaw => "yaw",
            Guard::Pitch => "pitch",
            Guard::Tilt => "tilt",
            Guard::Collision => "collision",
            Guard::Workspace => "workspace",
            Guard::TiltCone => "tilt_cone",
            Guard::SerialSingularity => "serial",
            Guard::ParallelSingularity => "parallel",
            Guard::Force => "force",
            Guard::Torque => "torque",
            Guard::TipSpeed => "tip_speed",
            Guard::AngularSpeed => "angular_speed",
            Guard::TipAccel => "tip_accel",
            Guard::AngularAccel => "angular_accel",
            Guard::JointSpeed => "joint_speed",
            Guard::JointAccel => "joint_accel",
        }
    }

    /// Unit of the value in SI, and the factor and unit used at the edges (mm, deg).
    pub const fn edge_unit(self) -> (f64, &'static str) {
        const DEG: f64 = 180.0 / core::f64::consts::PI;
        match self {
            Guard::Reach | Guard::SerialSingularity | Guard::ParallelSingularity => (1.0, ""),
            Guard::Stroke | Guard::Collision | Guard::Workspace => (1e3, "mm"),
            Guard::LinkAngle | Guard::Yaw | Guard::Pitch | Guard::Tilt | Guard::TiltCone => {
                (DEG, "deg")
            }
            Guard::Force => (1.0, "N"),
            Guard::Torque => (1.0, "N m"),
            Guard::TipSpeed => (1e3, "mm/s"),
            Guard::AngularSpeed => (DEG, "deg/s"),
            Guard::TipAccel => (1e3, "mm/s^2"),
            Guard::AngularAccel => (DEG, "deg/s^2"),
            // Joint rates mix units; the edge uses mm/s for legs and deg/s for angles.
            Guard::JointSpeed | Guard::JointAccel => (1.0, "SI"),
        }
    }
}

impl fmt::Display for Guard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a reading is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Subject {
    /// The whole robot or platform.
    Robot,
    /// One chain.
    Chain(Chain),
    /// One joint, 1..=6 in q order.
    Joint(u8),
    /// One world axis: 0 = x, 1 = y, 2 = z.
    Axis(u8),
}

impl fmt::Display for Subject {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Subject::Robot => f.write_str("-"),
            Subject::Chain(c) => write!(f, "{}", c.number()),
            Subject::Joint(j) => write!(f, "q{j}"),
            Subject::Axis(a) => f.write_str(match a {
                0 => "x",
                1 => "y",
                _ => "z",
            }),
        }
    }
}

/// One guard's measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading<T: Real> {
    pub guard: Guard,
    pub subject: Subject,
    /// The measured value (SI).
    pub value: T,
    /// The limit it was compared with: the violated level, or the stop level when fine.
    pub limit: T,
    /// Signed distance to the stop level, positive inside (SI, the guard's unit).
    pub margin: T,
    /// `None` when fine.
    pub severity: Option<Severity>,
}

/// Most violations a single evaluation can produce (joint ranges, tilt, collision, forces
/// per chain or joint, plus the robot-wide guards, plus the motion guards).
pub const MAX_VIOLATIONS: usize = 48;

/// Every violation of one evaluation, not just the first.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict<T: Real> {
    /// The violations in evaluation order.
    pub violations: heapless::Vec<Reading<T>, MAX_VIOLATIONS>,
    /// Violations that did not fit (never expected; counted rather than lost silently).
    pub overflow: u16,
    /// The worst severity seen, including overflowed ones.
    pub worst: Option<Severity>,
}

impl<T: Real> Default for Verdict<T> {
    fn default() -> Self {
        Verdict {
            violations: heapless::Vec::new(),
            overflow: 0,
            worst: None,
        }
    }
}

impl<T: Real> Verdict<T> {
    /// Records a reading if it is a violation.
    pub fn record(&mut self, r: &Reading<T>) {
        if let Some(s) = r.severity {
            self.worst = self.worst.max(Some(s));
            if self.violations.push(*r).is_err() {
                self.overflow = self.overflow.saturating_add(1);
            }
        }
    }
    /// True when no guard is violated at all.
    pub fn is_ok(&self) -> bool {
        self.worst.is_none()
    }
    /// True when a stop-level guard is violated.
    pub fn is_stop(&self) -> bool {
        self.worst == Some(Severity::Stop)
    }
    /// The first stop-level violation, if any.
    pub fn first_stop(&self) -> Option<&Reading<T>> {
        self.violations
            .iter()
            .find(|r| r.severity == Some(Severity::Stop))
    }
}

/// A warn level and a stop level for one guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Levels<T: Real> {
    pub warn: T,
    pub stop: T,
}

/// Every limit, in SI. See [`Limits::reference`] for the defaults and where they come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits<T: Real> {
    /// Prismatic stroke (RSPR), m: [min, max].
    pub stroke: [T; 2],
    /// Largest deviation of θ_i (RSPR) or α_i (USR) from its central value, rad.
    pub link_angle_max: T,
    /// Largest deviation of β_i (USR) from its central value, rad.
    pub pitch_max: T,
    /// Largest spherical-joint tilt, rad.
    pub tilt_max: T,
    /// Height of the plane of the central motors' tops above the base plane, m (11.4).
    pub collision_plane_height: T,
    /// Safety-circle radius in that plane, m; 0 disables the collision guard.
    pub collision_radius: T,
    /// Half-extents of the task box centred at [0, 0, hc], m.
    pub box_half: Vector3<T>,
    /// Margin around the task box, m.
    pub box_margin: T,
    /// Largest platform tilt (angle between n and z0), rad.
    pub tilt_cone: T,
    /// Serial measure (dimensionless, lower bound): warn and stop levels.
    pub serial: Levels<T>,
    /// Parallel inverse condition number (lower bound): warn and stop levels.
    pub parallel: Levels<T>,
    /// Largest speed of o_p, m/s.
    pub tip_speed: T,
    /// Largest angular speed, rad/s.
    pub angular_speed: T,
    /// Largest acceleration of o_p, m/s².
    pub tip_accel: T,
    /// Largest angular acceleration, rad/s².
    pub angular_accel: T,
    /// Largest joint speed: [prismatic m/s, revolute rad/s].
    pub joint_speed: [T; 2],
    /// Largest joint acceleration: [prismatic m/s², revolute rad/s²].
    pub joint_accel: [T; 2],
    /// The declared payload wrench the platform exerts on its environment.
    pub payload: Wrench<T>,
    /// Prismatic force (upper bound, N): warn = continuous rating, stop = peak.
    pub force: Levels<T>,
    /// Revolute torque (upper bound, N m): warn = continuous rating, stop = peak.
    pub torque: Levels<T>,
}

/// A limit that makes no sense.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitsError {
    /// The field (as in the TOML form).
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: &'static str,
}

impl fmt::Display for LimitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl<T: Real> Limits<T> {
    /// The reference robot's limits (CONVENTIONS.md, thesis chapter 4 and Table 11.2):
    /// - stroke 144 .. 210 mm, spherical-joint tilt 30 deg, tip speed 25 mm/s, the thesis
    ///   wrench [7, 7, 7 N, 0.7, 0.7, 0.7 N m] as the declared payload, continuous ratings
    ///   220 N and 0.5 N m as warn levels (thesis Table 11.2);
    /// - estimates to be measured on the robot: link angle ±80 deg about the central value
    ///   (the task needs -73 .. +42 deg); collision plane 60 mm, safety circle 40 mm (the
    ///   thesis found its radius experimentally; the task keeps the legs ≥ 71 mm out);
    ///   peak force and torque 2× the continuous ratings (typical of small gearmotors;
    ///   1.0 N m is also the thesis's synthesis bound); box margin 5 mm; tilt cone 25 deg;
    ///   singularity levels with the task's worst values (serial 0.265, parallel 0.059)
    ///   above warn; angular speed 30 deg/s; accelerations 0.25 m/s² and 300 deg/s²;
    ///   joint speeds 60 mm/s and 3 rad/s; joint accelerations 2 m/s² and 60 rad/s².
    pub fn reference() -> Self {
        let deg = |d: f64| lit::<T>(d.to_radians());
        Limits {
            stroke: [lit(0.144), lit(0.210)],
            link_angle_max: deg(80.0),
            pitch_max: deg(80.0),
            tilt_max: deg(30.0),
            collision_plane_height: lit(0.060),
            collision_radius: lit(0.040),
            box_half: Vector3::new(lit(0.020), lit(0.020), lit(0.010)),
            box_margin: lit(0.005),
            tilt_cone: deg(25.0),
            serial: Levels {
                warn: lit(0.15),
                stop: lit(0.05),
            },
            parallel: Levels {
                warn: lit(0.03),
                stop: lit(0.01),
            },
            tip_speed: lit(0.025),
            angular_speed: deg(30.0),
            tip_accel: lit(0.25),
            angular_accel: deg(300.0),
            joint_speed: [lit(0.060), lit(3.0)],
            joint_accel: [lit(2.0), lit(60.0)],
            payload: Wrench::new(lit(7.0), lit(7.0), lit(7.0), lit(0.7), lit(0.7), lit(0.7)),
            force: Levels {
                warn: lit(220.0),
                stop: lit(440.0),
            },
            torque: Levels {
                warn: lit(0.5),
                stop: lit(1.0),
            },
        }
    }

    /// Checks that every limit is finite and consistent.
    pub fn validate(&self) -> Result<(), LimitsError> {
        let err = |field, reason| Err(LimitsError { field, reason });
        let scalars: [(&'static str, T); 15] = [
            ("stroke_min_mm", self.stroke[0]),
            ("stroke_max_mm", self.stroke[1]),
            ("link_angle_max_deg", self.link_angle_max),
            ("pitch_max_deg", self.pitch_max),
            ("tilt_max_deg", self.tilt_max),
            ("collision_plane_height_mm", self.collision_plane_height),
            ("collision_radius_mm", self.collision_radius),
            ("box_margin_mm", self.box_margin),
            ("tilt_cone_deg", self.tilt_cone),
            ("tip_speed_mm_s", self.tip_speed),
            ("angular_speed_deg_s", self.angular_speed),
            ("tip_accel_mm_s2", self.tip_accel),
            ("angular_accel_deg_s2", self.angular_accel),
            ("joint_speed_linear_mm_s", self.joint_speed[0]),
            ("joint_speed_angular_deg_s", self.joint_speed[1]),
        ];
        for (field, v) in scalars {
            if !v.is_finite() {
                return err(field, "is not finite");
            }
            if v < T::zero() {
                return err(field, "is negative");
            }
        }
        let positive: [(&'static str, T); 8] = [
            ("tip_speed_mm_s", self.tip_speed),
            ("angular_speed_deg_s", self.angular_speed),
            ("tip_accel_mm_s2", self.tip_accel),
            ("angular_accel_deg_s2", self.angular_accel),
            ("joint_speed_linear_mm_s", self.joint_speed[0]),
            ("joint_speed_angular_deg_s", self.joint_speed[1]),
            ("joint_accel_linear_mm_s2", self.joint_accel[0]),
            ("joint_accel_angular_deg_s2", self.joint_accel[1]),
        ];
        for (field, v) in positive {
            if !(v > T::zero() && v.is_finite()) {
                return err(field, "must be positive and finite");
            }
        }
        let angles: [(&'static str, T); 4] = [
            ("link_angle_max_deg", self.link_angle_max),
            ("pitch_max_deg", self.pitch_max),
            ("tilt_max_deg", self.tilt_max),
            ("tilt_cone_deg", self.tilt_cone),
        ];
        for (field, v) in angles {
            if v > T::pi() {
                return err(field, "exceeds 180 deg");
            }
        }
        if !(self.stroke[0] < self.stroke[1]) {
            return err("stroke_min_mm", "must be below stroke_max_mm");
        }
        if !self
            .box_half
            .iter()
            .all(|h| *h >= T::zero() && h.is_finite())
        {
            return err("box_half_mm", "must be non-negative and finite");
        }
        if !self.payload.iter().all(|x| x.is_finite()) {
            return err("payload", "is not finite");
        }
        for (field, l) in [("serial", self.serial), ("parallel", self.parallel)] {
            if !(l.stop >= T::zero() && l.warn >= l.stop && l.warn <= T::one()) {
                return err(field, "needs 0 <= stop <= warn <= 1");
            }
        }
        for (field, l) in [("force", self.force), ("torque", self.torque)] {
            if !(l.warn > T::zero() && l.stop >= l.warn && l.stop.is_finite()) {
                return err(field, "needs 0 < warn <= stop (finite)");
            }
        }
        Ok(())
    }
}

/// Why the guards cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GuardSetupError {
    Limits(LimitsError),
    /// The central configuration (the reference of link angles and socket axes) has no
    /// solution.
    Central(IkError),
}

impl fmt::Display for GuardSetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GuardSetupError::Limits(e) => write!(f, "limits: {e}"),
            GuardSetupError::Central(e) => write!(f, "central configuration: {e}"),
        }
    }
}

/// A reading of `value` against warn and stop levels; a lower bound (the value must stay
/// ≥ the levels) or an upper bound (≤). A NaN value is always beyond the stop level.
fn bounded<T: Real>(
    guard: Guard,
    subject: Subject,
    value: T,
    levels: Levels<T>,
    lower: bool,
) -> Reading<T> {
    let beyond = |level: T| {
        if lower {
            !(value >= level)
        } else {
            !(value <= level)
        }
    };
    let (severity, limit) = if beyond(levels.stop) {
        (Some(Severity::Stop), levels.stop)
    } else if beyond(levels.warn) {
        (Some(Severity::Warn), levels.warn)
    } else {
        (None, levels.stop)
    };
    Reading {
        guard,
        subject,
        value,
        limit,
        margin: if lower {
            value - levels.stop
        } else {
            levels.stop - value
        },
        severity,
    }
}

/// A lower-bound reading (value must stay ≥ the levels).
fn lower<T: Real>(guard: Guard, subject: Subject, value: T, levels: Levels<T>) -> Reading<T> {
    bounded(guard, subject, value, levels, true)
}

/// An upper-bound reading (value must stay ≤ the levels).
fn upper<T: Real>(guard: Guard, subject: Subject, value: T, levels: Levels<T>) -> Reading<T> {
    bounded(guard, subject, value, levels, false)
}

fn stop_only<T: Real>(l: T) -> Levels<T> {
    Levels { warn: l, stop: l }
}

/// One platform motion sample for the motion guards.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSample<T: Real> {
    /// Platform twist [v; ω] (m/s, rad/s).
    pub twist: Twist<T>,
    /// Joint rates in q order.
    pub qdot: Joints<T>,
}

/// Scratch space of one guard evaluation on the control path
/// ([`Guards::evaluate_pose_into`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation<T: Real> {
    /// The inverse-kinematics solution (valid unless [`Solved::No`]).
    pub sol: Solution<T>,
    /// The Jacobians (valid with [`Solved::WithJacobian`]).
    pub jac: Jacobians<T>,
}

impl<T: Real> Evaluation<T> {
    /// Empty scratch space.
    pub fn new(branch: Branch) -> Self {
        Evaluation {
            sol: Solution::zeroed(branch),
            jac: Jacobians::zeroed(),
        }
    }
}

/// How much of the guards an evaluation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    /// Every pose guard.
    Full,
    /// Every guard that follows from the inverse kinematics and the Jacobian (reach,
    /// workspace, joint ranges, tilt, collision, serial singularity), not the parallel
    /// measure (an SVD) nor the payload statics (an LU): for a pose between two poses
    /// where those were checked (the supervisor's setpoints, see its documentation).
    Kinematic,
}

/// What a guard evaluation could compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solved {
    /// No inverse-kinematics solution (a Reach reading was given).
    No,
    /// A solution, but no Jacobian (a serial singularity, or the measures failed).
    WithoutJacobian,
    /// A solution and its Jacobians.
    WithJacobian,
}

/// The stop-level reading of a chain that cannot reach the pose.
fn unreachable<T: Real>(chain: Chain) -> Reading<T> {
    Reading {
        guard: Guard::Reach,
        subject: Subject::Chain(chain),
        value: T::zero(),
        limit: T::zero(),
        margin: -T::one(),
        severity: Some(Severity::Stop),
    }
}

/// The stages of a staged full evaluation, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Workspace box and tilt cone, inverse kinematics, joint ranges, spherical-joint
    /// tilts, collision, serial singularity.
    Kinematic,
    /// The Jacobians (Eq. 7.14, 7.18), and the start of the parallel measure's SVD
    /// ([`ConditionEstimator::begin`]).
    Jacobian,
    /// One sweep of the parallel measure's SVD ([`ConditionEstimator::sweep`]); repeated
    /// until it converges (one or two sweeps warm-started, four or five cold, at most
    /// [`crate::singularity::MAX_SWEEPS`]).
    Parallel,
    /// The payload statics (Eq. 7.10): actuator forces and torques.
    Statics,
}

/// The most stages a staged evaluation takes: the kinematic stage, the Jacobian, every
/// sweep the SVD may take, the statics.
pub const MAX_STAGES: u32 = 3 + crate::singularity::MAX_SWEEPS as u32;

/// A full guard evaluation spread over several calls of [`Guards::advance`], one
/// [`Stage`] per call, so that a caller with a fixed budget per control tick (the
/// supervisor) never runs a whole evaluation in one tick. Run to the end it reaches the
/// verdict of [`Guards::evaluate_pose`]: the same first stop-level reading, and whether a
/// warn level was reached (when nothing stops).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Staged<T: Real> {
    pose: Pose<T>,
    eval: Evaluation<T>,
    jac_ok: bool,
    inv_cond: T,
    inv_cond_ok: bool,
    stop: Option<Reading<T>>,
    warn: bool,
    next: Option<Stage>,
}

impl<T: Real> Staged<T> {
    /// Nothing to evaluate (finished).
    pub fn new(branch: Branch) -> Self {
        Staged {
            pose: Pose::central(T::zero()),
            eval: Evaluation::new(branch),
            jac_ok: false,
            inv_cond: T::zero(),
            inv_cond_ok: false,
            stop: None,
            warn: false,
            next: None,
        }
    }
    /// Starts over at `pose`.
    pub fn start(&mut self, pose: &Pose<T>) {
        self.pose = *pose;
        self.jac_ok = false;
        self.inv_cond_ok = false;
        self.stop = None;
        self.warn = false;
        self.next = Some(Stage::Kinematic);
    }
    /// The pose being evaluated.
    pub fn pose(&self) -> &Pose<T> {
        &self.pose
    }
    /// The stage the next call runs (None: finished).
    pub fn next_stage(&self) -> Option<Stage> {
        self.next
    }
    /// Whether the evaluation has finished.
    pub fn is_finished(&self) -> bool {
        self.next.is_none()
    }
    /// The first stop-level reading so far.
    pub fn stop(&self) -> Option<&Reading<T>> {
        self.stop.as_ref()
    }
    /// Whether a warn level was reached so far.
    pub fn warn(&self) -> bool {
        self.warn
    }
    /// The parallel measure (inverse condition number), once its SVD has converged.
    pub fn inv_cond(&self) -> Option<T> {
        self.inv_cond_ok.then_some(self.inv_cond)
    }
}

/// The guards prepared for one robot and branch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Guards<T: Real, M: Mechanism<T>> {
    robot: M,
    branch: Branch,
    limits: Limits<T>,
    axes: SocketAxes<T>,
    /// (qa, qb) of each chain at the central configuration: the reference of the angle ranges.
    central: PerChain<(T, T)>,
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// Prepares the guards: validates the limits and computes the central joint values and
    /// socket axes.
    pub fn new(robot: M, branch: Branch, limits: Limits<T>) -> Result<Self, GuardSetupError> {
        limits.validate().map_err(GuardSetupError::Limits)?;
        let central = inverse(&robot, &Pose::central(robot.hc()), branch)
            .map_err(GuardSetupError::Central)?;
        let axes = SocketAxes::new(&robot).map_err(GuardSetupError::Central)?;
        Ok(Guards {
            robot,
            branch,
            limits,
            axes,
            central: central.chains.map(|_, c| (c.qa, c.qb)),
        })
    }

    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The branch.
    pub fn branch(&self) -> Branch {
        self.branch
    }
    /// The limits.
    pub fn limits(&self) -> &Limits<T> {
        &self.limits
    }

    /// Evaluates every pose guard at `pose`, handing each reading to `visit` (violations
    /// and fine ones alike). Returns the inverse-kinematics solution when there is one.
    pub fn evaluate_pose(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<Solution<T>> {
        self.evaluate_pose_full(pose, visit).map(|(sol, _)| sol)
    }

    /// [`Guards::evaluate_pose`] that also returns the Jacobians it computed (None at a
    /// serial singularity or when the measures fail), so that callers on the control path
    /// need not compute them again.
    pub fn evaluate_pose_full(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<(Solution<T>, Option<Jacobians<T>>)> {
        self.evaluate_pose_warm(pose, visit, &mut ConditionEstimator::new())
    }

    /// [`Guards::evaluate_pose_full`] with the parallel measure's SVD warm-started by
    /// `cond` (keep one estimator per stream of nearby poses: the setpoints, the path
    /// samples; see [`ConditionEstimator`]). The readings are the same as from a cold
    /// start, to the SVD's convergence tolerance.
    pub fn evaluate_pose_warm(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
        cond: &mut ConditionEstimator<T>,
    ) -> Option<(Solution<T>, Option<Jacobians<T>>)> {
        let mut e = Evaluation::new(self.branch);
        match self.evaluate_pose_into(pose, visit, cond, &mut e, Depth::Full) {
            Solved::No => None,
            Solved::WithoutJacobian => Some((e.sol, None)),
            Solved::WithJacobian => Some((e.sol, Some(e.jac))),
        }
    }

    /// The control path's form of [`Guards::evaluate_pose_warm`]: the solution and the
    /// Jacobians are written into `out` (no copies of returned values; about 600 bytes
    /// on the Cortex-M4); the result says which of them are valid.
    pub fn evaluate_pose_into(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
        cond: &mut ConditionEstimator<T>,
        out: &mut Evaluation<T>,
        depth: Depth,
    ) -> Solved {
        self.workspace_readings(pose, visit);
        if let Err(e) = inverse_into(&self.robot, pose, self.branch, &mut out.sol) {
            visit(&unreachable(e.chain));
            return Solved::No;
        }
        if self.solution_readings(&out.sol, visit, cond, &mut out.jac, depth) {
            Solved::WithJacobian
        } else {
            Solved::WithoutJacobian
        }
    }

    /// The verdict at a pose: every violation, with its severity.
    pub fn check_pose(&self, pose: &Pose<T>) -> (Verdict<T>, Option<Solution<T>>) {
        let mut v = Verdict::default();
        let sol = self.evaluate_pose(pose, &mut |r| v.record(r));
        (v, sol)
    }

    fn workspace_readings(&self, pose: &Pose<T>, visit: &mut impl FnMut(&Reading<T>)) {
        let l = &self.limits;
        let d = Vector3::new(pose.t.x, pose.t.y, pose.t.z - self.robot.hc());
        // The worst axis of the box (the one closest to or furthest beyond its face).
        let mut worst: Option<Reading<T>> = None;
        for (k, (di, hi)) in d.iter().zip(l.box_half.iter()).enumerate() {
            let r = upper(
                Guard::Workspace,
                Subject::Axis(k as u8),
                di.abs(),
                stop_only(*hi + l.box_margin),
            );
            if worst.is_none_or(|w| r.margin < w.margin || !(r.margin >= w.margin)) {
                worst = Some(r);
            }
        }
        if let Some(w) = worst {
            visit(&w);
        }
        // Platform tilt: angle between n = R z and z0.
        let r = pose.r.matrix();
        let (nx, ny, nz) = (r.m13, r.m23, r.m33);
        let tilt = crate::scalar::sqrt(nx * nx + ny * ny).atan2(nz);
        visit(&upper(
            Guard::TiltCone,
            Subject::Robot,
            tilt,
            stop_only(l.tilt_cone),
        ));
    }

    /// The readings that need the solution; true when `jac` holds its Jacobians.
    fn solution_readings(
        &self,
        sol: &Solution<T>,
        visit: &mut impl FnMut(&Reading<T>),
        cond: &mut ConditionEstimator<T>,
        jac: &mut Jacobians<T>,
        depth: Depth,
    ) -> bool {
        self.kinematic_readings(sol, visit);
        let jac_ok = jacobian_into(&self.robot, sol, jac).is_ok();
        if depth == Depth::Kinematic {
            return jac_ok;
        }
        let Some(inv_cond) = self.parallel_reading(sol, jac_ok.then_some(&*jac), cond, visit)
        else {
            return false;
        };
        // Forces for the declared payload.
        if !jac_ok {
            return false; // a serial singularity: already a serial reading
        }
        self.statics_readings(jac, inv_cond, visit);
        true
    }

    /// Joint ranges, spherical-joint tilts, the collision radius and the serial
    /// singularity measures: what follows from the inverse kinematics alone.
    fn kinematic_readings(&self, sol: &Solution<T>, visit: &mut impl FnMut(&Reading<T>)) {
        let l = &self.limits;
        let kinds = self.robot.joint_kinds();
        let (guard_a, guard_b) = match kinds[0] {
            JointKind::Linear => (Guard::Stroke, Guard::LinkAngle),
            JointKind::Angular => (Guard::Yaw, Guard::Pitch),
        };
        let tilts = tilt_angles(sol, &self.axes);
        for chain in Chain::ALL {
            let subject = Subject::Chain(chain);
            let (qa, qb) = (sol.chains[chain].qa, sol.chains[chain].qb);
            let (ca, cb) = self.central[chain];
            // Joint ranges.
            match kinds[0] {
                JointKind::Linear => {
                    let low = lower(guard_a, subject, qa, stop_only(l.stroke[0]));
                    let high = upper(guard_a, subject, qa, stop_only(l.stroke[1]));
                    visit(if low.margin < high.margin {
                        &low
                    } else {
                        &high
                    });
                    visit(&upper(
                        guard_b,
                        subject,
                        wrap_angle(qb - cb).abs(),
                        stop_only(l.link_angle_max),
                    ));
                }
                JointKind::Angular => {
                    visit(&upper(
                        guard_a,
                        subject,
                        wrap_angle(qa - ca).abs(),
                        stop_only(l.link_angle_max),
                    ));
                    visit(&upper(
                        guard_b,
                        subject,
                        wrap_angle(qb - cb).abs(),
                        stop_only(l.pitch_max),
                    ));
                }
            }
            // Spherical-joint tilt.
            visit(&upper(
                Guard::Tilt,
                subject,
                tilts[chain],
                stop_only(l.tilt_max),
            ));
            // Section 11.4: the leg axis must pierce the motors' plane outside the circle.
            if l.collision_radius > T::zero() {
                let c = &sol.chains[chain];
                let radius = if c.s1.z.abs() > T::default_epsilon() {
                    let k = (l.collision_plane_height - c.b.z) / c.s1.z;
                    let (px, py) = (c.b.x + c.s1.x * k, c.b.y + c.s1.y * k);
                    crate::scalar::sqrt(px * px + py * py)
                } else {
                    // A horizontal leg never meets the plane.
                    T::max_value().unwrap_or(T::one() / T::default_epsilon())
                };
                visit(&lower(
                    Guard::Collision,
                    subject,
                    radius,
                    stop_only(l.collision_radius),
                ));
            }
        }
        // Singularities (CONVENTIONS.md measures): serial per chain from the serial
        // blocks, parallel from the SVD of the scaled Jtilde, which the Jacobian computes
        // anyway (it is only recomputed alone at a serial singularity, where J is not).
        for (chain, c) in sol.chains.iter() {
            visit(&lower(
                Guard::SerialSingularity,
                Subject::Chain(chain),
                self.robot.serial_measure(c).1,
                l.serial,
            ));
        }
    }

    /// The parallel singularity measure from the SVD of the scaled Jtilde (that of `jac`
    /// when there is one, else computed from `sol`): its value, or None after a stop
    /// reading when the SVD failed.
    fn parallel_reading(
        &self,
        sol: &Solution<T>,
        jac: Option<&Jacobians<T>>,
        cond: &mut ConditionEstimator<T>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<T> {
        let computed;
        let jtilde = match jac {
            Some(j) => &j.jtilde,
            None => {
                computed = tripod_jacobian(sol);
                &computed
            }
        };
        self.parallel_verdict(cond.inv_cond(jtilde, self.robot.rp()), visit)
    }

    /// The reading of the parallel measure (a stop when the SVD failed); its value.
    fn parallel_verdict(
        &self,
        result: Result<T, crate::singularity::SvdDidNotConverge>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<T> {
        let l = &self.limits;
        let Ok(inv_cond) = result else {
            visit(&Reading {
                guard: Guard::ParallelSingularity,
                subject: Subject::Robot,
                value: T::zero(),
                limit: l.parallel.stop,
                margin: -l.parallel.stop,
                severity: Some(Severity::Stop),
            });
            return None;
        };
        visit(&lower(
            Guard::ParallelSingularity,
            Subject::Robot,
            inv_cond,
            l.parallel,
        ));
        Some(inv_cond)
    }

    /// The actuator forces and torques that hold the declared payload.
    fn statics_readings(
        &self,
        jac: &Jacobians<T>,
        inv_cond: T,
        visit: &mut impl FnMut(&Reading<T>),
    ) {
        let l = &self.limits;
        let kinds = self.robot.joint_kinds();
        let Ok(st) = forces_with_inv_cond(jac, &l.payload, inv_cond, l.parallel.stop) else {
            return; // already a parallel reading
        };
        for (j, (tau, kind)) in st.tau.iter().zip(kinds.iter()).enumerate() {
            let (guard, levels) = match kind {
                JointKind::Linear => (Guard::Force, l.force),
                JointKind::Angular => (Guard::Torque, l.torque),
            };
            visit(&upper(
                guard,
                Subject::Joint(j as u8 + 1),
                tau.abs(),
                levels,
            ));
        }
    }

    /// Runs the next stage of a staged full evaluation (see [`Staged`]): one of the
    /// inverse kinematics with the kinematic guards, the Jacobians (and the start of the
    /// SVD), one sweep of the parallel measure's SVD (warm-started by `cond`, which holds
    /// the decomposition in progress between the calls), the payload statics. The
    /// evaluation ends early at the first stop-level reading.
    pub fn advance(&self, st: &mut Staged<T>, cond: &mut ConditionEstimator<T>) {
        let Some(stage) = st.next else { return };
        let Staged {
            pose,
            eval,
            jac_ok,
            inv_cond,
            inv_cond_ok,
            stop,
            warn,
            next,
        } = st;
        let mut visit = |r: &Reading<T>| match r.severity {
            Some(Severity::Stop) if stop.is_none() => *stop = Some(*r),
            Some(Severity::Warn) => *warn = true,
            _ => {}
        };
        *next = match stage {
            Stage::Kinematic => {
                self.workspace_readings(pose, &mut visit);
                match inverse_into(&self.robot, pose, self.branch, &mut eval.sol) {
                    Err(e) => {
                        visit(&unreachable(e.chain));
                        None
                    }
                    Ok(()) => {
                        self.kinematic_readings(&eval.sol, &mut visit);
                        Some(Stage::Jacobian)
                    }
                }
            }
            Stage::Jacobian => {
                *jac_ok = jacobian_into(&self.robot, &eval.sol, &mut eval.jac).is_ok();
                // The SVD of Jtilde (computed alone at a serial singularity, where J is
                // not).
                let computed;
                let jtilde = if *jac_ok {
                    &eval.jac.jtilde
                } else {
                    computed = tripod_jacobian(&eval.sol);
                    &computed
                };
                match cond.begin(jtilde, self.robot.rp()) {
                    Ok(()) => Some(Stage::Parallel),
                    Err(e) => {
                        self.parallel_verdict(Err(e), &mut visit);
                        None
                    }
                }
            }
            Stage::Parallel => match cond.sweep() {
                None => Some(Stage::Parallel),
                Some(result) => {
                    let value = self.parallel_verdict(result, &mut visit);
                    if let Some(x) = value {
                        *inv_cond = x;
                        *inv_cond_ok = true;
                    }
                    match value {
                        Some(_) if *jac_ok => Some(Stage::Statics),
                        _ => None,
                    }
                }
            },
            Stage::Statics => {
                self.statics_readings(&eval.jac, *inv_cond, &mut visit);
                None
            }
        };
        if stop.is_some() {
            *next = None;
        }
    }

    /// Evaluates the motion guards between two samples `dt` apart (speeds of `cur`,
    /// accelerations from `prev` to `cur`).
    pub fn evaluate_motion(
        &self,
        prev: &MotionSample<T>,
        cur: &MotionSample<T>,
        dt: T,
        visit: &mut impl FnMut(&Reading<T>),
    ) {
        let l = &self.limits;
        let [v, w, a, alpha] = platform_motion(prev, cur, dt);
        let r = Subject::Robot;
        visit(&upper(Guard::TipSpeed, r, v, stop_only(l.tip_speed)));
        visit(&upper(
            Guard::AngularSpeed,
            r,
            w,
            stop_only(l.angular_speed),
        ));
        visit(&upper(Guard::TipAccel, r, a, stop_only(l.tip_accel)));
        visit(&upper(
            Guard::AngularAccel,
            r,
            alpha,
            stop_only(l.angular_accel),
        ));
        let kinds = self.robot.joint_kinds();
        for (j, ((qd, qd0), kind)) in cur
            .qdot
            .iter()
            .zip(prev.qdot.iter())
            .zip(kinds.iter())
            .enumerate()
        {
            let (vmax, amax) = self.joint_motion_limits(*kind);
            let s = Subject::Joint(j as u8 + 1);
            visit(&upper(Guard::JointSpeed, s, qd.abs(), stop_only(vmax)));
            visit(&upper(
                Guard::JointAccel,
                s,
                ((*qd - *qd0) / dt).abs(),
                stop_only(amax),
            ));
        }
    }

    /// Whether [`Guards::evaluate_motion`] would give no stop-level reading (the same
    /// values against the same limits, a NaN beyond them), without building the
    /// readings: the control path's check, which needs the readings only on a stop.
    pub fn motion_within_limits(
        &self,
        prev: &MotionSample<T>,
        cur: &MotionSample<T>,
        dt: T,
    ) -> bool {
        let l = &self.limits;
        let [v, w, a, alpha] = platform_motion(prev, cur, dt);
        let mut ok = v <= l.tip_speed
            && w <= l.angular_speed
            && a <= l.tip_accel
            && alpha <= l.angular_accel;
        // Over plain arrays (nalgebra's iterators cost several times the arithmetic on the
        // Cortex-M4).
        let ([qd], [qd0]) = (cur.qdot.data.0, prev.qdot.data.0);
        let kinds = self.robot.joint_kinds();
        for ((v, v0), kind) in qd.iter().zip(qd0.iter()).zip(kinds.iter()) {
            let (vmax, amax) = self.joint_motion_limits(*kind);
            ok &= v.abs() <= vmax && ((*v - *v0) / dt).abs() <= amax;
        }
        ok
    }

    /// The speed and acceleration limits of a joint of `kind`.
    fn joint_motion_limits(&self, kind: JointKind) -> (T, T) {
        let l = &self.limits;
        match kind {
            JointKind::Linear => (l.joint_speed[0], l.joint_accel[0]),
            JointKind::Angular => (l.joint_speed[1], l.joint_accel[1]),
        }
    }
}

/// Tip speed, angular speed, tip acceleration and angular acceleration of a motion sample
/// (the accelerations from `prev`, `dt` earlier).
fn platform_motion<T: Real>(prev: &MotionSample<T>, cur: &MotionSample<T>, dt: T) -> [T; 4] {
    let (c, p) = (&cur.twist, &prev.twist);
    let norm = |x: T, y: T, z: T| crate::scalar::sqrt(x * x + y * y + z * z);
    [
        norm(c.x, c.y, c.z),
        norm(c.w, c.a, c.b),
        norm((c.x - p.x) / dt, (c.y - p.y) / dt, (c.z - p.z) / dt),
        norm((c.w - p.w) / dt, (c.a - p.a) / dt, (c.b - p.b) / dt),
    ]
}

/// Rotation angle between two orientations (rad).
pub fn orientation_distance<T: Real>(a: &Pose<T>, b: &Pose<T>) -> T {
    rotation_angle(&(a.r.inverse() * b.r))
}
