#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Stop precedence on the simulated board (`BoardSim`: the whole board application on the
//! plant, in virtual time), measured on the plant's true platform, not on what the code
//! intended: a `Home` (rehome) or a `StoreGeometry` sent while a controlled stop (SS1 after
//! a `Disable`, SS2 after the clutch) decelerates the robot from full speed is refused, and
//! the stop completes with exactly the motion it has alone (SR-3: no command weakens a stop
//! in force).

use control::geometry_store::record_of;
use kinematics_core::chain_geometry::PerChainGeometry;
use kinematics_core::geometry::RsprGeometry;
use master_link::{BoardToMaster, MasterToBoard, NackReason, ResetCause, RobotState, StopStatus};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

/// The stops under test and the command that starts each from following.
#[derive(Clone, Copy, Debug)]
enum Stop {
    /// `Disable` while following: SS1 (decelerate, then the drives off).
    Ss1,
    /// The clutch pressed while following: SS2 (decelerate, then hold with torque).
    Ss2,
}

impl Stop {
    /// Whether the status reports this stop in force.
    fn in_force(self, stop: StopStatus) -> bool {
        match self {
            Stop::Ss1 => matches!(
                stop,
                StopStatus::SafeStop1Decelerating | StopStatus::SafeStop1Braking
            ),
            Stop::Ss2 => matches!(
                stop,
                StopStatus::SafeStop2Decelerating | StopStatus::SafeOperatingStop
            ),
        }
    }

    fn command(self) -> MasterToBoard {
        match self {
            Stop::Ss1 => MasterToBoard::Disable,
            Stop::Ss2 => MasterToBoard::Clutch { engaged: true },
        }
    }
}

/// The commands that must not end or weaken the stop.
#[derive(Clone, Copy, Debug)]
enum Intrusion {
    Rehome,
    StoreGeometry,
}

/// What one run measured.
#[derive(Debug, PartialEq)]
struct Measured {
    /// Largest distance of the true platform from where it was when the stop began, m.
    travel_m: f64,
    /// The true platform position at the end, m.
    end_m: [f64; 3],
    /// The state and stop at the end.
    state: RobotState,
    stop: StopStatus,
    /// Milliseconds from the stop's command during which the stop was in force (its
    /// deceleration and braking for SS1; for SS2 also the held standstill that follows).
    in_force_ms: u64,
}

/// The stop's deceleration and the drives' switching off fit in this (the stop table's
/// 500 ms deceleration timeout plus the brakes' engage time).
const SETTLE_MS: u64 = 700;

/// A board brought up (homed, parked, enabled) and moving the platform at its full tip
/// speed along x towards a goal 20 mm away.
fn moving() -> Bench {
    let cfg = BoardSimConfig::reference(None).unwrap();
    let mut b = Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x5709,
    );
    b.bring_up().unwrap();
    let s = b.board.runtime().status();
    let target = MasterToBoard::PoseTarget {
        timestamp_us: b.now_us(),
        position_m: [
            s.setpoint_position_m[0] + 0.020,
            s.setpoint_position_m[1],
            s.setpoint_position_m[2],
        ],
        rotation_vector_rad: s.setpoint_rotation_vector_rad,
    };
    b.command(&target).unwrap();
    // Up to speed (25 mm/s at 0.25 m/s^2: 100 ms), well short of the goal (8 mm in 400 ms).
    b.run_ms(400).unwrap();
    assert_eq!(b.board.runtime().state(), RobotState::Enabled);
    b
}

/// The intrusion's message.
fn message(i: Intrusion) -> MasterToBoard {
    match i {
        Intrusion::Rehome => MasterToBoard::Home { rehome: true },
        Intrusion::StoreGeometry => MasterToBoard::StoreGeometry(record_of(
            &PerChainGeometry::from(RsprGeometry::<f64>::reference()),
            7,
        )),
    }
}

/// Starts `stop` at full speed; `intrusion` sent `after_ms` into it (None: the stop alone);
/// runs until the stop has completed and measures. The intrusion's answer must be a
/// refusal.
fn run(stop: Stop, intrusion: Option<(Intrusion, u64)>) -> Measured {
    let mut b = moving();
    let p0 = b.board.truth().pose.t;
    let stop_seq = b.send(&stop.command());
    let mut travel = 0.0f64;
    let mut sent = None;
    let mut in_force_ms = 0;
    for ms in 0..SETTLE_MS {
        if let Some((i, at)) = intrusion {
            if ms == at {
                assert!(
                    ms == 0 || stop.in_force(b.board.runtime().status().stop),
                    "{stop:?} no longer in force {ms} ms in"
                );
                sent = Some((i, b.send(&message(i))));
            }
        }
        b.tick().unwrap();
        travel = travel.max((b.board.truth().pose.t - p0).norm());
        if in_force_ms == ms && stop.in_force(b.board.runtime().status().stop) {
            in_force_ms = ms + 1;
        }
    }
    assert!(
        matches!(
            b.master.replies.get(&stop_seq),
            Some((_, BoardToMaster::Ack { .. }))
        ),
        "{stop:?}: the stop's command answered {:?}",
        b.master.replies.get(&stop_seq)
    );
    if let Some((i, seq)) = sent {
        let reply = b.master.replies.get(&seq).map(|(_, r)| *r);
        let refused = match reply {
            Some(BoardToMaster::Nack { reason, .. }) => reason != NackReason::NotConnected,
            Some(BoardToMaster::GeometryRefused { .. }) => true,
            _ => false,
        };
        assert!(
            refused,
            "{stop:?} with {i:?} {} ms in: answered {reply:?}, not refused",
            intrusion.map_or(0, |(_, at)| at)
        );
    }
    let end = b.board.truth().pose.t;
    let st = b.board.runtime().status();
    Measured {
        travel_m: travel,
        end_m: [end.x, end.y, end.z],
        state: st.state,
        stop: st.stop,
        in_force_ms,
    }
}

/// Property (SR-3, SR-2): for SS1 and SS2 started at full speed, a `Home` (rehome) or a
/// `StoreGeometry` sent while the stop is in force, at once, 5 ms in, halfway and in its
/// last millisecond (SS1: its deceleration and braking; SS2: its deceleration and the held
/// standstill, 200 ms in), is refused, and the platform's travel, its end position and the
/// board's end state are those of the stop alone, to the bit (the refused command changes
/// nothing the control sees).
#[test]
fn home_and_store_geometry_never_weaken_a_stop() {
    for stop in [Stop::Ss1, Stop::Ss2] {
        let alone = run(stop, None);
        eprintln!(
            "{stop:?} alone: travel {:.3} mm, in force {} ms, ends {:?} / {:?}",
            alone.travel_m * 1e3,
            alone.in_force_ms,
            alone.state,
            alone.stop
        );
        // The stop itself: deceleration from 25 mm/s within its distance (v^2/(2a) = 1.25
        // mm plus the lag of the platform), and it ends as its category says.
        assert!(
            alone.travel_m > 0.2e-3 && alone.travel_m < 3.0e-3,
            "{stop:?} alone: {alone:?}"
        );
        match stop {
            Stop::Ss1 => assert_eq!(alone.state, RobotState::Ready, "{alone:?}"),
            Stop::Ss2 => assert_eq!(alone.state, RobotState::Enabled, "{alone:?}"),
        }
        let n = alone.in_force_ms;
        assert!(n >= 20, "{stop:?} in force only {n} ms: {alone:?}");
        let instants = match stop {
            Stop::Ss1 => [0, 5, n / 2, n - 1],
            Stop::Ss2 => [0, 5, 50, 200],
        };
        for intrusion in [Intrusion::Rehome, Intrusion::StoreGeometry] {
            for at in instants {
                let with = run(stop, Some((intrusion, at)));
                assert_eq!(
                    with, alone,
                    "{stop:?} with {intrusion:?} {at} ms in: {with:?} against the stop alone {alone:?}"
                );
            }
        }
    }
}
