#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The front ends as processes against `host-sim board` (the simulated board on a Unix
//! socket, paced by the wall clock: a process of its own per test, so that each test has a
//! board of its own).
//!
//! * A front end that gets SIGTERM or SIGINT, or ends on an error of its own while the
//!   robot is enabled, leaves it disabled (drives off, `Ready`) within
//!   [`DISABLED_WITHIN`] of the signal: long before the board's 500 ms heartbeat timeout,
//!   and never with a `HeartbeatTimeout` fault.
//! * `host-sim teleop` starts from any board state: run twice in a row on one board
//!   (homed by the first run) both pass; on a board with a latched fault it shows the fault
//!   in words and refuses, and with `--clear-fault` clears it and runs.
//!
//! The board's state is read by an observer: a second connection that never says Hello
//! (every connection hears everything the board sends; an observer without a session
//! takes the board's frames of any session) and sends nothing but, in the fault test, an
//! `EmergencyStop` (taken from anyone).

use master_link::{BoardToMaster, FaultCause, MasterToBoard, RobotState, StatusReport};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use teleop::link::{self, Link};

/// How soon after the signal the board must report the drives off.
const DISABLED_WITHIN: Duration = Duration::from_millis(200);

const BIN: &str = env!("CARGO_BIN_EXE_host-sim");

/// A `host-sim board` process and its socket.
struct SimBoard {
    child: Child,
    socket: PathBuf,
    dir: tempfile::TempDir,
}

impl SimBoard {
    fn start() -> SimBoard {
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("board.sock");
        let child = Command::new(BIN)
            .args(["board", "--socket"])
            .arg(&socket)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        while !socket.exists() {
            assert!(t0.elapsed() < Duration::from_secs(10), "no board socket");
            std::thread::sleep(Duration::from_millis(20));
        }
        SimBoard { child, socket, dir }
    }

    fn observer(&self) -> Observer {
        Observer {
            link: link::open(&self.socket, 0, Duration::from_secs(5)).unwrap(),
            last: None,
        }
    }

    /// Starts a front end with `args` (`--connect` added), its output to `name`.log.
    fn front_end(&self, name: &str, args: &[&str]) -> Child {
        let log = std::fs::File::create(self.log(name)).unwrap();
        Command::new(BIN)
            .args(args)
            .arg("--connect")
            .arg(&self.socket)
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .unwrap()
    }

    fn log(&self, name: &str) -> PathBuf {
        self.dir.path().join(format!("{name}.log"))
    }

    fn read_log(&self, name: &str) -> String {
        std::fs::read_to_string(self.log(name)).unwrap_or_default()
    }
}

impl Drop for SimBoard {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A connection that only listens to the board's statuses.
struct Observer {
    link: Link,
    last: Option<StatusReport>,
}

impl Observer {
    /// Waits at most `timeout` for a status that satisfies `pred`; its arrival.
    fn wait(
        &mut self,
        timeout: Duration,
        pred: impl Fn(&StatusReport) -> bool,
    ) -> Option<(Instant, StatusReport)> {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(r) = self.link.recv(Duration::from_millis(5)).unwrap() {
                if let BoardToMaster::Status(s) = r.msg {
                    self.last = Some(s);
                    if pred(&s) {
                        return Some((Instant::now(), s));
                    }
                }
            }
        }
        None
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args(["-s", sig, &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -s {sig}");
}

/// Waits at most `timeout` for the process to end; its exit code.
fn wait_exit(child: &mut Child, timeout: Duration) -> Option<i32> {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    None
}

/// Starts the front end, waits until the robot is enabled (and a second more), sends
/// `sig` (None: the front end ends by itself), and checks that the drives are off within
/// [`DISABLED_WITHIN`] without a fault. The time from the signal to the status with the
/// drives off.
fn disabled_after(board: &SimBoard, name: &str, args: &[&str], sig: Option<&str>) -> Duration {
    let mut obs = board.observer();
    let mut child = board.front_end(name, args);
    let enabled = obs.wait(Duration::from_secs(60), |s| s.state == RobotState::Enabled);
    assert!(
        enabled.is_some(),
        "{name}: never enabled; log:\n{}",
        board.read_log(name)
    );
    obs.wait(Duration::from_secs(1), |_| false);
    let t0 = Instant::now();
    if let Some(sig) = sig {
        signal(&child, sig);
    }
    let off = obs.wait(Duration::from_secs(10), |s| s.state != RobotState::Enabled);
    let code = wait_exit(&mut child, Duration::from_secs(5));
    let log = board.read_log(name);
    let (t, s) = off.unwrap_or_else(|| panic!("{name}: still enabled; log:\n{log}"));
    assert_eq!(
        s.state,
        RobotState::Ready,
        "{name}: {:?}; log:\n{log}",
        s.fault
    );
    let waited = t - t0;
    eprintln!("{name}: drives off {waited:?} after the signal; exit {code:?}");
    if sig.is_some() {
        assert!(waited <= DISABLED_WITHIN, "{name}: {waited:?}; log:\n{log}");
    }
    assert!(code.is_some(), "{name} did not end; log:\n{log}");
    assert!(
        log.contains("disabled on the way out"),
        "{name}: log:\n{log}"
    );
    // Nothing the board would take for a lost master afterwards.
    let later = obs.wait(Duration::from_millis(700), |s| s.state == RobotState::Fault);
    assert!(later.is_none(), "{name}: {later:?}");
    waited
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// SIGTERM in the middle of the scripted path: the robot is disabled within 200 ms.
#[test]
fn teleop_path_disables_on_sigterm() {
    let board = SimBoard::start();
    let out = board.dir.path().join("out").display().to_string();
    disabled_after(
        &board,
        "teleop",
        &["teleop", "--path", "laparoscope", "--out", out.as_str()],
        Some("TERM"),
    );
}

/// The hand-controller teleoperation with a scripted device: SIGINT disables; an error of
/// the front end's own after the robot was enabled (its recording cannot be written)
/// disables too.
#[test]
fn teleop_device_disables_on_sigint_and_on_its_own_error() {
    let board = SimBoard::start();
    let script = write(
        board.dir.path(),
        "operator.txt",
        "# t_s x y z rx ry rz buttons\n0 0 0 0 0 0 0 present\n30 1 0 0 0 0 0 present\n",
    );
    let record = board.dir.path().join("s.mcap").display().to_string();
    let device = format!("scripted:{script}");
    let args = [
        "teleop",
        "--device",
        device.as_str(),
        "--record",
        record.as_str(),
    ];
    disabled_after(&board, "sigint", &args, Some("INT"));
    // The session recording cannot be written: the run ends with that error, after the
    // robot was enabled.
    let args = [
        "teleop",
        "--device",
        device.as_str(),
        "--record",
        "/dev/null/not-a-directory/s.mcap",
    ];
    disabled_after(&board, "own-error", &args, None);
    assert!(board.read_log("own-error").contains("not-a-directory"));
}

/// The OpenIGTLink bridge with `--enable`: SIGTERM disables.
#[test]
fn igtl_disables_on_sigterm() {
    let board = SimBoard::start();
    disabled_after(
        &board,
        "igtl",
        &["igtl", "--enable", "--listen", "127.0.0.1:0"],
        Some("TERM"),
    );
}

/// `--device keyboard` without a terminal says so.
#[test]
fn keyboard_without_a_terminal_is_refused_clearly() {
    let out = Command::new(BIN)
        .args([
            "teleop",
            "--connect",
            "/nonexistent",
            "--device",
            "keyboard",
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("stdin is not a terminal"), "{err}");
}

/// Twice in a row on one board: the second run finds the robot homed and skips homing;
/// then a latched fault is shown in words and refused, and cleared with `--clear-fault`.
#[test]
fn teleop_starts_from_any_board_state() {
    let board = SimBoard::start();
    let out = board.dir.path().join("out").display().to_string();
    let run = |name: &str, extra: &[&str]| {
        let mut args = vec!["teleop", "--path", "line", "--out", out.as_str()];
        args.extend_from_slice(extra);
        let mut child = board.front_end(name, &args);
        let code = wait_exit(&mut child, Duration::from_secs(120));
        (code, board.read_log(name))
    };
    let (code, log) = run("first", &[]);
    assert_eq!(code, Some(0), "{log}");
    let (code, log) = run("second", &[]);
    assert_eq!(code, Some(0), "{log}");
    assert!(
        log.contains("already homed (Ready): homing skipped"),
        "{log}"
    );

    let mut obs = board.observer();
    obs.link.send(&MasterToBoard::EmergencyStop).unwrap();
    let fault = obs.wait(Duration::from_secs(2), |s| s.state == RobotState::Fault);
    assert_eq!(
        fault.map(|(_, s)| s.fault.cause),
        Some(FaultCause::EmergencyStopMessage)
    );
    let (code, log) = run("faulted", &[]);
    assert_ne!(code, Some(0), "{log}");
    assert!(
        log.contains("latched fault: a master sent a stop") && log.contains("--clear-fault"),
        "{log}"
    );
    let (code, log) = run("cleared", &["--clear-fault"]);
    assert_eq!(code, Some(0), "{log}");
    assert!(log.contains("clearing it (--clear-fault)"), "{log}");
}

/// A scripted operator (`teleop --device scripted:FILE`) whose hand goes, from the central
/// pose, where the board's guards stop it, one guard at a time and back: z +17 mm (the
/// workspace's face at 175 mm: hc 160 + 10 mm + its 5 mm margin), 28 deg about x (the
/// 25 deg platform tilt cone), and x +20, y +20, z -12 mm with the rotation vector
/// (0, 22, 17) deg, a pose inside the box and the cone whose leg 1 is 134.0 mm (the
/// inverse kinematics: below the 144 mm stroke, while the platform tilt stays 21.9 deg
/// and the link angles within 35 deg). Every move is slower than the master's caps
/// (20 mm/s, 25 deg/s), so the board sees the operator's own path. The summary names, for
/// each, the guard and the first refused target's value beyond the limit.
#[test]
fn teleop_refusals_name_guard_value_and_limit() {
    let board = SimBoard::start();
    let script = write(
        board.dir.path(),
        "guards.txt",
        "# t_s  x y z [mm]  rx ry rz [deg]  buttons\n\
         0   0 0 0      0 0 0    present\n\
         1   0 0 0      0 0 0    present\n\
         4   0 0 17     0 0 0    present\n\
         5   0 0 17     0 0 0    present\n\
         8   0 0 0      0 0 0    present\n\
         9   0 0 0      0 0 0    present\n\
         12  0 0 0      28 0 0   present\n\
         13  0 0 0      28 0 0   present\n\
         16  0 0 0      0 0 0    present\n\
         17  0 0 0      0 0 0    present\n\
         21  20 20 -12  0 22 17  present\n\
         22  20 20 -12  0 22 17  present\n\
         26  0 0 0      0 0 0    present\n",
    );
    let record = board.dir.path().join("s.mcap").display().to_string();
    let device = format!("scripted:{script}");
    let mut child = board.front_end(
        "guards",
        &[
            "teleop",
            "--device",
            device.as_str(),
            "--record",
            record.as_str(),
            "--duration-s",
            "27",
        ],
    );
    let code = wait_exit(&mut child, Duration::from_secs(240));
    let log = board.read_log("guards");
    assert_eq!(code, Some(0), "{log}");
    // (guard, the words' start, the comparison, the limit, its unit)
    let cases = [
        ("workspace", "workspace z ", '>', 175.0, "mm"),
        ("platform tilt", "platform tilt ", '>', 25.0, "deg"),
        ("stroke", "stroke leg 1 ", '<', 144.0, "mm"),
    ];
    for (guard, start, op, limit, unit) in cases {
        let head = format!("  {guard}: the first at ");
        let line = log
            .lines()
            .find(|l| l.starts_with(&head))
            .unwrap_or_else(|| panic!("no {guard} refusal in the summary:\n{log}"));
        let words = line.split_once(" s: ").map_or("", |(_, w)| w);
        let rest = words
            .strip_prefix(start)
            .unwrap_or_else(|| panic!("{guard}: {line}"));
        // "<value> <unit> <op> <limit> <unit>"
        let f: Vec<&str> = rest.split(' ').collect();
        assert_eq!(f.len(), 5, "{line}");
        let value: f64 = f[0].parse().unwrap_or_else(|_| panic!("{line}"));
        assert_eq!(
            (f[1], f[2], f[3], f[4]),
            (
                unit,
                op.to_string().as_str(),
                format!("{limit:.1}").as_str(),
                unit
            ),
            "{line}"
        );
        // Beyond the limit (the words round to 0.1).
        let beyond = if op == '>' {
            value >= limit
        } else {
            value <= limit
        };
        assert!(beyond, "{line}");
        eprintln!("{line}");
    }
}
