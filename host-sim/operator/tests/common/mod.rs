//! The board the end-to-end tests drive: `RSPR_BOARD_SOCKET` when set (a board already
//! serving on that Unix socket: `host-sim board --socket PATH`, or the emulator of the real
//! board image, `firmware/board-emulator ... serve --socket PATH`; a board serves one
//! master at a time, so run the tests one at a time then), else the simulated
//! board (the board application on the plant, `simulation::serve`) in a thread of the
//! test, its virtual clock paced by the wall clock and by the test's master
//! (`simulation::serve`): a loaded host pauses it, never makes it jump.
//!
//! The tests' masters run on the board's clock (`Board::set_paced`, `teleop::pacing`): an
//! emulated board whose host stalls it (a loaded machine) pauses its virtual time, and
//! the master pauses with it, so that its stream is not stale by the board's clock and the
//! latencies it measures are the board's, not the host's pauses. A board that shares its
//! clock beside its socket (the simulated board here, the emulated one with
//! `--clock-lead-ms`) runs in lockstep with the test's master (`Board::set_lockstep`):
//! each waits for the other, within 2 ms.
//!
//! A board at `RSPR_BOARD_SOCKET` outlives each test and keeps its state between masters
//! (homed, where the robot stands). Each test starts as on a freshly homed board: once
//! enabled, the robot goes to the central pose, where the homing parks it (within the park
//! move's tolerance; [`TestBoard::enabled`]). Each test leaves it there, disabled, as the
//! console does on quit ([`EnabledBoard`]'s drop): not enabled with the master gone, which
//! the board takes for a lost master (`HeartbeatTimeout`, a fault the next bring-up
//! refuses), and at the centre, so that the next test starts where a freshly homed board
//! would.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use kinematics_core::RsprGeometry;
use master_link::{MasterToBoard, RobotState, StopStatus};
use masters::script::Waypoint;
use masters::{CartesianPose, OperatorButtons};
use nalgebra::{UnitQuaternion, Vector3};
use operator::conversions::setpoint_cp;
use operator::{Board, BringUpTimeouts, Outcome};
use std::ops::{Deref, DerefMut};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// A board to test against.
pub struct TestBoard {
    pub socket: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    _dir: Option<tempfile::TempDir>,
}

impl TestBoard {
    /// `RSPR_BOARD_SOCKET`, or a simulated board in a thread.
    pub fn start() -> TestBoard {
        let stop = Arc::new(AtomicBool::new(false));
        if let Some(p) = std::env::var_os("RSPR_BOARD_SOCKET") {
            return TestBoard {
                socket: PathBuf::from(p),
                stop,
                thread: None,
                _dir: None,
            };
        }
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("board.sock");
        let mut cfg = simulation::board::BoardSimConfig::reference(None).unwrap();
        // As `host-sim board`: the host is not real time, a late tick is the host's.
        cfg.service.watchdog.max_lateness_us = 1_000_000;
        cfg.service.overruns_to_fault = u32::MAX;
        let (s, flag) = (socket.clone(), Arc::clone(&stop));
        // The board shares its clock, as the emulated board of `against-emulator.sh` does
        // (a lead of 2 ms over the master's last reading).
        let pacing = simulation::serve::ServePacing {
            clock_lead_us: Some(2_000),
            ..Default::default()
        };
        let thread = std::thread::spawn(move || {
            simulation::serve::serve_paced(&s, cfg, pacing, &flag, &|| {}).unwrap();
        });
        TestBoard {
            socket,
            stop,
            thread: Some(thread),
            _dir: Some(dir),
        }
    }

    /// Connects, the master on the board's clock: the board's own, shared beside its
    /// socket, in lockstep (`Board::set_lockstep`) where the board shares it, else paced by
    /// its statuses.
    pub fn connect(&self) -> Board {
        let mut b = Board::open(&self.socket, 1_000_000, Duration::from_secs(10)).unwrap();
        b.set_paced(true);
        b.set_lockstep(true);
        b
    }

    /// Connects and brings the board to Enabled (hello, homing, enable), the robot at the
    /// central pose: a board of its own is there (the homing's park move); a board that
    /// outlived an earlier test (`RSPR_BOARD_SOCKET`) is sent there (one target, the
    /// board's supervisor plans the move).
    pub fn enabled(&self) -> EnabledBoard {
        let mut b = self.connect();
        b.bring_up(&BringUpTimeouts::default(), Default::default(), &mut |m| {
            eprintln!("  board: {m}")
        })
        .unwrap();
        let external = self.thread.is_none();
        let mut b = EnabledBoard { board: b, external };
        if external {
            let from = to_centre(&mut b).unwrap();
            eprintln!(
                "  board: to the central pose from [{:.4} {:.4} {:.4}] mm, {:.4} deg",
                from.position_m.x * 1e3,
                from.position_m.y * 1e3,
                from.position_m.z * 1e3,
                from.orientation
                    .angle_to(&centre().orientation)
                    .to_degrees()
            );
        }
        b
    }
}

/// The central pose of the reference robot (`Pose::central(hc)`, hc = 160 mm): where the
/// homing parks it (the park joints are its inverse kinematics; the park move ends within
/// 0.1 mm of them: 0.06 mm, z 160.065 mm, on the emulated board).
pub fn centre() -> CartesianPose {
    CartesianPose {
        position_m: Vector3::new(0.0, 0.0, RsprGeometry::<f64>::reference().hc),
        orientation: UnitQuaternion::identity(),
    }
}

/// Sends the robot to the central pose and waits until the setpoint is there (within
/// 1 µm and 1 µrad), then 0.5 s more for the drives to settle; the setpoint it started
/// from.
fn to_centre(b: &mut Board) -> Result<CartesianPose, String> {
    let c = centre();
    let from = match b.status() {
        Some((_, s)) => *s,
        None => b
            .wait_status(1.0, |_| true)
            .map_err(|e| e.to_string())?
            .ok_or("no status")?,
    };
    let from = setpoint_cp(&from).ok_or("no setpoint")?;
    match b.request_target(&c).map_err(|e| e.to_string())? {
        Outcome::Ack => {}
        o => return Err(format!("the target at the central pose: {o:?}")),
    }
    let there = b
        .wait_status(10.0, |s| {
            s.state != RobotState::Enabled
                || setpoint_cp(s).is_some_and(|p| {
                    (p.position_m - c.position_m).norm() < 1e-6
                        && p.orientation.angle_to(&c.orientation) < 1e-6
                })
        })
        .map_err(|e| e.to_string())?
        .ok_or("the setpoint not at the central pose within 10 s")?;
    if there.state != RobotState::Enabled {
        return Err(format!("on the way to the central pose: {there:?}"));
    }
    let t = b.now_s() + 0.5;
    b.poll_until(t).map_err(|e| e.to_string())?;
    b.discard_events();
    Ok(from)
}

/// An enabled board, disabled when dropped (as the console does on quit): on a board that
/// outlives the test, first back to the central pose; then Disable and the safe stop 1 to
/// its end. Errors are printed, not raised, there (a test that failed has said why; a
/// board left faulted or off-centre makes the next test's bring-up say so).
pub struct EnabledBoard {
    board: Board,
    external: bool,
}

impl Deref for EnabledBoard {
    type Target = Board;
    fn deref(&self) -> &Board {
        &self.board
    }
}

impl DerefMut for EnabledBoard {
    fn deref_mut(&mut self) -> &mut Board {
        &mut self.board
    }
}

impl Drop for EnabledBoard {
    fn drop(&mut self) {
        let enabled = |b: &Board| {
            b.status()
                .is_some_and(|(_, s)| s.state == RobotState::Enabled)
        };
        if self.external && enabled(&self.board) {
            if let Err(e) = to_centre(&mut self.board) {
                eprintln!("  board: not back to the central pose at the end: {e}");
            }
        }
        match self.board.request(MasterToBoard::Disable) {
            Ok(Outcome::Ack) => {
                let done = self.board.wait_status(5.0, |s| {
                    s.state != RobotState::Enabled
                        && matches!(s.stop, StopStatus::None | StopStatus::SafeStop1Done)
                });
                if !matches!(done, Ok(Some(_))) {
                    eprintln!("  board: Disable not done within 5 s: {done:?}");
                }
            }
            o => eprintln!("  board: Disable at the end: {o:?}"),
        }
    }
}

impl Drop for TestBoard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

pub const PRESENT: OperatorButtons = OperatorButtons {
    clutch: false,
    operator_present: true,
};
pub const CLUTCHED: OperatorButtons = OperatorButtons {
    clutch: true,
    operator_present: true,
};
pub const ABSENT: OperatorButtons = OperatorButtons {
    clutch: false,
    operator_present: false,
};

/// A master pose: position in mm, rotation about z in degrees.
pub fn master_at(x_mm: f64, y_mm: f64, z_mm: f64, rz_deg: f64) -> CartesianPose {
    CartesianPose {
        position_m: Vector3::new(x_mm, y_mm, z_mm) * 1e-3,
        orientation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rz_deg.to_radians()),
    }
}

/// A waypoint.
pub fn wp(at_s: f64, pose: CartesianPose, buttons: OperatorButtons) -> Waypoint {
    Waypoint {
        at_s,
        pose,
        buttons,
    }
}
