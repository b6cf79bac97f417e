#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! What the runtime records in its event log: the reset at boot, a master taking charge,
//! the holds and the Disable as stops, a fault with its stop (a repeat counting on its
//! entry), a geometry stored, and the relay test's latch before the fault that set it.

use control::modes::State;
use control::runtime::Runtime;
use hal::QuadratureCounter;
use kinematics_core::RsprGeometry;
use master_link::{
    EventKind, FaultCause, MasterToBoard, ResetCause, StopReason, StopStatus, NO_JOINT,
};

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

fn tick(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64) {
    *t += 1000;
    if (*t).is_multiple_of(20_000) {
        rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    }
    rt.tick(hw, *t);
    hw.step_ms();
}

fn kinds(rt: &Rt) -> Vec<(EventKind, u16)> {
    rt.events().entries().map(|e| (e.event, e.count)).collect()
}

/// Property: every kind of event the runtime sees is an entry of its event log, in order,
/// each with the stop in force after it; a repeat in the same boot counts on its entry.
#[test]
fn the_runtime_records_its_events() {
    let (mut hw, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut log = control::event_log::EventLog::new();
    log.start_boot();
    rt.restore_events(log);
    rt.boot_done(hw.counts(), 0, ResetCause::Watchdog, None)
        .unwrap();
    let mut t = 0;
    rt.command(
        &MasterToBoard::Hello {
            protocol_version: master_link::PROTOCOL_VERSION,
            nonce: 77,
            clock_us: 0,
        },
        t,
    )
    .unwrap();
    rt.command(&MasterToBoard::OperatorPresent { present: true }, t)
        .unwrap();
    rt.command(&MasterToBoard::AcknowledgeReset, t).unwrap();
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    while rt.state() != State::Ready {
        tick(&mut rt, &mut hw, &mut t);
        assert!(t < 60_000_000, "{:?}", rt.status().fault);
    }
    for _ in 0..100 {
        tick(&mut rt, &mut hw, &mut t);
    }
    rt.command(&MasterToBoard::Enable, t).unwrap();
    while rt.state() != State::Enabled {
        tick(&mut rt, &mut hw, &mut t);
    }
    // The clutch twice: one hold entry, counted twice.
    for _ in 0..2 {
        rt.command(&MasterToBoard::Clutch { engaged: true }, t)
            .unwrap();
        for _ in 0..50 {
            tick(&mut rt, &mut hw, &mut t);
        }
        rt.command(&MasterToBoard::Clutch { engaged: false }, t)
            .unwrap();
        for _ in 0..50 {
            tick(&mut rt, &mut hw, &mut t);
        }
    }
    rt.command(&MasterToBoard::Disable, t).unwrap();
    for _ in 0..600 {
        tick(&mut rt, &mut hw, &mut t);
    }
    assert_eq!(rt.state(), State::Ready);
    rt.geometry_stored(5, t);
    assert_eq!(rt.geometry_version(), 5);
    rt.command(&MasterToBoard::EmergencyStop, t).unwrap();
    tick(&mut rt, &mut hw, &mut t);
    assert_eq!(
        kinds(&rt),
        vec![
            (
                EventKind::Reset {
                    cause: ResetCause::Watchdog
                },
                1
            ),
            (EventKind::Master { id: 77 }, 1),
            (
                EventKind::Stop {
                    reason: StopReason::ClutchEngaged,
                    stop: StopStatus::SafeStop2Decelerating
                },
                2
            ),
            (
                EventKind::Stop {
                    reason: StopReason::Disable,
                    stop: StopStatus::SafeStop1Decelerating
                },
                1
            ),
            (EventKind::GeometryStored { version: 5 }, 1),
            (
                EventKind::Fault {
                    cause: FaultCause::EmergencyStopMessage,
                    joint: NO_JOINT,
                    value: 0.0,
                    stop: StopStatus::SafeTorqueOff
                },
                1
            ),
        ]
    );
    let page = rt.event_log_page(0);
    assert_eq!((page.len, page.count, page.total), (6, 6, 6));
    assert!(rt.events().entries().all(|e| e.boot == 1));
}

/// Property: a safety-chain fault is recorded after the relay test's latch, both stamped
/// pending (so the flash holds the latch no later than the fault); the test passing after
/// a power cycle is an entry of its own.
#[test]
fn the_relay_latch_comes_before_its_fault_and_its_test_is_recorded() {
    let (mut hw, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    rt.boot_done(hw.counts(), 0, ResetCause::PowerOn, None)
        .unwrap();
    let mut t = 0;
    hw.relay_welded = true;
    hw.press_estop(true);
    for _ in 0..40 {
        tick(&mut rt, &mut hw, &mut t);
    }
    let e: Vec<_> = rt.events().entries().copied().collect();
    let latch = e
        .iter()
        .position(|e| e.event == EventKind::RelayTest { pending: true })
        .unwrap();
    let fault = e
        .iter()
        .position(|e| {
            matches!(
                e.event,
                EventKind::Fault {
                    cause: FaultCause::SafetyRelayMismatch,
                    ..
                }
            )
        })
        .unwrap();
    assert!(latch < fault);
    assert!(e[latch].relay_test_pending && e[fault].relay_test_pending);
    // After a power cycle (the log restored, the relay repaired): the test.
    let mut log = *rt.events();
    log.start_boot();
    let boot = log.boot();
    let (mut hw, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    rt.restore_events(log);
    assert!(rt.relay_test_pending());
    rt.boot_done(hw.counts(), 0, ResetCause::PowerOn, None)
        .unwrap();
    let mut t = 0;
    for pressed in [true, false] {
        hw.press_estop(pressed);
        for _ in 0..30 {
            tick(&mut rt, &mut hw, &mut t);
        }
    }
    assert!(!rt.relay_test_pending());
    let newest = rt.events().newest().unwrap();
    assert_eq!(newest.event, EventKind::RelayTest { pending: false });
    assert!(!newest.relay_test_pending);
    assert_eq!(newest.boot, boot);
}
