//! The control tick.

use core::fmt;
use kinematics_core::guards::Limits;
use kinematics_core::statics::EffortMap;
use kinematics_core::supervisor::{
    Refusal, Supervisor, SupervisorConfig, SupervisorError, TickOutput,
};
use kinematics_core::{
    forward, scalar, Branch, FkConfig, FkError, FkTracker, JointKind, Joints, Mechanism, Pose,
    Real, Tracked,
};
use num_traits::Float;
use servo::backlash::Direction;
use servo::config::{ConfigError, ServoConfig};
use servo::encoder::{EncoderConfig, Encoders};
use servo::hal::{MotorOutputs, QuadratureCounter};
use servo::joint_servo::{JointServo, ServoOutput};
use servo::NUM_JOINTS;

/// The scalar of the control application: a nalgebra real that is also a `num_traits`
/// float (in practice `f32` on the MCU, `f64` on the host).
pub trait Scalar: Real + Float {}
impl<S: Real + Float> Scalar for S {}

/// Everything the controller needs. `Default` gives the reference robot's values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig<S: Scalar> {
    /// Control rate, Hz (default 1000; 100 .. 10 000).
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

/// A tool fixed to the platform: a mass at a point given in the platform frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolLoad<S: Scalar> {
    /// Mass, kg (thesis chapter 4: 1.2 kg).
    pub mass_kg: S,
    /// Centre of mass from o_p in {p}, m (thesis: a 0.1 m lever).
    pub com_p_m: [S; 3],
    /// Gravity, m/s² (along -z0).
    pub gravity_m_s2: S,
    /// Holding efforts above which the load, not the motion, chooses the flank:
    /// [prismatic N, revolute N m] (default 3 N, 0.05 N m: above the joints' friction).
    pub flank_threshold: [S; 2],
}

impl<S: Scalar> ToolLoad<S> {
    /// The thesis's tool: 1.2 kg on a 0.1 m lever along x_p.
    pub fn thesis() -> Self {
        ToolLoad {
            mass_kg: scalar::lit(1.2),
            com_p_m: [scalar::lit(0.1), S::zero(), S::zero()],
            gravity_m_s2: scalar::lit(9.81),
            flank_threshold: [scalar::lit(3.0), scalar::lit(0.05)],
        }
    }

    /// The wrench the platform exerts on the tool at `pose`: +m g along z0 and its moment
    /// about o_p (Eq. 7.11-7.13 convention: what the platform exerts on its environment).
    pub fn wrench(&self, pose: &Pose<S>) -> kinematics_core::Wrench<S> {
        // f = [0, 0, m g]; c = R com_p; moment c × f = [c_y f_z, -c_x f_z, 0] (written
        // out: it runs every other control tick with a tool).
        let fz = self.mass_kg * self.gravity_m_s2;
        let r = pose.r.matrix();
        let [x, y, z] = self.com_p_m;
        let cx = r.m11 * x + r.m12 * y + r.m13 * z;
        let cy = r.m21 * x + r.m22 * y + r.m23 * z;
        kinematics_core::Wrench::new(S::zero(), S::zero(), fz, cy * fz, -(cx * fz), S::zero())
    }
}

impl<S: Scalar> Default for ControllerConfig<S> {
    fn default() -> Self {
        ControllerConfig {
            rate_hz: scalar::lit(1000.0),
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
    /// The start joints do not give a pose.
    StartPose(FkError),
    /// The supervisor refused its settings or the start pose.
    Supervisor(SupervisorError<S>),
}

impl<S: Scalar> fmt::Display for ControllerError<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControllerError::Rate => f.write_str("rate_hz must be within 100 .. 10000 Hz"),
            ControllerError::Servo(e) => write!(f, "{e}"),
            ControllerError::StartPose(e) => write!(f, "start pose: {e}"),
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

/// What one tick did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickReport<S: Scalar> {
    /// The supervisor's setpoint (pose, joints, feed-forward, mode, warning, stop).
    pub setpoint: TickOutput<S>,
    /// Joint positions from the encoders.
    pub measured_q: [S; NUM_JOINTS],
    /// Measured pose from forward kinematics (the last good one if this tick's failed).
    pub measured_pose: Pose<S>,
    /// Newton iterations of this tick's forward kinematics, or its failure.
    pub fk: Result<u32, FkError>,
    /// Duties, saturation and the latched tracking fault.
    pub servo: ServoOutput<S>,
}

/// Counts kept by the controller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ControllerCounters {
    pub ticks: u64,
    pub fk_failures: u32,
    pub fk_max_iterations: u32,
}

/// The planning half of a tick: the supervisor's setpoint and the lead-screw flanks of the
/// known tool. It depends only on the master's targets, never on the encoders, so a host
/// may run it ahead of the servo half on another core (see [`Controller::into_parts`]).
#[derive(Clone, Debug)]
pub struct Planner<S: Scalar, M: Mechanism<S> + Clone> {
    supervisor: Supervisor<S, M>,
    tool: Option<ToolLoad<S>>,
    /// With a tool: Jtildeᵀ factorised at the last tick's setpoint. The flanks are updated
    /// every other tick, the factorisation on one and the solve on the next, so that no
    /// tick pays for both (about 1,500 and 700 instructions on the Cortex-M4).
    tool_map: Option<EffortMap<S>>,
    kinds: [JointKind; NUM_JOINTS],
    flanks: [Direction; NUM_JOINTS],
}

/// What the planner hands to the servo half for one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan<S: Scalar> {
    /// The supervisor's setpoint.
    pub setpoint: TickOutput<S>,
    /// The flank each lead screw rests on under the tool's weight (all unknown without a
    /// tool).
    pub flanks: [Direction; NUM_JOINTS],
}

impl<S: Scalar, M: Mechanism<S> + Clone> Planner<S, M> {
    /// The supervisor (counters, last refusal, latched stop).
    pub fn supervisor(&self) -> &Supervisor<S, M> {
        &self.supervisor
    }

    /// Declares the tool now on the platform (None: none).
    pub fn set_tool(&mut self, tool: Option<ToolLoad<S>>) {
        self.tool = tool;
        self.tool_map = None;
        if tool.is_none() {
            self.flanks = [Direction::Unknown; NUM_JOINTS];
        }
    }

    /// Hands a master target to the supervisor.
    pub fn submit(&mut self, pose: &Pose<S>, stamp_us: u64, now_us: u64) -> Result<(), Refusal<S>> {
        self.supervisor.submit(pose, stamp_us, now_us)
    }

    /// Clears a latched supervisor stop.
    pub fn clear_stop(&mut self) -> bool {
        self.supervisor.clear().is_ok()
    }

    /// Stops the robot as soon as the limits allow and holds it there
    /// ([`Supervisor::brake`]).
    pub fn hold(&mut self) {
        self.supervisor.brake();
    }

    /// The setpoint of this tick and the tool's flanks at it.
    pub fn tick(&mut self) -> Plan<S> {
        self.tick_with_budget(true)
    }

    /// [`Planner::tick`] on a budget per tick: the tool's flanks (optional work, the
    /// supervisor never waits for them) are left for the next tick when `spare` is false,
    /// e.g. on a tick where the forward kinematics factorised its Jacobian
    /// ([`Sensed::fk_factorised`]), so that the two never add up in one tick.
    pub fn tick_with_budget(&mut self, spare: bool) -> Plan<S> {
        let setpoint = self.supervisor.tick();
        // A known tool presses each lead screw against one flank: tell the backlash
        // compensation which (τ = J⁻ᵀ s_e at the setpoint; the motor pushes along τ), every
        // other tick: Jtildeᵀ factorised on one, τ solved on the next (the setpoint has
        // moved by one tick, some 25 µm: nothing for a threshold on τ). Where τ cannot be
        // computed the flanks stay as they were.
        if let (Some(tool), true) = (self.tool, spare) {
            match self.tool_map.take() {
                None => self.tool_map = self.supervisor.jacobians().map(EffortMap::new),
                Some(map) => {
                    if let Some(st) = map.forces(&tool.wrench(&setpoint.pose), S::one()) {
                        for ((f, tau), k) in self
                            .flanks
                            .iter_mut()
                            .zip(st.tau.iter())
                            .zip(self.kinds.iter())
                        {
                            let threshold = match k {
                                JointKind::Linear => tool.flank_threshold[0],
                                JointKind::Angular => tool.flank_threshold[1],
                            };
                            *f = if *tau > threshold {
                                Direction::Positive
                            } else if *tau < -threshold {
                                Direction::Negative
                            } else {
                                Direction::Unknown
                            };
                        }
                    }
                }
            }
        }
        Plan {
            setpoint,
            flanks: self.flanks,
        }
    }
}

/// What the servo half read at the start of a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensed<S: Scalar> {
    /// Joint positions from the encoders.
    pub q: [S; NUM_JOINTS],
    /// Newton iterations of the forward kinematics, or its failure.
    pub fk: Result<u32, FkError>,
    /// The forward kinematics factorised its Jacobian on this tick (its heavy ticks).
    pub fk_factorised: bool,
}

/// The servo half of a tick: encoders, measured pose, six joint servos, outputs.
#[derive(Clone, Debug)]
pub struct Drive<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    fk_cfg: FkConfig<S>,
    dt: S,
    servo: JointServo<S>,
    encoders: Encoders<S>,
    /// The measured pose: forward kinematics tracked from tick to tick (one Newton step
    /// per tick; nothing while the encoders stand still).
    fk: FkTracker<S>,
    counters: ControllerCounters,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Drive<S, M> {
    /// The controller's counters.
    pub fn counters(&self) -> &ControllerCounters {
        &self.counters
    }

    /// The measured pose (the last good forward kinematics).
    pub fn measured_pose(&self) -> &Pose<S> {
        self.fk.pose()
    }

    /// What the forward-kinematics tracker did so far (steps, refreshes, full solves).
    pub fn fk_counts(&self) -> &kinematics_core::TrackerCounts {
        self.fk.counts()
    }

    /// Resets the servo after a tracking fault, holding the measured joints.
    pub fn reset_servo(&mut self) {
        let q = self.encoders.positions();
        self.servo.reset(&q);
    }

    /// Reads the encoders and tracks the measured pose: the start of a tick, so that the
    /// sampling instant does not move with the planner's work.
    pub fn sense<H: QuadratureCounter>(&mut self, hw: &mut H) -> Sensed<S> {
        self.counters.ticks += 1;
        let q = self.encoders.read(hw);
        // Forward kinematics tracked from the last measured pose (FkTracker: nothing to do
        // while the encoders stand still, one Newton step while they move).
        let fk = match self
            .fk
            .update(&self.robot, &Joints::from_row_slice(&q), &self.fk_cfg)
        {
            Ok(t) => {
                let steps = match t {
                    Tracked::Unchanged => 0,
                    Tracked::Stepped { steps } => steps,
                    Tracked::Solved { iterations } => iterations,
                };
                self.counters.fk_max_iterations = self.counters.fk_max_iterations.max(steps);
                Ok(steps)
            }
            Err(e) => {
                self.counters.fk_failures += 1;
                Err(e)
            }
        };
        Sensed {
            q,
            fk,
            fk_factorised: self.fk.factorised(),
        }
    }

    /// Runs the six joint servos towards the plan and drives the outputs (all off on a
    /// tracking fault).
    pub fn act<H: MotorOutputs<S>>(
        &mut self,
        hw: &mut H,
        sensed: &Sensed<S>,
        plan: &Plan<S>,
    ) -> TickReport<S> {
        let q_meas = sensed.q;
        // Angles from the supervisor are wrapped to (-π, π]; unwrap them next to the
        // (continuous) encoder readings.
        let mut sp = to_array(&plan.setpoint.q);
        for ((s, m), k) in sp
            .iter_mut()
            .zip(q_meas.iter())
            .zip(self.robot.joint_kinds().iter())
        {
            if *k == JointKind::Angular {
                *s = *m + scalar::wrap_angle(*s - *m);
            }
        }
        self.servo.set_preloads(&plan.flanks);
        let spd = to_array(&plan.setpoint.qdot);
        let out = self.servo.update(&sp, &spd, &q_meas, self.dt);
        if out.fault.is_some() {
            hw.disable();
        } else {
            hw.set_duties(&out.duty);
        }
        TickReport {
            setpoint: plan.setpoint,
            measured_q: q_meas,
            measured_pose: *self.fk.pose(),
            fk: sensed.fk,
            servo: out,
        }
    }
}

/// The control application: each tick, the [`Drive`] senses, the [`Planner`] plans and the
/// [`Drive`] acts.
#[derive(Clone, Debug)]
pub struct Controller<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: ControllerConfig<S>,
    planner: Planner<S, M>,
    drive: Drive<S, M>,
}

fn to_array<S: Scalar>(q: &Joints<S>) -> [S; NUM_JOINTS] {
    [q.x, q.y, q.z, q.w, q.a, q.b]
}

impl<S: Scalar, M: Mechanism<S> + Clone> Controller<S, M> {
    /// A controller holding the robot where it is: the encoders' raw counters `raw` read
    /// the joint positions `start_q` (the homing result).
    pub fn new(
        robot: M,
        mut cfg: ControllerConfig<S>,
        raw: [u16; NUM_JOINTS],
        start_q: [S; NUM_JOINTS],
    ) -> Result<Self, ControllerError<S>> {
        let lo: S = scalar::lit(100.0);
        let hi: S = scalar::lit(10_000.0);
        if !(cfg.rate_hz >= lo && cfg.rate_hz <= hi) {
            return Err(ControllerError::Rate);
        }
        let dt = S::one() / cfg.rate_hz;
        cfg.supervisor.dt = dt;
        let mut encoders = Encoders::new(&cfg.encoders).map_err(ControllerError::Servo)?;
        encoders.update(&raw);
        encoders.set_positions(&start_q);
        let q0 = Joints::from_row_slice(&start_q);
        let fk = FkTracker::new(&robot, &q0, cfg.branch, &Pose::central(robot.hc()), &cfg.fk)
            .map_err(ControllerError::StartPose)?;
        let start_pose = *fk.pose();
        let supervisor = Supervisor::new(
            robot.clone(),
            cfg.branch,
            cfg.limits,
            cfg.supervisor,
            &start_pose,
        )
        .map_err(ControllerError::Supervisor)?;
        let mut servo = JointServo::new(&cfg.servo).map_err(ControllerError::Servo)?;
        servo.reset(&start_q);
        Ok(Controller {
            planner: Planner {
                supervisor,
                tool: cfg.tool,
                tool_map: None,
                kinds: robot.joint_kinds(),
                flanks: [Direction::Unknown; NUM_JOINTS],
            },
            drive: Drive {
                robot: robot.clone(),
                fk_cfg: cfg.fk,
                dt,
                servo,
                encoders,
                fk,
                counters: ControllerCounters::default(),
            },
            robot,
            cfg,
        })
    }

    /// The two halves, e.g. to run the planner ahead of the servo on another core of a
    /// host: ticking them as [`Controller::tick`] does gives the same results.
    pub fn into_parts(self) -> (Planner<S, M>, Drive<S, M>) {
        (self.planner, self.drive)
    }

    /// The planner.
    pub fn planner(&self) -> &Planner<S, M> {
        &self.planner
    }

    /// The supervisor (counters, last refusal, latched stop).
    pub fn supervisor(&self) -> &Supervisor<S, M> {
        &self.planner.supervisor
    }
    /// The controller's counters.
    pub fn counters(&self) -> &ControllerCounters {
        &self.drive.counters
    }
    /// What the forward-kinematics tracker did so far.
    pub fn fk_counts(&self) -> &kinematics_core::TrackerCounts {
        self.drive.fk_counts()
    }
    /// The control period, s.
    pub fn dt(&self) -> S {
        self.drive.dt
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

    /// Resets the servo after a tracking fault, holding the measured joints.
    pub fn reset_servo(&mut self) {
        self.drive.reset_servo();
    }

    /// One control tick: read the encoders and estimate the pose, advance the supervisor,
    /// run the six PIDs and drive the outputs (all off on a tracking fault).
    pub fn tick<H: QuadratureCounter + MotorOutputs<S>>(&mut self, hw: &mut H) -> TickReport<S> {
        let sensed = self.drive.sense(hw);
        // Optional work of the planner (the tool's flanks) off the heavy FK ticks.
        let plan = self.planner.tick_with_budget(!sensed.fk_factorised);
        self.drive.act(hw, &sensed, &plan)
    }
}
