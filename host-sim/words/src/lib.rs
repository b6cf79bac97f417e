//! The board's facts in plain words, for people: every front end (the operator's console,
//! `teleop`, the OpenIGTLink bridge's STATUS, the session recording) renders them here, so
//! that a refusal, a state, a stop, a fault or a margin reads the same everywhere.
//!
//! - Joints by name (`CONVENTIONS.md`, Joints): joints 0..=2 are "leg 1" .. "leg 3" (the
//!   prismatic l_i), 3..=5 "link 1" .. "link 3" (the rotating links θ_i).
//! - Values in the units people use at the edges: mm, deg, mm/s, deg/s, N, N m, A, V, ms,
//!   and the limit they broke: "workspace z 177.0 mm > 175.0 mm".
//! - No `Debug` formatting: every word here is chosen.

use kinematics_core::guards::Limits;
use master_link::{
    Breach, FaultCause, FaultRecord, GeometryRefusal, GuardId, GuardMargins, NackReason,
    RefusedTarget, ResetCause, RobotState, StopStatus, NO_JOINT,
};

/// Millimetres per metre.
const MM: f64 = 1e3;
/// Degrees per radian.
const DEG: f64 = 180.0 / core::f64::consts::PI;

/// The name of joint `j` (joint order): "leg 1" .. "leg 3", "link 1" .. "link 3"; `None`
/// for [`NO_JOINT`] or an index out of range.
pub fn joint_name(j: u8) -> Option<String> {
    match j {
        0..=2 => Some(format!("leg {}", j + 1)),
        3..=5 => Some(format!("link {}", j - 2)),
        _ => None,
    }
}

/// A value of joint `j` in its unit at the edge (mm for a leg, deg for a link), SI in.
fn joint_value(j: u8, si: f64) -> (f64, &'static str) {
    if j < 3 {
        (si * MM, "mm")
    } else {
        (si * DEG, "deg")
    }
}

/// The guard or rule, in words.
pub fn guard_name(g: GuardId) -> &'static str {
    match g {
        GuardId::None => "",
        GuardId::Reach => "reach",
        GuardId::Stroke => "stroke",
        GuardId::LinkAngle => "link angle",
        GuardId::Yaw => "yaw",
        GuardId::Pitch => "pitch",
        GuardId::Tilt => "tilt",
        GuardId::Collision => "collision",
        GuardId::Workspace => "workspace",
        GuardId::TiltCone => "platform tilt",
        GuardId::SerialSingularity => "serial singularity",
        GuardId::ParallelSingularity => "parallel singularity",
        GuardId::Force => "force",
        GuardId::Torque => "torque",
        GuardId::TipSpeed => "tip speed",
        GuardId::AngularSpeed => "angular speed",
        GuardId::TipAccel => "tip acceleration",
        GuardId::AngularAccel => "angular acceleration",
        GuardId::JointSpeed => "joint speed",
        GuardId::JointAccel => "joint acceleration",
        GuardId::Step => "step from the setpoint",
        GuardId::StepAngle => "turn from the setpoint",
        GuardId::Age => "target age",
    }
}

/// What a breach concerns, in words ("leg 2", "spherical joint 1", "z"), if anything.
fn subject_name(g: GuardId, s: u8) -> Option<String> {
    if s == NO_JOINT {
        return None;
    }
    let n = u32::from(s) + 1;
    match g {
        GuardId::Stroke | GuardId::Collision => Some(format!("leg {n}")),
        GuardId::LinkAngle | GuardId::Yaw | GuardId::Pitch => Some(format!("link {n}")),
        GuardId::Tilt => Some(format!("spherical joint {n}")),
        GuardId::Reach | GuardId::SerialSingularity => Some(format!("chain {n}")),
        GuardId::Workspace => Some(
            match s {
                0 => "x",
                1 => "y",
                _ => "z",
            }
            .to_string(),
        ),
        GuardId::Force | GuardId::Torque | GuardId::JointSpeed | GuardId::JointAccel => {
            joint_name(s)
        }
        _ => None,
    }
}

/// The factor from SI, the unit and the decimals of a breach's value and limit.
fn breach_unit(b: &Breach) -> (f64, &'static str, usize) {
    let joint_rate = |mm: &'static str, deg: &'static str| {
        if b.subject < 3 {
            (MM, mm, 1)
        } else {
            (DEG, deg, 1)
        }
    };
    match b.guard {
        GuardId::Stroke | GuardId::Collision | GuardId::Workspace | GuardId::Step => (MM, "mm", 1),
        GuardId::LinkAngle
        | GuardId::Yaw
        | GuardId::Pitch
        | GuardId::Tilt
        | GuardId::TiltCone
        | GuardId::StepAngle => (DEG, "deg", 1),
        GuardId::SerialSingularity | GuardId::ParallelSingularity => (1.0, "", 3),
        GuardId::Force => (1.0, "N", 1),
        GuardId::Torque => (1.0, "N m", 2),
        GuardId::TipSpeed => (MM, "mm/s", 1),
        GuardId::AngularSpeed => (DEG, "deg/s", 1),
        GuardId::TipAccel => (MM, "mm/s²", 0),
        GuardId::AngularAccel => (DEG, "deg/s²", 0),
        GuardId::JointSpeed => joint_rate("mm/s", "deg/s"),
        GuardId::JointAccel => joint_rate("mm/s²", "deg/s²"),
        GuardId::Age => (1e3, "ms", 0),
        GuardId::Reach | GuardId::None => (1.0, "", 0),
    }
}

/// A measured breach in words: the guard, what it concerns, the value and the limit with
/// their unit, e.g. "workspace z 177.0 mm > 175.0 mm", "stroke leg 2 212.4 mm > 210.0 mm";
/// `None` when nothing was measured ([`GuardId::None`]).
pub fn breach(b: &Breach) -> Option<String> {
    if b.guard == GuardId::None {
        return None;
    }
    let mut s = guard_name(b.guard).to_string();
    if let Some(subject) = subject_name(b.guard, b.subject) {
        s.push(' ');
        s.push_str(&subject);
    }
    if b.guard == GuardId::Reach {
        s.push_str(": no inverse-kinematics solution");
        return Some(s);
    }
    let (k, unit, decimals) = breach_unit(b);
    let (v, l) = (f64::from(b.value) * k, f64::from(b.limit) * k);
    let op = if v > l { ">" } else { "<" };
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    s.push_str(&format!(
        " {v:.decimals$}{unit} {op} {l:.decimals$}{unit}",
        decimals = decimals
    ));
    Some(s)
}

/// Why the board refused, in words a person at the robot can act on (at most 44
/// characters: the console shows it on one line).
pub fn reason(reason: NackReason) -> &'static str {
    match reason {
        NackReason::UnsupportedVersion => "the board speaks another protocol",
        NackReason::NotConnected => "no session: say hello first",
        NackReason::InvalidState => "not allowed in this state",
        NackReason::NotHomed => "not homed: home the robot first",
        NackReason::Faulted => "a fault is latched: clear it first",
        NackReason::FaultStillActive => "the fault's cause is still present",
        NackReason::InvalidJoint => "no such joint",
        NackReason::InvalidValue => "a value is not finite or not valid",
        NackReason::OutOfWorkspace => "the target is outside the workspace",
        NackReason::JointLimit => "the target violates a joint limit",
        NackReason::NearSingularity => "the target is too near a singularity",
        NackReason::VelocityLimit => "too fast",
        NackReason::StaleTarget => "the target is stale or out of order",
        NackReason::ClutchDisengaged => "the clutch is not engaged",
        NackReason::Busy => "busy (homing, enabling, brakes): retry",
        NackReason::AlreadyHomed => "already homed: re-homing needs confirming",
        NackReason::ResetNotAcknowledged => "acknowledge the board's last reset first",
        NackReason::SafetyRelayMismatch => "e-stop button and safety relay disagree",
        NackReason::BrakeCheckFailed => "the holding brakes failed their check",
        NackReason::OperatorAbsent => "operator absent (dead-man released)",
        NackReason::NotOwner => "another master owns the board",
        NackReason::TargetFromFuture => "the target's stamp is in the future",
        NackReason::ReplayedHello => "an old Hello of this master: a replay",
    }
}

/// A refused target in words: what was measured when the board measured it ([`breach`]),
/// else the rule ([`reason`]).
pub fn refusal(r: &RefusedTarget) -> String {
    breach(&r.breach).unwrap_or_else(|| reason(r.reason).to_string())
}

/// Why the board refused to store a calibrated geometry, in words.
pub fn geometry_refusal(r: GeometryRefusal) -> String {
    match r {
        GeometryRefusal::Crc => "the record's CRC does not match its contents".into(),
        GeometryRefusal::Layout { found } => {
            format!("record layout {found} is not one this firmware reads")
        }
        GeometryRefusal::Version => "version 0 is reserved for \"no stored geometry\"".into(),
        GeometryRefusal::NonFinite { index } => format!("value {index} is not finite"),
        GeometryRefusal::Nominal { index } => {
            format!("nominal value {index} (e, rb, rp, hc) is not the board's robot")
        }
        GeometryRefusal::OutOfTolerance { index } => {
            format!("value {index} is further from the nominal than a calibration can move it")
        }
        GeometryRefusal::NotAssemblable => {
            "the geometry cannot be assembled in its central configuration".into()
        }
        GeometryRefusal::CentralPose => {
            "the inverse kinematics of the central pose fails on the board's branch".into()
        }
        GeometryRefusal::InvalidState => {
            "the drives are on: store only when disabled or ready".into()
        }
        GeometryRefusal::Flash => "writing or verifying the flash failed".into(),
        GeometryRefusal::Unsupported => "this board cannot store a geometry".into(),
    }
}

/// The OpenIGTLink STATUS code (OpenIGTLink's `STATUS` message, protocol version 2 and
/// later) of a refusal: a target outside what the robot may reach is "configuration
/// error" (10: out of range), a stale or malformed one "illegal/invalid"; the board in a
/// state that takes no targets "not ready" (13), a fault "device error"/"disabled" (4).
pub fn igtl_status_code(reason: NackReason) -> u16 {
    match reason {
        NackReason::OutOfWorkspace
        | NackReason::JointLimit
        | NackReason::NearSingularity
        | NackReason::VelocityLimit => IGTL_CONFIGURATION_ERROR,
        NackReason::InvalidJoint
        | NackReason::InvalidValue
        | NackReason::StaleTarget
        | NackReason::TargetFromFuture => IGTL_ILLEGAL,
        NackReason::Faulted | NackReason::FaultStillActive => IGTL_DEVICE_ERROR,
        _ => IGTL_NOT_READY,
    }
}

/// OpenIGTLink STATUS code 3: "Invalid / illegal".
pub const IGTL_ILLEGAL: u16 = 3;
/// OpenIGTLink STATUS code 4: "Device error" (the device is disabled by a fault).
pub const IGTL_DEVICE_ERROR: u16 = 4;
/// OpenIGTLink STATUS code 10: "Configuration error" (parameter out of range).
pub const IGTL_CONFIGURATION_ERROR: u16 = 10;
/// OpenIGTLink STATUS code 13: "Not ready".
pub const IGTL_NOT_READY: u16 = 13;

/// The board's state in one word (the console's state field).
pub fn state_label(s: RobotState) -> &'static str {
    match s {
        RobotState::Boot => "Starting",
        RobotState::Disabled => "Disabled",
        RobotState::Homing => "Homing",
        RobotState::Ready => "Ready",
        RobotState::Enabled => "Enabled",
        RobotState::Fault => "Fault",
        RobotState::Enabling => "Enabling",
        RobotState::Commissioning => "Commissioning",
    }
}

/// Why the board last reset, in words.
pub fn reset_cause(c: ResetCause) -> &'static str {
    match c {
        ResetCause::PowerOn => "power-on",
        ResetCause::Pin => "reset pin",
        ResetCause::Software => "software reset",
        ResetCause::Watchdog => "watchdog",
        ResetCause::WindowWatchdog => "window watchdog",
        ResetCause::BrownOut => "brown-out (supply dip)",
        ResetCause::LowPower => "low-power reset",
    }
}

/// The board's state in plain words.
pub fn state(s: RobotState) -> &'static str {
    match s {
        RobotState::Boot => "starting",
        RobotState::Disabled => "disabled (drives off)",
        RobotState::Homing => "homing",
        RobotState::Ready => "ready (homed, drives off)",
        RobotState::Enabled => "enabled (following targets)",
        RobotState::Fault => "fault",
        RobotState::Enabling => "enabling (checking the brakes)",
        RobotState::Commissioning => "commissioning (testing the wiring)",
    }
}

/// A commissioning finding in plain words: what the board found, and the fix it implies
/// (`master_link::CommissionFindings`; the board profile's keys are named where the fix is
/// a correction in it).
pub fn commission_finding(f: master_link::CommissionFindings) -> (&'static str, &'static str) {
    use master_link::CommissionFindings as F;
    match f {
        F::MOTOR_REVERSED => (
            "the motor turns the wrong way: a positive duty moved the joint towards -q",
            "swap the motor's two leads at the driver (or set invert_motor = true)",
        ),
        F::ENCODER_REVERSED => (
            "the encoder counts the wrong way: it counts down as the joint moves towards +q",
            "swap the encoder's A and B wires (or set invert_encoder = true)",
        ),
        F::DIRECTION_MISMATCH => (
            "the encoder counted down under a positive duty (no second channel to tell whether the motor or the encoder is reversed)",
            "watch the joint: if it moved towards -q, swap the motor's leads; otherwise swap the encoder's A and B",
        ),
        F::ENCODER_SWAPPED => (
            "another joint's encoder counted this joint's motion: the encoder cables are swapped",
            "swap the two encoder connectors (or set encoder_channel to the one that moved)",
        ),
        F::SCALE => (
            "the encoder's counts per unit differ from the board profile's by more than 5 %",
            "check the gear ratio and the encoder's lines; set gear_ratio to the measured value",
        ),
        F::SWITCH_INVERTED => (
            "the home switch reads actuated where the joint is away from it",
            "fit a normally closed switch (contact to GND, opens when actuated) or rewire it to its NC contact",
        ),
        F::SWITCH_ACTUATED => (
            "the home switch reads actuated at rest (no second channel to tell whether the joint is at it)",
            "if the joint is not at its switch, wire the switch's NC contact",
        ),
        F::BRAKE_INVERTED => (
            "the joint moved with its brake applied and stood with it released: the brake is inverted",
            "fit a spring-applied brake (holds unpowered) or correct its coil's output",
        ),
        F::BRAKE_NOT_HOLDING => (
            "the joint moved with its brake applied and released alike: the brake does not hold",
            "check the brake's air gap, its wiring and its holding torque",
        ),
        F::NO_MOTION => (
            "nothing moved at the test's torque with the brake released",
            "check that the brake releases (its coil's supply), the motor's connection and the encoder",
        ),
        F::CURRENT_OFFSET => (
            "the current sense reads more than 20 mA at zero current",
            "check the sense amplifier's reference (1.65 V at 0 A); apply the offset shown",
        ),
        F::CURRENT_SIGN => (
            "the current sense reads against the duty",
            "swap the sense amplifier's inputs (or invert the current's sign)",
        ),
        F::DRIVER_FAULT_LINE => (
            "the drivers' fault line reads a fault with the drives off; nothing was driven",
            "check the driver (its supply, its own fault) and the nFAULT line's pull-up",
        ),
        F::TRAVEL_EXCEEDED => (
            "a joint moved beyond the test's travel limit; the test stopped at once",
            "find out why before going on: a loose coupling, a runaway, a sensor on the wrong joint",
        ),
        _ => ("several findings", "see each"),
    }
}

/// The stop in force in plain words, or `None` when none is: a robot that is not
/// enabled has its drives off after a completed stop (`SafeStop1Done`, `SafeTorqueOff`),
/// which is its normal rest, not a stop to report; in `Fault` every stop is reported.
pub fn stop(state: RobotState, stop: StopStatus) -> Option<&'static str> {
    let at_rest = matches!(
        state,
        RobotState::Boot | RobotState::Disabled | RobotState::Ready | RobotState::Homing
    );
    match stop {
        StopStatus::None => None,
        StopStatus::SafeTorqueOff | StopStatus::SafeStop1Done if at_rest => None,
        StopStatus::SafeTorqueOff => Some("torque off, brakes on"),
        StopStatus::SafeStop1Decelerating => Some("stopping, decelerating"),
        StopStatus::SafeStop1Braking => Some("stopping, brakes engaging"),
        StopStatus::SafeStop1Done => Some("stopped, brakes on"),
        StopStatus::SafeStop2Decelerating => Some("holding, decelerating"),
        StopStatus::SafeOperatingStop => Some("holding position"),
    }
}

/// The value of a fault in words with its unit, if the cause has one.
fn fault_value(rec: &FaultRecord) -> Option<String> {
    let v = f64::from(rec.value);
    let joint = (rec.joint != NO_JOINT).then_some(rec.joint);
    let in_joint_unit = |v: f64| match joint {
        Some(j) => {
            let (x, unit) = joint_value(j, v);
            format!("{x:.2} {unit}")
        }
        None => format!("{v:.4}"),
    };
    Some(match rec.cause {
        FaultCause::None
        | FaultCause::EmergencyStopButton
        | FaultCause::EmergencyStopMessage
        | FaultCause::DriverFault
        | FaultCause::NonFiniteInput => return None,
        FaultCause::SafetyRelayMismatch => {
            if rec.value == 1.0 {
                "button pressed, relay closed".to_string()
            } else {
                "button released, relay open".to_string()
            }
        }
        FaultCause::HeartbeatTimeout => format!("{v:.0} ms without a heartbeat"),
        FaultCause::JointLimit | FaultCause::LimitSwitch => format!("at {}", in_joint_unit(v)),
        FaultCause::FollowingError => format!("error {}", in_joint_unit(v)),
        FaultCause::StandstillLost | FaultCause::BrakeCheck => {
            format!("moved {}", in_joint_unit(v))
        }
        FaultCause::NoMotion | FaultCause::MotorOpen => format!("duty {:.0} %", v * 100.0),
        FaultCause::EncoderJump => format!("{v:.0} counts in one tick"),
        FaultCause::EncoderDead => format!("{v:.0} counts of motion expected"),
        FaultCause::CurrentImplausible | FaultCause::Overcurrent | FaultCause::Overload => {
            format!("{v:.2} A")
        }
        FaultCause::OverTemperature => format!("{:.0} % of the heat limit", v * 100.0),
        FaultCause::SupplyVoltage => format!("{v:.1} V"),
        FaultCause::HomingFailed => format!("homing error {v:.0}"),
        FaultCause::Singularity => format!("measure {v:.3}"),
        FaultCause::GuardStop => format!("value {v:.4}"),
        FaultCause::ForwardKinematics => format!("{v:.0} failures in a row"),
        FaultCause::DeadlineMissed => format!("{v:.0} µs late"),
        FaultCause::Internal => format!("code {v:.0}"),
        FaultCause::EncoderDisagree => {
            format!("encoder and second channel differ by {}", in_joint_unit(v))
        }
        FaultCause::PositionSensor => format!("second channel reading {v:.4}"),
    })
}

/// A fault in words: its cause, the joint by name and the value with its unit, e.g.
/// "following error on leg 2: error 1.20 mm", "e-stop message"; `None` for no fault.
pub fn fault(rec: &FaultRecord) -> Option<String> {
    if rec.cause == FaultCause::None {
        return None;
    }
    let mut s = rec.cause.name().to_string();
    if let Some(j) = joint_name(rec.joint) {
        s.push_str(" on ");
        s.push_str(&j);
    }
    if let Some(v) = fault_value(rec) {
        s.push_str(": ");
        s.push_str(&v);
    }
    Some(s)
}

/// A board time (ms since its boot) in words: "board time 51.364 s".
pub fn board_time(ms: u32) -> String {
    format!("board time {:.3} s", f64::from(ms) / 1e3)
}

/// One guard margin as the status reports it: a share of the guard's range left (1: far,
/// 0: at the stop level), with the share at which the board warns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margin {
    /// The guard, in words.
    pub guard: &'static str,
    /// The share of its range left, 0..1 (NaN: not known).
    pub left: f32,
    /// The share below which the board warns (`None`: it stops without warning first).
    pub warn: Option<f32>,
}

/// The margins of a status, each with its warn level: the stroke and link ranges warn
/// under 10 % (the board's `NEAR_JOINT_LIMIT`), the singularity measures where their warn
/// level lies in their range (the reference limits); the tilt, collision and workspace
/// guards stop without a warn level. All stop at 0 %.
pub fn margins(m: &GuardMargins) -> [Margin; 6] {
    let l = Limits::<f64>::reference();
    let share = |warn: f64, stop: f64| ((warn - stop) / (1.0 - stop)) as f32;
    [
        Margin {
            guard: "stroke",
            left: m.stroke,
            warn: Some(0.1),
        },
        Margin {
            guard: "tilt",
            left: m.tilt,
            warn: None,
        },
        Margin {
            guard: "collision",
            left: m.collision,
            warn: None,
        },
        Margin {
            guard: "workspace",
            left: m.workspace,
            warn: None,
        },
        Margin {
            guard: "serial singularity",
            left: m.serial,
            warn: Some(share(l.serial.warn, l.serial.stop)),
        },
        Margin {
            guard: "parallel singularity",
            left: m.parallel,
            warn: Some(share(l.parallel.warn, l.parallel.stop)),
        },
    ]
}

/// One margin in words: "stroke 17 % of its range left (warns under 10 %, stops at 0 %)".
pub fn margin(m: &Margin) -> String {
    if !m.left.is_finite() {
        return format!("{}: not known (the supervisor is not running)", m.guard);
    }
    let warn = match m.warn {
        Some(w) => format!("warns under {:.0} %, ", w * 100.0),
        None => String::new(),
    };
    format!(
        "{} {:.0} % of its range left ({warn}stops at 0 %)",
        m.guard,
        m.left * 100.0
    )
}

/// The nearest margin of a status, short (the console's line): "stroke 17 % left (warn
/// < 10 %, stop 0 %)", or "--" when none is known.
pub fn nearest_margin_short(m: &GuardMargins) -> String {
    let all = margins(m);
    let Some(n) = all
        .iter()
        .filter(|x| x.left.is_finite())
        .min_by(|a, b| a.left.total_cmp(&b.left))
    else {
        return "--".to_string();
    };
    let warn = match n.warn {
        Some(w) => format!("warn < {:.0} %, ", w * 100.0),
        None => String::new(),
    };
    format!("{} {:.0} % left ({warn}stop 0 %)", n.guard, n.left * 100.0)
}

/// The nearest margin of a status in words ([`margin`]), or that none is known.
pub fn nearest_margin(m: &GuardMargins) -> String {
    let all = margins(m);
    let nearest = all
        .iter()
        .filter(|x| x.left.is_finite())
        .min_by(|a, b| a.left.total_cmp(&b.left));
    match nearest {
        Some(n) => format!("nearest: {}", margin(n)),
        None => "margins not known (the supervisor is not running)".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(guard: GuardId, subject: u8, value: f32, limit: f32) -> Breach {
        Breach {
            guard,
            subject,
            value,
            limit,
        }
    }

    /// Each guard's breach names the guard, what it concerns, the value and the limit with
    /// their unit at the edge.
    #[test]
    fn breaches_name_guard_subject_value_and_limit() {
        let cases = [
            (
                b(GuardId::Workspace, 2, 0.177, 0.175),
                "workspace z 177.0 mm > 175.0 mm",
            ),
            (
                b(GuardId::Stroke, 1, 0.2124, 0.210),
                "stroke leg 2 212.4 mm > 210.0 mm",
            ),
            (
                b(GuardId::Stroke, 0, 0.1402, 0.144),
                "stroke leg 1 140.2 mm < 144.0 mm",
            ),
            (
                b(GuardId::Tilt, 2, 31.5f32.to_radians(), 30f32.to_radians()),
                "tilt spherical joint 3 31.5 deg > 30.0 deg",
            ),
            (
                b(GuardId::SerialSingularity, 0, 0.04, 0.05),
                "serial singularity chain 1 0.040 < 0.050",
            ),
            (
                b(GuardId::Step, NO_JOINT, 0.24, 0.06),
                "step from the setpoint 240.0 mm > 60.0 mm",
            ),
            (
                b(GuardId::Age, NO_JOINT, 0.2, 0.1),
                "target age 200 ms > 100 ms",
            ),
            (
                b(GuardId::JointSpeed, 4, 3.5, 3.0),
                "joint speed link 2 200.5 deg/s > 171.9 deg/s",
            ),
        ];
        for (breach_, text) in cases {
            assert_eq!(breach(&breach_).as_deref(), Some(text));
        }
        assert_eq!(breach(&Breach::NONE), None);
    }

    /// A refusal without a measurement reads as its rule.
    #[test]
    fn refusal_without_measurement_names_the_rule() {
        let r = RefusedTarget {
            reason: NackReason::NotHomed,
            ..RefusedTarget::default()
        };
        assert_eq!(refusal(&r), "not homed: home the robot first");
    }

    /// Every reason fits the console's line.
    #[test]
    fn reasons_fit_one_line() {
        use NackReason as N;
        for r in [
            N::UnsupportedVersion,
            N::NotConnected,
            N::InvalidState,
            N::NotHomed,
            N::Faulted,
            N::FaultStillActive,
            N::InvalidJoint,
            N::InvalidValue,
            N::OutOfWorkspace,
            N::JointLimit,
            N::NearSingularity,
            N::VelocityLimit,
            N::StaleTarget,
            N::ClutchDisengaged,
            N::Busy,
            N::AlreadyHomed,
            N::ResetNotAcknowledged,
            N::SafetyRelayMismatch,
            N::BrakeCheckFailed,
            N::OperatorAbsent,
            N::NotOwner,
            N::TargetFromFuture,
            N::ReplayedHello,
        ] {
            assert!(reason(r).chars().count() <= 44, "{}", reason(r));
        }
    }

    /// A robot at rest after a completed stop shows no stop; a fault or a hold does.
    #[test]
    fn stop_line_is_empty_without_a_stop_in_force() {
        for s in [RobotState::Ready, RobotState::Disabled] {
            assert_eq!(stop(s, StopStatus::SafeStop1Done), None);
            assert_eq!(stop(s, StopStatus::SafeTorqueOff), None);
        }
        assert_eq!(stop(RobotState::Enabled, StopStatus::None), None);
        assert!(stop(RobotState::Fault, StopStatus::SafeTorqueOff).is_some());
        assert_eq!(
            stop(RobotState::Enabled, StopStatus::SafeOperatingStop),
            Some("holding position")
        );
    }

    /// Faults name the cause, the joint by name and the value in its unit.
    #[test]
    fn faults_name_cause_joint_and_value() {
        let rec = FaultRecord {
            cause: FaultCause::FollowingError,
            joint: 1,
            value: 0.0012,
            time_ms: 10,
        };
        assert_eq!(
            fault(&rec).as_deref(),
            Some("following error on leg 2: error 1.20 mm")
        );
        let rec = FaultRecord {
            cause: FaultCause::EmergencyStopMessage,
            joint: NO_JOINT,
            value: 0.0,
            time_ms: 51_364,
        };
        assert_eq!(fault(&rec).as_deref(), Some("e-stop message"));
        assert_eq!(board_time(rec.time_ms), "board time 51.364 s");
        let rec = FaultRecord {
            cause: FaultCause::JointLimit,
            joint: 4,
            value: 1.5f32.to_radians() + 1.0,
            time_ms: 0,
        };
        assert!(fault(&rec).is_some_and(
            |s| s.starts_with("joint out of range on link 2: at ") && s.ends_with(" deg")
        ));
        assert_eq!(fault(&FaultRecord::NONE), None);
    }

    /// Margins carry their unit (a share of the range, %) and their warn and stop levels.
    #[test]
    fn margins_have_units_and_levels() {
        let m = GuardMargins {
            nearest: 0.17,
            serial: 0.5,
            parallel: 0.6,
            stroke: 0.17,
            tilt: 0.8,
            collision: 0.9,
            workspace: 0.4,
        };
        assert_eq!(
            nearest_margin(&m),
            "nearest: stroke 17 % of its range left (warns under 10 %, stops at 0 %)"
        );
        let nan = GuardMargins {
            nearest: f32::NAN,
            serial: f32::NAN,
            parallel: f32::NAN,
            stroke: f32::NAN,
            tilt: f32::NAN,
            collision: f32::NAN,
            workspace: f32::NAN,
        };
        assert!(nearest_margin(&nan).contains("not known"));
        assert_eq!(
            nearest_margin_short(&m),
            "stroke 17 % left (warn < 10 %, stop 0 %)"
        );
        assert_eq!(nearest_margin_short(&nan), "--");
        // The serial warn level from the reference limits: (0.15 - 0.05) / (1 - 0.05).
        assert!(margins(&m)[4]
            .warn
            .is_some_and(|w| (w - 0.10526).abs() < 1e-4));
    }
}
