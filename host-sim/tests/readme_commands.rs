#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The README's examples run as written: every `host-sim …` line of its ```sh blocks (and
//! `cargo run … -p host-sim -- …`, which is the same binary), in the README's order, through
//! `sh -c` in one fresh directory with this build's `host-sim` first on `PATH`, so that
//! redirections (`< poses.csv > joints.csv`) and the files one line writes for the next
//! (`target/calibration/calibrated.toml`) work as a user's shell has them.
//!
//! What the README presumes of the user is provided, and nothing else is changed:
//! - the user's own files: `poses.csv` as a pose CSV before `ik --csv`, and as tracker
//!   measurements (simulated) before `calibrate --measurements`;
//! - `host-sim board --socket /tmp/board.sock` runs in the background for the lines after
//!   it that connect to that socket, on a socket in the test's directory (the path
//!   replaced, so that tests and users do not share one);
//! - a line for a real board's serial device (`/dev/ttyUSB0`) must fail, naming the device;
//! - `host-sim faults` (the whole campaign, about a minute) is run on one fault kind in
//!   one condition: its flags are the README's, the campaign is `host-sim/faults`'s tests.
//!
//! Every other line must exit 0. A README line this test does not recognise fails it.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// The README's shell lines that run `host-sim`, comments removed, `cargo run … --` made
/// `host-sim`.
fn readme_commands() -> Vec<String> {
    let readme = Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
    let text = std::fs::read_to_string(&readme).unwrap();
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in text.lines() {
        if let Some(fence) = line.strip_prefix("```") {
            in_sh = !in_sh && fence.trim() == "sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        let command = match line.find(" #") {
            Some(i) => &line[..i],
            None => line,
        }
        .trim();
        if let Some(rest) = command.strip_prefix("cargo run ") {
            // `cargo run [--release] -p host-sim -- ARGS`.
            let (flags, args) = rest.split_once(" -- ").unwrap_or((rest, ""));
            if flags.split_whitespace().any(|w| w == "host-sim") {
                out.push(format!("host-sim {args}").trim().to_string());
            }
        } else if command.starts_with("host-sim ") {
            out.push(command.to_string());
        }
    }
    out
}

/// A directory of the test's own with `bin/host-sim`.
fn workspace() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_host-sim"), bin.join("host-sim")).unwrap();
    (dir, bin)
}

struct Shell {
    cwd: PathBuf,
    path: String,
}

struct Ran {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Shell {
    fn command(&self, line: &str) -> Command {
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg(line)
            .current_dir(&self.cwd)
            .env("PATH", &self.path);
        c
    }

    fn run(&self, line: &str) -> Ran {
        let out = self.command(line).stdin(Stdio::null()).output().unwrap();
        Ran {
            code: out.status.code(),
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }

    fn ok(&self, line: &str) -> Ran {
        let r = self.run(line);
        assert_eq!(
            r.code,
            Some(0),
            "README line `{line}` failed:\n{}\n{}",
            r.stdout,
            r.stderr
        );
        r
    }
}

/// The background board, stopped (SIGINT, as a user's Ctrl-C) when dropped.
struct Background(Child);

impl Drop for Background {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-INT", &self.0.id().to_string()])
            .status();
        for _ in 0..50 {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn every_command_of_the_readme_runs_as_written() {
    let commands = readme_commands();
    // The README's examples: kinematics, design, calibration, the board; a parse that
    // finds far fewer has lost them.
    assert!(commands.len() >= 20, "{commands:#?}");
    let (dir, bin) = workspace();
    let sh = Shell {
        cwd: dir.path().to_path_buf(),
        path: format!(
            "{}:{}",
            bin.display(),
            std::env::var("PATH").unwrap_or_default()
        ),
    };
    let socket = dir.path().join("board.sock");
    let socket_text = socket.to_str().unwrap();
    let mut board: Option<Background> = None;
    for line in &commands {
        eprintln!("$ {line}");
        let line = line.replace("/tmp/board.sock", socket_text);
        // A board line run in the background (`... &`) once the README's board serves:
        // that board is the one it means.
        let line = match line.strip_suffix('&') {
            Some(l) if board.is_some() && l.trim_end().starts_with("host-sim board ") => continue,
            Some(l) => l.trim_end().to_string(),
            None => line,
        };
        if line.starts_with("host-sim board ") {
            let child = sh
                .command(&format!("exec {line}"))
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            board = Some(Background(child));
            // The socket exists once the board serves (a failure detector, not a timing).
            let mut waited = 0;
            while !socket.exists() && waited < 600 {
                std::thread::sleep(Duration::from_millis(100));
                waited += 1;
            }
            assert!(socket.exists(), "`{line}` made no socket in 60 s");
            continue;
        }
        if line.contains("/dev/ttyUSB0") {
            let r = sh.run(&line);
            assert_ne!(r.code, Some(0), "`{line}` without a board succeeded");
            assert!(
                r.stderr.contains("/dev/ttyUSB0"),
                "`{line}`: the error does not name the device: {}",
                r.stderr
            );
            continue;
        }
        if line.contains("--device spacemouse") {
            // Without a SpaceMouse (no spacenavd, no 3Dconnexion input device here) it
            // must say what is missing.
            let r = sh.run(&line);
            assert_ne!(r.code, Some(0), "`{line}` without a SpaceMouse succeeded");
            let e = r.stderr.to_lowercase();
            assert!(
                e.contains("spacenav") || e.contains("3dconnexion"),
                "`{line}`: the error does not name the device: {}",
                r.stderr
            );
            continue;
        }
        if line.contains(socket_text) {
            assert!(board.is_some(), "`{line}` before the README's board line");
        }
        if line.starts_with("host-sim ros2 ") || line.starts_with("host-sim view ") {
            serves_until_stopped(&sh, &line);
            board_takes_a_new_master(&sh, socket_text);
            continue;
        }
        if line.contains("ik --csv < poses.csv") {
            std::fs::write(
                dir.path().join("poses.csv"),
                "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n0,0,160,0,0,0\n10,-5,165,5,0,0\n",
            )
            .unwrap();
            sh.ok(&line);
            let joints = std::fs::read_to_string(dir.path().join("joints.csv")).unwrap();
            assert_eq!(joints.lines().count(), 3, "{joints}");
            continue;
        }
        if line.contains("calibrate --measurements poses.csv") {
            sh.ok("host-sim calibrate simulate --poses 40 --validation 20 --out measured");
            std::fs::copy(
                dir.path().join("measured/measurements.csv"),
                dir.path().join("poses.csv"),
            )
            .unwrap();
        }
        if line == "host-sim faults" {
            sh.ok("host-sim faults --kinds e-stop --conditions holding");
            continue;
        }
        let r = sh.ok(&line);
        assert!(
            !r.stdout.contains("{ ") && !r.stderr.contains("{ "),
            "`{line}` prints Debug text:\n{}\n{}",
            r.stdout,
            r.stderr
        );
    }
    drop(board);
}

/// A front end that serves until the user stops it (`ros2`, `view`): started, it must say
/// it serves (its own first line on stdout, after the bring-up's `board: ...` lines, within
/// 120 s: a failure detector, not a timing),
/// still run a second later, and end with exit 0 on SIGINT
/// (a user's Ctrl-C; the robot disabled on the way out).
fn serves_until_stopped(sh: &Shell, line: &str) {
    use std::io::BufRead;
    let mut child = sh
        .command(&format!("exec {line}"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut reader = std::io::BufReader::new(stdout);
        // Its own first line: the bring-up's lines (`board: ...`) come before it.
        let mut first = String::new();
        loop {
            first.clear();
            match reader.read_line(&mut first) {
                Ok(n) if n > 0 && first.starts_with("board: ") => continue,
                _ => break,
            }
        }
        let _ = tx.send(first);
        // Drained to the end, so that the front end never writes to a closed pipe.
        let _ = std::io::copy(&mut reader, &mut std::io::sink());
    });
    let first = rx.recv_timeout(Duration::from_secs(120));
    // Still serving a second later (not failing after its first line).
    std::thread::sleep(Duration::from_secs(1));
    let running = matches!(child.try_wait(), Ok(None));
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let out = child.wait_with_output().unwrap();
    assert!(
        first.as_ref().is_ok_and(|l| !l.is_empty()) && running,
        "`{line}` did not serve (first line {first:?}, running {running}): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "`{line}` did not end cleanly on SIGINT: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Waits until the board takes a new master's `Hello` after a front end that held it has
/// gone (`faultlog` says Hello and reads the log), at most 60 s: a failure detector, not a
/// timing. How long it took is printed: after `ros2` disabled a following robot on its
/// way out, the simulated board refused another master (`NotOwner`) for more than the
/// front ends' 1 s of retries, though the board's own stop ends in about 31 ms; the cause
/// is not found yet.
fn board_takes_a_new_master(sh: &Shell, socket: &str) {
    let start = std::time::Instant::now();
    loop {
        let r = sh.run(&format!("host-sim faultlog --connect {socket}"));
        if r.code == Some(0) {
            eprintln!(
                "the board took a new master {:.1} s after the front end ended",
                start.elapsed().as_secs_f64()
            );
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the board refuses a new master 60 s after the front end ended: {}",
            r.stderr
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The parser finds what the README shows, comments removed and `cargo run` made the
/// binary (a check of the test's own reading).
#[test]
fn the_readme_lines_are_read_as_commands() {
    let c = readme_commands();
    assert!(c.iter().any(|l| l == "host-sim sim"), "{c:#?}");
    assert!(
        c.iter()
            .any(|l| l == "host-sim ik --csv < poses.csv > joints.csv"),
        "{c:#?}"
    );
    assert!(c.iter().all(|l| !l.contains('#')), "{c:#?}");
}
