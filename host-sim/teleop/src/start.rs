//! The board a front end finds when it connects, in words, and what the person must decide.
//!
//! Every front end (`host-sim teleop`, with or without `--device`, `host-sim igtl`, the
//! console) starts from whatever state the board is in: a robot homed already is not homed
//! again, and two things are never done without the person's say-so:
//!
//! - **a watchdog or brown-out reset** the board reports unacknowledged means the board
//!   stopped itself; nobody should move the robot before finding out why (`host-sim
//!   faultlog`). The front ends refuse to go on and name the cause and what acknowledges it:
//!   the flag `--acknowledge-reset` (typed knowingly) or the console's key `a` (with a
//!   confirmation that names the cause);
//! - **a latched fault** is shown in plain words (cause, joint, value with its unit) and
//!   cleared only with `--clear-fault` or the console's key `c`.
//!
//! A robot enabled (or homing, or enabling) under another master, and a `Hello` the board
//! refuses because another master owns it, end the front end with the reason.

use master_link::{FaultCause, FaultRecord, NackReason, ResetCause, RobotState, NO_JOINT};

/// What the person allowed at start (`--acknowledge-reset`, `--clear-fault`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StartOptions {
    /// Acknowledge an unacknowledged watchdog or brown-out reset.
    pub acknowledge_reset: bool,
    /// Clear a latched fault.
    pub clear_fault: bool,
}

/// The joints' names in the board's order.
const JOINT_NAMES: [&str; 6] = ["l1", "l2", "l3", "th1", "th2", "th3"];

/// A reset cause in words.
pub fn reset_words(cause: ResetCause) -> &'static str {
    match cause {
        ResetCause::PowerOn => "power-on",
        ResetCause::Pin => "reset pin",
        ResetCause::Software => "software reset",
        ResetCause::Watchdog => "watchdog reset (the board stopped itself: a tick or a task hung)",
        ResetCause::WindowWatchdog => "window watchdog reset (the control loop ran off its period)",
        ResetCause::BrownOut => "brown-out reset (the supply dipped)",
        ResetCause::LowPower => "low-power reset",
    }
}

/// Why a front end does not go on past an unacknowledged reset, with the two ways to
/// acknowledge it.
pub fn unacknowledged_reset_text(cause: ResetCause) -> String {
    format!(
        "the board's last reset ({cause:?}: {}) is not acknowledged; find out why first (host-sim faultlog --connect ...), then acknowledge it knowingly: --acknowledge-reset, or the console's key a",
        reset_words(cause)
    )
}

/// A fault cause in words.
pub fn fault_words(cause: FaultCause) -> &'static str {
    match cause {
        FaultCause::None => "no fault",
        FaultCause::EmergencyStopButton => "the e-stop button was pressed",
        FaultCause::EmergencyStopMessage => "a master sent a stop",
        FaultCause::SafetyRelayMismatch => "the e-stop button and the safety relay disagree",
        FaultCause::HeartbeatTimeout => "the master's heartbeat was lost",
        FaultCause::JointLimit => "a joint left its range",
        FaultCause::LimitSwitch => "a limit switch closed",
        FaultCause::FollowingError => "a joint did not follow its setpoint",
        FaultCause::NoMotion => "a joint was driven hard and did not move",
        FaultCause::EncoderJump => "an encoder jumped",
        FaultCause::EncoderDead => "an encoder does not count",
        FaultCause::MotorOpen => "a motor circuit is open",
        FaultCause::CurrentImplausible => "a motor current does not fit its model",
        FaultCause::Overcurrent => "a motor current tripped",
        FaultCause::Overload => "a joint pushed with its rated force too long",
        FaultCause::OverTemperature => "a motor ran too hot (I2t)",
        FaultCause::DriverFault => "a motor driver reported a fault",
        FaultCause::SupplyVoltage => "the supply voltage left its range",
        FaultCause::HomingFailed => "homing failed",
        FaultCause::Singularity => "the supervisor stopped at a singularity",
        FaultCause::GuardStop => "the supervisor stopped at a guard",
        FaultCause::ForwardKinematics => "the forward kinematics failed",
        FaultCause::DeadlineMissed => "the control tick missed its deadline",
        FaultCause::StandstillLost => "the robot moved during a safe stop",
        FaultCause::BrakeCheck => "a holding brake failed its check",
        FaultCause::NonFiniteInput => "a value that is not a number reached the servo",
        FaultCause::EncoderDisagree => {
            "an encoder disagrees with the joint's second position sensor (stuck, dead or miscounting)"
        }
        FaultCause::PositionSensor => "a joint's second position sensor failed",
        FaultCause::Internal => "an internal error",
    }
}

/// The unit of a cause's value.
pub fn value_unit(cause: FaultCause, joint: u8) -> &'static str {
    let leg = joint < 3;
    match cause {
        FaultCause::JointLimit
        | FaultCause::LimitSwitch
        | FaultCause::FollowingError
        | FaultCause::StandstillLost
        | FaultCause::BrakeCheck
        | FaultCause::EncoderDisagree => {
            if leg {
                "m"
            } else {
                "rad"
            }
        }
        FaultCause::EncoderJump | FaultCause::EncoderDead => "counts",
        FaultCause::Overcurrent | FaultCause::Overload | FaultCause::CurrentImplausible => "A",
        FaultCause::SupplyVoltage => "V",
        FaultCause::HeartbeatTimeout => "ms",
        FaultCause::DeadlineMissed => "us late",
        FaultCause::OverTemperature => "x rating",
        FaultCause::NoMotion | FaultCause::MotorOpen => "duty",
        FaultCause::HomingFailed => "code",
        _ => "",
    }
}

/// A latched fault in plain words: what happened, the joint, the value with its unit.
pub fn fault_text(f: &FaultRecord) -> String {
    let joint = if f.joint == NO_JOINT {
        String::new()
    } else {
        format!(
            ", joint {}",
            JOINT_NAMES
                .get(usize::from(f.joint))
                .copied()
                .unwrap_or("?")
        )
    };
    format!(
        "{} ({:?}{joint}, value {} {})",
        fault_words(f.cause),
        f.cause,
        f.value,
        value_unit(f.cause, f.joint)
    )
}

/// Why a front end does not go on past a latched fault.
pub fn latched_fault_text(f: &FaultRecord) -> String {
    format!(
        "the board has a latched fault: {}; clear it knowingly: --clear-fault, or the console's key c",
        fault_text(f)
    )
}

/// Why a front end does not take a robot that is moving or held under another master
/// (`Some`), or `None` when the state lets it start.
pub fn busy_text(state: RobotState) -> Option<String> {
    match state {
        RobotState::Enabled | RobotState::Enabling | RobotState::Homing => Some(format!(
            "the robot is {state:?} under another session: disable it from the master that runs it (or the console's key d) first"
        )),
        _ => None,
    }
}

/// Why the board refused this master's `Hello`, in words.
pub fn hello_refused_text(reason: NackReason) -> String {
    match reason {
        NackReason::NotOwner => "the board refused the Hello (NotOwner): another master owns the robot and it is not disabled; disable it there first".into(),
        NackReason::ReplayedHello => "the board refused the Hello (ReplayedHello): this master's clock is not newer than the owner's last".into(),
        other => format!("the board refused the Hello ({other:?})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The refusals name the cause and the flag or key that resolves it.
    #[test]
    fn texts_name_the_cause_and_the_remedy() {
        let r = unacknowledged_reset_text(ResetCause::Watchdog);
        assert!(r.contains("Watchdog") && r.contains("--acknowledge-reset") && r.contains("key a"));
        let f = FaultRecord {
            cause: FaultCause::HeartbeatTimeout,
            joint: NO_JOINT,
            value: 512.0,
            ..FaultRecord::default()
        };
        let t = latched_fault_text(&f);
        assert!(
            t.contains("heartbeat was lost") && t.contains("512 ms"),
            "{t}"
        );
        assert!(t.contains("--clear-fault") && t.contains("key c"), "{t}");
        assert!(busy_text(RobotState::Ready).is_none());
        assert!(busy_text(RobotState::Enabled).is_some_and(|t| t.contains("Enabled")));
    }
}
