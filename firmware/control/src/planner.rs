//! The planning half of a control tick: the setpoint supervisor
//! (`kinematics_core::supervisor`) and the lead-screw flanks of a known tool. It depends
//! only on the master's targets, never on the encoders, so a host may run it ahead of the
//! servo half on another core (see [`crate::Controller::into_parts`]).

use kinematics_core::statics::EffortMap;
use kinematics_core::supervisor::{Refusal, Supervisor, TickOutput};
use kinematics_core::{scalar, JointKind, Mechanism, Pose};
use servo::backlash::Direction;
use servo::NUM_JOINTS;

use crate::scalar::Scalar;

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

/// The planning half of a tick: the supervisor's setpoint and the lead-screw flanks of the
/// known tool. It depends only on the master's targets, never on the encoders, so a host
/// may run it ahead of the servo half on another core (see [`Controller::into_parts`]).
#[derive(Clone, Debug)]
pub struct Planner<S: Scalar, M: Mechanism<S> + Clone> {
    pub(crate) supervisor: Supervisor<S, M>,
    tool: Option<ToolLoad<S>>,
    /// With a tool: Jtildeᵀ factorised at the last period's setpoint. The flanks are
    /// updated in the evaluation phase every other period, the factorisation on one and the
    /// solve on the next, so that no period pays for both (about 1,100 and 700
    /// instructions on the Cortex-M4).
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
    /// A planner around a supervisor (holding at its start pose), with the tool `tool`.
    pub fn new(
        supervisor: Supervisor<S, M>,
        kinds: [JointKind; NUM_JOINTS],
        tool: Option<ToolLoad<S>>,
    ) -> Self {
        Planner {
            supervisor,
            tool,
            tool_map: None,
            kinds,
            flanks: [Direction::Unknown; NUM_JOINTS],
        }
    }

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

    /// One control period: the step ([`Planner::step`]), then the evaluation phase
    /// ([`Planner::evaluate`]).
    pub fn tick(&mut self) -> Plan<S> {
        let plan = self.step();
        self.evaluate();
        plan
    }

    /// The real-time step of a period: the supervisor's setpoint
    /// ([`Supervisor::step`]) and the tool's flanks as the evaluation phases before it
    /// found them.
    pub fn step(&mut self) -> Plan<S> {
        Plan {
            setpoint: self.supervisor.step(),
            flanks: self.flanks,
        }
    }

    /// The evaluation phase of a period, after its step's outputs are written: the
    /// supervisor's checker stages ([`Supervisor::evaluate`]) and the tool's flanks at
    /// the step's setpoint, which the next step carries.
    pub fn evaluate(&mut self) {
        self.supervisor.evaluate();
        // A known tool presses each lead screw against one flank: tell the backlash
        // compensation which (τ = J⁻ᵀ s_e at the setpoint; the motor pushes along τ), every
        // other period: Jtildeᵀ factorised on one, τ solved on the next (the setpoint has
        // moved by one tick, some 25 µm: nothing for a threshold on τ). Where τ cannot be
        // computed the flanks stay as they were.
        let Some(tool) = self.tool else { return };
        match self.tool_map.take() {
            None => self.tool_map = self.supervisor.jacobians().map(EffortMap::new),
            Some(map) => {
                let wrench = tool.wrench(self.supervisor.setpoint());
                if let Some(st) = map.forces(&wrench, S::one()) {
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
}
