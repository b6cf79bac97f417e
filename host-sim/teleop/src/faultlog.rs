//! The board's logs over the link (`host-sim faultlog`): Hello, then
//!
//! * the fault log page by page (`FaultLogRequest`), printed as a table: when (ms since
//!   the board's boot), the cause, the joint, the value with its unit, the stop it caused
//!   and how many times it repeated; with the reset the board reports (a watchdog reset
//!   keeps the log);
//! * the non-volatile event log page by page (`EventLogRequest`; a power cycle keeps it),
//!   printed in plain words, one entry a line: the boot and the time in it, how many times
//!   it happened, and what (a fault with its joint, value and stop; a stop that is not a
//!   fault; a reset and its cause; a master taking charge; a geometry stored; the safety
//!   relay's test latched or passed; entries lost).

use std::fmt::Write as _;

use master_link::{
    BoardToMaster, EventEntry, EventKind, EventLogPage, FaultLogEntry, MasterToBoard, ResetCause,
    ResetStatus, StopReason, StopStatus, EVENT_LOG_PAGE, FAULT_LOG_PAGE, NO_JOINT,
};

use crate::session::Session;
use crate::start::value_unit;
use crate::TeleopError;

/// The joint names in joint order.
const JOINTS: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

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
        "last reset: {}{}",
        board_words::reset_cause(reset.cause),
        if reset.acknowledged {
            ""
        } else {
            " (not acknowledged: the board will not enable until the master acknowledges it)"
        }
    );
    let _ = writeln!(o, "{} entries, oldest first", entries.len());
    let _ = writeln!(
        o,
        "{:>10}  {:<22} {:<7} {:>14} {:<10} {:<26} {:>5}",
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
            "{:>10}  {:<22} {:<7} {:>14.6} {:<10} {:<26} {:>5}",
            r.time_ms,
            r.cause.name(),
            joint,
            r.value,
            value_unit(r.cause, r.joint),
            // A fault's stop, reported whatever the state (as in `Fault`).
            board_words::stop(master_link::RobotState::Fault, e.stop).unwrap_or("none"),
            e.count
        );
    }
    o
}

/// Reads the whole event log (after `read`'s Hello, or opening one): every entry the
/// board holds, oldest first, and the last page's header (the entry counter, the lost).
pub fn read_events(s: &mut Session) -> Result<(Vec<EventEntry>, EventLogPage), TeleopError> {
    if s.hello.is_none() {
        s.hello(5.0)?;
    }
    let mut entries = Vec::new();
    let mut first = 0u16;
    loop {
        let seq = s.send(MasterToBoard::EventLogRequest { first })?;
        let page = match s.reply(seq, 2.0)? {
            BoardToMaster::EventLog(page) => page,
            other => {
                return Err(TeleopError::Frame(format!(
                    "EventLogRequest answered with {other:?}"
                )))
            }
        };
        let n = usize::from(page.count).min(EVENT_LOG_PAGE);
        entries.extend(page.entries.iter().take(n).copied());
        first = first.saturating_add(u16::from(page.count));
        if page.count == 0 || first >= page.len {
            return Ok((entries, page));
        }
    }
}

/// A stop in words.
pub fn stop_words(stop: StopStatus) -> &'static str {
    match stop {
        StopStatus::None => "no stop",
        StopStatus::SafeTorqueOff => "STO: torque off, brakes applied",
        StopStatus::SafeStop1Decelerating => "SS1: decelerating",
        StopStatus::SafeStop1Braking => "SS1: at rest, brakes engaging",
        StopStatus::SafeStop1Done => "SS1 done: brakes applied, torque off",
        StopStatus::SafeStop2Decelerating => "SS2: decelerating, then holding",
        StopStatus::SafeOperatingStop => "safe operating stop: holding under power",
    }
}

/// A reset's cause in words.
pub fn reset_words(cause: ResetCause) -> &'static str {
    match cause {
        ResetCause::PowerOn => "power-on",
        ResetCause::Pin => "the reset pin",
        ResetCause::Software => "a software reset",
        ResetCause::Watchdog => "the watchdog",
        ResetCause::WindowWatchdog => "the window watchdog",
        ResetCause::BrownOut => "a brown-out (supply dip)",
        ResetCause::LowPower => "a low-power reset",
    }
}

fn joint_name(joint: u8) -> String {
    JOINTS
        .get(usize::from(joint))
        .map_or(joint.to_string(), |n| n.to_string())
}

/// What an entry of the event log records, in words.
pub fn event_words(e: &EventEntry) -> String {
    match e.event {
        EventKind::Fault {
            cause,
            joint,
            value,
            stop,
        } => {
            let mut w = format!("fault: {}", cause.name());
            if joint != NO_JOINT {
                let _ = write!(w, " on {}", joint_name(joint));
            }
            let unit = value_unit(cause, joint);
            if value != 0.0 || !unit.is_empty() {
                let _ = write!(w, ", value {value}");
                if !unit.is_empty() {
                    let _ = write!(w, " {unit}");
                }
            }
            let _ = write!(w, "; then {}", stop_words(stop));
            w
        }
        EventKind::Stop { reason, stop } => {
            let why = match reason {
                StopReason::Disable => "the master's Disable",
                StopReason::HeartbeatLate => "the master's heartbeat late: hold",
                StopReason::ClutchEngaged => "the master's clutch engaged: hold",
                StopReason::OperatorAbsent => "the operator let go of the dead-man: hold",
            };
            format!("stop: {why}; {}", stop_words(stop))
        }
        EventKind::Reset { cause } => format!("board started after {}", reset_words(cause)),
        EventKind::Master { id } => format!("a master took charge (session {id:#010x})"),
        EventKind::GeometryStored { version } => {
            format!("calibrated geometry version {version} stored in flash")
        }
        EventKind::RelayTest { pending: true } => "safety relay test pending: the board will \
             not home or enable until the e-stop is pressed and released after a power cycle"
            .to_string(),
        EventKind::RelayTest { pending: false } => "safety relay test passed".to_string(),
        EventKind::Lost { count } => {
            format!("{count} entries lost (they left the board's RAM before reaching flash)")
        }
    }
}

/// The event log in plain words, one entry a line, oldest first.
pub fn events_table(entries: &[EventEntry], page: &EventLogPage) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "event log (kept in flash across power cycles): {} entries, oldest first ({} logged ever{})",
        entries.len(),
        page.total,
        if page.lost > 0 {
            format!("; {} lost in this boot", page.lost)
        } else {
            String::new()
        }
    );
    let _ = writeln!(o, "{:>5} {:>12} {:>6}  what", "boot", "time s", "times");
    for e in entries {
        let _ = writeln!(
            o,
            "{:>5} {:>12.3} {:>6}  {}{}",
            e.boot,
            f64::from(e.time_ms) / 1000.0,
            e.count,
            event_words(e),
            if e.relay_test_pending && !matches!(e.event, EventKind::RelayTest { .. }) {
                " (relay test pending)"
            } else {
                ""
            }
        );
    }
    o
}
