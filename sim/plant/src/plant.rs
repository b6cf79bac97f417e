//! The six joints together: the interface the host simulator drives.

use crate::backlash::Backlash;
use crate::config::{
    BrakeConfig, ConfigError, PlantConfig, PrismaticConfig, RotaryConfig, JOINT_NAMES,
};
use crate::friction::Friction;
use crate::gearing::Transmission;
use crate::hbridge::HBridge;
use crate::joint::{BrakeModel, Joint, JointFaults, JointKind, JointModel};
use crate::leadscrew::LeadScrew;
use crate::motor::DcMotor;
use crate::position_sensor::{PositionSensor, SensorFaults};
use std::fmt;

/// Number of actuated joints.
pub const NUM_JOINTS: usize = 6;

/// A fault to inject into one joint (see [`Plant::inject`]). Faults add up; clear them
/// with [`Plant::clear_faults`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// The encoder counter freezes while the shaft turns (e.g. a broken encoder cable).
    EncoderStuck,
    /// The encoder misses one count in every `one_in` (noise, too high an edge rate).
    EncoderLosesCounts {
        /// Drop one count in this many (>= 1).
        one_in: u32,
    },
    /// The motor leads are open: no current, no torque, no back-EMF braking.
    MotorDisconnected,
    /// The load side jams (collision, seized bearing): it stops and stays.
    LoadSeized,
    /// The encoder keeps only one count in every `one_in` (a failing sensor, a dirty
    /// disc: it counts a fraction of the motion).
    EncoderCountsOneIn {
        /// Keep one count in this many (>= 2).
        one_in: u32,
    },
    /// The encoder's counter jumps by `counts` at once (noise on the A/B lines); applied
    /// once, nothing stays injected.
    EncoderJump {
        /// Counts added (either sign, not 0).
        counts: i32,
    },
    /// The motor's terminals are shorted: the driver latches its short-circuit fault as
    /// soon as it drives the motor; the shorted winding brakes the shaft.
    MotorShorted,
    /// The driver's current regulation stops limiting the current.
    CurrentRegulationLost,
    /// Part of the winding is shorted: the resistance drops to `resistance_ratio` of
    /// the nominal (in (0, 1]).
    WindingShort {
        /// Remaining fraction of the winding's resistance.
        resistance_ratio: f64,
    },
    /// The driver reports a fault of its own (over-temperature, under-voltage lockout)
    /// and keeps its bridge off.
    DriverFailed,
    /// A transistor of the bridge fails short (stuck on): while the bridge is enabled the
    /// motor sees the full supply towards +q whatever the duty, and the driver's current
    /// regulation, bypassed, limits nothing. Disabling the bridge (its enable line, the
    /// safety relay) removes the stage's supply and stops it.
    BridgeStuckOn,
    /// The brake's lining is worn: it holds `holding_ratio` of its rated torque (in
    /// [0, 1)).
    BrakeWorn {
        /// Remaining fraction of the holding torque.
        holding_ratio: f64,
    },
    /// The joint's absolute position sensor (the second channel) freezes at its reading
    /// now (a worn track, a lifted wiper, a frozen converter channel).
    PositionSensorStuck,
    /// A wire of the joint's absolute position sensor is open: its input reads 0 counts.
    PositionSensorOpen,
    /// The joint's absolute position sensor's reading walks away from the position at
    /// `per_s` joint units per second (m/s, rad/s; finite, not 0) from now on.
    PositionSensorDrift {
        /// The drift's rate, m/s or rad/s.
        per_s: f64,
    },
}

/// Errors of the plant's run-time interface. Nothing in the plant panics on bad input.
#[derive(Debug, Clone, PartialEq)]
pub enum PlantError {
    /// A joint index outside 0..6.
    JointOutOfRange {
        /// The index given.
        joint: usize,
    },
    /// A command or setting that is NaN or infinite; the previous value is kept.
    NotFinite {
        /// What was being set.
        what: &'static str,
        /// Joint index.
        joint: usize,
        /// The rejected value.
        value: f64,
    },
    /// A step length that is not finite and positive.
    InvalidStep {
        /// The rejected step, s.
        dt: f64,
    },
    /// A fault parameter out of range.
    InvalidFault(Fault),
}

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlantError::JointOutOfRange { joint } => {
                write!(f, "joint index {joint} out of range 0..{NUM_JOINTS}")
            }
            PlantError::NotFinite { what, joint, value } => write!(
                f,
                "{what} of joint {} is not finite: {value}",
                JOINT_NAMES.get(*joint).copied().unwrap_or("?")
            ),
            PlantError::InvalidStep { dt } => {
                write!(f, "step length must be finite and positive, got {dt} s")
            }
            PlantError::InvalidFault(fault) => write!(f, "invalid fault parameters: {fault:?}"),
        }
    }
}

impl std::error::Error for PlantError {}

/// Which joints' duty commands were outside [-1, 1] and were saturated by the supply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DutySaturation(pub [bool; NUM_JOINTS]);

impl DutySaturation {
    /// At least one joint saturated.
    pub fn any(&self) -> bool {
        self.0.iter().any(|s| *s)
    }
}

/// Running statistics since construction or [`Plant::reset_stats`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantStats {
    /// Steps taken.
    pub steps: u64,
    /// Simulated time, s.
    pub time_s: f64,
    /// Largest |current| at the end of any step, A.
    pub peak_abs_current_a: [f64; NUM_JOINTS],
    /// Steps taken while the joint's duty command was saturated.
    pub saturated_steps: [u64; NUM_JOINTS],
    /// Steps that ended with |current| above the motor's nominal (continuous) current.
    pub over_nominal_current_steps: [u64; NUM_JOINTS],
    /// Largest |force| (N) or |torque| (N m) the transmission carried at the joint.
    pub peak_abs_transmitted_effort: [f64; NUM_JOINTS],
    /// Largest |motor effort| `n Kt i` at the joint (N or N m).
    pub peak_abs_motor_effort: [f64; NUM_JOINTS],
    /// Steps in which the driver's current regulation limited the current.
    pub current_limited_steps: [u64; NUM_JOINTS],
}

/// The physical plant: six actuated joints `q = [l1, l2, l3, theta1, theta2, theta3]`
/// (m, m, m, rad, rad, rad). SI units throughout.
#[derive(Debug, Clone)]
pub struct Plant {
    config: PlantConfig,
    joints: [Joint; NUM_JOINTS],
    /// The second position channel: one absolute sensor per joint, on the load side.
    sensors: [PositionSensor; NUM_JOINTS],
    time: f64,
    stats: PlantStats,
}

fn prismatic_model(p: &PrismaticConfig, bridge: HBridge, brake: &BrakeConfig) -> JointModel {
    JointModel {
        kind: JointKind::Prismatic,
        motor: DcMotor {
            resistance: p.drive.resistance_ohm,
            inductance: p.drive.inductance_h,
            torque_constant: p.drive.torque_constant_nm_per_a,
            back_emf_constant: p.drive.back_emf_v_s_per_rad,
            rotor_inertia: p.drive.rotor_inertia_kg_m2,
            nominal_current: p.drive.nominal_current_a,
        },
        bridge,
        transmission: Transmission::gear_and_screw(
            p.gear_ratio,
            p.drive.gear_efficiency,
            LeadScrew {
                lead: p.lead_mm * 1e-3,
                efficiency: p.leadscrew_efficiency,
            },
            p.drive.transmission_inertia_kg_m2,
        ),
        backlash: Backlash {
            width: p.backlash_mm * 1e-3,
        },
        motor_friction: Friction {
            coulomb: p.drive.coulomb_friction_motor_side_nm,
            viscous: p.drive.viscous_friction_motor_side_nm_s_per_rad,
            breakaway_ratio: p.drive.breakaway_to_coulomb_ratio,
        },
        load_inertia: p.load_mass_kg,
        load_friction: Friction {
            coulomb: p.load_coulomb_friction_n,
            viscous: p.load_viscous_friction_n_s_per_m,
            breakaway_ratio: p.drive.breakaway_to_coulomb_ratio,
        },
        current_limit: p.drive.current_limit_a,
        driver_ocp: p.drive.driver_ocp_a,
        brake: BrakeModel {
            holding_torque: p.drive.brake_holding_torque_nm,
            engage_s: brake.engage_ms * 1e-3,
            release_s: brake.release_ms * 1e-3,
        },
    }
}

fn rotary_model(r: &RotaryConfig, bridge: HBridge, brake: &BrakeConfig) -> JointModel {
    JointModel {
        kind: JointKind::Rotary,
        motor: DcMotor {
            resistance: r.drive.resistance_ohm,
            inductance: r.drive.inductance_h,
            torque_constant: r.drive.torque_constant_nm_per_a,
            back_emf_constant: r.drive.back_emf_v_s_per_rad,
            rotor_inertia: r.drive.rotor_inertia_kg_m2,
            nominal_current: r.drive.nominal_current_a,
        },
        bridge,
        transmission: Transmission::gearhead(
            r.gear_ratio,
            r.drive.gear_efficiency,
            r.drive.transmission_inertia_kg_m2,
        ),
        backlash: Backlash {
            width: (r.backlash_arcsec / 3600.0).to_radians(),
        },
        motor_friction: Friction {
            coulomb: r.drive.coulomb_friction_motor_side_nm,
            viscous: r.drive.viscous_friction_motor_side_nm_s_per_rad,
            breakaway_ratio: r.drive.breakaway_to_coulomb_ratio,
        },
        load_inertia: r.load_inertia_kg_m2,
        load_friction: Friction {
            coulomb: r.load_coulomb_friction_nm,
            viscous: r.load_viscous_friction_nm_s_per_rad,
            breakaway_ratio: r.drive.breakaway_to_coulomb_ratio,
        },
        current_limit: r.drive.current_limit_a,
        driver_ocp: r.drive.driver_ocp_a,
        brake: BrakeModel {
            holding_torque: r.drive.brake_holding_torque_nm,
            engage_s: brake.engage_ms * 1e-3,
            release_s: brake.release_ms * 1e-3,
        },
    }
}

fn check_finite(what: &'static str, values: &[f64; NUM_JOINTS]) -> Result<(), PlantError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(joint) => Err(PlantError::NotFinite {
            what,
            joint,
            value: values[joint],
        }),
        None => Ok(()),
    }
}

impl Plant {
    /// Builds the plant from a configuration (validated again here), all joints at rest
    /// at `q = 0` with the backlash gap centred and the counters at 0.
    pub fn new(config: &PlantConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let bridge = HBridge {
            supply: config.hbridge.supply_v,
            on_resistance: config.hbridge.on_resistance_ohm,
        };
        let cpr = config.encoder.counts_per_rev();
        let joints = std::array::from_fn(|j| {
            let model = if j < 3 {
                prismatic_model(&config.prismatic[j], bridge, &config.brake)
            } else {
                rotary_model(&config.rotary[j - 3], bridge, &config.brake)
            };
            Joint::new(model, cpr)
        });
        let ps = &config.position_sensor;
        let sensors = std::array::from_fn(|j| {
            let (cpu, mid) = if j < 3 {
                (ps.leg_counts_per_m(), ps.leg_mid_mm * 1e-3)
            } else {
                (ps.link_counts_per_rad(), ps.link_mid_deg.to_radians())
            };
            PositionSensor::new(
                cpu,
                mid,
                ps.noise_lsb,
                ps.offset_lsb,
                0x5EED_0000 + j as u64,
            )
        });
        Ok(Plant {
            config: config.clone(),
            joints,
            sensors,
            time: 0.0,
            stats: PlantStats::default(),
        })
    }

    /// The configuration the plant was built from.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// Read-only access to one joint (its model, gap, transmitted force, ...).
    pub fn joint(&self, joint: usize) -> Result<&Joint, PlantError> {
        self.joints
            .get(joint)
            .ok_or(PlantError::JointOutOfRange { joint })
    }

    /// Puts every joint at rest at `q`: motor and load at rest, backlash gap centred, no
    /// current, encoder counters 0 here. Duty, external load and faults are kept.
    pub fn set_joint_positions(&mut self, q: [f64; NUM_JOINTS]) -> Result<(), PlantError> {
        check_finite("position", &q)?;
        for (joint, qj) in self.joints.iter_mut().zip(q) {
            joint.set_position(qj);
        }
        Ok(())
    }

    /// Sets the H-bridge duties, held until changed. A duty outside [-1, 1] is saturated
    /// to the supply voltage and reported in the result (and counted in the stats while
    /// held); a non-finite duty is rejected and nothing changes.
    pub fn set_duty(&mut self, duty: [f64; NUM_JOINTS]) -> Result<DutySaturation, PlantError> {
        check_finite("duty", &duty)?;
        let mut sat = DutySaturation::default();
        for (j, (joint, d)) in self.joints.iter_mut().zip(duty).enumerate() {
            let applied = HBridge::saturate(d).ok_or(PlantError::NotFinite {
                what: "duty",
                joint: j,
                value: d,
            })?;
            sat.0[j] = applied.saturated;
            joint.set_duty(applied);
        }
        Ok(sat)
    }

    /// The duties being applied (after saturation).
    pub fn duty(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].duty().applied)
    }

    /// Sets the external loads, held until changed: the force (N, prismatic joints, along
    /// the leg) or torque (N m, rotary joints, about the link axis) that the environment
    /// (platform, payload, gravity) applies to the joint **in the +q direction**. Gravity
    /// pulling a leg shorter is negative; a load that resists extension is negative.
    pub fn set_external_load(&mut self, load: [f64; NUM_JOINTS]) -> Result<(), PlantError> {
        check_finite("external load", &load)?;
        for (joint, l) in self.joints.iter_mut().zip(load) {
            joint.set_external_load(l);
        }
        Ok(())
    }

    /// Advances the plant by `dt` seconds. Any finite `dt > 0` is stable; for accuracy
    /// use at most 100 us (see the crate documentation).
    pub fn step(&mut self, dt: f64) -> Result<(), PlantError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(PlantError::InvalidStep { dt });
        }
        for (j, joint) in self.joints.iter_mut().enumerate() {
            joint.step(dt);
            let i = joint.current().abs();
            let s = &mut self.stats;
            // (The current is finite: the step is stable for every dt.)
            if i > s.peak_abs_current_a[j] {
                s.peak_abs_current_a[j] = i;
            }
            s.saturated_steps[j] += u64::from(joint.duty().saturated);
            s.over_nominal_current_steps[j] += u64::from(i > joint.model().motor.nominal_current);
            s.peak_abs_transmitted_effort[j] =
                s.peak_abs_transmitted_effort[j].max(joint.transmitted_effort().abs());
            s.peak_abs_motor_effort[j] = s.peak_abs_motor_effort[j].max(joint.motor_effort().abs());
            s.current_limited_steps[j] += u64::from(joint.current_limited());
        }
        self.time += dt;
        self.stats.steps += 1;
        self.stats.time_s += dt;
        Ok(())
    }

    /// Takes `round(duration / dt)` steps of `dt`.
    pub fn advance(&mut self, duration: f64, dt: f64) -> Result<(), PlantError> {
        if !(dt.is_finite() && dt > 0.0 && duration.is_finite()) {
            return Err(PlantError::InvalidStep { dt });
        }
        let steps = (duration / dt).round().max(0.0) as u64;
        for _ in 0..steps {
            self.step(dt)?;
        }
        Ok(())
    }

    /// Simulated time since construction, s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The six 16-bit hardware encoder counters (wrapping), as the MCU's timers read them.
    pub fn encoder_counts(&self) -> [u16; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].encoder_counter())
    }

    /// The second position channel's six converter readings (0 .. 65535 counts over each
    /// sensor's electrical travel), of the load-side positions now
    /// ([`crate::position_sensor`]).
    pub fn position_sensor_counts(&self) -> [u16; NUM_JOINTS] {
        std::array::from_fn(|j| self.sensors[j].reading(self.joints[j].position(), self.time))
    }

    /// Joint `joint`'s absolute position sensor.
    pub fn position_sensor(&self, joint: usize) -> Result<&PositionSensor, PlantError> {
        self.sensors
            .get(joint)
            .ok_or(PlantError::JointOutOfRange { joint })
    }

    /// True load-side joint positions (after backlash): what the robot's pose uses.
    pub fn joint_positions(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].position())
    }

    /// Motor angles mapped to joint units (what a perfect encoder would report).
    pub fn motor_side_joint_positions(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].motor_side_position())
    }

    /// Load-side joint velocities, m/s and rad/s.
    pub fn joint_velocities(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].velocity())
    }

    /// Motor velocities mapped to joint units.
    pub fn motor_side_joint_velocities(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].motor_side_velocity())
    }

    /// Armature currents, A (+ drives towards +q).
    pub fn currents(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].current())
    }

    /// Encoder counts per joint unit: counts/m for l1..l3, counts/rad for theta1..3.
    pub fn counts_per_joint_unit(&self) -> [f64; NUM_JOINTS] {
        let cpr = self.config.encoder.counts_per_rev();
        std::array::from_fn(|j| self.joints[j].model().counts_per_joint_unit(cpr))
    }

    /// Continuous effort each joint delivers at its motor's nominal current (N, N m).
    pub fn rated_efforts(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].model().rated_effort())
    }

    /// Steady no-load joint speeds at full duty (m/s, rad/s).
    pub fn no_load_speeds(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].model().no_load_speed(1.0))
    }

    /// Enables the six H-bridges (the driver enable line) or turns them off: off, the
    /// bridges are high-impedance and the motors coast (no braking by the bridge). Enabling
    /// clears the drivers' latched faults; a cause that persists trips again.
    pub fn set_bridges_enabled(&mut self, enabled: bool) {
        for j in &mut self.joints {
            j.set_bridge_enabled(enabled);
        }
    }

    /// Which bridges drive their motor (enabled and not latched off by their driver).
    pub fn bridges_on(&self) -> [bool; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].bridge_on())
    }

    /// Some driver has latched a fault (the drivers' shared fault output).
    pub fn driver_fault(&self) -> bool {
        self.joints.iter().any(|j| j.driver_fault())
    }

    /// Powers (`true`: released) or unpowers (applied) each joint's brake coil; the brakes
    /// follow after their release or engage time (`[brake]` in the configuration).
    pub fn set_brakes_released(&mut self, released: [bool; NUM_JOINTS]) {
        for (j, r) in self.joints.iter_mut().zip(released) {
            j.set_brake_released(r);
        }
    }

    /// Which brakes hold now.
    pub fn brakes_holding(&self) -> [bool; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].brake_holding())
    }

    /// Sets the bridges' supply voltage (a sag, a surge), V; finite and not negative.
    pub fn set_supply_voltage(&mut self, volts: f64) -> Result<(), PlantError> {
        if !(volts.is_finite() && volts >= 0.0) {
            return Err(PlantError::NotFinite {
                what: "supply voltage",
                joint: 0,
                value: volts,
            });
        }
        for j in &mut self.joints {
            j.set_supply(volts);
        }
        Ok(())
    }

    /// The bridges' supply voltage, V.
    pub fn supply_voltage(&self) -> f64 {
        self.joints[0].model().bridge.supply
    }

    /// The motors' efforts at the joints, `n Kt i` (N, N m).
    pub fn motor_efforts(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].motor_effort())
    }

    /// The efforts the transmissions carry at the joints (N, N m; + pushes towards +q).
    pub fn transmitted_efforts(&self) -> [f64; NUM_JOINTS] {
        std::array::from_fn(|j| self.joints[j].transmitted_effort())
    }

    /// Injects a fault into joint `joint` (0..6); faults add up.
    pub fn inject(&mut self, joint: usize, fault: Fault) -> Result<(), PlantError> {
        let q = self.joint(joint)?.position();
        let now = self.time;
        let sensor = self
            .sensors
            .get_mut(joint)
            .ok_or(PlantError::JointOutOfRange { joint })?;
        let mut sf = sensor.faults();
        match fault {
            Fault::PositionSensorStuck => {
                sf.stuck = Some(sensor.reading(q, now));
                sensor.set_faults(sf);
                return Ok(());
            }
            Fault::PositionSensorOpen => {
                sf.open_wire = true;
                sensor.set_faults(sf);
                return Ok(());
            }
            Fault::PositionSensorDrift { per_s } => {
                if !(per_s.is_finite() && per_s != 0.0) {
                    return Err(PlantError::InvalidFault(fault));
                }
                sf.drift = Some((per_s, now));
                sensor.set_faults(sf);
                return Ok(());
            }
            _ => {}
        }
        let j = self
            .joints
            .get_mut(joint)
            .ok_or(PlantError::JointOutOfRange { joint })?;
        let mut f = j.faults();
        match fault {
            Fault::PositionSensorStuck
            | Fault::PositionSensorOpen
            | Fault::PositionSensorDrift { .. } => {}
            Fault::EncoderStuck => f.encoder_stuck = true,
            Fault::EncoderLosesCounts { one_in } => {
                if one_in == 0 {
                    return Err(PlantError::InvalidFault(fault));
                }
                f.encoder_lose_one_in = Some(one_in);
            }
            Fault::MotorDisconnected => f.motor_disconnected = true,
            Fault::LoadSeized => f.load_seized = true,
            Fault::EncoderJump { counts } => {
                if counts == 0 {
                    return Err(PlantError::InvalidFault(fault));
                }
                j.glitch_encoder(i64::from(counts));
                return Ok(());
            }
            Fault::EncoderCountsOneIn { one_in } => {
                if one_in < 2 {
                    return Err(PlantError::InvalidFault(fault));
                }
                f.encoder_keep_one_in = Some(one_in);
            }
            Fault::MotorShorted => f.motor_shorted = true,
            Fault::CurrentRegulationLost => f.current_regulation_lost = true,
            Fault::WindingShort { resistance_ratio } => {
                if !(resistance_ratio > 0.0 && resistance_ratio <= 1.0) {
                    return Err(PlantError::InvalidFault(fault));
                }
                f.winding_resistance_ratio = Some(resistance_ratio);
            }
            Fault::DriverFailed => f.driver_failed = true,
            Fault::BridgeStuckOn => f.bridge_stuck_on = true,
            Fault::BrakeWorn { holding_ratio } => {
                if !(0.0..1.0).contains(&holding_ratio) {
                    return Err(PlantError::InvalidFault(fault));
                }
                f.brake_holding_ratio = Some(holding_ratio);
            }
        }
        j.set_faults(f);
        Ok(())
    }

    /// Removes every fault of joint `joint`, its position sensor's too. Counts missed
    /// while the encoder was faulty stay missed.
    pub fn clear_faults(&mut self, joint: usize) -> Result<(), PlantError> {
        let j = self
            .joints
            .get_mut(joint)
            .ok_or(PlantError::JointOutOfRange { joint })?;
        j.set_faults(JointFaults::default());
        if let Some(s) = self.sensors.get_mut(joint) {
            s.set_faults(SensorFaults::default());
        }
        Ok(())
    }

    /// The faults injected into joint `joint`'s position sensor.
    pub fn sensor_faults(&self, joint: usize) -> Result<SensorFaults, PlantError> {
        Ok(self.position_sensor(joint)?.faults())
    }

    /// Replaces the set of faults injected into joint `joint` (e.g. a simulator's hard stop
    /// seizing the load while an injected encoder fault stays).
    pub fn set_faults(&mut self, joint: usize, faults: JointFaults) -> Result<(), PlantError> {
        if let Some(r) = faults.winding_resistance_ratio {
            if !(r > 0.0 && r <= 1.0) {
                return Err(PlantError::InvalidFault(Fault::WindingShort {
                    resistance_ratio: r,
                }));
            }
        }
        if let Some(r) = faults.brake_holding_ratio {
            if !(0.0..1.0).contains(&r) {
                return Err(PlantError::InvalidFault(Fault::BrakeWorn {
                    holding_ratio: r,
                }));
            }
        }
        if faults.encoder_lose_one_in == Some(0) {
            return Err(PlantError::InvalidFault(Fault::EncoderLosesCounts {
                one_in: 0,
            }));
        }
        let j = self
            .joints
            .get_mut(joint)
            .ok_or(PlantError::JointOutOfRange { joint })?;
        j.set_faults(faults);
        Ok(())
    }

    /// The faults injected into joint `joint`.
    pub fn faults(&self, joint: usize) -> Result<JointFaults, PlantError> {
        Ok(self.joint(joint)?.faults())
    }

    /// Running statistics.
    pub fn stats(&self) -> &PlantStats {
        &self.stats
    }

    /// Restarts the statistics.
    pub fn reset_stats(&mut self) {
        self.stats = PlantStats::default();
    }
}
