//! The live 3-D view of a board: its status stream on the scene's channels
//! ([`scene::Scene`]) served by the Foxglove SDK's WebSocket server (and, optionally,
//! recorded to an MCAP file through the same channels).
//!
//! **Read-only.** The board sends its status to the master whose `Hello` it accepted, so
//! the view says `Hello` (as the console does) and then only listens: it never homes,
//! enables or sends a target, and on the way out the fail-safe of every front end
//! ([`crate::shutdown`]) disables a robot it could not have enabled. While another master
//! has the robot enabled the board refuses the view's `Hello` (one owner), and the view
//! says so. The target of another master is not in the board's status, so `/servo_cp`
//! stays empty here (the simulation's MCAP has it).

use crate::board::{Board, BoardError, BoardEvent};
use crate::conversions::{measured_cp, setpoint_cp};
use crate::error::OperatorError;
use kinematics_core::pose::Pose;
use master_link::{RobotState as WireState, StatusReport};
use masters::CartesianPose;
use scene::{GuardMargins, RobotState, Scene, Snapshot};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// How often the robot description is sent again for clients that subscribe later, s.
pub const DESCRIPTION_PERIOD_S: f64 = 1.0;

/// What the view did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ViewCounters {
    /// Status reports put on the channels.
    pub statuses: u64,
    /// Of them, with a measured pose the description could not pose (no transforms).
    pub unposed: u64,
}

/// A master-side pose as the kinematics' pose.
pub fn pose_of(p: &CartesianPose) -> Pose<f64> {
    Pose {
        t: p.position_m,
        r: p.orientation.to_rotation_matrix(),
    }
}

/// Unix time, ns: the live channels' log time.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// The scene's snapshot of a status report at `time_ns`.
pub fn snapshot(time_ns: u64, s: &StatusReport) -> Snapshot {
    let m = &s.margins;
    let f = |x: f32| f64::from(x);
    Snapshot {
        time_ns,
        measured: measured_cp(s).as_ref().map(pose_of),
        setpoint: setpoint_cp(s).as_ref().map(pose_of),
        target: None,
        measured_joints: Some(s.joints.map(f64::from)),
        margins: Some(GuardMargins {
            nearest: f(m.nearest),
            serial: f(m.serial),
            parallel: f(m.parallel),
            stroke: f(m.stroke),
            tilt: f(m.tilt),
            collision: f(m.collision),
            workspace: f(m.workspace),
        }),
        state: Some(RobotState {
            state: board_words::state_label(s.state).to_string(),
            stop: board_words::stop(s.state, s.stop)
                .unwrap_or_default()
                .to_string(),
            fault: board_words::fault(&s.fault).unwrap_or_default(),
            fault_latched: s.state == WireState::Fault,
        }),
    }
}

/// Says `Hello`, then puts every status of the board on the scene's channels until `stop`
/// (the robot description every [`DESCRIPTION_PERIOD_S`]); `log` hears what happens.
pub fn run(
    board: &mut Board,
    scene: &mut Scene,
    stop: &AtomicBool,
    log: &mut dyn FnMut(&str),
) -> Result<ViewCounters, OperatorError> {
    board.send_hello()?;
    let mut counters = ViewCounters::default();
    let mut last_description = f64::NEG_INFINITY;
    let mut said_first = false;
    while !stop.load(Ordering::Relaxed) {
        let now = board.now_s();
        if now - last_description >= DESCRIPTION_PERIOD_S {
            last_description = now;
            scene.log_description(now_ns());
        }
        let events = board.poll(Duration::from_millis(5))?;
        if let Some(reason) = board.take_hello_refused() {
            // One owner: another master has the robot (enabled), so no status comes.
            return Err(BoardError::HelloRefused(reason).into());
        }
        for e in events {
            if let BoardEvent::Status(_, s) = e {
                let before = scene.unposed;
                scene.log(&snapshot(now_ns(), &s));
                counters.statuses += 1;
                counters.unposed += scene.unposed - before;
                if !said_first {
                    said_first = true;
                    log(&format!(
                        "first status: {}",
                        board_words::state_label(s.state)
                    ));
                }
            }
        }
    }
    Ok(counters)
}
