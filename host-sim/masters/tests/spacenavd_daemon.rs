#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The client against the real daemon: Debian's `spacenavd` started without any device.
//!
//! Ignored by default (it needs the `spacenavd` binary); `tests/spacenavd-daemon.sh`
//! installs it when missing and runs this test. It shows that the daemon can run in a
//! test: started with `-d` (no daemonising) in a temporary directory it binds
//! `run/spnav.sock` relative to its working directory (Debian's 1.1 build), answers the
//! protocol-1 handshake and fails the device queries (status −1: no device), so the
//! client connects with protocol 1 and reports no device. The daemon is this test's
//! child and is killed by its own handle at the end.

use masters::spacenav::{SpnavClient, SpnavOptions};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Daemon(Child);

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
#[ignore = "needs Debian's spacenavd; run by tests/spacenavd-daemon.sh"]
fn real_spacenavd_without_a_device() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("run")).unwrap();
    let config = dir.path().join("spnavrc");
    std::fs::write(&config, "").unwrap();
    let log = dir.path().join("spnavd.log");
    let child = Command::new("spacenavd")
        .arg("-d")
        .arg("-c")
        .arg(&config)
        .arg("-l")
        .arg(&log)
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spacenavd (apt-get install spacenavd)");
    let _daemon = Daemon(child);
    let candidates: Vec<PathBuf> = vec![dir.path().join("run/spnav.sock")];
    let end = Instant::now() + Duration::from_secs(5);
    let socket = loop {
        if let Some(p) = candidates.iter().find(|p| p.exists()) {
            break p.clone();
        }
        assert!(
            Instant::now() < end,
            "spacenavd made no socket in {} within 5 s; its log:\n{}",
            dir.path().display(),
            std::fs::read_to_string(&log).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let c = SpnavClient::connect(&socket, &SpnavOptions::default()).unwrap();
    assert_eq!(c.protocol(), 1, "spacenavd 1.x speaks protocol 1");
    assert_eq!(c.device(), None, "no device plugged in");
    let log_text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(
        log_text.contains("client name: rspr-masters"),
        "log:\n{log_text}"
    );
}
