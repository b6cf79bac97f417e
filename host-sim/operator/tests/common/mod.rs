//! The board the end-to-end tests drive: `RSPR_BOARD_SOCKET` when set (a board already
//! serving on that Unix socket: `host-sim board --socket PATH`, or the emulator of the real
//! board image, `firmware/board-emulator ... serve --socket PATH`; run the tests one at a
//! time then, `--test-threads=1`: a board serves one master at a time), else the simulated
//! board (the board application on the plant, `simulation::serve`) in a thread of the
//! test, paced by the wall clock.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use masters::script::Waypoint;
use masters::{CartesianPose, OperatorButtons};
use nalgebra::{UnitQuaternion, Vector3};
use operator::{Board, BringUpTimeouts};
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
        let thread = std::thread::spawn(move || {
            simulation::serve::serve(&s, cfg, &flag, &|| {}).unwrap();
        });
        TestBoard {
            socket,
            stop,
            thread: Some(thread),
            _dir: Some(dir),
        }
    }

    /// Connects.
    pub fn connect(&self) -> Board {
        Board::open(&self.socket, 1_000_000, Duration::from_secs(10)).unwrap()
    }

    /// Connects and brings the board to Enabled (hello, homing, enable).
    pub fn enabled(&self) -> Board {
        let mut b = self.connect();
        b.bring_up(&BringUpTimeouts::default(), &mut |m| {
            eprintln!("  board: {m}")
        })
        .unwrap();
        b
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
