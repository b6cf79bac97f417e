#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The simulated board's event log across a power cycle (`BoardSim::power_cycle`: a new
//! board on the same flash), read over the link by the in-process master.

use master_link::{
    EventEntry, EventKind, FaultCause, MasterToBoard, NackReason, ResetCause, RobotState,
    StopReason, StopStatus, NO_JOINT,
};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

fn bench(cfg: BoardSimConfig) -> Bench {
    Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x5e55,
    )
}

fn faults_of(entries: &[EventEntry], cause: FaultCause) -> Vec<EventEntry> {
    entries
        .iter()
        .filter(|e| matches!(e.event, EventKind::Fault { cause: c, .. } if c == cause))
        .copied()
        .collect()
}

/// Property: a power cycle keeps the event log: the resets of both boots (the boot counter
/// up by one), the master's session, the faults with their repeat counts (an e-stop message
/// sent three times in one boot is one entry of count 3), the stops that were not faults
/// (a Disable), and the relay test's latch: after a welded relay (the button pressed, the
/// relay's feedback still closed) and a power cycle, Home is refused with
/// `SafetyRelayMismatch` and Enable refused, until the relay passes its test (pressed: seen
/// open; released: seen closed), after which the board homes and enables.
#[test]
fn a_power_cycle_keeps_the_event_log_and_the_relay_test_latch() {
    let mut b = bench(BoardSimConfig::reference(None).unwrap());
    b.bring_up().unwrap();
    // A stop that is no fault.
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_ms(600).unwrap();
    assert_eq!(b.board.runtime().state(), RobotState::Ready);
    // The same fault three times in one boot.
    for _ in 0..3 {
        b.command(&MasterToBoard::EmergencyStop).unwrap();
        b.run_ms(50).unwrap();
        b.command(&MasterToBoard::ClearFault).unwrap();
        b.run_ms(50).unwrap();
    }
    // A welded relay: the button pressed, the relay's feedback stays closed.
    b.board.hw.relay_welded = true;
    b.board.press_estop(true);
    b.run_ms(100).unwrap();
    b.board.press_estop(false);
    b.run_ms(100).unwrap();
    assert!(b.board.runtime().relay_test_pending());
    let (before, _) = b.read_event_log().unwrap();
    b.run_ms(20).unwrap();
    assert_eq!(
        b.board.runtime().events().pending_len(),
        0,
        "everything written before the power goes"
    );
    let words = b.board.flash().events.words_programmed;

    // The power cycle (the relay replaced: the board's surroundings as at power-up).
    let mut b = b.power_cycle(0xb007).unwrap();
    b.run_ms(20).unwrap();
    let (after, page) = b.read_event_log().unwrap();
    // What the first boot logged is all there, with its counts (the second boot's entries
    // follow: its reset, its master).
    assert_eq!(&after[..before.len()], &before[..], "{after:#?}");
    let resets: Vec<(u16, EventKind)> = after
        .iter()
        .filter(|e| matches!(e.event, EventKind::Reset { .. }))
        .map(|e| (e.boot, e.event))
        .collect();
    assert_eq!(
        resets,
        vec![
            (
                1,
                EventKind::Reset {
                    cause: ResetCause::PowerOn
                }
            ),
            (
                2,
                EventKind::Reset {
                    cause: ResetCause::PowerOn
                }
            )
        ]
    );
    let estop = faults_of(&after, FaultCause::EmergencyStopMessage);
    assert_eq!(estop.len(), 1, "{estop:?}");
    assert_eq!(estop[0].count, 3);
    assert!(matches!(
        estop[0].event,
        EventKind::Fault {
            joint: NO_JOINT,
            stop: StopStatus::SafeTorqueOff,
            ..
        }
    ));
    let relay = faults_of(&after, FaultCause::SafetyRelayMismatch);
    assert_eq!(relay.len(), 1);
    assert!(
        relay[0].relay_test_pending,
        "the fault is written with the latch"
    );
    assert!(matches!(relay[0].event, EventKind::Fault { value, .. } if value == 1.0));
    assert!(after.iter().any(|e| e.event
        == EventKind::Stop {
            reason: StopReason::Disable,
            stop: StopStatus::SafeStop1Decelerating
        }));
    assert!(after
        .iter()
        .any(|e| e.event == EventKind::Master { id: 0x5e55 } && e.boot == 1));
    assert!(after
        .iter()
        .any(|e| e.event == EventKind::Master { id: 0xb007 } && e.boot == 2));
    assert!(after
        .iter()
        .any(|e| e.event == EventKind::RelayTest { pending: true }));
    assert_eq!(page.lost, 0);
    assert!(page.total as usize >= after.len());
    println!(
        "{} entries after the power cycle ({} words programmed in the first boot):",
        after.len(),
        words
    );
    for e in &after {
        println!("  {e:?}");
    }

    // The latch survived: Home and Enable refused until the relay test passes.
    assert!(b.board.runtime().relay_test_pending());
    assert_eq!(
        b.request(&MasterToBoard::Home { rehome: false }, 100)
            .unwrap(),
        Some(NackReason::SafetyRelayMismatch)
    );
    assert!(b.request(&MasterToBoard::Enable, 100).unwrap().is_some());
    assert_eq!(b.board.runtime().state(), RobotState::Disabled);
    // The relay test: pressed (the relay opens), released (it closes).
    b.board.press_estop(true);
    b.run_ms(50).unwrap();
    b.board.press_estop(false);
    b.run_ms(50).unwrap();
    assert!(!b.board.runtime().relay_test_pending());
    b.command(&MasterToBoard::ClearFault).unwrap();
    b.run_ms(50).unwrap();
    b.bring_up().unwrap();
    assert_eq!(b.board.runtime().state(), RobotState::Enabled);
    let (log, _) = b.read_event_log().unwrap();
    assert!(log
        .iter()
        .any(|e| e.event == EventKind::RelayTest { pending: false } && e.boot == 2));
}

/// Property: the ring's bound and its rotation on the simulated board: with sectors of 16
/// records, many entries written while the robot is enabled wait for the drives to be off
/// before a sector is erased (never an erase with the drives on), and after a power cycle
/// the newest entries are there.
#[test]
fn the_event_flash_rotates_only_with_the_drives_off() {
    let mut cfg = BoardSimConfig::reference(None).unwrap();
    cfg.event_flash = (2, 16 * control::event_log::record::RECORD_LEN);
    let mut b = bench(cfg);
    b.bring_up().unwrap();
    let erases_enabled = b.board.flash().events.erases;
    // Holds while enabled, by the clutch and by the dead-man in turn: each a new stop entry
    // (a repeat of the same reason would count on its entry).
    for k in 0..40u32 {
        let (hold, release) = if k % 2 == 0 {
            (
                MasterToBoard::Clutch { engaged: true },
                MasterToBoard::Clutch { engaged: false },
            )
        } else {
            (
                MasterToBoard::OperatorPresent { present: false },
                MasterToBoard::OperatorPresent { present: true },
            )
        };
        b.command(&hold).unwrap();
        b.run_ms(20).unwrap();
        b.command(&release).unwrap();
        b.run_ms(20).unwrap();
        assert_eq!(
            b.board.runtime().state(),
            RobotState::Enabled,
            "{:?}",
            b.board.runtime().status().fault
        );
    }
    assert_eq!(
        b.board.flash().events.erases,
        erases_enabled,
        "no erase with the drives on"
    );
    let waiting = b.board.runtime().events().pending_len();
    assert!(waiting > 0, "the full sector waits");
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_ms(1000).unwrap();
    assert!(b.board.flash().events.erases > erases_enabled);
    assert_eq!(b.board.runtime().events().pending_len(), 0);
    let newest = *b.board.runtime().events().newest().unwrap();
    let mut b = b.power_cycle(7).unwrap();
    let (after, _) = b.read_event_log().unwrap();
    assert!(after.contains(&newest), "{newest:?} in {after:#?}");
}
