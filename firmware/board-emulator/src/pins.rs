//! The boards' pin maps, in one place: which pin carries what, as each board image drives
//! it: [`BOARD`], the reference board (STM32F405RG, LQFP64), and [`NUCLEO_F429ZI_MAP`], the
//! NUCLEO-F429ZI (STM32F429ZI, LQFP144, the emulated STM32F427's die); a [`BoardTarget`]
//! adds the board's current sense. The sources of truth are the tables at the top of
//! `firmware/cortex-m/board/src/board.rs` and `firmware/cortex-m/nucleo-f429zi/src/board.rs`;
//! everything else in this crate reads pins from here. Two checks hold them together:
//! `tests/pin_map.rs` compares each map with its table, and the closed-loop run checks that
//! the image configures every pin as its map says (GPIO mode, alternate function, pull;
//! `host-sim/board-scenarios`, `scenarios::boot::pins`).
//!
//! Joint order everywhere: `l1, l2, l3, theta1, theta2, theta3`.

/// A GPIO port the boards use (the STM32F405 has A..I, the LQFP64 package brings out A, B,
/// C, D2 and H0/H1; the STM32F429ZI's LQFP144 brings out A..G).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Port {
    /// `GPIOA`.
    A,
    /// `GPIOB`.
    B,
    /// `GPIOC`.
    C,
    /// `GPIOD`.
    D,
    /// `GPIOE`.
    E,
    /// `GPIOF`.
    F,
    /// `GPIOG`.
    G,
}

impl Port {
    /// The port's index in RM0090's order (A = 0), which is also the `EXTIx` code of
    /// `SYSCFG_EXTICRx` (RM0090 rev 19 section 9.2.3: 0000 = PA, 0001 = PB, ...).
    pub const fn index(self) -> usize {
        match self {
            Port::A => 0,
            Port::B => 1,
            Port::C => 2,
            Port::D => 3,
            Port::E => 4,
            Port::F => 5,
            Port::G => 6,
        }
    }

    /// The letter.
    pub const fn letter(self) -> char {
        match self {
            Port::A => 'A',
            Port::B => 'B',
            Port::C => 'C',
            Port::D => 'D',
            Port::E => 'E',
            Port::F => 'F',
            Port::G => 'G',
        }
    }
}

/// One pin: port and number 0..=15.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PinId {
    /// The port.
    pub port: Port,
    /// The pin number, 0..=15.
    pub number: u8,
}

impl PinId {
    /// `P<port><number>`.
    pub const fn new(port: Port, number: u8) -> Self {
        PinId { port, number }
    }
}

impl std::fmt::Display for PinId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "P{}{}", self.port.letter(), self.number)
    }
}

/// The timers of the encoders (chapters 17 and 18 of RM0090, modelled by rigless).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncoderTimer {
    /// TIM1 (advanced-control).
    Tim1,
    /// TIM2 (32-bit).
    Tim2,
    /// TIM3.
    Tim3,
    /// TIM4.
    Tim4,
    /// TIM5 (32-bit).
    Tim5,
    /// TIM8 (advanced-control).
    Tim8,
}

impl EncoderTimer {
    /// The timer's base address (RM0090 rev 19 table 1).
    pub const fn base(self) -> u64 {
        match self {
            EncoderTimer::Tim1 => 0x4001_0000,
            EncoderTimer::Tim2 => 0x4000_0000,
            EncoderTimer::Tim3 => 0x4000_0400,
            EncoderTimer::Tim4 => 0x4000_0800,
            EncoderTimer::Tim5 => 0x4000_0C00,
            EncoderTimer::Tim8 => 0x4001_0400,
        }
    }

    /// The alternate function that puts the timer's channels 1 and 2 on their pins
    /// (DS8626 table 9: AF1 for TIM1/TIM2, AF2 for TIM3..TIM5, AF3 for TIM8).
    pub const fn alternate_function(self) -> u8 {
        match self {
            EncoderTimer::Tim1 | EncoderTimer::Tim2 => 1,
            EncoderTimer::Tim3 | EncoderTimer::Tim4 | EncoderTimer::Tim5 => 2,
            EncoderTimer::Tim8 => 3,
        }
    }

    /// The vendor's name.
    pub const fn name(self) -> &'static str {
        match self {
            EncoderTimer::Tim1 => "TIM1",
            EncoderTimer::Tim2 => "TIM2",
            EncoderTimer::Tim3 => "TIM3",
            EncoderTimer::Tim4 => "TIM4",
            EncoderTimer::Tim5 => "TIM5",
            EncoderTimer::Tim8 => "TIM8",
        }
    }
}

/// The timers of chapter 19 (TIM9..TIM14), which this crate models around rigless.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SmallTimer {
    /// TIM9: two channels, slave mode controller (RM0090 rev 19 section 19.1).
    Tim9,
    /// TIM10: one channel.
    Tim10,
    /// TIM11: one channel.
    Tim11,
    /// TIM12: two channels, slave mode controller; the embassy time driver.
    Tim12,
    /// TIM13: one channel.
    Tim13,
    /// TIM14: one channel.
    Tim14,
}

impl SmallTimer {
    /// All six, in the manual's order.
    pub const ALL: [SmallTimer; 6] = [
        SmallTimer::Tim9,
        SmallTimer::Tim10,
        SmallTimer::Tim11,
        SmallTimer::Tim12,
        SmallTimer::Tim13,
        SmallTimer::Tim14,
    ];

    /// The vendor's name.
    pub const fn name(self) -> &'static str {
        match self {
            SmallTimer::Tim9 => "TIM9",
            SmallTimer::Tim10 => "TIM10",
            SmallTimer::Tim11 => "TIM11",
            SmallTimer::Tim12 => "TIM12",
            SmallTimer::Tim13 => "TIM13",
            SmallTimer::Tim14 => "TIM14",
        }
    }

    /// The alternate function that puts the timer's channels on their pins (DS8626 table 9:
    /// AF3 for TIM8..TIM11, AF9 for TIM12..TIM14).
    pub const fn alternate_function(self) -> u8 {
        match self {
            SmallTimer::Tim9 | SmallTimer::Tim10 | SmallTimer::Tim11 => 3,
            SmallTimer::Tim12 | SmallTimer::Tim13 | SmallTimer::Tim14 => 9,
        }
    }

    /// On APB2 (TIM9..TIM11) or APB1 (TIM12..TIM14), RM0090 rev 19 section 6.3.
    pub const fn on_apb2(self) -> bool {
        matches!(
            self,
            SmallTimer::Tim9 | SmallTimer::Tim10 | SmallTimer::Tim11
        )
    }
}

/// One quadrature encoder input: the timer in encoder mode and its two pins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderWiring {
    /// The timer counting it.
    pub timer: EncoderTimer,
    /// Channel A (TIx CH1).
    pub a: PinId,
    /// Channel B (TIx CH2).
    pub b: PinId,
}

/// One PWM output: the timer channel and its pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PwmWiring {
    /// The timer.
    pub timer: SmallTimer,
    /// The channel, 1 or 2.
    pub channel: u8,
    /// The pin.
    pub pin: PinId,
}

/// An analog input: the pin and its ADC1 channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AnalogInput {
    /// The pin.
    pub pin: PinId,
    /// The ADC1/2 channel (`ADC12_INx`).
    pub channel: u8,
}

/// The board's pin map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PinMap {
    /// Encoders, joint order.
    pub encoders: [EncoderWiring; 6],
    /// PWM of the H-bridges (sign-magnitude), joint order.
    pub pwm: [PwmWiring; 6],
    /// Direction of each H-bridge: high = towards +q.
    pub dir: [PinId; 6],
    /// The common driver enable: high = bridges on.
    pub driver_enable: PinId,
    /// The drivers' wired-OR nFAULT (open drain, board pull-up): low = a driver reports a
    /// fault.
    pub driver_fault: PinId,
    /// Supply-voltage sense through [`SUPPLY_DIVIDER`].
    pub supply_sense: AnalogInput,
    /// Brake coils, legs then links: high = released (spring-applied brakes hold when
    /// unpowered).
    pub brakes: [PinId; 2],
    /// The e-stop input (EXTI13): NC chain to ground with the internal pull-up; high =
    /// pressed (or a broken wire).
    pub estop: PinId,
    /// The safety relay's force-guided feedback contact, closed to ground while the relay
    /// holds: high = relay open.
    pub relay_feedback: PinId,
    /// Home / limit switches: NC to ground with pull-up; high = actuated. Joint order.
    pub home_switch: [PinId; 6],
    /// Motor current sense (bidirectional amplifier), joint order.
    pub current_sense: [AnalogInput; 6],
    /// Master link USART3 TX (board -> master).
    pub link_tx: PinId,
    /// Master link USART3 RX (master -> board).
    pub link_rx: PinId,
    /// Status LED.
    pub led: PinId,
}

use Port::{A, B, C, D, E, F, G};

const fn p(port: Port, number: u8) -> PinId {
    PinId::new(port, number)
}

const fn encoder(timer: EncoderTimer, a: PinId, b: PinId) -> EncoderWiring {
    EncoderWiring { timer, a, b }
}

const fn pwm(timer: SmallTimer, channel: u8, pin: PinId) -> PwmWiring {
    PwmWiring {
        timer,
        channel,
        pin,
    }
}

const fn analog(pin: PinId, channel: u8) -> AnalogInput {
    AnalogInput { pin, channel }
}

/// The board (`firmware/cortex-m/board/src/board.rs`).
pub const BOARD: PinMap = PinMap {
    encoders: [
        encoder(EncoderTimer::Tim1, p(A, 8), p(A, 9)),
        encoder(EncoderTimer::Tim2, p(A, 15), p(B, 3)),
        encoder(EncoderTimer::Tim3, p(B, 4), p(B, 5)),
        encoder(EncoderTimer::Tim4, p(B, 6), p(B, 7)),
        encoder(EncoderTimer::Tim5, p(A, 0), p(A, 1)),
        encoder(EncoderTimer::Tim8, p(C, 6), p(C, 7)),
    ],
    pwm: [
        pwm(SmallTimer::Tim9, 1, p(A, 2)),
        pwm(SmallTimer::Tim9, 2, p(A, 3)),
        pwm(SmallTimer::Tim10, 1, p(B, 8)),
        pwm(SmallTimer::Tim11, 1, p(B, 9)),
        pwm(SmallTimer::Tim13, 1, p(A, 6)),
        pwm(SmallTimer::Tim14, 1, p(A, 7)),
    ],
    dir: [p(B, 12), p(B, 13), p(B, 14), p(B, 15), p(C, 8), p(C, 9)],
    driver_enable: p(A, 10),
    driver_fault: p(C, 15),
    supply_sense: analog(p(B, 0), 8),
    brakes: [p(A, 11), p(A, 12)],
    estop: p(C, 13),
    relay_feedback: p(C, 14),
    home_switch: [p(C, 10), p(C, 11), p(C, 12), p(D, 2), p(A, 4), p(B, 1)],
    current_sense: [
        analog(p(C, 0), 10),
        analog(p(C, 1), 11),
        analog(p(C, 2), 12),
        analog(p(C, 3), 13),
        analog(p(C, 4), 14),
        analog(p(C, 5), 15),
    ],
    link_tx: p(B, 10),
    link_rx: p(B, 11),
    led: p(A, 5),
};

/// The NUCLEO-F429ZI (`firmware/cortex-m/nucleo-f429zi/src/board.rs`): the reference
/// board's timers, USART3 and ADC1 on pins the NUCLEO-144 leaves free.
pub const NUCLEO_F429ZI_MAP: PinMap = PinMap {
    encoders: [
        encoder(EncoderTimer::Tim1, p(E, 9), p(E, 11)),
        encoder(EncoderTimer::Tim2, p(A, 15), p(B, 3)),
        encoder(EncoderTimer::Tim3, p(B, 4), p(B, 5)),
        encoder(EncoderTimer::Tim4, p(D, 12), p(D, 13)),
        encoder(EncoderTimer::Tim5, p(A, 0), p(A, 1)),
        encoder(EncoderTimer::Tim8, p(C, 6), p(C, 7)),
    ],
    pwm: [
        pwm(SmallTimer::Tim9, 1, p(E, 5)),
        pwm(SmallTimer::Tim9, 2, p(E, 6)),
        pwm(SmallTimer::Tim10, 1, p(F, 6)),
        pwm(SmallTimer::Tim11, 1, p(F, 7)),
        pwm(SmallTimer::Tim13, 1, p(F, 8)),
        pwm(SmallTimer::Tim14, 1, p(F, 9)),
    ],
    dir: [p(F, 12), p(F, 13), p(F, 14), p(F, 15), p(G, 0), p(G, 1)],
    driver_enable: p(G, 2),
    driver_fault: p(G, 5),
    supply_sense: analog(p(B, 1), 9),
    brakes: [p(G, 3), p(G, 4)],
    estop: p(E, 15),
    relay_feedback: p(E, 14),
    home_switch: [p(D, 0), p(D, 1), p(D, 2), p(D, 3), p(D, 4), p(D, 5)],
    current_sense: [
        analog(p(A, 3), 3),
        analog(p(C, 0), 10),
        analog(p(C, 3), 13),
        analog(p(C, 2), 12),
        analog(p(A, 5), 5),
        analog(p(A, 6), 6),
    ],
    link_tx: p(D, 8),
    link_rx: p(D, 9),
    led: p(B, 14),
};

/// A board the emulator runs: its pin map and its current sense's scale (the rest of the
/// analog front end, the 12:1 supply divider and the 1.65 V zero of the current sense, is
/// the same on every board).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardTarget {
    /// The name (`--board`).
    pub name: &'static str,
    /// The pin map.
    pub map: PinMap,
    /// Current sense: amps per volt away from [`CURRENT_SENSE_ZERO_V`].
    pub current_sense_a_per_v: f64,
    /// The board has the second position channel ([`crate::position_channel`]).
    pub position_channel: bool,
}

/// The reference board (STM32F405RG).
pub const REFERENCE: BoardTarget = BoardTarget {
    name: "reference",
    map: BOARD,
    current_sense_a_per_v: CURRENT_SENSE_A_PER_V,
    position_channel: false,
};

/// The reference board with the second position channel (STM32F405ZG,
/// `--features position-channel`): [`BOARD`] with SPI3 on PC10..PC12 for the channel's
/// converter, so the legs' home switches on PD3..PD5 ([`crate::position_channel`]).
pub const POSITION_CHANNEL_MAP: PinMap = PinMap {
    home_switch: [p(D, 3), p(D, 4), p(D, 5), p(D, 2), p(A, 4), p(B, 1)],
    ..BOARD
};

/// The reference board with the second position channel.
pub const POSITION_CHANNEL: BoardTarget = BoardTarget {
    name: "position-channel",
    map: POSITION_CHANNEL_MAP,
    current_sense_a_per_v: CURRENT_SENSE_A_PER_V,
    position_channel: true,
};

/// The NUCLEO-F429ZI with its Hall current sensors (ACS711, 90 mV/A at 3.3 V), as the
/// image's `CURRENT_A_PER_COUNT` = 3.3 V / 4096 counts / 0.090 V/A.
pub const NUCLEO_F429ZI: BoardTarget = BoardTarget {
    name: "nucleo-f429zi",
    map: NUCLEO_F429ZI_MAP,
    current_sense_a_per_v: 1.0 / 0.090,
    position_channel: false,
};

/// Every board the emulator runs.
pub const TARGETS: [BoardTarget; 2] = [REFERENCE, NUCLEO_F429ZI];

/// The board named `name`.
pub fn target(name: &str) -> Option<BoardTarget> {
    TARGETS.into_iter().find(|t| t.name == name)
}

/// Supply-voltage sense divider (PB0 / ADC12_IN8): the pin sees the supply divided by this
/// (110 kΩ over 10 kΩ: 24 V -> 2.0 V; 39.6 V full scale at 3.3 V), as the board's
/// `SUPPLY_V_PER_COUNT` = 3.3 V / 4096 x 12.
pub const SUPPLY_DIVIDER: f64 = 12.0;

/// The ADC reference (VDDA = VREF+ = the 3.3 V rail), V.
pub const VREF_V: f64 = 3.3;

/// Current sense: bidirectional amplifier (gain 20 V/V) on a 10 mΩ shunt, 0 A at mid-supply
/// (1.65 V): amps per volt away from mid-supply, as the board's `CURRENT_A_PER_COUNT` =
/// 3.3 V / 4096 counts / (20 x 0.010 Ω).
pub const CURRENT_SENSE_A_PER_V: f64 = 1.0 / (20.0 * 0.010);

/// The sense output at 0 A, V.
pub const CURRENT_SENSE_ZERO_V: f64 = VREF_V / 2.0;

/// How the image must configure a pin (RM0090 rev 19 section 8.4: `GPIOx_MODER`,
/// `GPIOx_AFRL/H`, `GPIOx_PUPDR`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PinConfig {
    /// General-purpose output (MODER 01).
    Output,
    /// Input (MODER 00) with the internal pull-up (PUPDR 01).
    InputPullUp,
    /// Alternate function `af` (MODER 10).
    Alternate(u8),
    /// Analog (MODER 11).
    Analog,
}

/// Every pin of `map` with the configuration the board needs and what it carries.
pub fn expected_configuration(map: &PinMap) -> Vec<(PinId, PinConfig, String)> {
    const NAMES: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];
    let mut v = Vec::new();
    for (e, n) in map.encoders.iter().zip(NAMES) {
        let af = e.timer.alternate_function();
        v.push((e.a, PinConfig::Alternate(af), format!("encoder {n} A")));
        v.push((e.b, PinConfig::Alternate(af), format!("encoder {n} B")));
    }
    for (w, n) in map.pwm.iter().zip(NAMES) {
        let af = w.timer.alternate_function();
        v.push((w.pin, PinConfig::Alternate(af), format!("PWM {n}")));
    }
    for (pin, n) in map.dir.iter().zip(NAMES) {
        v.push((*pin, PinConfig::Output, format!("DIR {n}")));
    }
    v.push((map.driver_enable, PinConfig::Output, "driver enable".into()));
    v.push((map.brakes[0], PinConfig::Output, "brakes legs".into()));
    v.push((map.brakes[1], PinConfig::Output, "brakes links".into()));
    v.push((map.led, PinConfig::Output, "status LED".into()));
    v.push((map.estop, PinConfig::InputPullUp, "e-stop".into()));
    v.push((
        map.relay_feedback,
        PinConfig::InputPullUp,
        "relay feedback".into(),
    ));
    v.push((
        map.driver_fault,
        PinConfig::InputPullUp,
        "driver nFAULT".into(),
    ));
    for (pin, n) in map.home_switch.iter().zip(NAMES) {
        v.push((*pin, PinConfig::InputPullUp, format!("home switch {n}")));
    }
    for (a, n) in map.current_sense.iter().zip(NAMES) {
        v.push((a.pin, PinConfig::Analog, format!("current {n}")));
    }
    v.push((
        map.supply_sense.pin,
        PinConfig::Analog,
        "supply sense".into(),
    ));
    // USART3 (PB10/PB11, PD8/PD9): AF7 (DS8626 table 9, DS9405 table 12).
    v.push((map.link_tx, PinConfig::Alternate(7), "link TX".into()));
    v.push((map.link_rx, PinConfig::Alternate(7), "link RX".into()));
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// No pin has two jobs, on either board.
    #[test]
    fn every_pin_has_one_job() {
        for t in TARGETS {
            let all: Vec<PinId> = expected_configuration(&t.map)
                .iter()
                .map(|(p, _, _)| *p)
                .collect();
            let set: BTreeSet<PinId> = all.iter().copied().collect();
            assert_eq!(set.len(), all.len(), "{}: a pin used twice", t.name);
            assert_eq!(all.len(), 46, "{}: every board pin listed once", t.name);
        }
    }

    /// The NUCLEO's current scale is its firmware's: 3.3 V / 4096 counts / 0.090 V/A.
    #[test]
    fn nucleo_current_scale_matches_its_firmware() {
        let a_per_count = VREF_V / 4096.0 * NUCLEO_F429ZI.current_sense_a_per_v;
        assert!((a_per_count - 3.3 / 4096.0 / 0.090).abs() < 1e-15);
    }

    /// The divider puts 24 V at 2.0 V, and the monitored range (20..28 V) inside VREF.
    #[test]
    fn supply_divider_scaling() {
        let sensed = |supply_v: f64| supply_v / SUPPLY_DIVIDER;
        assert!((sensed(24.0) - 2.0).abs() < 1e-12);
        assert!(sensed(28.0) < VREF_V && sensed(36.0) < VREF_V);
    }

    /// The current scale is the firmware's: 3.3 V / 4096 counts / (20 x 0.010 Ω) per count.
    #[test]
    fn current_scale_matches_the_firmware() {
        let a_per_count = VREF_V / 4096.0 * CURRENT_SENSE_A_PER_V;
        assert!((a_per_count - 3.3 / 4096.0 / (20.0 * 0.010)).abs() < 1e-15);
    }
}
