#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Restart interlocks on the simulated board (`BoardSim`: the whole board application on
//! the plant, its link included): `ClearFault` re-tests the latched fault's cause and is
//! refused, with the reason, while the cause persists; once the cause has gone it is taken,
//! and the robot has not moved meanwhile.

use master_link::{FaultCause, MasterToBoard, NackReason, ResetCause, RobotState};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

/// A fault whose cause the test can hold present and then remove on the plant.
#[derive(Clone, Copy, Debug)]
enum Cause {
    /// The e-stop button pressed (and released).
    Button,
    /// A limit switch forced closed (and back to its true level).
    LimitSwitch,
    /// The supply sagged to 12 V (and back to 24 V).
    Supply,
    /// A current sensor reads 10 A over the truth (and back to no offset).
    Overcurrent,
    /// The master's heartbeats stop (and resume).
    Heartbeat,
}

impl Cause {
    fn expected(self) -> FaultCause {
        match self {
            Cause::Button => FaultCause::EmergencyStopButton,
            Cause::LimitSwitch => FaultCause::LimitSwitch,
            Cause::Supply => FaultCause::SupplyVoltage,
            Cause::Overcurrent => FaultCause::Overcurrent,
            Cause::Heartbeat => FaultCause::HeartbeatTimeout,
        }
    }

    fn set(self, b: &mut Bench, present: bool) {
        match self {
            Cause::Button => b.board.hw.press_estop(present),
            Cause::LimitSwitch => b.board.hw.switch_forced[0] = present.then_some(true),
            Cause::Supply => b
                .board
                .hw
                .plant
                .set_supply_voltage(if present { 12.0 } else { 24.0 })
                .unwrap(),
            Cause::Overcurrent => b.board.hw.current_offset_a[3] = if present { 10.0 } else { 0.0 },
            Cause::Heartbeat => b.heartbeat = !present,
        }
    }
}

/// Largest distance of the true platform from `p0` over `ms` periods, m.
fn travel(b: &mut Bench, p0: nalgebra::Vector3<f64>, ms: u64) -> f64 {
    let mut max = 0.0f64;
    for _ in 0..ms {
        b.tick().unwrap();
        max = max.max((b.board.truth().pose.t - p0).norm());
    }
    max
}

/// Property: for each cause the plant can hold (the e-stop button, a limit switch, a supply
/// sag, a current over its trip, a silent master), the fault latches with that cause named;
/// `ClearFault` while the cause persists is refused with `FaultStillActive`, again and
/// again, and the platform stays within 0.01 mm of where it stopped; once every latched
/// cause has gone (the current's heat in the motors' thermal model included: 21.6 s here)
/// `ClearFault` is taken and the fault is cleared.
#[test]
fn clear_fault_is_refused_while_its_cause_persists() {
    for cause in [
        Cause::Button,
        Cause::LimitSwitch,
        Cause::Supply,
        Cause::Overcurrent,
        Cause::Heartbeat,
    ] {
        let cfg = BoardSimConfig::reference(None).unwrap();
        let mut b = Bench::new(
            BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
            0xC1EA,
        );
        b.bring_up().unwrap();
        cause.set(&mut b, true);
        b.run_until("the fault", 2_000, |s| {
            s.runtime().state() == RobotState::Fault
        })
        .unwrap();
        let first = b.board.runtime().status().fault.cause;
        assert_eq!(first, cause.expected(), "{cause:?}: first fault");
        // The stop completes (drives off, brakes on).
        b.run_ms(800).unwrap();
        let p0 = b.board.truth().pose.t;
        for attempt in 0..3 {
            let seq = b.send(&MasterToBoard::ClearFault);
            let moved = travel(&mut b, p0, 50);
            let reply = b.master.replies.get(&seq).map(|(_, r)| *r);
            assert!(
                matches!(
                    reply,
                    Some(master_link::BoardToMaster::Nack {
                        reason: NackReason::FaultStillActive,
                        ..
                    })
                ),
                "{cause:?}: ClearFault {attempt} with the cause present answered {reply:?}"
            );
            assert_eq!(
                b.board.runtime().state(),
                RobotState::Fault,
                "{cause:?}: still latched"
            );
            assert!(moved <= 0.01e-3, "{cause:?}: moved {:.4} mm", moved * 1e3);
        }
        cause.set(&mut b, false);
        // A cause may outlast its condition: a current read over its trip has heated the
        // motors' thermal model, which must cool below its derating level first; the
        // clear stays refused until then.
        let gone = b
            .run_until("the cause gone", 600_000, |s| {
                s.runtime().cause_still_present(s.now_us()).is_none()
            })
            .unwrap();
        eprintln!("{cause:?}: first {first:?}; every cause gone {gone} ms after its condition");
        b.command(&MasterToBoard::ClearFault)
            .unwrap_or_else(|e| panic!("{cause:?}: ClearFault after the cause went: {e}"));
        b.run_ms(100).unwrap();
        assert_ne!(
            b.board.runtime().state(),
            RobotState::Fault,
            "{cause:?}: cleared"
        );
    }
}
