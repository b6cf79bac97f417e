//! Throughput of the three device parsers on their byte fixtures, repeated:
//! `cargo run --release -p masters --example parser_throughput`.

use masters::evdev::EvdevDecoder;
use masters::spacenav::PacketReader;
use masters::udp::{DatagramGate, GateConfig, PoseDatagram, FLAG_TRACKING_VALID};
use std::hint::black_box;
use std::time::Instant;

fn fixture(name: &str) -> Vec<u8> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    std::fs::read(&p).unwrap_or_default()
}

fn report(what: &str, items: u64, bytes: u64, seconds: f64) {
    println!(
        "{what}: {:.1} M items/s, {:.0} MB/s ({items} items in {seconds:.3} s)",
        items as f64 / seconds / 1e6,
        bytes as f64 / seconds / 1e6
    );
}

fn main() {
    let rounds = 500_000;
    // spacenavd: whole packets of the protocol-0 fixture (8 packets + a cut one, dropped).
    let spnav = fixture("spacenavd_v0.bin");
    let whole = &spnav[..spnav.len() / 32 * 32];
    let t = Instant::now();
    let mut n = 0u64;
    for _ in 0..rounds {
        let mut r = PacketReader::default();
        r.push(whole);
        while let Some(p) = r.next_packet() {
            black_box(p);
            n += 1;
        }
    }
    report(
        "spacenavd packets",
        n,
        (whole.len() * rounds) as u64,
        t.elapsed().as_secs_f64(),
    );

    let ev = fixture("evdev_rel.bin");
    let t = Instant::now();
    let mut d = EvdevDecoder::new();
    let mut reports = Vec::new();
    for _ in 0..rounds {
        reports.clear();
        d.push_bytes(&ev, &mut reports);
        black_box(&reports);
    }
    let events = d.counters().events;
    report(
        "evdev events",
        events,
        (ev.len() * rounds) as u64,
        t.elapsed().as_secs_f64(),
    );

    let mut gate = DatagramGate::new(GateConfig::default());
    let n_dg = 1_000_000u32;
    let t = Instant::now();
    for k in 0..n_dg {
        let d = PoseDatagram {
            flags: FLAG_TRACKING_VALID,
            session: 1,
            sequence: k,
            timestamp_us: u64::from(k) * 1000,
            position_mm: [1.0, 2.0, 3.0],
            orientation_wxyz: [1.0, 0.0, 0.0, 0.0],
            buttons: 2,
        }
        .encode();
        black_box(gate.judge(&d, f64::from(k) * 1e-3));
    }
    report(
        "UDP datagrams (encode + judge)",
        gate.accepted(),
        u64::from(n_dg) * 56,
        t.elapsed().as_secs_f64(),
    );
}
