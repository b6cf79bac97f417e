#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The simulated board served on a socket (`simulation::serve`) keeps its own time, paced
//! by its master: a master that its host holds up holds the board with it, so that the
//! board never takes a loaded host for a lost master; a master silent beyond the wait is
//! let go (the board runs on and judges the silence by its own clock).
//!
//! The board sends a status every 20 ms of its time once a master said Hello, so the
//! statuses that arrive while the master stands still count the board time that passed.

use simulation::serve::{serve_paced, ServePacing};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use teleop::session::Session;

/// A simulated board served in a thread on a socket of its own.
struct Served {
    socket: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    dir: PathBuf,
}

impl Served {
    fn start(pacing: ServePacing) -> Served {
        static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let dir = std::env::temp_dir().join(format!(
            "served-board-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let socket = dir.join("board.sock");
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread = {
            let (socket, stop) = (socket.clone(), Arc::clone(&stop));
            std::thread::spawn(move || {
                let mut cfg = simulation::board::BoardSimConfig::reference(None).unwrap();
                cfg.service.watchdog.max_lateness_us = 1_000_000;
                cfg.service.overruns_to_fault = u32::MAX;
                serve_paced(&socket, cfg, pacing, &stop, &|| {
                    let _ = ready_tx.send(());
                })
                .unwrap();
            })
        };
        ready_rx.recv_timeout(Duration::from_secs(30)).unwrap();
        Served {
            socket,
            stop,
            thread: Some(thread),
            dir,
        }
    }

    /// A master on the host's clock (the statuses stamped with their arrival), said Hello.
    fn master(&self) -> Session {
        let link = teleop::link::open(&self.socket, 1_000_000, Duration::from_secs(10)).unwrap();
        let mut s = Session::new(link);
        s.paced = false;
        s.hello(10.0).unwrap();
        s.wait(0.2).unwrap();
        s
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The master stands still (no heartbeat, nothing read) for `stall_s` of host time, then
/// polls for 0.3 s: the host times (link clock) the stall began and ended, and the
/// arrival times of the statuses received after it began.
fn stall(s: &mut Session, stall_s: f64) -> (f64, f64, Vec<f64>) {
    let seen = s.statuses.len();
    let t0 = s.link.now_s();
    std::thread::sleep(Duration::from_secs_f64(stall_s));
    let t1 = s.link.now_s();
    s.wait(0.3).unwrap();
    let arrivals = s.statuses.iter().skip(seen).map(|r| r.t_s).collect();
    (t0, t1, arrivals)
}

/// Property: while the master stands still for 0.8 s of host time, the board's clock runs
/// at most its master lead (50 ms) beyond the master's last heartbeat: at most 4 statuses
/// (20 ms each, one period of slack each side) are sent meanwhile, where a board on the
/// wall clock sends 40 (the board, homing or enabled, would have held after 100 ms without
/// a heartbeat and stopped after 500 ms); once the master polls again, the board goes on.
#[test]
fn a_master_held_up_by_its_host_holds_the_board() {
    let board = Served::start(ServePacing::default());
    let mut s = board.master();
    let (t0, t1, arrivals) = stall(&mut s, 0.8);
    let during = arrivals.iter().filter(|&&t| t > t0 && t < t1).count();
    assert!(
        during <= 4,
        "{during} statuses arrived while the master stood still for {:.2} s: the board ran on without it",
        t1 - t0
    );
    assert!(
        arrivals.len() > during,
        "the board went on once the master did: {} statuses after the stall",
        arrivals.len() - during
    );
}

/// Property: a master silent beyond the board's master wait (here 0.3 s of host time) is
/// let go: the board runs on, and within the 1.5 s stall sends statuses again (at least
/// 5, 100 ms of its time; a board on the wall clock sends about 60 after the wait, a board
/// that still waited none).
#[test]
fn a_master_silent_beyond_the_wait_is_let_go() {
    let board = Served::start(ServePacing {
        master_wait: Duration::from_millis(300),
        ..ServePacing::default()
    });
    let mut s = board.master();
    let (t0, t1, arrivals) = stall(&mut s, 1.5);
    let after_wait = arrivals.iter().filter(|&&t| t > t0 + 0.4 && t < t1).count();
    assert!(
        after_wait >= 5,
        "{after_wait} statuses arrived between 0.4 s and {:.2} s of the master's silence: the board still waited for it",
        t1 - t0
    );
}
