//! `StoreGeometry` on the emulated board (the release image, `rspr-board`), in the board's
//! time, with the master of `link_master`: the flash write happens only with the drives off
//! and the brakes applied, as the pins show through the write, and a write refused while
//! the drives are on leaves the control ticks and the flash alone. The event log's words,
//! programmed while the drives are on, cost no control period. The image is
//! `$RSPR_BOARD_ELF`, else the Cortex-M workspace's default target directory (`run.sh` sets
//! it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod link_master;

use std::path::{Path, PathBuf};

use board_emulator::bench::{Action, Bench, BenchConfig, FLASH_WORD_MAX_NS};
use board_emulator::board::Outputs;
use board_emulator::flash::{FlashOp, EVENTS_BASE, GEOMETRY_BASE};
use control::geometry_store::{decode_slot, record_of, SLOT_LEN};
use kinematics_core::{PerChainGeometry, RsprGeometry};
use link_master::{Master, MS};
use master_link::{BoardToMaster, GeometryRefusal, MasterToBoard, RobotState};

fn image() -> PathBuf {
    std::env::var_os("RSPR_BOARD_ELF").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../cortex-m/target/thumbv7em-none-eabihf/release/rspr-board")
        },
        PathBuf::from,
    )
}

/// The outputs a board that needs no control period drives: the drivers off, every duty 0,
/// both brake groups applied (their pins low).
fn quiet(o: &Outputs) -> bool {
    !o.driver_enable && o.duty.iter().all(|d| *d == 0.0) && o.brakes_released == [false; 2]
}

/// The geometry's programmed words in `ops`, with their instants.
fn geometry_words(ops: &[FlashOp]) -> Vec<(u64, u64)> {
    ops.iter()
        .filter_map(|op| match op {
            FlashOp::Program { at, address, .. } if *address >= GEOMETRY_BASE => {
                Some((at.0, *address))
            }
            _ => None,
        })
        .collect()
}

/// The event log's programmed words in `ops`, with their instants.
fn event_words(ops: &[FlashOp]) -> Vec<u64> {
    ops.iter()
        .filter_map(|op| match op {
            FlashOp::Program { at, address, .. } if *address < GEOMETRY_BASE => Some(at.0),
            _ => None,
        })
        .collect()
}

/// The control ticks' starts (arrivals at the `UART4` handler, the interrupt executor of the
/// control task) not yet taken.
fn ticks(m: &mut Master, uart4: u64) -> Vec<u64> {
    std::mem::take(&mut m.bench.hits)
        .into_iter()
        .filter(|(_, a)| *a == uart4)
        .map(|(t, _)| t.0)
        .collect()
}

/// Property (the stop precedence's flash write, on the pins of the real image):
/// * disabled, a `StoreGeometry` of the reference robot is taken: the 64 words of its slot
///   are programmed into sector 11 (the record decodes from them), each holding the core
///   for the programming time (no control tick starts between the first and the last), and
///   at every sample through the write (every 100 µs, and every output edge) the driver
///   enable is low, every duty 0 and both brake pins low (applied); the watchdog does not
///   reset the part; after a power cycle the board boots with the record (`HelloReply`'s
///   `geometry_version`);
/// * homing (the drives on), and during the SS1 of a `Disable` that follows: refused with
///   `InvalidState`, no word of sector 11 programmed, the control ticks 1 ms apart (the
///   deadline, 1.25 ms, never reached) with the driver enable high;
/// * the event log's words programmed while the drives are on (the stop's record) leave
///   every control tick on time: no gap between tick starts beyond 1.25 ms.
#[test]
fn store_geometry_writes_only_with_the_drives_off_and_costs_no_period() {
    let mut config = BenchConfig::reference(image()).unwrap_or_else(|e| {
        panic!("{e}: build it with `firmware/cortex-m/board/build-and-size.sh`")
    });
    let word_ns = FLASH_WORD_MAX_NS;
    config.flash_word_ns = word_ns;
    let mut m = Master::new(Bench::start(config.clone()).unwrap());
    let uart4 = m.bench.firmware.function("UART4").unwrap();
    m.bench.act(Action::WatchInstruction(uart4));
    m.hello(0x6e0_0001).unwrap();
    assert!(m
        .run_until(500, |m| m.state() == Some(RobotState::Disabled))
        .unwrap());
    let record = record_of(&PerChainGeometry::from(RsprGeometry::<f64>::reference()), 7);

    // (a) Disabled: the write, sampled every 100 µs.
    let _ = ticks(&mut m, uart4);
    m.bench.flash_ops.clear();
    m.bench.edges.clear();
    m.turn_ns = 100_000;
    m.sampling = true;
    let seq_reply = m
        .command(&MasterToBoard::StoreGeometry(record), 200)
        .unwrap();
    let mut samples: Vec<(u64, Outputs)> = Vec::new();
    samples.extend(
        std::mem::take(&mut m.bench.edges)
            .into_iter()
            .map(|(t, o)| (t.0, o)),
    );
    let ops = std::mem::take(&mut m.bench.flash_ops);
    let words = geometry_words(&ops);
    assert_eq!(
        words.len(),
        SLOT_LEN / 4,
        "the slot's words programmed: {words:?}"
    );
    let (first, last) = (words[0].0, words[words.len() - 1].0);
    let spacing = words.windows(2).map(|w| w[1].0 - w[0].0).min().unwrap();
    assert!(
        spacing >= word_ns,
        "each word holds the core {word_ns} ns: {spacing}"
    );
    let tick_starts = ticks(&mut m, uart4);
    assert!(
        !tick_starts
            .iter()
            .any(|t| (first..last + word_ns).contains(t)),
        "no tick runs while the core is stalled"
    );
    samples.append(&mut m.samples);
    m.sampling = false;
    let inside = samples
        .iter()
        .filter(|(t, _)| (first..=last + word_ns).contains(t))
        .count();
    assert!(
        inside as u64 >= (last - first) / 100_000,
        "sampled every 100 us through the write: {inside}"
    );
    assert!(
        samples.iter().all(|(_, o)| quiet(o)),
        "the pins through the write: {samples:?}"
    );
    let shadow = m.bench.flash();
    let slot = (GEOMETRY_BASE - EVENTS_BASE) as usize;
    let bytes: [u8; SLOT_LEN] = shadow[slot..slot + SLOT_LEN].try_into().unwrap();
    assert_eq!(
        decode_slot(&bytes),
        Some(record),
        "the slot holds the record"
    );
    // The emulated array does not change within a run (rigless 0.4 leaves programming
    // out; `src/flash.rs`): the firmware's read-back finds the slot erased and answers
    // `Flash`, where the part answers `GeometryStored`. The record is in the kept flash.
    assert!(
        matches!(
            seq_reply,
            Some(BoardToMaster::GeometryRefused {
                reason: GeometryRefusal::Flash,
                ..
            })
        ),
        "the reply: {seq_reply:?}"
    );
    assert!(m.bench.last.resets.is_empty(), "{:?}", m.bench.last.resets);
    println!(
        "StoreGeometry disabled: {} words in {:.2} ms (word spacing {:.1} us), {} pin samples inside, the core stalled, {:?}",
        words.len(),
        (last + word_ns - first) as f64 / 1e6,
        spacing as f64 / 1e3,
        inside,
        seq_reply
    );
    m.turn_ns = MS;

    // (b) Homing, the drives on: refused, nothing written, the ticks on time.
    assert!(matches!(
        m.command(&MasterToBoard::Home { rehome: false }, 50)
            .unwrap(),
        Some(BoardToMaster::Ack { .. })
    ));
    m.run_ms(300).unwrap();
    assert_eq!(m.state(), Some(RobotState::Homing));
    assert!(m.bench.last.outputs.driver_enable);
    let _ = ticks(&mut m, uart4);
    m.bench.flash_ops.clear();
    m.bench.edges.clear();
    let refused = m
        .command(&MasterToBoard::StoreGeometry(record), 50)
        .unwrap();
    assert!(
        matches!(
            refused,
            Some(BoardToMaster::GeometryRefused {
                reason: GeometryRefusal::InvalidState,
                ..
            })
        ),
        "{refused:?}"
    );
    assert!(m.bench.last.outputs.driver_enable);
    // Disable: SS1 with the drives on while it decelerates and applies the brakes.
    assert!(matches!(
        m.command(&MasterToBoard::Disable, 50).unwrap(),
        Some(BoardToMaster::Ack { .. })
    ));
    let during_stop = m.command(&MasterToBoard::StoreGeometry(record), 5).unwrap();
    let stop_state = m.state();
    let drives_on = m.bench.last.outputs.driver_enable;
    assert!(
        matches!(
            during_stop,
            Some(BoardToMaster::GeometryRefused {
                reason: GeometryRefusal::InvalidState,
                ..
            })
        ),
        "{during_stop:?} in {stop_state:?}"
    );
    assert!(drives_on, "the stop still drives when the store is refused");
    m.run_ms(150).unwrap();
    let tick_starts = ticks(&mut m, uart4);
    let ops = std::mem::take(&mut m.bench.flash_ops);
    assert!(
        geometry_words(&ops).is_empty(),
        "nothing programmed in sector 11"
    );
    let gaps: Vec<u64> = tick_starts.windows(2).map(|w| w[1] - w[0]).collect();
    let worst = gaps.iter().copied().max().unwrap();
    assert!(worst <= 1_250_000, "a control period missed: {worst} ns");
    // The SS1's torque off: the driver enable's falling edge.
    let off = m
        .bench
        .edges
        .iter()
        .find(|(_, o)| !o.driver_enable)
        .map(|(t, _)| t.0)
        .expect("the SS1 ends with the drivers off");
    let logged: Vec<u64> = event_words(&ops).into_iter().filter(|t| *t < off).collect();
    println!(
        "refused while homing and in SS1: {} ticks, gaps {:.3}..{:.3} ms, {} event-log words programmed with the drives on",
        tick_starts.len(),
        gaps.iter().copied().min().unwrap() as f64 / 1e6,
        worst as f64 / 1e6,
        logged.len()
    );
    assert!(
        !logged.is_empty(),
        "the stop's event is written while the drives are on"
    );

    // (c) A power cycle: the board boots with the record the write left.
    let kept = m.bench.flash();
    let _ = m.bench.finish();
    config.flash = Some(kept);
    let mut m = Master::new(Bench::start(config).unwrap());
    match m.hello(0x6e0_0002).unwrap() {
        BoardToMaster::HelloReply {
            geometry_version, ..
        } => assert_eq!(
            geometry_version, 7,
            "the stored record after the power cycle"
        ),
        other => panic!("{other:?}"),
    }
    let _ = m.bench.finish();
}
