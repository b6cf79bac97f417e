//! The robot around the board at pin level: the plant with the board's surroundings of
//! `sim/board-on-plant` ([`BoardOnPlant`]: the drivers' enable, the brakes' two coil
//! groups, the supply, nFAULT, the safety relay opened by the button or failed, the
//! switches and hard stops; [`Platform`]: the tool's weight as joint loads at the true
//! pose), driven by the outputs read off the pins ([`Outputs`]) and read back as the
//! board's input signals ([`Signals`]).
//!
//! * **Switches and stops**, where the firmware expects them
//!   (`control::runtime::reference_mechanics` around `Limits::reference()`, handed to
//!   [`Layout::reference`]): each leg's home switch is actuated (its NC contact open) at and
//!   below 143 mm, 1 mm below the shortest stroke; each link's hard stop is 85 deg below its
//!   central angle. Beyond what the firmware monitors (a joint more than 2 mm or 3 deg
//!   outside its guard range is a fault) sit the end stops it never reaches in operation:
//!   the legs' 1 mm below and above their monitored range, the links' 85 deg above the
//!   central angle. Each link has a limit switch actuated within 2 deg of its lower stop. A
//!   stop seizes the load side when it is driven into it (the motor runs through the
//!   backlash onto it and stalls, its current rising to the driver's limit) and frees it
//!   when the bridge drives it back out.
//! * **The safety chain**: the e-stop button opens the safety relay (unless its contacts are
//!   welded); the relay can also fail open without the button. Open, it removes the
//!   bridges' power (coasting) and the brake coils' power (braking), whatever the MCU
//!   drives.
//! * **The power stage**: the driver enable and brake pins reach the plant's bridges and
//!   brakes (with their engage and release times) through the relay; the supply; a driver
//!   that reports a fault of its own pulls the shared nFAULT low.
//! * **The tool**: 1.2 kg with its centre of mass 100 mm from o_p along x_p (the thesis's
//!   tool): its weight as joint loads, -J^-T s_e at the true pose of the load-side joints,
//!   refreshed every millisecond. The scenarios attach it once the robot is homed and
//!   parked: homing moves one joint at a time far from the others (a link 85 deg), where
//!   the joints' loads would need the platform's coupling, which this model lacks.
//!
//! * **The wiring** ([`MechanicsConfig::wiring`], `board_on_plant::Wiring`, straight unless
//!   a test miswires the robot: [`crate::miswiring`]): a motor's leads reversed (the
//!   current sense still reads the board's duty sign), an encoder's A and B swapped, two
//!   encoders' cables swapped, the counts per joint unit scaled (a gear ratio off), a
//!   normally open home switch, a brake's coil inverted; the pins see the counters, the
//!   currents and the switches as wired, the bridges and brakes act as wired.
//!
//! Not modelled: switch bounce and hysteresis; the joints' coupling through the platform
//! other than the tool's static loads (inertia of the platform, friction in the passive
//! joints).

use board_on_plant::{BoardOnPlant, Layout, Platform, ReferenceMechanics};

pub use board_on_plant::Wiring;
use kinematics_core::guards::Limits;
use kinematics_core::{Branch, Pose, RsprGeometry};
use plant::{Plant, PlantConfig, PlantError, NUM_JOINTS};

pub use board_on_plant::{AtStop, Tool};

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

/// Where the stops and switches are, and where the joints start. Joint units: m (legs),
/// rad (links).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanicsConfig {
    /// Where every joint starts (at rest).
    pub start_q: [f64; NUM_JOINTS],
    /// The joints' central configuration.
    pub central_q: [f64; NUM_JOINTS],
    /// The switches and the hard stops.
    pub layout: Layout,
    /// The tool, if carried.
    pub tool: Option<Tool>,
    /// How the motors, encoders, switches and brakes are wired to the board
    /// ([`Wiring::straight`]: as the pin map says).
    pub wiring: Wiring,
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
        let mech = control::runtime::reference_mechanics(&Limits::<f64>::reference());
        Ok(MechanicsConfig {
            start_q: central,
            central_q: central,
            layout: Layout::reference(&ReferenceMechanics {
                central_q: central,
                leg_switch_m: mech.leg_switch_m,
                link_stop_below_central_rad: mech.link_stop_below_central_rad,
                range: mech.range,
            }),
            tool,
            wiring: Wiring::straight(),
        })
    }
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

/// The board's surroundings on the plant, at pin level.
#[derive(Debug, Clone)]
pub struct Mechanics {
    board: BoardOnPlant,
    platform: Platform,
    cfg: MechanicsConfig,
    surroundings: Surroundings,
    /// The counters as wired, read after every step (the wiring's count scale accumulates
    /// over the reads: once per step).
    counts: [u16; NUM_JOINTS],
    /// Time, s.
    t_s: f64,
}

impl Mechanics {
    /// The shipped plant (`sim/plant/plant.toml`) at `cfg.start_q`, its brakes applied and
    /// holding, its bridges off.
    pub fn new(cfg: MechanicsConfig) -> Result<Self, MechanicsError> {
        let config = PlantConfig::shipped().map_err(|e| MechanicsError::Config(e.to_string()))?;
        let plant = Plant::new(&config).map_err(|e| MechanicsError::Config(e.to_string()))?;
        let mut board = BoardOnPlant::at_rest(plant, cfg.start_q)?.with_layout(&cfg.layout);
        board.wiring = cfg.wiring;
        let counts = board.read_counts();
        let mut platform =
            Platform::new(cfg.start_q, 0.0).map_err(|e| MechanicsError::Central(e.to_string()))?;
        platform.tool = cfg.tool;
        let mut m = Mechanics {
            board,
            platform,
            cfg,
            surroundings: Surroundings::default(),
            counts,
            t_s: 0.0,
        };
        m.refresh_loads()?;
        Ok(m)
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.board.plant
    }

    /// The configuration.
    pub fn config(&self) -> &MechanicsConfig {
        &self.cfg
    }

    /// Joints standing at a stop.
    pub fn at_stop(&self) -> [Option<AtStop>; NUM_JOINTS] {
        self.board.at_stop()
    }

    /// Plant steps each joint stood at a stop.
    pub fn steps_at_stop(&self) -> [u64; NUM_JOINTS] {
        self.board.steps_at_stop
    }

    /// The surroundings.
    pub fn surroundings(&self) -> &Surroundings {
        &self.surroundings
    }

    /// The tool's loads now, N and N m.
    pub fn loads(&self) -> [f64; NUM_JOINTS] {
        self.platform.loads()
    }

    /// Attaches the tool (`Some`) or takes it off (`None`); its loads apply at once.
    pub fn set_tool(&mut self, tool: Option<Tool>) -> Result<(), MechanicsError> {
        self.cfg.tool = tool;
        self.platform.tool = tool;
        self.refresh_loads()
    }

    /// Changes the surroundings: the supply and the drivers at once, the relay from the
    /// next step.
    pub fn set_surroundings(&mut self, s: Surroundings) -> Result<(), MechanicsError> {
        self.surroundings = s;
        self.board.plant.set_supply_voltage(s.supply_v)?;
        self.board.estop = s.estop_pressed;
        self.board.relay_welded = s.relay_welded;
        self.board.relay_stuck_open = s.relay_stuck_open;
        for (j, failed) in s.driver_failed.into_iter().enumerate() {
            self.board.set_driver_failed(j, failed)?;
        }
        Ok(())
    }

    /// The tool's weight as joint loads at the true pose (`board_on_plant::Platform`);
    /// kept as they were where the pose does not solve. Without the tool the loads are
    /// zero and the pose is not needed: no forward kinematics.
    pub fn refresh_loads(&mut self) -> Result<(), MechanicsError> {
        if self.platform.tool.is_some() {
            let q = self.board.plant.joint_positions();
            if self.platform.update(q, self.t_s).is_err() {
                return Ok(());
            }
        }
        self.platform.apply_loads(&mut self.board.plant)?;
        Ok(())
    }

    /// Advances the mechanics by `dt` under the MCU's `outputs` (held over the step).
    pub fn step(&mut self, outputs: &Outputs, dt: f64) -> Result<(), MechanicsError> {
        self.board.set_outputs(
            outputs.driver_enable,
            outputs.brakes_released,
            &outputs.signed_duty(),
        );
        self.board.step(dt)?;
        self.counts = self.board.read_counts();
        self.t_s += dt;
        Ok(())
    }

    /// The second position channel's readings now (`plant::PositionSensor`: 65536 counts
    /// over each potentiometer's travel, with its noise, offset and faults), joint order.
    pub fn position_counts(&self) -> [u16; NUM_JOINTS] {
        self.board.plant.position_sensor_counts()
    }

    /// Injects a fault of the plant into `joint` (an encoder that sticks or miscounts, a
    /// position sensor that sticks, ...), from now on.
    pub fn inject(&mut self, joint: usize, fault: plant::Fault) -> Result<(), MechanicsError> {
        self.board.plant.inject(joint, fault)?;
        self.counts = self.board.read_counts();
        Ok(())
    }

    /// What the board's inputs see now.
    pub fn signals(&self) -> Signals {
        Signals {
            encoder_counts: self.counts,
            currents_a: self.board.sensed_currents(),
            switches_actuated: self.board.switch_levels(),
            estop_pressed: self.surroundings.estop_pressed,
            relay_open: self.board.relay_open(),
            driver_fault: self.board.plant.driver_fault(),
            supply_v: self.board.plant.supply_voltage(),
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
        let l = cfg.layout;
        let leg_switch = l.switch_below[0].unwrap_or_default();
        assert!((leg_switch - 0.143).abs() < 1e-12);
        for j in 3..6 {
            let below = cfg.central_q[j] - l.stop_below[j].unwrap_or_default();
            assert!(
                (below.to_degrees() - 85.0).abs() < 1e-9,
                "joint {j}: {below}"
            );
        }
        assert!(l.stop_below[0].unwrap_or_default() < leg_switch);
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
        let lower = m.config().layout.stop_below[3].unwrap_or_default();
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

    /// The wiring reaches the pins: with every miswiring on some joint and every joint
    /// driven towards +q with the brakes released, the reversed motor's joint runs to -q
    /// and its current still reads the duty's sign, the reversed encoder counts down, the
    /// swapped counters read each other's encoders, the scaled one counts 1.1 times the
    /// plant's, the normally open switch reads actuated away from its point, and the
    /// inverted brake holds its joint.
    #[test]
    fn the_wiring_reaches_the_pins() -> Result<(), MechanicsError> {
        let mut cfg = MechanicsConfig::reference(None)?;
        cfg.wiring = crate::miswiring::parse(&[
            "motor-reversed=l1",
            "encoders-swapped=l2,theta2",
            "gear-scale=l3:1.1",
            "encoder-reversed=theta1",
            "brake-inverted=theta3",
            "switch-normally-open=l1",
        ])
        .map_err(|e| MechanicsError::Config(e.to_string()))?;
        let mut m = Mechanics::new(cfg)?;
        let (q0, plant0, pins0) = (
            m.plant().joint_positions(),
            m.plant().encoder_counts(),
            m.signals().encoder_counts,
        );
        // Away from its switch point (the leg's switch is at 143 mm, the joint at rest
        // well above): the normally open contact reads actuated.
        assert!(m.signals().switches_actuated[0]);
        let drive = outputs([0.3; 6], [true; 6], true, true);
        for _ in 0..2_000 {
            m.step(&drive, 1e-4)?;
        }
        let q = m.plant().joint_positions();
        let dq: Vec<f64> = q.iter().zip(q0).map(|(a, b)| a - b).collect();
        assert!(dq[0] < -1e-4, "l1 reversed: {dq:?}");
        assert!(
            dq[1] > 1e-4 && dq[2] > 1e-4 && dq[3] > 1e-3 && dq[4] > 1e-3,
            "{dq:?}"
        );
        assert!(dq[5].abs() < 1e-4, "theta3's brake holds: {dq:?}");
        let i = m.signals().currents_a;
        assert!(i[0] > 0.0, "l1's current reads the duty's sign: {i:?}");
        let (plant, pins) = (m.plant().encoder_counts(), m.signals().encoder_counts);
        let d = |a: [u16; 6], b: [u16; 6], k: usize| f64::from(a[k].wrapping_sub(b[k]) as i16);
        assert_eq!(
            d(pins, pins0, 1),
            d(plant, plant0, 4),
            "counter 1 reads theta2's"
        );
        assert_eq!(
            d(pins, pins0, 4),
            d(plant, plant0, 1),
            "counter 4 reads l2's"
        );
        assert!(d(pins, pins0, 3) < 0.0 && d(plant, plant0, 3) > 0.0);
        let scaled = d(pins, pins0, 2) / d(plant, plant0, 2);
        // Rounded to whole counts over hundreds of counts.
        assert!((scaled - 1.1).abs() < 0.01, "l3 scaled by {scaled}");
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
