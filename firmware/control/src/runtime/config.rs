//! The runtime's settings, the reference robot's, and why a setting is refused.

use core::fmt;

use kinematics_core::{Branch, Mechanism, Pose};
use servo::config::ConfigError;
use servo::NUM_JOINTS;

use crate::absolute::{ChannelCalibration, ChannelConfig};
use crate::brakes::BrakeCheckConfig;
use crate::commissioning::CommissionConfig;
use crate::controller::ControllerConfig;
use crate::current::CurrentConfig;
use crate::drive::to_array;
use crate::heartbeat::{HeartbeatConfig, HeartbeatConfigError};
use crate::homing::{HomeMethod, HomingConfig, HomingError, HomingSetupError, Mechanics};
use crate::monitors::{EncoderCheckConfig, PowerConfig};
use crate::park::ParkConfig;
use crate::scalar::Scalar;
use crate::sensing::SensingError;
use crate::stops::StopConfig;
use crate::targets::TargetClockConfig;

/// Everything the runtime needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeConfig<S: Scalar> {
    /// The control application (and the sensing's encoder and FK settings).
    pub controller: ControllerConfig<S>,
    /// Homing.
    pub homing: HomingConfig<S>,
    /// The board's mechanics (joint ranges).
    pub mechanics: Mechanics<S>,
    /// Heartbeat hold / disable times.
    pub heartbeat: HeartbeatConfig,
    /// Master target timestamps.
    pub targets: TargetClockConfig,
    /// Consecutive forward-kinematics failures that latch `FORWARD_KINEMATICS`.
    pub fk_failures_to_fault: u32,
    /// The stops' timing.
    pub stops: StopConfig,
    /// The brake check and release at enable.
    pub brakes: BrakeCheckConfig<S>,
    /// Motor currents: limits, I²t, trips.
    pub current: CurrentConfig<S>,
    /// Encoder plausibility.
    pub encoder_check: EncoderCheckConfig<S>,
    /// The power stage's supply range.
    pub power: PowerConfig<S>,
    /// Ticks the e-stop button and the safety relay may disagree (the relay's switching).
    pub relay_debounce_ticks: u16,
    /// The park move after homing (speeds, path check, settling).
    pub park: ParkConfig<S>,
    /// The second position channel's calibration (read where the board has it fitted).
    pub channel_calibration: ChannelCalibration<S>,
    /// The second position channel's monitor against the encoders.
    pub channel: ChannelConfig<S>,
    /// Commissioning's test of a joint.
    pub commission: CommissionConfig<S>,
}

/// Why the runtime refuses its settings: each concern's own error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RuntimeError {
    /// The homing settings (the joint concerned).
    Homing(HomingError),
    /// The servo or encoder settings.
    Servo(ConfigError),
    /// The sensing (encoders, forward kinematics).
    Sensing(SensingError),
    /// The heartbeat's times.
    Heartbeat(HeartbeatConfigError),
    /// The control rate is outside 100 .. 10 000 Hz.
    Rate,
}

impl fmt::Display for RuntimeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RuntimeError::Homing(e) => write!(f, "homing settings: {e:?}"),
            RuntimeError::Servo(e) => write!(f, "servo settings: {e}"),
            RuntimeError::Sensing(e) => write!(f, "sensing settings: {e:?}"),
            RuntimeError::Heartbeat(_) => {
                f.write_str("heartbeat: the hold time must be positive and below the disable time")
            }
            RuntimeError::Rate => f.write_str("the control rate must be within 100 .. 10000 Hz"),
        }
    }
}

impl From<HomingSetupError> for RuntimeError {
    fn from(e: HomingSetupError) -> Self {
        match e {
            HomingSetupError::Homing(h) => RuntimeError::Homing(h),
            HomingSetupError::Servo(s) => RuntimeError::Servo(s),
        }
    }
}

/// The reference robot's mechanics: the board profile's mechanical ranges
/// (`board_profile::BoardProfile::REFERENCE`: 2 mm beyond the guards' 144 .. 210 mm stroke,
/// 3 deg beyond their ±80 deg link angle), and its switches and stops placed around the
/// guards' ranges `limits` (the supervisor keeps every setpoint inside them; thesis
/// chapter 11): the legs' home switches 1 mm below the shortest stroke (143 mm for
/// 144 .. 210 mm), the links' hard stops 5 deg beyond their largest angle below the
/// central angles (85 deg for ±80 deg). A measured joint beyond its range is a
/// fault (the servo's following error and the backlash stay well inside); the switch lies
/// just inside the range, the link's stop just outside it (homing reaches it, see
/// `HomingConfig::for_mechanics`).
pub fn reference_mechanics<S: Scalar>(limits: &kinematics_core::guards::Limits<S>) -> Mechanics<S> {
    let lit = kinematics_core::scalar::lit::<S>;
    let deg = |d: f64| lit(d.to_radians());
    let [short, _] = limits.stroke;
    Mechanics {
        leg_switch_m: short - lit(0.001),
        link_stop_below_central_rad: limits.link_angle_max + deg(5.0),
        range: board_profile::BoardProfile::REFERENCE
            .ranges()
            .map(|[lo, hi]| [lit(lo), lit(hi)]),
    }
}

/// The default configuration of `robot` assembled on `branch` with the mechanics `mech`,
/// resting at `rest` before homing (None: at its central configuration, where it parks):
/// homing to the mechanics' switches and stops, parking at the central configuration.
pub fn reference_config_for<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    branch: Branch,
    mech: Option<Mechanics<S>>,
    rest: Option<[S; NUM_JOINTS]>,
) -> Result<RuntimeConfig<S>, kinematics_core::IkError> {
    let central = kinematics_core::inverse(robot, &Pose::central(robot.hc()), branch)?;
    let central_q = to_array(&central.q());
    let controller = ControllerConfig {
        branch,
        ..ControllerConfig::default()
    };
    let mech = mech.unwrap_or_else(|| reference_mechanics(&controller.limits));
    let rest = rest.unwrap_or(central_q);
    let encoder_check = EncoderCheckConfig::reference(controller.encoders.counts_per_unit);
    let channel_calibration = ChannelCalibration::reference(&mech.range);
    let widths = controller.servo.backlash.joints.map(|b| b.width);
    let current = CurrentConfig::default();
    let continuous = current.motors.map(|m| m.continuous_a);
    let channel = ChannelConfig::reference(
        &channel_calibration,
        &controller.encoders.counts_per_unit,
        &widths,
        &encoder_check.top_speed,
        &continuous,
        S::one() / controller.rate_hz,
    );
    let mut homing = HomingConfig::for_mechanics(&mech, &central_q, &rest, Some(central_q));
    // The verification's two channels agree within the monitor's bound over the move.
    for (j, a) in homing.verify.agree.iter_mut().enumerate() {
        let at = |x: &[S; NUM_JOINTS]| x.get(j).copied().unwrap_or_else(S::zero);
        *a = at(&channel.agree)
            + at(&channel.backlash)
            + channel.scale * at(&homing.verify.distance);
    }
    let brakes = BrakeCheckConfig::default();
    // The home switches the test may find actuated: those homing drives down onto.
    let home_switch = homing.joints.map(|h| {
        (h.method == HomeMethod::Switch && !h.towards_positive)
            .then_some((h.home_position, h.switch_travel_max))
    });
    let commission = CommissionConfig::reference(
        brakes.duty,
        home_switch,
        controller.encoders.counts_per_unit,
    );
    Ok(RuntimeConfig {
        commission,
        encoder_check,
        controller,
        homing,
        mechanics: mech,
        heartbeat: HeartbeatConfig::default(),
        targets: TargetClockConfig::default(),
        fk_failures_to_fault: 10,
        stops: StopConfig::default(),
        brakes,
        current,
        power: PowerConfig::default(),
        relay_debounce_ticks: 20,
        park: ParkConfig::default(),
        channel_calibration,
        channel,
    })
}
