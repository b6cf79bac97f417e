//! The emulator's pin maps (`pins::BOARD`, `pins::NUCLEO_F429ZI_MAP`) against the boards'
//! own: the tables at the top of `firmware/cortex-m/board/src/board.rs` and
//! `firmware/cortex-m/nucleo-f429zi/src/board.rs` (the sources of truth) and the constants
//! next to them.
//! A pin moved on the board and not here (or the other way round) fails this test; the
//! closed-loop run checks the registers the image configures (`host-sim/board-scenarios`,
//! `scenarios::boot::pins`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;

use board_emulator::pins::{
    PinId, PinMap, BOARD, NUCLEO_F429ZI, NUCLEO_F429ZI_MAP, SUPPLY_DIVIDER,
};

const BOARD_RS: &str = include_str!("../../cortex-m/board/src/board.rs");
const BOARD_CARGO: &str = include_str!("../../cortex-m/board/Cargo.toml");
const NUCLEO_RS: &str = include_str!("../../cortex-m/nucleo-f429zi/src/board.rs");

/// The documented table: function -> (pin column, peripheral column).
fn documented() -> BTreeMap<String, (String, String)> {
    documented_in(BOARD_RS)
}

/// The documented table of a `board.rs`.
fn documented_in(board_rs: &str) -> BTreeMap<String, (String, String)> {
    let mut rows = BTreeMap::new();
    for line in board_rs.lines() {
        let Some(row) = line.strip_prefix("//! |") else {
            continue;
        };
        let cells: Vec<String> = row
            .split('|')
            .map(|c| c.trim().to_string())
            .filter(|c| !c.is_empty())
            .collect();
        if let [function, pin, peripheral] = cells.as_slice() {
            if !function.starts_with('-') && function != "function" {
                rows.insert(function.clone(), (pin.clone(), peripheral.clone()));
            }
        }
    }
    rows
}

fn pins(p: &[PinId], sep: &str) -> String {
    p.iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(sep)
}

/// What the emulator's map says for each documented row (the board's wording of the pin
/// column).
fn ours() -> Vec<(&'static str, String)> {
    ours_for(&BOARD, false)
}

/// The rows of `b`; `split_currents`: the currents in two rows of three (the NUCLEO's
/// inputs are not one range).
fn ours_for(b: &PinMap, split_currents: bool) -> Vec<(&'static str, String)> {
    let cur = |r: std::ops::Range<usize>| {
        b.current_sense[r]
            .iter()
            .map(|a| a.pin.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let enc = |j: usize| pins(&[b.encoders[j].a, b.encoders[j].b], " / ");
    let mut v: Vec<(&'static str, String)> = vec![
        ("encoder l1 A / B", enc(0)),
        ("encoder l2 A / B", enc(1)),
        ("encoder l3 A / B", enc(2)),
        ("encoder theta1 A / B", enc(3)),
        ("encoder theta2 A / B", enc(4)),
        ("encoder theta3 A / B", enc(5)),
    ];
    v.extend([
        ("PWM l1 / l2", pins(&[b.pwm[0].pin, b.pwm[1].pin], " / ")),
        ("PWM l3", b.pwm[2].pin.to_string()),
        ("PWM theta1", b.pwm[3].pin.to_string()),
        ("PWM theta2", b.pwm[4].pin.to_string()),
        ("PWM theta3", b.pwm[5].pin.to_string()),
        ("DIR l1, l2, l3", pins(&b.dir[..3], ", ")),
        ("DIR theta1, 2, 3", pins(&b.dir[3..], ", ")),
        ("driver enable (all)", b.driver_enable.to_string()),
        (
            "driver fault (nFAULT, wired-OR of the six drivers)",
            b.driver_fault.to_string(),
        ),
        ("supply voltage sense", b.supply_sense.pin.to_string()),
        ("brakes, legs l1..l3", b.brakes[0].to_string()),
        ("brakes, links theta1..3", b.brakes[1].to_string()),
        ("emergency stop", b.estop.to_string()),
        ("safety relay feedback", b.relay_feedback.to_string()),
        ("home switch l1, l2, l3", pins(&b.home_switch[..3], ", ")),
        ("home switch theta1, 2, 3", pins(&b.home_switch[3..], ", ")),
        ("master link TX / RX", pins(&[b.link_tx, b.link_rx], " / ")),
        ("status LED", b.led.to_string()),
    ]);
    if split_currents {
        v.push(("motor current l1, l2, l3", cur(0..3)));
        v.push(("motor current theta1, 2, 3", cur(3..6)));
    } else {
        v.push((
            "motor current l1..theta3",
            format!("{}..{}", b.current_sense[0].pin, b.current_sense[5].pin),
        ));
    }
    v
}

/// The NUCLEO-F429ZI's documented table is the emulator's map, row by row (only SWD, the
/// HSE input and the time driver left out), with the firmware's current scale and the
/// peripherals the map's channels name.
#[test]
fn the_emulator_nucleo_pin_map_is_its_documented_table() {
    let doc = documented_in(NUCLEO_RS);
    assert!(doc.len() >= 25, "the table was not found: {doc:?}");
    let mut covered = Vec::new();
    for (function, pin) in ours_for(&NUCLEO_F429ZI_MAP, true) {
        let Some((doc_pin, _)) = doc.get(function) else {
            panic!("the NUCLEO's board.rs documents no row {function:?}");
        };
        assert_eq!(&pin, doc_pin, "{function}");
        covered.push(function.to_string());
    }
    let left: Vec<&String> = doc.keys().filter(|k| !covered.contains(k)).collect();
    assert_eq!(left, vec!["HSE 8 MHz", "SWD", "time driver"]);
    let per = |f: &str| doc.get(f).map(|(_, p)| p.clone()).unwrap_or_default();
    let b = &NUCLEO_F429ZI_MAP;
    for (j, f) in [
        "encoder l1 A / B",
        "encoder l2 A / B",
        "encoder l3 A / B",
        "encoder theta1 A / B",
        "encoder theta2 A / B",
        "encoder theta3 A / B",
    ]
    .iter()
    .enumerate()
    {
        assert!(per(f).starts_with(b.encoders[j].timer.name()), "{f}");
    }
    for (j, f) in [
        (2, "PWM l3"),
        (3, "PWM theta1"),
        (4, "PWM theta2"),
        (5, "PWM theta3"),
    ] {
        assert_eq!(
            per(f),
            format!("{} CH{}", b.pwm[j].timer.name(), b.pwm[j].channel)
        );
    }
    let chans = |r: std::ops::Range<usize>| {
        b.current_sense[r]
            .iter()
            .map(|a| format!("IN{}", a.channel))
            .collect::<Vec<_>>()
            .join(", ")
    };
    assert_eq!(
        per("motor current l1, l2, l3"),
        format!("ADC1 {}", chans(0..3))
    );
    assert_eq!(
        per("motor current theta1, 2, 3"),
        format!("ADC1 {}", chans(3..6))
    );
    assert!(per("supply voltage sense").starts_with(&format!("ADC1 IN{}", b.supply_sense.channel)));
    assert!(per("emergency stop").contains(&format!("EXTI{}", b.estop.number)));
    assert!(NUCLEO_RS.contains("pub const CURRENT_A_PER_COUNT: f32 = 3.3 / 4096.0 / 0.090;"));
    assert!((NUCLEO_F429ZI.current_sense_a_per_v - 1.0 / 0.090).abs() < 1e-12);
    assert!(NUCLEO_RS.contains("pub const SUPPLY_V_PER_COUNT: f32 = 3.3 / 4096.0 * 12.0;"));
}

/// Every pin of the board's documented table is the emulator's, row by row (the second
/// position channel's converter on SPI3 and the legs' switches it moves, on the
/// `position-channel` boards, F405ZG, against `pins::POSITION_CHANNEL_MAP` and
/// `position_channel`), and every row the emulator
/// drives or reads is covered (only SWD, the crystal and the time driver, which have no
/// board-side signal to model, are left out).
#[test]
fn the_emulator_pin_map_is_the_boards_documented_table() {
    let doc = documented();
    assert!(doc.len() >= 25, "the table was not found: {doc:?}");
    let mut covered = Vec::new();
    for (function, pin) in ours() {
        let Some((doc_pin, _)) = doc.get(function) else {
            panic!(
                "board.rs documents no row {function:?}; rows: {:?}",
                doc.keys()
            );
        };
        assert_eq!(&pin, doc_pin, "{function}");
        covered.push(function.to_string());
    }
    // The `position-channel` boards (F405ZG): the converter on SPI3 and its CNV, the legs'
    // switches moved off SPI3's pins (`pins::POSITION_CHANNEL_MAP`,
    // `position_channel::{SPI3_PINS, CNV}`).
    use board_emulator::pins::POSITION_CHANNEL_MAP as PC;
    use board_emulator::position_channel::{CNV, SPI3_AF, SPI3_PINS};
    let rows = [
        (
            "position channel converter SCK / MISO / MOSI (`position-channel` boards only)",
            pins(&SPI3_PINS, " / "),
            format!("SPI3 (AF{SPI3_AF}), AD7689"),
        ),
        (
            "position channel converter CNV (`position-channel` boards only)",
            CNV.to_string(),
            "GPIO out".to_string(),
        ),
        (
            "home switch l1, l2, l3 (`position-channel` boards: SPI3 has PC10..PC12)",
            pins(&PC.home_switch[..3], ", "),
            "GPIO in".to_string(),
        ),
    ];
    for (function, pin, peripheral) in rows {
        assert_eq!(doc.get(function), Some(&(pin, peripheral)), "{function}");
        covered.push(function.to_string());
    }
    assert_eq!(PC.home_switch[3..], BOARD.home_switch[3..]);
    assert_eq!(
        PC,
        board_emulator::pins::PinMap {
            home_switch: PC.home_switch,
            ..BOARD
        },
        "the channel's board moves only the legs' switches"
    );
    let left: Vec<&String> = doc.keys().filter(|k| !covered.contains(k)).collect();
    assert_eq!(
        left,
        vec!["HSE 8 MHz crystal", "SWD", "time driver"],
        "rows of board.rs the emulator does not model"
    );
}

/// The peripherals of the documented rows: the PWM timers and channels, the encoder timers,
/// the analog channels, the e-stop's EXTI line, the link's USART, the time driver.
#[test]
fn the_peripherals_are_the_boards() {
    let doc = documented();
    let per = |f: &str| doc.get(f).map(|(_, p)| p.clone()).unwrap_or_default();
    let b = &BOARD;
    assert_eq!(per("PWM l1 / l2"), "TIM9 CH1 / CH2");
    assert_eq!(
        (b.pwm[0].timer.name(), b.pwm[0].channel, b.pwm[1].channel),
        ("TIM9", 1, 2)
    );
    for (j, f) in [
        (2, "PWM l3"),
        (3, "PWM theta1"),
        (4, "PWM theta2"),
        (5, "PWM theta3"),
    ] {
        assert_eq!(
            per(f),
            format!("{} CH{}", b.pwm[j].timer.name(), b.pwm[j].channel)
        );
    }
    for (j, f) in [
        "encoder l1 A / B",
        "encoder l2 A / B",
        "encoder l3 A / B",
        "encoder theta1 A / B",
        "encoder theta2 A / B",
        "encoder theta3 A / B",
    ]
    .iter()
    .enumerate()
    {
        assert!(per(f).starts_with(b.encoders[j].timer.name()), "{f}");
    }
    assert_eq!(
        per("motor current l1..theta3"),
        format!(
            "ADC1 IN{}..IN{}",
            b.current_sense[0].channel, b.current_sense[5].channel
        )
    );
    assert!(per("supply voltage sense").starts_with(&format!(
        "ADC1 IN{}, divider {}:1",
        b.supply_sense.channel, SUPPLY_DIVIDER
    )));
    assert!(per("emergency stop").contains(&format!("EXTI{}", b.estop.number)));
    assert!(per("master link TX / RX").starts_with("USART3"));
    assert_eq!(per("time driver"), "TIM12 (no pins)");
    assert!(BOARD_CARGO.contains("time-driver-tim12"));
}

/// The scales the emulator's analog inputs use are the firmware's constants.
#[test]
fn the_analog_scales_are_the_firmwares() {
    assert!(BOARD_RS.contains("pub const SUPPLY_V_PER_COUNT: f32 = 3.3 / 4096.0 * 12.0;"));
    assert!(
        BOARD_RS.contains("pub const CURRENT_A_PER_COUNT: f32 = 3.3 / 4096.0 / (20.0 * 0.010);")
    );
    assert!(BOARD_RS.contains("pub const CURRENT_ZERO_COUNT: f32 = 2048.0;"));
    assert!(BOARD_RS.contains("pub const ESTOP_ACTIVE_HIGH: bool = true;"));
    assert!(BOARD_RS.contains("pub const SWITCH_ACTIVE_HIGH: bool = true;"));
    assert!(BOARD_RS.contains("pub const INVERT_MOTOR: [bool; 6] = [false; 6];"));
    assert!(BOARD_RS.contains("pub const INVERT_ENCODER: [bool; 6] = [false; 6];"));
}
