#![allow(clippy::unwrap_used, clippy::expect_used)]
//! `host-sim teleop --device udp:...` and `host-sim replay` end to end: the binary serves
//! the simulated board (`host-sim board --socket`), a second one brings it up and
//! teleoperates with a UDP position master at 1:2 scaling, recording to MCAP, while this
//! test sends the master's datagrams (the documented 56-byte format,
//! `masters::udp::PoseDatagram`) through the real socket and parser: 10 mm in +x over
//! 1 s. Then `host-sim replay` prints the summary with the latency and writes the plots.
//! Checked: the board's setpoint moved 5 mm in x (within 1 µm), the summary and the
//! plots. About 40 s (homing the simulated board in wall-clock time takes most of it).

use masters::recording::Recording;
use masters::udp::{PoseDatagram, BUTTON_OPERATOR_PRESENT, FLAG_TRACKING_VALID};
use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn udp_master_teleoperates_records_and_replays() {
    let bin = env!("CARGO_BIN_EXE_host-sim");
    let dir = tempfile_dir();
    let sock = dir.join("board.sock");
    let _board = Kill(
        Command::new(bin)
            .args(["board", "--socket"])
            .arg(&sock)
            .stdout(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let port = {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.local_addr().unwrap().port()
    };
    let file = dir.join("session.mcap");
    let mut teleop = Kill(
        Command::new(bin)
            .args(["teleop", "--connect"])
            .arg(&sock)
            .args([
                "--device",
                &format!("udp:127.0.0.1:{port}"),
                "--scale-translation",
                "0.5",
                "--duration-s",
                "3.5",
                "--record",
            ])
            .arg(&file)
            .stdout(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let mut out = BufReader::new(teleop.0.stdout.take().unwrap());
    let mut printed = String::new();
    loop {
        let mut line = String::new();
        assert!(
            out.read_line(&mut line).unwrap() > 0,
            "teleop ended: {printed}"
        );
        printed.push_str(&line);
        if line.starts_with("teleoperating with") {
            break;
        }
    }
    // The master: at rest 0.3 s, 10 mm in +x over 1 s, at rest, 100 Hz.
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let t0 = Instant::now();
    let mut sequence = 0u32;
    while t0.elapsed() < Duration::from_secs_f64(2.5) {
        let t = t0.elapsed().as_secs_f64();
        let x = 10.0 * ((t - 0.3) / 1.0).clamp(0.0, 1.0);
        let d = PoseDatagram {
            flags: FLAG_TRACKING_VALID,
            session: 0x5eed,
            sequence,
            timestamp_us: t0.elapsed().as_micros() as u64,
            position_mm: [x as f32, 0.0, 0.0],
            orientation_wxyz: [1.0, 0.0, 0.0, 0.0],
            buttons: BUTTON_OPERATOR_PRESENT,
        };
        tx.send_to(&d.encode(), ("127.0.0.1", port)).unwrap();
        sequence += 1;
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = teleop.0.wait().unwrap();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut out, &mut rest).unwrap();
    printed.push_str(&rest);
    eprintln!("{printed}");
    assert!(status.success(), "teleop failed: {printed}");
    assert!(
        printed.contains("master input -> board setpoint"),
        "{printed}"
    );

    let rec = Recording::open(&file).unwrap();
    let sp: Vec<_> = rec.statuses().filter_map(|s| s.setpoint).collect();
    let moved = sp.last().unwrap().position_m - sp.first().unwrap().position_m;
    eprintln!(
        "setpoint moved [{:.4}, {:.4}, {:.4}] mm",
        moved.x * 1e3,
        moved.y * 1e3,
        moved.z * 1e3
    );
    assert!(
        (moved.x - 0.005).abs() < 1e-6 && moved.y.abs() < 1e-6,
        "{moved:?}"
    );
    assert!(
        rec.session.master.starts_with("udp:"),
        "{}",
        rec.session.master
    );

    let plots = dir.join("plots");
    let replay = Command::new(bin)
        .arg("replay")
        .arg(&file)
        .arg("--out")
        .arg(&plots)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&replay.stdout);
    eprintln!("{text}");
    assert!(
        replay.status.success(),
        "{}",
        String::from_utf8_lossy(&replay.stderr)
    );
    assert!(text.contains("master input -> board setpoint"), "{text}");
    for name in [
        "input.png",
        "position.png",
        "orientation.png",
        "lag.png",
        "margins.png",
    ] {
        assert!(plots.join(name).is_file(), "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fresh directory under the target directory's tmp (no tempfile dependency here).
fn tempfile_dir() -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("hand-controller-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}
