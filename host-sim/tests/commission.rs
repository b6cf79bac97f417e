#![allow(clippy::unwrap_used, clippy::expect_used)]
//! `host-sim commission` against the simulated board served on a socket (the second
//! position channel fitted): on a straight robot it reports every joint wired as the pin
//! map says; on a miswired one (two encoders swapped, a gear ratio 10 % off) it names
//! each miswiring with its joint and fix, and writes a board profile with the measured
//! gear ratio (read back by `BoardProfile::from_toml_str`) and the wiring corrections.

use std::process::Command as Process;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Serves the simulated board wired as `wiring`, runs `host-sim commission --yes` on it,
/// and returns its success, its output and its output directory.
fn run(name: &str, wiring: board_on_plant::Wiring) -> (bool, String, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("commission-{name}-{}", std::process::id()));
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
            cfg.position_channel = true;
            cfg.wiring = wiring;
            simulation::serve::serve(&sock, cfg, &stop, &|| {
                let _ = ready_tx.send(());
            })
            .unwrap();
        })
    };
    ready_rx.recv_timeout(Duration::from_secs(10)).unwrap();
    let out_dir = dir.join("out");
    let out = Process::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["commission", "--yes", "--connect"])
        .arg(&sock)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    (out.status.success(), text, out_dir)
}

/// Property: a robot wired as the pin map says is reported so, joint by joint, and its
/// profile is written unchanged.
#[test]
fn a_straight_robot_is_reported_wired_as_the_pin_map_says() {
    let (ok, text, out) = run("straight", board_on_plant::Wiring::straight());
    assert!(ok, "{text}");
    for j in ["l1", "l2", "l3", "theta1", "theta2", "theta3"] {
        assert!(text.contains(&format!("  {j}: OK")), "{j}: {text}");
    }
    assert!(
        text.contains("every joint tested is wired as the pin map says"),
        "{text}"
    );
    let profile = std::fs::read_to_string(out.join("board-profile.toml")).unwrap();
    let p = board_profile::BoardProfile::from_toml_str(&profile).unwrap();
    assert_eq!(p, board_profile::BoardProfile::REFERENCE);
}

/// Property: encoders l1 and l2 swapped and theta2's gear ratio 10 % off are each found,
/// named with the joint and the fix, and the written corrections say so.
#[test]
fn a_miswired_robot_is_told_what_to_fix() {
    let mut w = board_on_plant::Wiring::straight();
    w.encoders_swapped = Some((0, 1));
    w.count_scale[4] = 1.1;
    let (ok, text, out) = run("miswired", w);
    assert!(ok, "{text}");
    assert!(
        text.contains("l1: FOUND another joint's encoder counted"),
        "{text}"
    );
    assert!(
        text.contains("l2: FOUND another joint's encoder counted"),
        "{text}"
    );
    assert!(text.contains("swap the two encoder connectors"), "{text}");
    assert!(
        text.contains("theta2: FOUND the encoder's counts per unit differ"),
        "{text}"
    );
    assert!(text.contains("  theta3: OK"), "{text}");
    let profile = std::fs::read_to_string(out.join("board-profile.toml")).unwrap();
    let p = board_profile::BoardProfile::from_toml_str(&profile).unwrap();
    let gear = p.joints[4].gear_ratio / board_profile::BoardProfile::REFERENCE.joints[4].gear_ratio;
    assert!(
        (gear - 1.1).abs() < 0.02,
        "theta2's gear ratio scaled by {gear}"
    );
    let wiring = std::fs::read_to_string(out.join("wiring.toml")).unwrap();
    assert!(
        wiring.contains("encoder_channel = [1, 0, 2, 3, 4, 5]"),
        "{wiring}"
    );
    let report = std::fs::read_to_string(out.join("report.txt")).unwrap();
    assert!(
        report.contains("6 joint(s) tested, 3 with findings"),
        "{report}"
    );
}
