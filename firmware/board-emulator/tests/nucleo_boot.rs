//! The NUCLEO-F429ZI's release image (`firmware/cortex-m/nucleo-f429zi`, bin
//! `rspr-nucleo-f429zi`) boots on the emulated STM32F427 (the F429's die) with its own board
//! around it (`pins::NUCLEO_F429ZI`): the control tick runs with the independent watchdog fed
//! every period, and the image configures every pin as the NUCLEO's pin map says (mode,
//! alternate function, pull; RM0090 rev 19 section 8.4). The image is `$RSPR_NUCLEO_ELF`,
//! else the Cortex-M workspace's default target directory (`run.sh` sets it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::pins::{expected_configuration, PinConfig, NUCLEO_F429ZI};

fn image() -> PathBuf {
    std::env::var_os("RSPR_NUCLEO_ELF").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../cortex-m/target/thumbv7em-none-eabihf/release/rspr-nucleo-f429zi")
        },
        PathBuf::from,
    )
}

/// `IWDG_KR` and its reload key.
const IWDG_KR: u64 = 0x4000_3000;
const IWDG_RELOAD: u64 = 0xAAAA;

#[test]
fn the_nucleo_image_ticks_and_configures_its_pins() {
    let mut config = BenchConfig::reference(image()).unwrap_or_else(|e| {
        panic!("{e}: build it with `firmware/cortex-m/board/build-and-size.sh board-nucleo-f429zi`")
    });
    config.board = NUCLEO_F429ZI;
    config.record_until_ns = 300_000_000;
    let mut bench = Bench::start(config).unwrap();
    bench.run_for(300_000_000).unwrap();

    // The 1 kHz tick: the watchdog fed about once per period from 0.1 to 0.3 s (a tick
    // feeds it once; the bound leaves a period at each end).
    let recorded = std::mem::take(&mut bench.recorded);
    let feeds = recorded
        .iter()
        .filter(|r| {
            r.write
                && r.address == IWDG_KR
                && r.value == IWDG_RELOAD
                && (100_000_000..300_000_000).contains(&r.at.0)
        })
        .count();
    assert!((198..=201).contains(&feeds), "{feeds} IWDG feeds in 0.2 s");

    // Every pin as the map says: GPIOx_MODER, PUPDR, AFRL, AFRH of ports A..G.
    let base = |port: usize| 0x4002_0000 + 0x400 * port as u64;
    let mut addresses = Vec::new();
    for port in 0..7 {
        let b = base(port);
        addresses.extend([b, b + 0x0C, b + 0x20, b + 0x24]);
    }
    bench.act(Action::Peek(addresses));
    bench.run_for(1_000_000).unwrap();
    let peeked = std::mem::take(&mut bench.peeked);
    let reg = |a: u64| {
        peeked
            .iter()
            .find(|(x, _)| *x == a)
            .and_then(|(_, v)| *v)
            .unwrap_or(0)
    };
    let expected = expected_configuration(&NUCLEO_F429ZI.map);
    let mut wrong = Vec::new();
    for (pin, want, what) in &expected {
        let b = base(pin.port.index());
        let n = u64::from(pin.number);
        let mode = (reg(b) >> (2 * n)) & 0b11;
        let pull = (reg(b + 0x0C) >> (2 * n)) & 0b11;
        let afr = if n < 8 { reg(b + 0x20) } else { reg(b + 0x24) };
        let af = (afr >> (4 * (n % 8))) & 0xF;
        let ok = match want {
            PinConfig::Output => mode == 0b01,
            PinConfig::InputPullUp => mode == 0b00 && pull == 0b01,
            PinConfig::Alternate(x) => mode == 0b10 && af == u64::from(*x),
            PinConfig::Analog => mode == 0b11,
        };
        if !ok {
            wrong.push(format!(
                "{pin} ({what}): want {want:?}, MODER {mode:02b} PUPDR {pull:02b} AF {af}"
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    println!(
        "{}: {feeds} IWDG feeds in 0.1..0.3 s, {} pins as mapped, {} RTT bytes",
        image().display(),
        expected.len(),
        bench.last.rtt_bytes
    );
    let _ = bench.finish();
}
