//! The control application of one period, hardware-agnostic: the [`Planner`] (setpoint
//! supervisor, the tool's flanks) and the [`Drive`] (joint servos, outputs), fed by the
//! tick's measurements ([`crate::sensing::Measured`]). [`Controller::tick`] runs from the
//! readings to the outputs (the supervisor's step, the servos); [`Controller::evaluate`],
//! after the outputs are written, runs the rest of the period (the supervisor's checker
//! stages, the flanks).

use core::fmt;
use kinematics_core::guards::Limits;
use kinematics_core::supervisor::{Refusal, Supervisor, SupervisorConfig, SupervisorError};
use kinematics_core::{forward, scalar, Branch, FkConfig, Joints, Mechanism, Pose};
use servo::config::{ConfigError, ServoConfig};
use servo::encoder::EncoderConfig;
use servo::NUM_JOINTS;

use crate::drive::{Drive, TickReport};
use crate::planner::{Planner, ToolLoad};
use crate::sensing::Measured;

pub use crate::scalar::Scalar;

/// Everything the controller needs. `Default` gives the reference robot's values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig<S: Scalar> {
    /// Control rate, Hz (default: the board profile's; 100 .. 10 000).
    pub rate_hz: S,
    /// Inverse-kinematics branch the robot is assembled on (default 0, all outer).
    pub branch: Branch,
    /// Safety limits (default: the reference robot's).
    pub limits: Limits<S>,
    /// Setpoint supervisor (its `dt` is set from `rate_hz`).
    pub supervisor: SupervisorConfig<S>,
    /// PID gains, backlash compensation and tracking-error limits per joint.
    pub servo: ServoConfig<S>,
    /// Encoder resolutions.
    pub encoders: EncoderConfig<S>,
    /// Forward-kinematics solver settings for the measured pose.
    pub fk: FkConfig<S>,
    /// A known tool on the platform (default none). Its weight sets the lead screws'
    /// backlash flank: a joint whose holding effort exceeds the threshold rests on one
    /// flank whichever way it moves.
    pub tool: Option<ToolLoad<S>>,
}

impl<S: Scalar> Default for ControllerConfig<S> {
    fn default() -> Self {
        ControllerConfig {
            rate_hz: scalar::lit(board_profile::BoardProfile::REFERENCE.rate_hz()),
            branch: Branch::OUTER,
            limits: Limits::reference(),
            supervisor: SupervisorConfig::default(),
            servo: ServoConfig::default(),
            encoders: EncoderConfig::default(),
            fk: FkConfig::default(),
            tool: None,
        }
    }
}

/// Why the controller cannot start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControllerError<S: Scalar> {
    /// `rate_hz` outside 100 .. 10 000 Hz.
    Rate,
    /// A servo or encoder setting.
    Servo(ConfigError),
    /// The robot has no measured pose (not homed, or its forward kinematics failed).
    NoPose,
    /// The supervisor refused its settings or the start pose.
    Supervisor(SupervisorError<S>),
}

impl<S: Scalar> fmt::Display for ControllerError<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControllerError::Rate => f.write_str("rate_hz must be within 100 .. 10000 Hz"),
            ControllerError::Servo(e) => write!(f, "{e}"),
            ControllerError::NoPose => f.write_str("no measured pose to start from"),
            ControllerError::Supervisor(e) => write!(f, "{e}"),
        }
    }
}

/// Why a jog cannot be turned into a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JogError {
    /// The jog distance is NaN or infinite.
    NonFinite,
    /// The jogged joints have no pose on the branch (out of reach).
    NoSolution,
}

/// The control application: each tick the [`Planner`] plans and the [`Drive`] acts on the
/// tick's measurements.
#[derive(Clone, Debug)]
pub struct Controller<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: ControllerConfig<S>,
    planner: Planner<S, M>,
    drive: Drive<S>,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Controller<S, M> {
    /// A controller holding the robot where the tick's measurements say it is (it must
    /// be homed: the measured pose is the supervisor's start).
    pub fn new(
        robot: M,
        cfg: ControllerConfig<S>,
        measured: &Measured<S>,
    ) -> Result<Self, ControllerError<S>> {
        let start_pose = measured.pose.ok_or(ControllerError::NoPose)?;
        Self::starting_at(robot, cfg, measured, &start_pose)
    }

    /// A controller whose supervisor starts at `start_pose` (a pose it has verified, which
    /// the measurements stand within their resolution of: the caller's to check), its
    /// servos where the tick's measurements say the joints are (they pull the joints the
    /// few counts onto the supervisor's setpoint).
    // Cold (at enable, a stop, the park move; never in a tick): compiled for size.
    #[cold]
    pub fn starting_at(
        robot: M,
        mut cfg: ControllerConfig<S>,
        measured: &Measured<S>,
        start_pose: &Pose<S>,
    ) -> Result<Self, ControllerError<S>> {
        let lo: S = scalar::lit(100.0);
        let hi: S = scalar::lit(10_000.0);
        if !(cfg.rate_hz >= lo && cfg.rate_hz <= hi) {
            return Err(ControllerError::Rate);
        }
        let dt = S::one() / cfg.rate_hz;
        cfg.supervisor.dt = dt;
        let start_pose = *start_pose;
        let supervisor = Supervisor::new(
            robot.clone(),
            cfg.branch,
            cfg.limits,
            cfg.supervisor,
            &start_pose,
        )
        .map_err(ControllerError::Supervisor)?;
        let kinds = robot.joint_kinds();
        let drive = Drive::new(kinds, dt, &cfg.servo, measured).map_err(ControllerError::Servo)?;
        Ok(Controller {
            planner: Planner::new(supervisor, kinds, cfg.tool),
            drive,
            robot,
            cfg,
        })
    }

    /// The two halves, e.g. to run the planner ahead of the servo on another core of a
    /// host: ticking them as [`Controller::tick`] does gives the same results.
    pub fn into_parts(self) -> (Planner<S, M>, Drive<S>) {
        (self.planner, self.drive)
    }

    /// The planner.
    pub fn planner(&self) -> &Planner<S, M> {
        &self.planner
    }
    /// The drive.
    pub fn drive(&self) -> &Drive<S> {
        &self.drive
    }
    /// The supervisor (counters, last refusal, latched stop).
    pub fn supervisor(&self) -> &Supervisor<S, M> {
        self.planner.supervisor()
    }
    /// The control period, s.
    pub fn dt(&self) -> S {
        self.drive.dt()
    }
    /// The configuration in use.
    pub fn config(&self) -> &ControllerConfig<S> {
        &self.cfg
    }

    /// Declares the tool now on the platform (None: none).
    pub fn set_tool(&mut self, tool: Option<ToolLoad<S>>) {
        self.cfg.tool = tool;
        self.planner.set_tool(tool);
    }

    /// The joints of the current setpoint (q order).
    pub fn setpoint_joints(&self) -> Result<Joints<S>, JogError> {
        kinematics_core::inverse(&self.robot, self.supervisor().setpoint(), self.cfg.branch)
            .map(|sol| sol.q())
            .map_err(|_| JogError::NoSolution)
    }

    /// The pose whose joints are `q` on the branch (FK warm-started at the setpoint): a
    /// joint-space jog expressed as a Cartesian target, so that it passes the same
    /// supervisor and guards as any target.
    pub fn joints_target(&self, q: &Joints<S>) -> Result<Pose<S>, JogError> {
        if !q.iter().all(|x| x.is_finite()) {
            return Err(JogError::NonFinite);
        }
        forward(
            &self.robot,
            q,
            self.cfg.branch,
            self.supervisor().setpoint(),
            &self.cfg.fk,
        )
        .map(|fk| fk.pose)
        .map_err(|_| JogError::NoSolution)
    }

    /// Hands a master target to the supervisor.
    pub fn submit(&mut self, pose: &Pose<S>, stamp_us: u64, now_us: u64) -> Result<(), Refusal<S>> {
        self.planner.submit(pose, stamp_us, now_us)
    }

    /// Clears a latched supervisor stop (the servo's tracking fault is cleared by
    /// [`Controller::reset_servo`]).
    pub fn clear_stop(&mut self) -> bool {
        self.planner.clear_stop()
    }

    /// Stops the robot as soon as the limits allow and holds it there
    /// ([`Supervisor::brake`]).
    pub fn hold(&mut self) {
        self.planner.hold();
    }

    /// Resets the servo after a tracking fault, its loops at the motors' positions
    /// `motor` ([`Measured::motor`]).
    pub fn reset_servo(&mut self, motor: &[S; NUM_JOINTS]) {
        self.drive.reset(motor);
    }

    /// The real-time tick on the tick's measurements: the supervisor's step and the six
    /// PIDs; the duties are in the report (the runtime limits them and writes the outputs;
    /// [`TickReport::apply`] writes them as they are). Once the outputs are written,
    /// [`Controller::evaluate`] must run before the next tick (else the supervisor brakes).
    pub fn tick(&mut self, measured: &Measured<S>) -> TickReport<S> {
        let plan = self.planner.step();
        self.drive.act(measured, &plan)
    }

    /// The evaluation phase of the period, after the tick's outputs: the supervisor's
    /// checker stages and the tool's flanks ([`Planner::evaluate`]).
    pub fn evaluate(&mut self) {
        self.planner.evaluate();
    }
}
