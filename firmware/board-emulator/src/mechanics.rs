//! The robot around the board: the host's plant model (`plant`: motors, drivers with their
//! current regulation, bridges, spring-applied brakes, gearing, lead screws, backlash,
//! friction, encoders, the supply) with what it leaves to its user: where the hard stops and
//! the switches are, the safety chain, and the tool's weight.
//!
//! * **Switches and stops**, where the firmware expects them
//!   (`control::runtime::reference_mechanics` around `Limits::reference()`): each leg's home
//!   switch is actuated (its NC contact open) at and below 143 mm, 1 mm below the shortest
//!   stroke; each link's hard stop is 85 deg below its central angle. Beyond what the
//!   firmware monitors (a joint more than 2 mm or 3 deg outside its guard range is a fault)
//!   sit the end stops it never reaches in operation: the legs' 1 mm below and above their
//!   monitored range, the links' 85 deg above the central angle. Each link has a limit
//!   switch actuated within 2 deg of its lower stop. A stop seizes the load side when it is
//!   driven into it (`plant::Fault::LoadSeized`: the motor runs through the backlash onto it
//!   and stalls, its current rising to the driver's limit) and frees it when the bridge drives
//!   it back out, as `firmware/control/tests/common` does.
//! * **The safety chain**: the e-stop button opens the safety relay (unless its contacts are
//!   welded); the relay can also fail open without the button (a cut wire, a failed coil).
//!   Open, it removes the bridges' power (coasting) and the brake coils' power (braking),
//!   whatever the MCU drives.
//! * **The power stage**: the MCU's driver enable and brake outputs reach the plant's bridges
//!   (`Plant::set_bridges_enabled`: off = coast) and brakes (`Plant::set_brakes_released`,
//!   with their engage and release times) through the relay; the supply
//!   (`Plant::set_supply_voltage`); a driver that reports a fault of its own
//!   (`plant::Fault::DriverFailed`) pulls the shared nFAULT low (`Plant::driver_fault`).
//! * **The tool**: 1.2 kg with its centre of mass 100 mm from o_p along x_p (the thesis's
//!   tool; `firmware/control/tests/common` `tool_loads`): its weight as joint loads,
//!   -J^-T s_e at the true pose of the load-side joints, refreshed every millisecond. The
//!   scenarios attach it once the robot is homed and parked: homing moves one joint at a
//!   time far from the others (a link 85 deg), where the joints' loads would need the
//!   platform's coupling, which this model lacks.
//!
//! Not modelled: switch bounce and hysteresis; the joints' coupling through the platform
//! other than the tool's static loads (inertia of the platform, friction in the passive
//! joints).

use kinematics_core::guards::Limits;
use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::{forward, jacobian, Branch, FkConfig, Pose, RsprGeometry, Wrench};
use nalgebra::{Vector3, Vector6};
use plant::{Fault, Plant, PlantConfig, PlantError, NUM_JOINTS};

use crate::board::{Outputs, Signals};

/// Why the mechanics could not be built or stepped.
#[derive(Debug, thiserror::Error)]
pub enum MechanicsError {
    /// The plant's configuration.
    #[error("plant configuration: {0}")]
    Config(String),
    /// The plant refused a command.
    #[error("plant: {0}")]
    Plant(String),
    /// The reference robot's central configuration.
    #[error("central configuration of the reference robot: {0}")]
    Central(String),
}

impl From<PlantError> for MechanicsError {
    fn from(e: PlantError) -> Self {
        MechanicsError::Plant(e.to_string())
    }
}

/// The tool the platform carries: mass, kg, and its centre of mass from o_p in {p}, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tool {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass in the platform frame, m.
    pub lever_m: [f64; 3],
}

impl Tool {
    /// The thesis's tool: 1.2 kg on a 0.1 m lever along x_p.
    pub const THESIS: Tool = Tool {
        mass_kg: 1.2,
        lever_m: [0.100, 0.0, 0.0],
    };
}

/// Gravity, m/s².
pub const GRAVITY_M_S2: f64 = 9.81;

/// Where the stops and switches are, and where the joints start. Joint units: m (legs),
/// rad (links).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanicsConfig {
    /// Where every joint starts (at rest).
    pub start_q: [f64; NUM_JOINTS],
    /// The joints' central configuration.
    pub central_q: [f64; NUM_JOINTS],
    /// A leg's home switch is actuated at and below this length.
    pub leg_switch_m: f64,
    /// Each joint's end stops (lower, upper).
    pub stops: [(f64, f64); NUM_JOINTS],
    /// A link's limit switch is actuated this close to its lower stop.
    pub link_switch_above_stop_rad: f64,
    /// The tool, if carried.
    pub tool: Option<Tool>,
}

/// The reference robot's central configuration (outer branch), joint order, m and rad.
pub fn central_q() -> Result<[f64; NUM_JOINTS], MechanicsError> {
    let g = RsprGeometry::<f64>::reference();
    let solution = kinematics_core::inverse(&g, &Pose::central(g.hc), Branch::OUTER)
        .map_err(|e| MechanicsError::Central(format!("{e:?}")))?;
    let q = solution.q();
    Ok(std::array::from_fn(|j| q[j]))
}

impl MechanicsConfig {
    /// The reference robot resting at its central configuration, with the switches and
    /// stops where the firmware's `reference_mechanics` puts them, carrying `tool`.
    pub fn reference(tool: Option<Tool>) -> Result<Self, MechanicsError> {
        let central = central_q()?;
        let mech = control::runtime::reference_mechanics(&central, &Limits::<f64>::reference());
        let stop = mech.link_stop_below_central_rad;
        let stops = std::array::from_fn(|j| {
            let [lo, hi] = mech.range.get(j).copied().unwrap_or_default();
            if j < 3 {
                (lo - 0.001, hi + 0.001)
            } else {
                let c = central.get(j).copied().unwrap_or_default();
                (c - stop, c + stop)
            }
        });
        Ok(MechanicsConfig {
            start_q: central,
            central_q: central,
            leg_switch_m: mech.leg_switch_m,
            stops,
            link_switch_above_stop_rad: 2f64.to_radians(),
            tool,
        })
    }

    /// Whether joint `j`'s switch is actuated at `q`.
    pub fn switch_actuated(&self, j: usize, q: f64) -> bool {
        if j < 3 {
            q <= self.leg_switch_m
        } else {
            let (lower, _) = self.stops.get(j).copied().unwrap_or_default();
            q <= lower + self.link_switch_above_stop_rad
        }
    }
}

/// Which stop a joint stands at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AtStop {
    /// The lower (-q) stop.
    Lower,
    /// The upper (+q) stop.
    Upper,
}

/// What the world does besides the joints (the scenarios set these).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surroundings {
    /// The e-stop button pressed (its chain open).
    pub estop_pressed: bool,
    /// The safety relay's contacts welded shut: it does not open with the button.
    pub relay_welded: bool,
    /// The safety relay open without the button (a failed coil, a cut wire).
    pub relay_stuck_open: bool,
    /// The bridges' supply, V.
    pub supply_v: f64,
    /// Joints whose driver reports a fault of its own and keeps its bridge off.
    pub driver_failed: [bool; NUM_JOINTS],
}

impl Default for Surroundings {
    fn default() -> Self {
        Surroundings {
            estop_pressed: false,
            relay_welded: false,
            relay_stuck_open: false,
            supply_v: 24.0,
            driver_failed: [false; NUM_JOINTS],
        }
    }
}

impl Surroundings {
    /// The safety relay is open.
    pub fn relay_open(&self) -> bool {
        (self.estop_pressed && !self.relay_welded) || self.relay_stuck_open
    }
}

/// The plant with its stops, switches, safety chain and tool.
#[derive(Debug, Clone)]
pub struct Mechanics {
    plant: Plant,
    cfg: MechanicsConfig,
    at_stop: [Option<AtStop>; NUM_JOINTS],
    /// The faults injected now per joint: (seized at a stop, driver failed).
    faults: [(bool, bool); NUM_JOINTS],
    surroundings: Surroundings,
    /// The last pose of the tool's mapping (the FK's start).
    pose: Pose<f64>,
    /// The tool's loads now, N and N m (+q).
    loads: [f64; NUM_JOINTS],
    /// Steps where a joint stood at a stop.
    pub steps_at_stop: [u64; NUM_JOINTS],
}

impl Mechanics {
    /// The shipped plant (`sim/plant/plant.toml`) at `cfg.start_q`, its brakes applied
    /// and its bridges off.
    pub fn new(cfg: MechanicsConfig) -> Result<Self, MechanicsError> {
        let config = PlantConfig::shipped().map_err(|e| MechanicsError::Config(e.to_string()))?;
        let mut plant = Plant::new(&config).map_err(|e| MechanicsError::Config(e.to_string()))?;
        // At power-on the spring-applied brakes hold already: applied and engaged (their
        // engage time run out unloaded), then the joints placed.
        plant.set_bridges_enabled(false);
        plant.set_brakes_released([false; NUM_JOINTS]);
        plant.set_joint_positions(cfg.start_q)?;
        plant.advance(0.05, 1e-4)?;
        plant.set_joint_positions(cfg.start_q)?;
        let g = RsprGeometry::<f64>::reference();
        let mut m = Mechanics {
            plant,
            cfg,
            at_stop: [None; NUM_JOINTS],
            faults: [(false, false); NUM_JOINTS],
            surroundings: Surroundings::default(),
            pose: Pose::central(g.hc),
            loads: [0.0; NUM_JOINTS],
            steps_at_stop: [0; NUM_JOINTS],
        };
        m.refresh_loads()?;
        Ok(m)
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The configuration.
    pub fn config(&self) -> &MechanicsConfig {
        &self.cfg
    }

    /// Joints standing at a stop.
    pub fn at_stop(&self) -> [Option<AtStop>; NUM_JOINTS] {
        self.at_stop
    }

    /// The surroundings.
    pub fn surroundings(&self) -> &Surroundings {
        &self.surroundings
    }

    /// The tool's loads now, N and N m.
    pub fn loads(&self) -> [f64; NUM_JOINTS] {
        self.loads
    }

    /// The true platform pose (forward kinematics of the load-side joints), when it solves.
    pub fn true_pose(&self) -> Option<Pose<f64>> {
        let g = RsprGeometry::<f64>::reference();
        let q = Vector6::from_row_slice(&self.plant.joint_positions());
        forward(&g, &q, Branch::OUTER, &self.pose, &FkConfig::default())
            .ok()
            .map(|s| s.pose)
    }

    /// Attaches the tool (`Some`) or takes it off (`None`); its loads apply at once.
    pub fn set_tool(&mut self, tool: Option<Tool>) -> Result<(), MechanicsError> {
        self.cfg.tool = tool;
        if tool.is_none() {
            self.loads = [0.0; NUM_JOINTS];
            self.plant.set_external_load(self.loads)?;
        }
        self.refresh_loads()
    }

    /// Changes the surroundings (the supply at once, the rest at the next step).
    pub fn set_surroundings(&mut self, s: Surroundings) -> Result<(), MechanicsError> {
        self.surroundings = s;
        self.plant.set_supply_voltage(s.supply_v)?;
        Ok(())
    }

    /// The tool's weight as joint loads at the true pose: -J^-T s_e, s_e = [m g z0; c x m g z0]
    /// (CONVENTIONS.md, "Forces"). Kept as it was where the pose does not solve.
    pub fn refresh_loads(&mut self) -> Result<(), MechanicsError> {
        let Some(tool) = self.cfg.tool else {
            return Ok(());
        };
        let g = RsprGeometry::<f64>::reference();
        let q = Vector6::from_row_slice(&self.plant.joint_positions());
        let Ok(fk) = forward(&g, &q, Branch::OUTER, &self.pose, &FkConfig::default()) else {
            return Ok(());
        };
        self.pose = fk.pose;
        let f = Vector3::new(0.0, 0.0, tool.mass_kg * GRAVITY_M_S2);
        let c = fk.pose.r * Vector3::from(tool.lever_m);
        let m = c.cross(&f);
        let se = Wrench::from_row_slice(&[f.x, f.y, f.z, m.x, m.y, m.z]);
        let Ok(jac) = jacobian(&g, &fk.solution) else {
            return Ok(());
        };
        let Ok(st) = forces_with_inv_cond(&jac, &se, 1.0, 0.0) else {
            return Ok(());
        };
        self.loads = std::array::from_fn(|j| -st.tau[j]);
        self.plant.set_external_load(self.loads)?;
        Ok(())
    }

    /// Advances the mechanics by `dt` under the MCU's `outputs` (held over the step).
    pub fn step(&mut self, outputs: &Outputs, dt: f64) -> Result<(), MechanicsError> {
        let powered = !self.surroundings.relay_open();
        self.plant
            .set_bridges_enabled(outputs.driver_enable && powered);
        let [legs, links] = outputs.brakes_released;
        self.plant.set_brakes_released(std::array::from_fn(|j| {
            powered && if j < 3 { legs } else { links }
        }));
        let duty = outputs.signed_duty();
        for (j, stop) in self.at_stop.iter_mut().enumerate() {
            let d = duty.get(j).copied().unwrap_or_default();
            let away = match stop {
                Some(AtStop::Lower) => d > 0.0,
                Some(AtStop::Upper) => d < 0.0,
                None => false,
            };
            if away {
                *stop = None;
            }
        }
        for j in 0..NUM_JOINTS {
            let seized = self.at_stop.get(j).copied().flatten().is_some();
            let failed = self
                .surroundings
                .driver_failed
                .get(j)
                .copied()
                .unwrap_or_default();
            self.set_faults(j, seized, failed)?;
        }
        self.plant.set_duty(duty)?;
        self.plant.step(dt)?;
        let q = self.plant.joint_positions();
        for j in 0..NUM_JOINTS {
            let (lower, upper) = self.cfg.stops.get(j).copied().unwrap_or_default();
            let qj = q.get(j).copied().unwrap_or_default();
            let d = duty.get(j).copied().unwrap_or_default();
            if let Some(stop) = self.at_stop.get_mut(j) {
                if stop.is_none() {
                    if qj <= lower && d <= 0.0 {
                        *stop = Some(AtStop::Lower);
                    } else if qj >= upper && d >= 0.0 {
                        *stop = Some(AtStop::Upper);
                    }
                }
                if stop.is_some() {
                    if let Some(n) = self.steps_at_stop.get_mut(j) {
                        *n += 1;
                    }
                }
            }
        }
        Ok(())
    }

    fn set_faults(&mut self, j: usize, seized: bool, failed: bool) -> Result<(), PlantError> {
        let Some(now) = self.faults.get_mut(j) else {
            return Ok(());
        };
        if *now == (seized, failed) {
            return Ok(());
        }
        *now = (seized, failed);
        self.plant.clear_faults(j)?;
        if seized {
            self.plant.inject(j, Fault::LoadSeized)?;
        }
        if failed {
            self.plant.inject(j, Fault::DriverFailed)?;
        }
        Ok(())
    }

    /// What the board's inputs see now.
    pub fn signals(&self) -> Signals {
        let q = self.plant.joint_positions();
        Signals {
            encoder_counts: self.plant.encoder_counts(),
            currents_a: self.plant.currents(),
            switches_actuated: std::array::from_fn(|j| {
                self.cfg
                    .switch_actuated(j, q.get(j).copied().unwrap_or_default())
            }),
            estop_pressed: self.surroundings.estop_pressed,
            relay_open: self.surroundings.relay_open(),
            driver_fault: self.plant.driver_fault(),
            supply_v: self.plant.supply_voltage(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outputs(duty: [f64; 6], dir: [bool; 6], enable: bool, brakes: bool) -> Outputs {
        Outputs {
            duty,
            dir_positive: dir,
            driver_enable: enable,
            brakes_released: [brakes; 2],
            led: false,
        }
    }

    fn mechanics(tool: Option<Tool>) -> Result<Mechanics, MechanicsError> {
        Mechanics::new(MechanicsConfig::reference(tool)?)
    }

    /// The switches and stops are where the firmware's reference mechanics puts them: leg
    /// switches at 143 mm, link stops 85 deg below the central angles.
    #[test]
    fn switches_and_stops_where_the_firmware_expects_them() -> Result<(), MechanicsError> {
        let cfg = MechanicsConfig::reference(None)?;
        assert!((cfg.leg_switch_m - 0.143).abs() < 1e-12);
        for j in 3..6 {
            let below = cfg.central_q[j] - cfg.stops[j].0;
            assert!(
                (below.to_degrees() - 85.0).abs() < 1e-9,
                "joint {j}: {below}"
            );
        }
        assert!(cfg.stops[0].0 < cfg.leg_switch_m);
        Ok(())
    }

    /// A link driven towards -q stops at its stop (within one step's travel) with its
    /// current at the driver's limit and its limit switch actuated; driven back it leaves.
    #[test]
    fn a_link_stalls_at_its_hard_stop_and_leaves_it() -> Result<(), MechanicsError> {
        let mut m = mechanics(None)?;
        let mut d = [0.0; 6];
        d[3] = 0.3;
        let toward = outputs(d, [true, true, true, false, true, true], true, true);
        for _ in 0..80_000 {
            m.step(&toward, 1e-4)?;
        }
        let (lower, _) = m.config().stops[3];
        let q = m.plant().joint_positions()[3];
        assert_eq!(m.at_stop()[3], Some(AtStop::Lower));
        assert!((q - lower).abs() < 1e-3, "q {q} stop {lower}");
        assert!(m.plant().currents()[3] < -0.3, "{:?}", m.plant().currents());
        assert!(m.signals().switches_actuated[3]);
        let away = outputs(d, [true; 6], true, true);
        for _ in 0..2_000 {
            m.step(&away, 1e-4)?;
        }
        assert_eq!(m.at_stop()[3], None);
        assert!(m.plant().joint_positions()[3] > lower + 1e-3);
        Ok(())
    }

    /// Unpowered brakes hold against the tool's weight (the load side moves within the
    /// backlash only: half of the legs' 0.12 mm, the links' 20 arc-seconds); the relay open
    /// takes the bridges' power whatever the enable says.
    #[test]
    fn brakes_hold_the_tool_and_the_relay_cuts_the_bridges() -> Result<(), MechanicsError> {
        let mut m = mechanics(Some(Tool::THESIS))?;
        assert!(m.loads().iter().any(|l| l.abs() > 1.0), "{:?}", m.loads());
        let q0 = m.plant().joint_positions();
        for _ in 0..1_000 {
            m.step(&outputs([0.0; 6], [true; 6], false, false), 1e-4)?;
        }
        let q = m.plant().joint_positions();
        let moved: Vec<f64> = q.iter().zip(q0).map(|(a, b)| (a - b).abs()).collect();
        assert!(moved.iter().take(3).all(|d| *d <= 0.061e-3), "{moved:?}");
        assert!(
            moved
                .iter()
                .skip(3)
                .all(|d| *d <= 10.1f64 / 3600.0 * 1f64.to_radians()),
            "{moved:?}"
        );
        let s = Surroundings {
            estop_pressed: true,
            ..Surroundings::default()
        };
        m.set_surroundings(s)?;
        m.step(&outputs([0.5; 6], [true; 6], true, true), 1e-4)?;
        assert_eq!(m.plant().bridges_on(), [false; 6]);
        assert!(m.signals().relay_open);
        Ok(())
    }

    /// A driver that fails pulls nFAULT low.
    #[test]
    fn a_failed_driver_pulls_nfault_low() -> Result<(), MechanicsError> {
        let mut m = mechanics(None)?;
        let mut s = Surroundings::default();
        s.driver_failed[2] = true;
        m.set_surroundings(s)?;
        m.step(&outputs([0.0; 6], [true; 6], true, true), 1e-4)?;
        assert!(m.signals().driver_fault);
        Ok(())
    }
}
