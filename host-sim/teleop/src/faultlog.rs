//! The board's fault log over the link (`host-sim faultlog`): Hello, then the log page by
//! page (`FaultLogRequest`), printed as a table: when (ms since the board's boot), the
//! cause, the joint, the value with its unit, the stop it caused and how many times it
//! repeated; with the reset the board reports (a watchdog reset keeps the log).

use std::fmt::Write as _;

use master_link::{
    BoardToMaster, FaultCause, FaultLogEntry, MasterToBoard, ResetStatus, FAULT_LOG_PAGE, NO_JOINT,
};

use crate::session::Session;
use crate::TeleopError;

/// The joint names in joint order.
const JOINTS: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// The unit of a cause's value.
pub fn value_unit(cause: FaultCause, joint: u8) -> &'static str {
    let leg = joint < 3;
    match cause {
        FaultCause::JointLimit
        | FaultCause::LimitSwitch
        | FaultCause::FollowingError
        | FaultCause::StandstillLost
        | FaultCause::BrakeCheck => {
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

/// Reads the whole log: the reset the board reported and every entry, oldest first.
pub fn read(s: &mut Session) -> Result<(ResetStatus, Vec<FaultLogEntry>), TeleopError> {
    s.hello(5.0)?;
    let reset = s.reset.unwrap_or_default();
    let mut entries = Vec::new();
    let mut first = 0u16;
    loop {
        let seq = s.send(MasterToBoard::FaultLogRequest { first })?;
        let page = match s.reply(seq, 2.0)? {
            BoardToMaster::FaultLog(page) => page,
            other => {
                return Err(TeleopError::UnexpectedReply {
                    request: "FaultLogRequest",
                    reply: format!("{other:?}"),
                })
            }
        };
        let n = usize::from(page.count).min(FAULT_LOG_PAGE);
        entries.extend(page.entries.iter().take(n).copied());
        first = first.saturating_add(u16::from(page.count));
        if page.count == 0 || first >= page.len {
            break;
        }
    }
    Ok((reset, entries))
}

/// The log as a table.
pub fn table(reset: &ResetStatus, entries: &[FaultLogEntry]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "last reset: {:?}{}",
        reset.cause,
        if reset.acknowledged {
            ""
        } else {
            " (not acknowledged: the board will not enable until the master acknowledges it)"
        }
    );
    let _ = writeln!(o, "{} entries, oldest first", entries.len());
    let _ = writeln!(
        o,
        "{:>10}  {:<22} {:<7} {:>14} {:<10} {:<22} {:>5}",
        "time ms", "cause", "joint", "value", "unit", "stop", "count"
    );
    for e in entries {
        let r = e.record;
        let joint = if r.joint == NO_JOINT {
            "-".to_string()
        } else {
            JOINTS
                .get(usize::from(r.joint))
                .map_or(r.joint.to_string(), |n| n.to_string())
        };
        let _ = writeln!(
            o,
            "{:>10}  {:<22} {:<7} {:>14.6} {:<10} {:<22} {:>5}",
            r.time_ms,
            format!("{:?}", r.cause),
            joint,
            r.value,
            value_unit(r.cause, r.joint),
            format!("{:?}", e.stop),
            e.count
        );
    }
    o
}
