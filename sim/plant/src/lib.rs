//! # plant: the six actuated joints of the RSPR prototype, as a physical plant
//!
//! The host simulator closes the loop around the controller with this model: it sets the
//! H-bridge duties and the external loads, steps the plant at a fixed step (10..100 kHz,
//! at least ten times the control rate) and reads the wrapping 16-bit encoder counters.
//!
//! ## Conventions
//! * Joint order everywhere: `q = [l1, l2, l3, theta1, theta2, theta3]`: three prismatic
//!   lead-screw legs (m), then three rotating links (rad). SI units in the whole API.
//! * Positive duty produces positive motor torque, positive motor rotation, positive
//!   joint motion and increasing encoder counts.
//! * External load ([`Plant::set_external_load`]): the force (N) or torque (N m) that the
//!   environment applies to the joint **in the +q direction**. Gravity shortening a
//!   vertical leg is negative.
//! * [`Plant::joint_positions`] are the true load-side positions (after backlash), which
//!   the robot's pose follows; the encoders see the motor side,
//!   [`Plant::motor_side_joint_positions`].
//!
//! ## Per joint
//! H-bridge ([`hbridge`]) -> DC motor with current as a state ([`motor`]) -> gearing
//! ([`gearing`], [`leadscrew`]) with load-proportional mesh friction (efficiency) ->
//! backlash deadband ([`backlash`]) -> load mass or inertia with Coulomb/viscous friction
//! and stiction ([`friction`]); a quadrature encoder on the motor shaft ([`encoder`]); an
//! absolute position sensor on the load side, the second position channel
//! ([`position_sensor`]: a potentiometer read by a 16-bit converter, with its noise,
//! resolution, offset and faults).
//! [`joint`] holds the time step, [`plant`] the six joints, [`config`] the parameters
//! (`plant.toml`).
//!
//! ## Step size
//! The electrical part is integrated exactly (exponential over the step), the back-EMF
//! coupling, friction and the backlash contact implicitly, so [`Plant::step`] is stable
//! for every `dt` > 0: there is no largest stable step (tested up to 10 ms, where the
//! state stays bounded but is only ~20 % accurate). Accuracy is first order in `dt`: on a
//! demanding duty/load/reversal scenario, against a 1 us reference, the velocity error is
//! 0.03 % of the no-load speed at 10 us, 0.3 % at 100 us, 1.4 % at 500 us and 6 % at
//! 1 ms. Use 10..100 us (10..100 kHz). The parts of a step that depend only on the
//! parameters and `dt` (the electrical exponentials, the implicit steps' denominators) are
//! computed once per `dt`, so a fixed `dt` is cheapest: one step of all six joints costs
//! about 0.3 us (`cargo bench -p simulation --bench sim`, `sim/plant_1ms`: 10 steps).
//!
//! ## Parameters (shipped `plant.toml`, see its comments for the sources)
//! The resolutions fix the gearing: 2000 counts per motor revolution (500 lines, x4) and
//! 0.0015 mm/count give 3 mm of leg travel per motor revolution (2:1 anti-backlash spur
//! pair onto a 6 mm-lead PTFE lead screw, 66.5 % overall); 0.005 deg/count gives 36:1 on
//! the rotating links (two precision spur stages, 90 %).
//!
//! | | legs l1..l3 | links theta1..3 |
//! |---|---|---|
//! | motor (class) | 40 mm, 150 W, 24 V (maxon RE 40) | 25 mm, 10 W, 24 V (maxon RE 25) |
//! | R, L, Kt | 0.317 ohm, 82 uH, 30.2 mN m/A | 2.14 ohm, 238 uH, 23.4 mN m/A |
//! | nominal current, stall current at 24 V | 5.77 A, 69 A | 1.2 A, 11 A |
//! | rated effort at nominal current | 234 N (thesis: 220 N) | 0.87 N m (thesis: 0.5 N m) |
//! | no-load speed at 24 V | 378 mm/s | 28 rad/s |
//! | backlash | 0.12 mm | 20 arcsec |
//!
//! 220 N at 3 mm per motor revolution needs about 0.17 N m of continuous motor torque,
//! hence the 40 mm motor on the legs; its stall current (69 A at full duty) is far above
//! any small H-bridge's rating, so the controller (or a driver current limit) must keep
//! the current near the nominal 5.8 A: [`PlantStats`] counts the steps above it.
//!
//! ## The drive side
//! * **Driver current regulation** (cycle-by-cycle chopping, `current_limit_a`): the
//!   current never exceeds the limit, set to the rating over the transmission's
//!   efficiency (5.23 A on a leg: 220 N; 0.66 A on a link: 0.5 N m). Lost with
//!   [`Fault::CurrentRegulationLost`].
//! * **Bridge enable** ([`Plant::set_bridges_enabled`]): off, the bridges are
//!   high-impedance and the motors coast; duty 0 with the bridges on shorts the motor
//!   (back-EMF braking). A driver latches a short circuit ([`Fault::MotorShorted`]) or a
//!   fault of its own ([`Fault::DriverFailed`]) on its fault output
//!   ([`Plant::driver_fault`]) and turns its bridge off until re-enabled.
//! * **Holding brakes** ([`Plant::set_brakes_released`]): spring-applied on the motor
//!   shafts, holding torque `brake_holding_torque_nm` as friction on the motor side,
//!   following the coil after `[brake] engage_ms` / `release_ms`. The plant starts with
//!   the bridges enabled and the brakes released (the plant alone behaves as before).
//! * **Supply** ([`Plant::set_supply_voltage`]): a sag scales every bridge's voltage.
//!
//! ## Not modelled
//! Joint end stops, the coupling of the six joints through the platform (the simulator
//! supplies it as external loads), motor heating, PWM ripple, encoder index pulses and
//! edge-rate limits.

pub mod backlash;
pub mod config;
pub mod encoder;
pub mod friction;
pub mod gearing;
pub mod hbridge;
pub mod joint;
pub mod leadscrew;
pub mod motor;
pub mod plant;
pub mod position_sensor;

pub use config::{ConfigError, PlantConfig, JOINT_NAMES};
pub use joint::{BrakeModel, JointFaults, JointKind};
pub use plant::{DutySaturation, Fault, Plant, PlantError, PlantStats, NUM_JOINTS};
pub use position_sensor::{PositionSensor, SensorFaults};
