#![allow(clippy::unwrap_used, clippy::expect_used)]
//! `host-sim faultlog` against the simulated board served on a socket: a master presses
//! the e-stop over the link, then the command reads the logs back and prints them.

use std::process::Command as Process;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Property: an emergency stop sent over the link is in the log `host-sim faultlog`
/// prints, with its stop, and the reset (power-on) is reported.
#[test]
fn faultlog_prints_what_the_board_logged() {
    let dir = std::env::temp_dir().join(format!("faultlog-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sock = dir.join("board.sock");
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let server = {
        let (sock, stop) = (sock.clone(), Arc::clone(&stop));
        std::thread::spawn(move || {
            let mut cfg = simulation::board::BoardSimConfig::reference(None).unwrap();
            cfg.service.watchdog.max_lateness_us = 1_000_000;
            cfg.service.overruns_to_fault = u32::MAX;
            simulation::serve::serve(&sock, cfg, &stop, &|| {
                let _ = ready_tx.send(());
            })
            .unwrap();
        })
    };
    ready_rx.recv_timeout(Duration::from_secs(10)).unwrap();
    {
        let link = teleop::link::open(&sock, 1_000_000, Duration::from_secs(5)).unwrap();
        let mut s = teleop::session::Session::new(link);
        s.hello(5.0).unwrap();
        let seq = s.send(master_link::MasterToBoard::EmergencyStop).unwrap();
        s.reply(seq, 2.0).unwrap();
        s.wait(0.1).unwrap();
    }
    let out = Process::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["faultlog", "--connect"])
        .arg(&sock)
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("last reset: power-on"), "{text}");
    assert!(text.contains("1 entries"), "{text}");
    assert!(text.contains("e-stop message"), "{text}");
    assert!(text.contains("torque off, brakes on"), "{text}");
    // The event log in plain words: the boot, the master, the e-stop with its stop.
    assert!(text.contains("event log (kept in flash"), "{text}");
    assert!(text.contains("board started after power-on"), "{text}");
    assert!(text.contains("a master took charge"), "{text}");
    assert!(
        text.contains("fault: e-stop message; then STO: torque off, brakes applied"),
        "{text}"
    );
}
