//! The watchdog: the core stalled long enough for the control tick to miss its deadline; the
//! firmware logs `DeadlineMissed`, stops (STO) and starves the IWDG, which resets the part;
//! after the reset the board reports the watchdog reset unacknowledged, keeps the fault log,
//! and, once homed, refuses to enable until the master acknowledges it. The run does this
//! before its homing, so that one homing (33 s of virtual time) serves both.
//!
//! How the tick is starved: the emulator holds the core (`Host::hold`) for 2 ms while the
//! clock and every peripheral run on (the time driver's TIM12, the IWDG on the LSI), as a
//! bus stall does: a flash erase or program of the bank the core fetches from stalls its
//! fetches (RM0090 rev 19 section 3.5.x: "any attempt to read the flash memory while it is
//! being written or erased causes the bus to stall"), a debugger's halt with the timers not
//! frozen. The firmware is not changed and not told: it finds its next tick 2 ms late.

use master_link::{
    BoardToMaster, FaultCause, MasterToBoard, NackReason, ResetCause, ResetStatus, RobotState,
    StopStatus, Warnings,
};

use super::{Run, ScenarioError};
use board_emulator::bench::Action;

/// How long the core is held, ns: past the deadline policy's 250 µs lateness, short of the
/// IWDG's 10 ms timeout (so that the firmware itself sees the late tick and logs it).
pub const HOLD_NS: u64 = 2_000_000;

/// The stall, the reset, and the board after it.
pub fn starved(run: &mut Run) -> Result<(), ScenarioError> {
    let resets_before = run.rig.lock().bench.last.resets.len();
    let since = run.s.statuses.len();
    let t0 = run.now_ns();
    run.act(Action::HoldCore(HOLD_NS));
    // Until the reset (at most 50 ms).
    let mut reset = None;
    for _ in 0..50 {
        run.wait(0.001)?;
        reset = run.rig.lock().bench.last.resets.get(resets_before).cloned();
        if reset.is_some() {
            break;
        }
    }
    let seen_before = run
        .rows_since(since)
        .into_iter()
        .find(|r| r.status.fault.cause == FaultCause::DeadlineMissed);
    // The board boots again: Hello (teleop's), the reply's reset status.
    run.s.hello = None;
    run.wait(0.05)?;
    let hello_since = run.rig.lock().messages.len();
    run.s.hello(1.0)?;
    let reply = {
        let rig = run.rig.lock();
        rig.messages
            .get(hello_since..)
            .unwrap_or_default()
            .iter()
            .rev()
            .find_map(|r| match r.msg {
                BoardToMaster::HelloReply { reset, .. } => Some(reset),
                _ => None,
            })
    };
    let since = run.s.statuses.len();
    run.wait(0.1)?;
    let status = run.rows_since(since).last().map(|r| r.status);
    // The fault log, read over the link.
    let pages = run.s.fault_log.len();
    run.s.send(MasterToBoard::FaultLogRequest { first: 0 })?;
    let end = run.now_s() + 0.5;
    while run.s.fault_log.len() == pages && run.now_s() < end {
        run.wait(0.01)?;
    }
    let page = run.s.fault_log.get(pages).copied();
    let entries: Vec<master_link::FaultLogEntry> = page.map_or(Vec::new(), |p| {
        p.entries
            .iter()
            .take(usize::from(p.count))
            .copied()
            .collect()
    });
    let logged = entries
        .iter()
        .find(|e| e.record.cause == FaultCause::DeadlineMissed);
    let unacknowledged = ResetStatus {
        cause: ResetCause::Watchdog,
        acknowledged: false,
    };
    let fresh = status.is_some_and(|s| {
        s.state == RobotState::Disabled
            && s.warnings.contains(Warnings::NOT_HOMED)
            && s.reset == unacknowledged
    });
    run.check(
        "a starved tick: DeadlineMissed logged, the IWDG resets the part, the reset reported unacknowledged, the log kept",
        reset.as_ref().is_some_and(|r| r.cause == "IWDG")
            && reply == Some(unacknowledged)
            && fresh
            && logged.is_some_and(|e| e.stop == StopStatus::SafeTorqueOff),
        format!(
            "core held for {:.1} ms at {:.3} s; reset {}; status with DeadlineMissed before the reset: {}; after it HelloReply reset {:?}, status {:?} / NOT_HOMED {} / reset {:?}; fault log over the link: {} kept ({} ever), {}",
            HOLD_NS as f64 / 1e6,
            t0 as f64 / 1e9,
            reset.as_ref().map_or("none".to_string(), |r| format!(
                "by {} {:.3} ms after the hold began",
                r.cause,
                r.at.0.saturating_sub(t0) as f64 / 1e6
            )),
            seen_before.map_or("none (the IWDG was faster than the 20 ms telemetry)".to_string(), |r| format!(
                "{:?} value {:.0} us",
                r.status.stop, r.status.fault.value
            )),
            reply,
            status.map(|s| s.state),
            status.is_some_and(|s| s.warnings.contains(Warnings::NOT_HOMED)),
            status.map(|s| s.reset),
            page.map_or(0, |p| p.len),
            page.map_or(0, |p| p.total),
            match logged {
                Some(e) => format!(
                    "DeadlineMissed at {} ms of the previous boot, {:.0} us late, stop {:?}; entries {:?}",
                    e.record.time_ms,
                    e.record.value,
                    e.stop,
                    entries.iter().map(|e| e.record.cause).collect::<Vec<_>>()
                ),
                None => format!(
                    "no DeadlineMissed among {:?}",
                    entries.iter().map(|e| e.record.cause).collect::<Vec<_>>()
                ),
            }
        ),
    );
    Ok(())
}

/// After the watchdog reset: `Home` refused (`ResetNotAcknowledged`) until the master
/// acknowledges the reset (nothing moves before a person has); then the reset reads
/// acknowledged.
pub fn acknowledge(run: &mut Run) -> Result<(), ScenarioError> {
    let refused = run.s.request(MasterToBoard::Home { rehome: false }, 1.0)?;
    let ack = run.s.request(MasterToBoard::AcknowledgeReset, 1.0)?;
    let since = run.s.statuses.len();
    let row = run.wait_for(since, 0.2, |s| s.reset.acknowledged)?;
    let st = row.map(|r| r.status);
    run.check(
        "after the watchdog reset Home is refused (ResetNotAcknowledged) until AcknowledgeReset",
        refused == Some(NackReason::ResetNotAcknowledged)
            && ack.is_none()
            && st.is_some_and(|s| {
                s.state == RobotState::Disabled
                    && s.reset
                        == ResetStatus {
                            cause: ResetCause::Watchdog,
                            acknowledged: true,
                        }
            }),
        format!(
            "Home answered {refused:?}; AcknowledgeReset {}; then {:?} with reset {:?}",
            ack.map_or("Ack".to_string(), |r| format!("Nack {r:?}")),
            st.map(|s| s.state),
            st.map(|s| s.reset)
        ),
    );
    Ok(())
}

/// The end of the run: enabled once more, then Disable (SS1 done, Ready).
pub fn disable(run: &mut Run) -> Result<(), ScenarioError> {
    let enabled = run.enable()?;
    let since = run.s.statuses.len();
    let nack = run.s.request(MasterToBoard::Disable, 1.0)?;
    let ready = run.wait_for(since, 1.0, |s| {
        s.state == RobotState::Ready && s.stop == StopStatus::None
    })?;
    run.check(
        "enables once more and disables at the end (SS1 done, Ready)",
        enabled.is_none() && nack.is_none() && ready.is_some(),
        format!(
            "Enable {enabled:?}; Disable {nack:?}; Ready, the stop over: {}",
            ready.is_some()
        ),
    );
    Ok(())
}
