//! The board with the second position channel (the image built with `--no-default-features
//! --features position-channel`: STM32F405ZG, a potentiometer per joint on ADC3, PF3..PF8)
//! on the emulated board, in the board's time, with the master of `link_master`: the plant's
//! potentiometers through rigless's ADC3 (`board_emulator::position_channel`). The image is
//! `$RSPR_BOARD_PC_ELF`, else `rspr-board-position-channel` in the Cortex-M workspace's
//! default target directory (`firmware/cortex-m/board/build-and-size.sh` copies it there;
//! `run.sh` sets the variable).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod link_master;

use std::path::{Path, PathBuf};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::position_channel::POTENTIOMETERS;
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

/// `GPIOF_MODER` (RM0090 rev 19 section 8.4.1).
const GPIOF_MODER: u64 = 0x4002_1400;

/// A leg's potentiometer: 100 mm over 65536 counts (`sim/plant/plant.toml`), so one step
/// of the 12-bit converter (16 counts) is 24.4 µm; a link's: 340 deg, 0.083 deg a step.
const LEG_STEP_M: f64 = 0.1 / 4096.0;
const LINK_STEP_RAD: f64 = 340.0 * std::f64::consts::PI / 180.0 / 4096.0;

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

/// ADC3's registers (RM0090 rev 19 section 13.13): `SQR3` (the regular sequence's first
/// channel) and `DR` (the data register), at ADC3's base 0x4001_2200.
const ADC3_SQR3: u64 = 0x4001_2234;
const ADC3_DR: u64 = 0x4001_224C;

/// Property (the plant's potentiometers reach the real image's ADC3 driver): the image
/// built with the channel boots with the channel fitted in its status and PF3..PF8 in
/// analog mode, and every control tick converts the six inputs in joint order
/// (IN9, IN14, IN15, IN4, IN5, IN6 in `SQR3`), each word in `DR` the plant's reading of
/// its joint at rest through the 12-bit converter: within the floors of the reading's
/// ideal count (its offset included) plus and minus the noise's bound (3.47 x
/// `noise_lsb`, `plant::PositionSensor`), times 4095/65536.
#[test]
fn the_plants_potentiometers_reach_the_image_through_adc3() {
    let mut config = BenchConfig::reference(image()).unwrap_or_else(|e| {
        panic!(
            "{e}: build it with `firmware/cortex-m/board/build-and-size.sh board-position-channel`"
        )
    });
    config.position_channel = true;
    let start_q = config.mechanics.start_q;
    let mut m = Master::new(Bench::start(config).unwrap());
    m.hello(0xadc3_0000).unwrap();
    assert!(m.run_until(500, |m| m.status.is_some()).unwrap());
    assert!(
        m.status.unwrap().position_channel,
        "the status says the channel is fitted"
    );
    m.bench.act(Action::Peek(vec![GPIOF_MODER]));
    m.bench.act(Action::Record(5 * MS));
    m.run_ms(6).unwrap();
    let moder = m
        .bench
        .peeked
        .iter()
        .find(|(a, _)| *a == GPIOF_MODER)
        .and_then(|(_, v)| *v);
    for p in POTENTIOMETERS {
        let mode = moder.map(|v| (v >> (2 * p.pin.number)) & 0b11);
        assert_eq!(mode, Some(0b11), "{} analog", p.pin);
    }
    let plant = plant::Plant::new(&plant::PlantConfig::shipped().unwrap()).unwrap();
    let expected: Vec<(u8, std::ops::RangeInclusive<u64>)> = POTENTIOMETERS
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let s = plant.position_sensor(j).unwrap();
            let ideal = s.ideal_counts(start_q[j]);
            let spread = 3.47 * s.noise_lsb;
            let word = |c: f64| (c.round().clamp(0.0, 65535.0) * 4095.0 / 65536.0).floor() as u64;
            (p.channel, word(ideal - spread)..=word(ideal + spread))
        })
        .collect();
    // Each DR read with the channel the last SQR3 write selected.
    let mut channel = None;
    let mut words: Vec<(u8, u64)> = Vec::new();
    for r in std::mem::take(&mut m.bench.recorded) {
        if r.write && r.address == ADC3_SQR3 {
            channel = Some((r.value & 0x1F) as u8);
        }
        if !r.write && r.address == ADC3_DR {
            words.push((channel.expect("SQR3 before DR"), r.value & 0xFFFF));
        }
    }
    assert!(words.len() >= 6 * 4, "six conversions a tick: {words:?}");
    let order: Vec<u8> = words.iter().take(6).map(|(c, _)| *c).collect();
    let first = expected.iter().position(|(c, _)| *c == order[0]).unwrap();
    for (k, (c, w)) in words.iter().enumerate() {
        let (want, range) = &expected[(first + k) % 6];
        assert_eq!(c, want, "the joint order: {order:?}");
        assert!(range.contains(w), "IN{c}: {w} not in {range:?}");
    }
    println!(
        "ADC3: {} conversions in 5 ms, words {:?}",
        words.len(),
        &words[..6]
    );
    let _ = m.bench.finish();
}

/// Property (the second channel on the real image and its ADC3 driver):
/// * the status says the channel is fitted, and the image puts PF3..PF8 in analog mode;
/// * `Home` restores the position from the channel and only verifies it: no joint travels
///   more than the verification's move (1 mm or 1 deg out and back) and 0.1 mm or 0.1 deg
///   more, and the measured joints read the true ones within 0.1 mm (legs) and 0.05 deg
///   plus one converter step (links: 16 counts of the plant's 65536, 0.083 deg);
/// * a leg jogged at 2 mm/s for 0.4 s with both channels healthy: no fault;
/// * its encoder stuck while it is jogged: the drivers off (PA10 low: the fault's STO)
///   within 20 ms of board time and 0.1 mm of the leg's motion, the fault
///   `EncoderDisagree` on that joint in the status and the fault log read over the link;
/// * a power cycle with the robot where the fault left it: `Home` restores it again with
///   no sweep.
#[test]
#[ignore = "fails on today's firmware: a healthy link's channel trips EncoderDisagree (value 0.00088 rad) during Home's verify move; the channel's bounds (control::absolute::ChannelConfig::reference) assume a 16-bit converter, the board's driver reads ADC3's 12 bits (a step of 16 counts, 0.083 deg on a link)"]
fn the_second_channel_cross_checks_the_encoder_and_restores_the_position() {
    let mut config = BenchConfig::reference(image()).unwrap_or_else(|e| {
        panic!(
            "{e}: build it with `firmware/cortex-m/board/build-and-size.sh board-position-channel`"
        )
    });
    config.position_channel = true;
    let mut m = Master::new(Bench::start(config.clone()).unwrap());
    m.hello(0xadc3_0001).unwrap();
    assert!(m.run_until(500, |m| m.status.is_some()).unwrap());
    assert!(
        m.status.unwrap().position_channel,
        "the status says the channel is fitted"
    );
    m.bench.act(Action::Peek(vec![GPIOF_MODER]));
    m.run_ms(1).unwrap();
    let moder = m
        .bench
        .peeked
        .iter()
        .find(|(a, _)| *a == GPIOF_MODER)
        .and_then(|(_, v)| *v);
    for p in POTENTIOMETERS {
        let mode = moder.map(|v| (v >> (2 * p.pin.number)) & 0b11);
        assert_eq!(mode, Some(0b11), "{} analog", p.pin);
    }

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
            (1.1f64.to_radians(), 0.05f64.to_radians() + LINK_STEP_RAD)
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
        LEG_STEP_M * 1e6,
        LINK_STEP_RAD.to_degrees()
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
    assert_eq!(m.state(), Some(RobotState::Fault));
    assert_eq!(fault.cause, FaultCause::EncoderDisagree, "{fault:?}");
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
            .any(|e| e.record.cause == FaultCause::EncoderDisagree && e.record.joint == 0),
        "{page:?}"
    );
    println!(
        "stuck encoder: EncoderDisagree on l1, the drivers off {detected_ms:.1} ms after, the leg moved {:.1} um before and {:.1} um in all, value {}",
        before * 1e6,
        after * 1e6,
        fault.value
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
