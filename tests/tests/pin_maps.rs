#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The board targets' pin maps: for each target, the table at the top of its `board.rs`
//! (what a lab wires from) is the code that configures the pins (`Board::new`), no pin and
//! no timer channel has two jobs, every encoder sits on a timer with the encoder interface
//! (TIM1/2/3/4/5/8) on that timer's channel 1 and 2 pins, every PWM output on a pin of its
//! timer's channel, every analog input on an ADC1 input; the NUCLEO-F429ZI's map leaves
//! alone what that board already wires, and its bring-up guide's wiring table is its pin
//! map. The alternate-function pins are the datasheets' (DS8626 / DS9405, "Alternate
//! function mapping"), written here for the pins of the STM32F405RG (LQFP64) and the
//! STM32F429ZI (LQFP144).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The pins of a timer channel (all the packages' pins of DS8626 / DS9405; a pin the
/// package lacks fails to compile with embassy-stm32 anyway).
fn channel_pins(timer: &str, channel: u8) -> &'static [&'static str] {
    match (timer, channel) {
        ("TIM1", 1) => &["PA8", "PE9"],
        ("TIM1", 2) => &["PA9", "PE11"],
        ("TIM2", 1) => &["PA0", "PA5", "PA15"],
        ("TIM2", 2) => &["PA1", "PB3"],
        ("TIM3", 1) => &["PA6", "PB4", "PC6"],
        ("TIM3", 2) => &["PA7", "PB5", "PC7"],
        ("TIM4", 1) => &["PB6", "PD12"],
        ("TIM4", 2) => &["PB7", "PD13"],
        ("TIM5", 1) => &["PA0"],
        ("TIM5", 2) => &["PA1"],
        ("TIM8", 1) => &["PC6"],
        ("TIM8", 2) => &["PC7"],
        ("TIM9", 1) => &["PA2", "PE5"],
        ("TIM9", 2) => &["PA3", "PE6"],
        ("TIM10", 1) => &["PB8", "PF6"],
        ("TIM11", 1) => &["PB9", "PF7"],
        ("TIM13", 1) => &["PA6", "PF8"],
        ("TIM14", 1) => &["PA7", "PF9"],
        _ => &[],
    }
}

/// ADC1's input channel on a pin (ADC123_IN0..15).
fn adc1_channel(pin: &str) -> Option<u8> {
    let table = [
        "PA0", "PA1", "PA2", "PA3", "PA4", "PA5", "PA6", "PA7", "PB0", "PB1", "PC0", "PC1", "PC2",
        "PC3", "PC4", "PC5",
    ];
    table.iter().position(|p| *p == pin).map(|i| i as u8)
}

/// The timers with the encoder interface (RM0090: TIM1..TIM5 and TIM8; TIM9..TIM14 have
/// none).
const ENCODER_TIMERS: [&str; 6] = ["TIM1", "TIM2", "TIM3", "TIM4", "TIM5", "TIM8"];

/// One row of a pin table: the function, its pins, its peripheral column.
#[derive(Debug, Clone)]
struct Row {
    function: String,
    pins: Vec<String>,
    peripheral: String,
}

/// The pin starting at `c[i]` (`PA15`, `PD2`: a port A..K and a number, on word
/// boundaries) and the index after it.
fn pin_at(c: &[char], i: usize) -> Option<(String, usize)> {
    if *c.get(i)? != 'P' || (i > 0 && c[i - 1].is_ascii_alphanumeric()) {
        return None;
    }
    if !('A'..='K').contains(c.get(i + 1)?) {
        return None;
    }
    let mut j = i + 2;
    while j < c.len() && c[j].is_ascii_digit() {
        j += 1;
    }
    if j == i + 2 || (j < c.len() && c[j].is_ascii_alphanumeric()) {
        return None;
    }
    Some((c[i..j].iter().collect(), j))
}

/// Every pin named in `s`, in order; a range `PC0..PC5` expands to its pins.
fn pins_in(s: &str) -> Vec<String> {
    let c: Vec<char> = s.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let Some((pin, j)) = pin_at(&c, i) else {
            i += 1;
            continue;
        };
        if c.get(j) == Some(&'.') && c.get(j + 1) == Some(&'.') {
            if let Some((to, k)) = pin_at(&c, j + 2) {
                let from_n: u32 = pin[2..].parse().unwrap();
                let to_n: u32 = to[2..].parse().unwrap();
                for n in from_n..=to_n {
                    out.push(format!("{}{n}", &pin[..2]));
                }
                i = k;
                continue;
            }
        }
        out.push(pin);
        i = j;
    }
    out
}

/// The ADC input channels a peripheral cell names (`ADC1 IN10..IN15`, `ADC1 IN3, IN10`).
fn adc_channels(cell: &str) -> BTreeSet<u8> {
    let mut out = BTreeSet::new();
    let nums: Vec<(usize, u8)> = cell
        .match_indices("IN")
        .filter_map(|(i, _)| {
            let d: String = cell[i + 2..]
                .chars()
                .take_while(char::is_ascii_digit)
                .collect();
            d.parse().ok().map(|n| (i, n))
        })
        .collect();
    for w in nums.windows(2) {
        let (i, a) = w[0];
        let (_, b) = w[1];
        if cell[i..]
            .trim_start_matches(|c: char| c.is_ascii_alphanumeric())
            .starts_with("..")
        {
            out.extend(a..=b);
        }
    }
    out.extend(nums.iter().map(|(_, n)| *n));
    out
}

/// The `//!` table at the top of a `board.rs`.
fn doc_table(board_rs: &str) -> Vec<Row> {
    board_rs
        .lines()
        .filter_map(|l| l.strip_prefix("//! |"))
        .filter(|l| !l.starts_with('-') && !l.trim_start().starts_with("function"))
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            if cells.len() < 3 || cells[0].starts_with("---") {
                return None;
            }
            Some(Row {
                function: cells[0].to_string(),
                pins: pins_in(cells[1]),
                peripheral: cells[2].to_string(),
            })
        })
        .collect()
}

/// The rows for a function that starts with `prefix`.
fn rows<'a>(table: &'a [Row], prefix: &str) -> Vec<&'a Row> {
    table
        .iter()
        .filter(|r| r.function.starts_with(prefix))
        .collect()
}

/// The lines of the board without the second position channel: an item after
/// `#[cfg(feature = "position-channel")]` (up to where its brackets close) left out.
fn without_position_channel<'a>(lines: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out = Vec::new();
    let (mut skipping, mut depth) = (false, 0i32);
    for l in lines {
        if l.trim() == "#[cfg(feature = \"position-channel\")]" {
            skipping = true;
            depth = 0;
            continue;
        }
        if skipping {
            for c in l.chars() {
                match c {
                    '(' | '[' | '{' => depth += 1,
                    ')' | ']' | '}' => depth -= 1,
                    _ => {}
                }
            }
            if depth <= 0 && (l.trim_end().ends_with(',') || l.trim_end().ends_with(';')) {
                skipping = false;
            }
            continue;
        }
        out.push(l);
    }
    out
}

/// What `Board::new` does with each pin, from its code: `(pin, role)` where role is
/// `enc:TIMx:ch`, `pwm:TIMx:ch`, `out`, `in`, `adc`, `uart:TX`/`uart:RX`.
fn code_pins(board_rs: &str) -> Vec<(String, String)> {
    let start = board_rs
        .find("pub fn new(p: Peripherals)")
        .expect("Board::new");
    let code: String = without_position_channel(
        board_rs[start..]
            .lines()
            .take_while(|l| !l.starts_with("}"))
            .map(|l| l.split("//").next().unwrap_or("")),
    )
    .join(" ");
    let code: String = code.split_whitespace().collect::<Vec<_>>().join("");
    let mut out = Vec::new();
    // Encoders: Qei::new(p.TIMx,p.A,p.B,
    for part in code.split("Qei::new(p.").skip(1) {
        let f: Vec<&str> = part.split(',').take(3).collect();
        let tim = f[0];
        out.push((f[1].trim_start_matches("p.").into(), format!("enc:{tim}:1")));
        out.push((f[2].trim_start_matches("p.").into(), format!("enc:{tim}:2")));
    }
    // PWM: SimplePwm::new(p.TIMx,Some(PwmPin::new(p.PIN,pp)),Some(..)|None,..: the
    // channels in order.
    for part in code.split("SimplePwm::new(p.").skip(1) {
        let tim = part.split(',').next().unwrap();
        for (i, a) in part[tim.len() + 1..].split("),").enumerate() {
            let Some(pin) = a.strip_prefix("Some(PwmPin::new(p.") else {
                break;
            };
            let pin = pin.split(',').next().unwrap();
            out.push((pin.into(), format!("pwm:{tim}:{}", i + 1)));
        }
    }
    for part in code.split("Output::new(p.").skip(1) {
        out.push((part.split(',').next().unwrap().into(), "out".into()));
    }
    for part in code.split("Input::new(p.").skip(1) {
        out.push((part.split(',').next().unwrap().into(), "in".into()));
    }
    for part in code
        .split(".degrade_adc()")
        .collect::<Vec<_>>()
        .iter()
        .rev()
        .skip(1)
    {
        let pin = part.rsplit("p.").next().unwrap();
        out.push((pin.into(), "adc".into()));
    }
    if let Some(part) = code.split("Uart::new(p.").nth(1) {
        let f: Vec<&str> = part.split(',').take(3).collect();
        out.push((f[1].trim_start_matches("p.").into(), "uart:RX".into()));
        out.push((f[2].trim_start_matches("p.").into(), "uart:TX".into()));
    }
    out
}

/// The checks every target's map passes; returns the table's pins by function for the
/// target-specific checks.
fn check_target(board_rs_path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(board_rs_path).unwrap();
    let table = doc_table(&text);
    let name = board_rs_path.display().to_string();
    assert!(
        table.len() > 20,
        "{name}: the pin table has {} rows",
        table.len()
    );

    // No pin has two jobs on either board the table describes: the board without the
    // second position channel (the rows not marked for `position-channel` boards), and the
    // board with it (those rows, in place of the rows of the same function they replace).
    let (channel, table): (Vec<Row>, Vec<Row>) = table
        .into_iter()
        .partition(|r| r.function.contains("`position-channel` boards"));
    let base = |f: &str| f.split(" (").next().unwrap_or(f).trim().to_string();
    let replaced: BTreeSet<String> = channel.iter().map(|r| base(&r.function)).collect();
    let with_channel = table
        .iter()
        .filter(|r| !replaced.contains(&base(&r.function)))
        .chain(channel.iter());
    for (board, rows) in [
        ("", table.iter().collect::<Vec<_>>()),
        (" (position-channel board)", with_channel.collect()),
    ] {
        let mut seen: BTreeMap<String, String> = BTreeMap::new();
        for r in rows {
            for p in &r.pins {
                if let Some(prev) = seen.insert(p.clone(), r.function.clone()) {
                    panic!("{name}{board}: {p} is both '{prev}' and '{}'", r.function);
                }
            }
        }
    }

    // Encoders: six rows of A / B on a timer with the encoder interface, channel 1 / 2 pins.
    let enc = rows(&table, "encoder");
    assert_eq!(enc.len(), 6, "{name}: six encoders");
    let mut channels = BTreeSet::new();
    for r in &enc {
        let tim = r.peripheral.split_whitespace().next().unwrap();
        assert!(
            ENCODER_TIMERS.contains(&tim),
            "{name}: {} on {tim}, which has no encoder interface",
            r.function
        );
        assert_eq!(r.pins.len(), 2, "{name}: {}", r.function);
        for (ch, pin) in [(1, &r.pins[0]), (2, &r.pins[1])] {
            assert!(
                channel_pins(tim, ch).contains(&pin.as_str()),
                "{name}: {} {pin} is not a {tim} CH{ch} pin",
                r.function
            );
            assert!(
                channels.insert((tim.to_string(), ch)),
                "{name}: {tim} CH{ch} twice"
            );
        }
    }
    // PWM: six outputs, each on a pin of its timer channel, no channel twice (nor one an
    // encoder uses).
    let pwm = rows(&table, "PWM");
    let mut outputs = 0;
    for r in &pwm {
        let periph: Vec<&str> = r.peripheral.split(['/', ',']).map(str::trim).collect();
        let tim = r.peripheral.split_whitespace().next().unwrap();
        assert!(
            !ENCODER_TIMERS.contains(&tim),
            "{name}: PWM on an encoder's timer"
        );
        for (i, pin) in r.pins.iter().enumerate() {
            let ch: u8 = periph
                .get(i)
                .and_then(|c| c.rsplit("CH").next())
                .and_then(|c| c.trim().parse().ok())
                .unwrap();
            assert!(
                channel_pins(tim, ch).contains(&pin.as_str()),
                "{name}: PWM {pin} is not a {tim} CH{ch} pin"
            );
            assert!(
                channels.insert((tim.to_string(), ch)),
                "{name}: {tim} CH{ch} twice"
            );
            outputs += 1;
        }
    }
    assert_eq!(outputs, 6, "{name}: six PWM outputs");
    // DIR: six outputs.
    let dir: Vec<String> = rows(&table, "DIR")
        .iter()
        .flat_map(|r| r.pins.clone())
        .collect();
    assert_eq!(dir.len(), 6, "{name}: six DIR outputs");
    // Currents and the supply on ADC1 inputs, at the channel the table says.
    let mut analog: Vec<(String, String)> = Vec::new();
    for r in rows(&table, "motor current")
        .into_iter()
        .chain(rows(&table, "supply"))
    {
        for p in &r.pins {
            analog.push((p.clone(), r.peripheral.clone()));
        }
    }
    assert_eq!(analog.len(), 7, "{name}: six currents and the supply");
    for (pin, periph) in &analog {
        let ch = adc1_channel(pin).unwrap_or_else(|| panic!("{name}: {pin} is no ADC1 input"));
        assert!(
            adc_channels(periph).contains(&ch),
            "{name}: {pin} is ADC1 IN{ch}, the table says {periph}"
        );
    }

    // The table is the code: every pin Board::new configures, with the job the table gives.
    let code = code_pins(&text);
    let by_pin: BTreeMap<&str, &str> = code.iter().map(|(p, r)| (p.as_str(), r.as_str())).collect();
    assert_eq!(
        by_pin.len(),
        code.len(),
        "{name}: the code takes a pin twice"
    );
    let expect = |pin: &str, role: &str, what: &str| {
        assert_eq!(
            by_pin.get(pin).copied(),
            Some(role),
            "{name}: {what}: the table says {pin}, the code does not configure it as {role}"
        );
    };
    for r in &enc {
        let tim = r.peripheral.split_whitespace().next().unwrap();
        expect(&r.pins[0], &format!("enc:{tim}:1"), &r.function);
        expect(&r.pins[1], &format!("enc:{tim}:2"), &r.function);
    }
    for r in &pwm {
        let tim = r.peripheral.split_whitespace().next().unwrap();
        let periph: Vec<&str> = r.peripheral.split(['/', ',']).map(str::trim).collect();
        for (i, pin) in r.pins.iter().enumerate() {
            let ch = periph[i].rsplit("CH").next().unwrap().trim();
            expect(pin, &format!("pwm:{tim}:{ch}"), &r.function);
        }
    }
    for p in &dir {
        expect(p, "out", "DIR");
    }
    for f in ["driver enable", "brakes", "status LED"] {
        for r in rows(&table, f) {
            expect(&r.pins[0], "out", f);
        }
    }
    for f in [
        "driver fault",
        "emergency stop",
        "safety relay",
        "home switch",
    ] {
        for r in rows(&table, f) {
            for p in &r.pins {
                expect(p, "in", f);
            }
        }
    }
    for (pin, _) in &analog {
        expect(pin, "adc", "analog input");
    }
    let link = rows(&table, "master link");
    assert_eq!(link.len(), 1);
    expect(&link[0].pins[0], "uart:TX", "link TX");
    expect(&link[0].pins[1], "uart:RX", "link RX");
    // And the code configures nothing the table does not list.
    let listed: BTreeSet<&str> = table
        .iter()
        .flat_map(|r| r.pins.iter().map(String::as_str))
        .collect();
    for (pin, role) in &code {
        assert!(
            listed.contains(pin.as_str()),
            "{name}: the code configures {pin} ({role}), the table does not list it"
        );
    }
    table
}

/// Property: the reference board's (STM32F405RG) table is its code and has no conflict.
#[test]
fn the_reference_boards_pin_map_has_no_conflict() {
    check_target(&root().join("firmware/cortex-m/board/src/board.rs"));
}

/// Property: the NUCLEO-F429ZI's table is its code, has no conflict, and leaves the
/// board's own wiring alone (UM1974): the Ethernet PHY's RMII lines other than PA1 (whose
/// solder bridge the guide opens), USB OTG, LD1 / LD2, the user button, the 32 kHz
/// crystal, SWD and the HSE input.
#[test]
fn the_nucleo_f429zi_pin_map_has_no_conflict_and_spares_the_boards_own_wiring() {
    let path = root().join("firmware/cortex-m/nucleo-f429zi/src/board.rs");
    let table = check_target(&path);
    let taken = [
        "PA2", "PA7", "PB13", "PC1", "PC4", "PC5", "PG11", "PG13", // Ethernet RMII
        "PA8", "PA9", "PA10", "PA11", "PA12", "PG6", "PG7", // USB OTG FS
        "PB0", "PB7", "PC13", "PC14", "PC15", "PH1", // LD1, LD2, B1, LSE, HSE's OSC_OUT
    ];
    for r in &table {
        if r.function.starts_with("SWD") || r.function.starts_with("HSE") {
            continue;
        }
        for p in &r.pins {
            assert!(
                !taken.contains(&p.as_str()),
                "{}: {p} is wired on the NUCLEO-F429ZI",
                r.function
            );
        }
    }
}

/// Property: the wiring table of the NUCLEO-F429ZI's bring-up guide gives every function
/// the pins of its pin map, in the same order (rows matched by function).
#[test]
fn the_nucleo_bring_up_guide_wires_the_pin_map() {
    let map = doc_table(
        &std::fs::read_to_string(root().join("firmware/cortex-m/nucleo-f429zi/src/board.rs"))
            .unwrap(),
    );
    let guide =
        std::fs::read_to_string(root().join("firmware/cortex-m/nucleo-f429zi/README.md")).unwrap();
    let section = guide
        .split("<!-- wiring -->")
        .nth(1)
        .and_then(|s| s.split("<!-- /wiring -->").next())
        .expect("the guide's wiring table between <!-- wiring --> markers");
    let mut checked = 0;
    for line in section.lines().filter(|l| l.starts_with('|')) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 || cells[1] == "function" || cells[1].starts_with("---") {
            continue;
        }
        let function = cells[1];
        let pins = pins_in(cells[2]);
        let row = map
            .iter()
            .find(|r| r.function == function)
            .unwrap_or_else(|| panic!("the guide wires '{function}', the pin map has no such row"));
        assert_eq!(
            pins, row.pins,
            "{function}: guide {:?}, pin map {:?}",
            pins, row.pins
        );
        checked += 1;
    }
    let wired: usize = map
        .iter()
        .filter(|r| {
            !r.pins.is_empty() && !r.function.starts_with("SWD") && !r.function.starts_with("HSE")
        })
        .count();
    assert_eq!(
        checked, wired,
        "every pin-map row with pins is in the guide's table"
    );
}
