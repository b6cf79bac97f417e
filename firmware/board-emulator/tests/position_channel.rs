//! The board with the second position channel (the image built with `--no-default-features
//! --features position-channel`: STM32F405ZG, a potentiometer per joint on an AD7689 on SPI3,
//! `CNV` on PD0) on the emulated board, in the board's time, with the master of
//! `link_master`: the plant's potentiometers through the emulated converter
//! (`board_emulator::position_channel`, `board_emulator::ad7689`). The image is
//! `$RSPR_BOARD_PC_ELF`, else `rspr-board-position-channel` in the Cortex-M workspace's
//! default target directory (`firmware/cortex-m/board/build-and-size.sh` copies it there;
//! `run.sh` sets the variable).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod link_master;

use std::path::{Path, PathBuf};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::pins::{PinId, Port, POSITION_CHANNEL};
use board_emulator::position_channel::{CNV, INPUTS, SPI3_AF, SPI3_PINS};
use board_profile::position_channel::{ad7689, PositionChannel};
use link_master::{Master, MS};
use master_link::{BoardToMaster, FaultCause, MasterToBoard, RobotState};

fn image() -> PathBuf {
    std::env::var_os("RSPR_BOARD_PC_ELF").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR")).join(
                "../cortex-m/target/thumbv7em-none-eabihf/release/rspr-board-position-channel",
            )
        },
        PathBuf::from,
    )
}

/// A port's `MODER`, `AFRH` (RM0090 rev 19 sections 8.4.1, 8.4.10): GPIOA's base and
/// 0x400 a port.
fn moder(port: Port) -> u64 {
    0x4002_0000 + 0x400 * port.index() as u64
}
fn afrh(port: Port) -> u64 {
    moder(port) + 0x24
}

/// The converter's step in joint units (the profile's: 1.53 µm on a leg, 0.0052 deg on a
/// link).
fn step(j: usize) -> f64 {
    PositionChannel::REFERENCE.step_unit(j)
}

/// The bench for the position-channel image on its board.
fn config() -> BenchConfig {
    let mut config = BenchConfig::reference(image()).unwrap_or_else(|e| {
        panic!(
            "{e}: build it with `firmware/cortex-m/board/build-and-size.sh board-position-channel`"
        )
    });
    config.board = POSITION_CHANNEL;
    config.position_channel = true;
    config
}

/// Checks the channel's pins as the image sets them: SPI3's on AF6, `CNV` an output.
fn check_pins(m: &mut Master) {
    let addresses = vec![moder(Port::C), afrh(Port::C), moder(Port::D)];
    m.bench.act(Action::Peek(addresses.clone()));
    m.run_ms(1).unwrap();
    let peek = |a: u64| {
        m.bench
            .peeked
            .iter()
            .find(|(x, _)| *x == a)
            .and_then(|(_, v)| *v)
            .unwrap()
    };
    let (mc, af, md) = (peek(addresses[0]), peek(addresses[1]), peek(addresses[2]));
    let pin = |p: PinId| u64::from(p.number);
    for p in SPI3_PINS {
        assert_eq!((mc >> (2 * pin(p))) & 0b11, 0b10, "{p} alternate");
        assert_eq!(
            (af >> (4 * (pin(p) - 8))) & 0xF,
            u64::from(SPI3_AF),
            "{p} AF{SPI3_AF}"
        );
    }
    assert_eq!((md >> (2 * pin(CNV))) & 0b11, 0b01, "{CNV} output");
}

/// `Home` until `Ready`, with each joint's largest travel from where it started.
fn home(m: &mut Master) -> [f64; 6] {
    let start = m.bench.last.q;
    let reply = m
        .command(&MasterToBoard::Home { rehome: false }, 50)
        .unwrap();
    assert!(
        matches!(reply, Some(BoardToMaster::Ack { .. })),
        "{reply:?}"
    );
    let mut travel = [0.0f64; 6];
    let deadline = m.now() + 15_000 * MS;
    while m.now() < deadline {
        m.turn().unwrap();
        for (t, (q, q0)) in travel.iter_mut().zip(m.bench.last.q.iter().zip(start)) {
            *t = t.max((q - q0).abs());
        }
        if m.state() == Some(RobotState::Ready) {
            break;
        }
        assert_ne!(
            m.state(),
            Some(RobotState::Fault),
            "{:?}",
            m.status.map(|s| s.fault)
        );
    }
    assert_eq!(m.state(), Some(RobotState::Ready), "homed within 15 s");
    travel
}

/// The causes that name a joint's encoder: its disagreement with the second channel, and
/// the encoder's own checks (no counts while its motor turns, a jump).
const ENCODER_CAUSES: [FaultCause; 3] = [
    FaultCause::EncoderDisagree,
    FaultCause::EncoderDead,
    FaultCause::EncoderJump,
];

/// SPI3's data register (RM0090 rev 19 section 28.5.4; SPI3 at 0x4000_3C00).
const SPI3_DR: u64 = 0x4000_3C0C;

/// Property (the plant's potentiometers reach the real image's AD7689 driver): the image
/// built with the channel boots with the channel fitted in its status, SPI3's pins on AF6
/// and `CNV` an output, and every control tick reads six frames on SPI3 whose fifth carries
/// the converter's configuration (the profile's `CFG`: the sequencer over IN0..IN5) and the
/// others none, each answer the plant's reading of its joint at rest (joint order): within
/// the reading's ideal count (its offset included) plus and minus the noise's bound
/// (3.47 x `noise_lsb`, `plant::PositionSensor`), rounded.
#[test]
fn the_plants_potentiometers_reach_the_image_through_the_ad7689() {
    let config = config();
    let start_q = config.mechanics.start_q;
    let mut m = Master::new(Bench::start(config).unwrap());
    m.hello(0xadc3_0000).unwrap();
    assert!(m.run_until(500, |m| m.status.is_some()).unwrap());
    assert!(
        m.status.unwrap().position_channel,
        "the status says the channel is fitted"
    );
    check_pins(&mut m);
    m.bench.act(Action::Record(5 * MS));
    m.run_ms(6).unwrap();
    let plant = plant::Plant::new(&plant::PlantConfig::shipped().unwrap()).unwrap();
    let expected: Vec<std::ops::RangeInclusive<u64>> = (0..6)
        .map(|j| {
            let s = plant.position_sensor(j).unwrap();
            let ideal = s.ideal_counts(start_q[j]);
            let spread = 3.47 * s.noise_lsb;
            let c = |x: f64| x.round().clamp(0.0, 65535.0) as u64;
            c(ideal - spread)..=c(ideal + spread)
        })
        .collect();
    // The frames in order: (what the image wrote, what it read).
    let mut frames: Vec<(u64, u64)> = Vec::new();
    let mut read_at: Vec<u64> = Vec::new();
    let mut written = None;
    for r in std::mem::take(&mut m.bench.recorded) {
        if r.address != SPI3_DR {
            continue;
        }
        if r.write {
            written = Some(r.value & 0xFFFF);
        } else {
            frames.push((
                written.take().expect("a write before each read"),
                r.value & 0xFFFF,
            ));
            read_at.push(r.at.0);
        }
    }
    let cfg = u64::from(ad7689::frame(ad7689::CFG));
    // A tick's six frames: the one with the configuration is the fifth.
    let first = frames
        .iter()
        .position(|(w, _)| *w == cfg)
        .expect("the configuration")
        + 2;
    let ticks: Vec<&[(u64, u64)]> = frames[first..].chunks_exact(6).collect();
    assert!(ticks.len() >= 4, "six frames a tick: {frames:?}");
    // Within a tick the conversions are at least `tCYC` apart (the driver's timing), and
    // the six take the tick's busy time: from the first read to the last.
    let spans: Vec<u64> = read_at[first..]
        .chunks_exact(6)
        .map(|t| {
            for w in t.windows(2) {
                assert!(w[1] - w[0] >= u64::from(ad7689::T_CYC_NS), "reads at {t:?}");
            }
            t[5] - t[0]
        })
        .collect();
    println!(
        "a tick's six reads span {spans:?} ns (5 x tCYC = {} ns)",
        5 * ad7689::T_CYC_NS
    );
    for tick in &ticks {
        for (k, (w, r)) in tick.iter().enumerate() {
            assert_eq!(*w, if k == 4 { cfg } else { 0 }, "frame {k} wrote {w:#x}");
            let j = INPUTS.iter().position(|i| usize::from(*i) == k).unwrap();
            assert!(
                expected[j].contains(r),
                "joint {j}: {r} not in {:?}",
                expected[j]
            );
        }
    }
    println!(
        "worst control tick since boot: {} us",
        m.status.unwrap().tick_exec_max_us
    );
    println!(
        "AD7689: {} ticks of six frames in 5 ms, the first {:?}",
        ticks.len(),
        ticks[0]
    );
    let _ = m.bench.finish();
}

/// Property (the second channel on the real image and its AD7689 driver):
/// * the status says the channel is fitted, and the image puts SPI3's pins on AF6 and
///   `CNV` (PD0) as an output;
/// * `Home` restores the position from the channel and only verifies it: no joint travels
///   more than the verification's move (1 mm or 1 deg out and back) and 0.1 mm or 0.1 deg
///   more, and the measured joints read the true ones within 0.1 mm (legs) and 0.05 deg
///   plus one converter step (links: one count of the AD7689's 65536, 0.0052 deg);
/// * a leg jogged at 2 mm/s for 0.4 s with both channels healthy: no fault;
/// * its encoder stuck while it is jogged: the drivers off (PA10 low: the fault's STO)
///   within 20 ms of board time and 0.1 mm of the leg's motion, a fault naming that
///   joint's encoder in the status and the fault log read over the link (while the leg
///   moves the channel's window allows the backlash, 0.2 mm, so the encoder's own check,
///   `EncoderDead`: its motor turns and it does not count, may name it first);
/// * a power cycle with the robot where the fault left it: `Home` restores it again with
///   no sweep.
#[test]
fn the_second_channel_cross_checks_the_encoder_and_restores_the_position() {
    let mut config = config();
    let mut m = Master::new(Bench::start(config.clone()).unwrap());
    m.hello(0xadc3_0001).unwrap();
    assert!(m.run_until(500, |m| m.status.is_some()).unwrap());
    assert!(
        m.status.unwrap().position_channel,
        "the status says the channel is fitted"
    );
    check_pins(&mut m);

    let t0 = m.now();
    let travel = home(&mut m);
    let homing_s = (m.now() - t0) as f64 / 1e9;
    m.run_ms(100).unwrap();
    let measured = m.status.unwrap().joints;
    let truth = m.bench.last.q;
    for j in 0..6 {
        let (travel_max, error_max) = if j < 3 {
            (1.1e-3, 0.1e-3)
        } else {
            (1.1f64.to_radians(), 0.05f64.to_radians() + step(j))
        };
        let error = (f64::from(measured[j]) - truth[j]).abs();
        assert!(travel[j] < travel_max, "joint {j} travelled {:?}", travel);
        assert!(
            error < error_max,
            "joint {j}: measured {measured:?}, true {truth:?}"
        );
    }
    println!(
        "restored in {homing_s:.2} s, travel {travel:?}, error {:?} (converter step {:.1} um, {:.3} deg)",
        (0..6).map(|j| (f64::from(measured[j]) - truth[j]).abs()).collect::<Vec<_>>(),
        step(0) * 1e6,
        step(3).to_degrees()
    );

    // Enable, then jog leg 1: both channels healthy.
    m.command(&MasterToBoard::OperatorPresent { present: true }, 50)
        .unwrap();
    let enable = m.command(&MasterToBoard::Enable, 50).unwrap();
    assert!(
        matches!(enable, Some(BoardToMaster::Ack { .. })),
        "{enable:?}"
    );
    assert!(m
        .run_until(1_000, |m| m.state() == Some(RobotState::Enabled))
        .unwrap());
    m.jog = Some((0, 2e-3));
    let q0 = m.bench.last.q[0];
    m.run_ms(400).unwrap();
    let moved = m.bench.last.q[0] - q0;
    assert_eq!(
        m.state(),
        Some(RobotState::Enabled),
        "{:?}",
        m.status.map(|s| s.fault)
    );
    assert!(moved > 0.5e-3, "the leg moved {moved} m");
    // The tick's worst execution time so far (the AD7689's six conversions in it).
    println!(
        "worst control tick so far: {} us (jitter {} us)",
        m.status.unwrap().tick_exec_max_us,
        m.status.unwrap().tick_jitter_max_us
    );

    // The encoder sticks while the leg moves.
    m.bench.act(Action::PlantFault {
        joint: 0,
        fault: plant::Fault::EncoderStuck,
    });
    m.turn_ns = 100_000;
    let injected = m.now();
    let q_injected = m.bench.last.q[0];
    m.bench.edges.clear();
    // Every 100 µs: the leg's true position, until the drivers go off (the STO's edge on
    // PA10) or 200 ms pass.
    let mut off_at = None;
    let mut q_at_off = q_injected;
    while m.now() < injected + 200 * MS && off_at.is_none() {
        m.turn().unwrap();
        off_at = m
            .bench
            .edges
            .iter()
            .find(|(t, o)| t.0 >= injected && !o.driver_enable)
            .map(|(t, _)| t.0);
        if off_at.is_none() {
            q_at_off = m.bench.last.q[0];
        }
    }
    let off_at = off_at.expect("the drivers off within 200 ms of the stuck encoder");
    let detected_ms = (off_at - injected) as f64 / 1e6;
    let before = (q_at_off - q_injected).abs();
    m.jog = None;
    m.turn_ns = MS;
    m.run_ms(100).unwrap();
    let fault = m.status.unwrap().fault;
    let after = (m.bench.last.q[0] - q_injected).abs();
    println!(
        "stuck encoder: {fault:?}, the drivers off {detected_ms:.1} ms after, the leg moved {:.1} um before and {:.1} um in all",
        before * 1e6,
        after * 1e6,
    );
    assert_eq!(m.state(), Some(RobotState::Fault));
    assert!(ENCODER_CAUSES.contains(&fault.cause), "{fault:?}");
    assert_eq!(fault.joint, 0, "{fault:?}");
    assert!(
        detected_ms <= 20.0,
        "the drivers off {detected_ms} ms after"
    );
    assert!(
        before < 0.1e-3,
        "the leg moved {before} m before the drivers went off"
    );
    m.send(&MasterToBoard::FaultLogRequest { first: 0 });
    let fault_log = |m: &Master| {
        m.replies.iter().find_map(|(_, r)| match r {
            BoardToMaster::FaultLog(p) => Some(*p),
            _ => None,
        })
    };
    m.run_until(100, |m| fault_log(m).is_some()).unwrap();
    let page = fault_log(&m).expect("the fault log over the link");
    assert!(
        page.entries[..usize::from(page.count)]
            .iter()
            .any(|e| ENCODER_CAUSES.contains(&e.record.cause) && e.record.joint == 0),
        "{page:?}"
    );

    // A power cycle where the robot stands now: restored again, no sweep.
    let rest = m.bench.last.q;
    let kept = m.bench.flash();
    let _ = m.bench.finish();
    config.mechanics.start_q = rest;
    config.flash = Some(kept);
    let mut m = Master::new(Bench::start(config).unwrap());
    m.hello(0xadc3_0002).unwrap();
    assert!(m.run_until(500, |m| m.status.is_some()).unwrap());
    let travel = home(&mut m);
    for j in 0..6 {
        let bound = if j < 3 { 1.1e-3 } else { 1.1f64.to_radians() };
        assert!(travel[j] < bound, "after the power cycle: {travel:?}");
    }
    println!("after a power cycle: restored, travel {travel:?}");
    let _ = m.bench.finish();
}
