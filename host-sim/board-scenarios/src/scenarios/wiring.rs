//! The registers the checks watch, derived from the board's pin map
//! ([`board_emulator::pins::BoardTarget`], checked against the board's own `board.rs` table
//! by the emulator's `tests/pin_map.rs`), so that every scenario runs on every board the
//! emulator models: the GPIO ports the map uses, the driver enable's and the brakes' bits in
//! their ports' `GPIOx_BSRR`, the e-stop's EXTI line, its `SYSCFG_EXTICRx` field and its
//! interrupt, the PWM timers' `CCMR1`. Addresses are RM0090 rev 19's memory map (table 1).

use board_emulator::board::Outputs;
use board_emulator::pins::{BoardTarget, PinId, Port, SmallTimer};
use master_link::{FaultCause, StatusReport};

/// `GPIOA`; the ports follow 0x400 apart (RM0090 rev 19 table 1).
const GPIOA: u64 = 0x4002_0000;
/// `SYSCFG_EXTICR1`; `EXTICR2..4` follow 4 bytes apart (section 9.2.3).
const SYSCFG_EXTICR1: u64 = 0x4001_3808;
/// `EXTI_IMR`.
pub const EXTI_IMR: u64 = 0x4001_3C00;
/// `EXTI_RTSR`.
pub const EXTI_RTSR: u64 = 0x4001_3C08;

/// A GPIO port's base address.
pub const fn gpio_base(port: Port) -> u64 {
    GPIOA + 0x400 * port.index() as u64
}

/// A small timer's base address (RM0090 rev 19 table 1).
pub const fn small_timer_base(timer: SmallTimer) -> u64 {
    match timer {
        SmallTimer::Tim9 => 0x4001_4000,
        SmallTimer::Tim10 => 0x4001_4400,
        SmallTimer::Tim11 => 0x4001_4800,
        SmallTimer::Tim12 => 0x4000_1800,
        SmallTimer::Tim13 => 0x4000_1C00,
        SmallTimer::Tim14 => 0x4000_2000,
    }
}

/// An output pin as the firmware drives it: writes to its port's `GPIOx_BSRR` (section
/// 8.4.7: bit n sets pin n, bit n + 16 resets it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputPin {
    /// The pin.
    pub pin: PinId,
}

impl OutputPin {
    /// Its port's `GPIOx_BSRR`.
    pub const fn bsrr(self) -> u64 {
        gpio_base(self.pin.port) + 0x18
    }

    /// The bit of `BSRR` that drives it high (`BSn`).
    pub const fn set(self) -> u64 {
        1 << self.pin.number
    }

    /// The bit of `BSRR` that drives it low (`BRn`).
    pub const fn reset(self) -> u64 {
        1 << (self.pin.number + 16)
    }

    /// Whether `(address, value)` drives it high (`high`) or low.
    pub const fn written(self, address: u64, value: u64, high: bool) -> bool {
        address == self.bsrr() && value & if high { self.set() } else { self.reset() } != 0
    }

    /// `GPIOG_BSRR BR2`-style name of the write that drives it `high` or low.
    pub fn name(self, high: bool) -> String {
        format!(
            "GPIO{}_BSRR {}{}",
            self.pin.port.letter(),
            if high { "BS" } else { "BR" },
            self.pin.number
        )
    }
}

/// What the checks watch on one board.
#[derive(Debug, Clone, PartialEq)]
pub struct Wiring {
    /// The board.
    pub target: BoardTarget,
    /// The common driver enable (high = bridges on).
    pub driver_enable: OutputPin,
    /// The brake outputs, legs then links (high = released).
    pub brakes: [OutputPin; 2],
    /// The e-stop input (its pin number is its EXTI line).
    pub estop: PinId,
    /// Every port the map uses, in order.
    pub ports: Vec<Port>,
    /// Each PWM timer's `CCMR1` and whether its channel 2 drives a bridge too.
    pub pwm_ccmr1: Vec<(SmallTimer, u64, bool)>,
}

impl Wiring {
    /// The registers of `target`'s pin map.
    pub fn of(target: BoardTarget) -> Self {
        let map = &target.map;
        let mut ports: Vec<Port> = board_emulator::pins::expected_configuration(map)
            .iter()
            .map(|(p, _, _)| p.port)
            .collect();
        ports.sort();
        ports.dedup();
        let mut pwm_ccmr1: Vec<(SmallTimer, u64, bool)> = Vec::new();
        for w in &map.pwm {
            let two = w.channel == 2;
            match pwm_ccmr1.iter_mut().find(|(t, _, _)| *t == w.timer) {
                Some(entry) => entry.2 |= two,
                None => pwm_ccmr1.push((w.timer, small_timer_base(w.timer) + 0x18, two)),
            }
        }
        Wiring {
            target,
            driver_enable: OutputPin {
                pin: map.driver_enable,
            },
            brakes: map.brakes.map(|pin| OutputPin { pin }),
            estop: map.estop,
            ports,
            pwm_ccmr1,
        }
    }

    /// The e-stop's EXTI line.
    pub const fn estop_line(&self) -> u8 {
        self.estop.number
    }

    /// The interrupt (the vector's handler symbol) of the e-stop's EXTI line (RM0090 rev 19
    /// table 62: lines 0..4 have their own, 5..9 and 10..15 share one).
    pub fn estop_handler(&self) -> &'static str {
        match self.estop_line() {
            0 => "EXTI0",
            1 => "EXTI1",
            2 => "EXTI2",
            3 => "EXTI3",
            4 => "EXTI4",
            5..=9 => "EXTI9_5",
            _ => "EXTI15_10",
        }
    }

    /// The `SYSCFG_EXTICRx` that routes the e-stop's line, and the shift of its 4-bit field
    /// (section 9.2.3: EXTICR1 holds lines 0..3, field n at bits 4n..4n+3).
    pub const fn estop_exticr(&self) -> (u64, u32) {
        let line = self.estop_line() as u64;
        (SYSCFG_EXTICR1 + 4 * (line / 4), 4 * (line % 4) as u32)
    }
}

/// The supply the sense must follow in [`supply_step`], V: inside the firmware's
/// monitored range (`control::monitors::PowerConfig`, 20 to 28 V), 2 V below the 24 V
/// supply.
pub const STEPPED_SUPPLY_V: f64 = 22.0;

/// The most the reported supply may differ from the supply, V: the 12:1 divider's
/// resolution is 3.3 V / 4096 x 12 = 9.7 mV per count; 0.2 V is twenty counts, while
/// any other analog input (a current sense at 1.65 V reads as 19.8 V) misses by volts.
pub const SUPPLY_TOLERANCE_V: f64 = 0.2;

/// The supply sense on its pin: the bridges' supply stepped from 24 V to
/// [`STEPPED_SUPPLY_V`] and back while the robot is idle; the board's reports follow it.
pub fn supply_step(run: &mut super::Run) -> Result<(), super::ScenarioError> {
    let nominal = run.surroundings.supply_v;
    let mut low = run.surroundings;
    low.supply_v = STEPPED_SUPPLY_V;
    run.set_surroundings(low);
    let since = run.s.statuses.len();
    run.wait(0.06)?;
    let at_low = run
        .rows_since(since)
        .last()
        .map(|r| f64::from(r.status.supply_v));
    let mut back = run.surroundings;
    back.supply_v = nominal;
    run.set_surroundings(back);
    let since = run.s.statuses.len();
    run.wait(0.06)?;
    let at_nominal = run
        .rows_since(since)
        .last()
        .map(|r| f64::from(r.status.supply_v));
    let near =
        |v: Option<f64>, want: f64| v.is_some_and(|v| (v - want).abs() <= SUPPLY_TOLERANCE_V);
    let pin = run.wiring.target.map.supply_sense.pin;
    run.check(
        "the supply sense follows the supply (24 V, 22 V, 24 V)",
        near(at_low, STEPPED_SUPPLY_V) && near(at_nominal, nominal),
        format!(
            "{pin}: reported {} at {STEPPED_SUPPLY_V:.1} V, {} back at {nominal:.1} V (within {SUPPLY_TOLERANCE_V} V wanted)",
            at_low.map_or("nothing".into(), |v| format!("{v:.3} V")),
            at_nominal.map_or("nothing".into(), |v| format!("{v:.3} V")),
        ),
    );
    Ok(())
}

/// The joints' names, joint order.
const JOINTS: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// What the run made of every wired pin: each output seen at both levels (each bridge
/// driven with its DIR pin high and with it low), each input read by the firmware as its
/// reports show it (each encoder moving its joint, each current sense reading both
/// signs, the supply sense following the supply's step, the e-stop, relay feedback
/// and nFAULT lines each raising their fault). The home switches are read in the homing
/// check (legs on their switches) and the pins check (every one configured).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Coverage {
    /// Per bridge: driven (duty > 0) with DIR high, with DIR low.
    driven: [[bool; 2]; 6],
    /// Driver enable seen low, high.
    enable: [bool; 2],
    /// Per brake output: seen low, high.
    brakes: [[bool; 2]; 2],
    /// The LED seen off, on.
    led: [bool; 2],
}

/// The least travel of a joint's reported position over the run for its encoder to
/// count as read: 1 mm of leg, 1 deg of link (the homing moves every joint tens of times
/// that).
const MIN_TRAVEL: [f64; 6] = [
    1e-3,
    1e-3,
    1e-3,
    std::f64::consts::PI / 180.0,
    std::f64::consts::PI / 180.0,
    std::f64::consts::PI / 180.0,
];

/// The least current, either sign, a current sense must report for its pin to count as
/// read, A: ten ADC counts of the coarser board's scale (3.3 V / 4096 / 0.090 V/A =
/// 9 mA per count), far above a zero reading's one-count noise.
const MIN_CURRENT_A: f64 = 0.09;

impl Coverage {
    /// Adds the outputs as the pins showed them at one instant.
    pub fn add(&mut self, o: &Outputs) {
        for (j, driven) in self.driven.iter_mut().enumerate() {
            let duty = o.duty.get(j).copied().unwrap_or_default();
            let high = o.dir_positive.get(j).copied().unwrap_or_default();
            if duty > 0.0 {
                driven[usize::from(high)] = true;
            }
        }
        self.enable[usize::from(o.driver_enable)] = true;
        for (seen, released) in self.brakes.iter_mut().zip(o.brakes_released) {
            seen[usize::from(released)] = true;
        }
        self.led[usize::from(o.led)] = true;
    }

    /// The pins the run left unexercised (empty: every one), with what was seen of the
    /// inputs, from the outputs added and the board's reports `statuses`.
    pub fn judge(&self, w: &Wiring, statuses: &[StatusReport]) -> (Vec<String>, String) {
        let map = &w.target.map;
        let mut missing = Vec::new();
        let both = |s: &[bool; 2]| s[0] && s[1];
        for (j, name) in JOINTS.iter().enumerate() {
            let d = self.driven.get(j).copied().unwrap_or_default();
            if !both(&d) {
                missing.push(format!(
                    "PWM {name} {} / DIR {name} {}: driven with DIR high {}, low {}",
                    map.pwm[j].pin, map.dir[j], d[1], d[0]
                ));
            }
        }
        if !both(&self.enable) {
            missing.push(format!("driver enable {}", map.driver_enable));
        }
        for (k, seen) in self.brakes.iter().enumerate() {
            if !both(seen) {
                missing.push(format!("brake output {}", map.brakes[k]));
            }
        }
        if !both(&self.led) {
            missing.push(format!("status LED {}", map.led));
        }
        let range = |f: &dyn Fn(&StatusReport) -> f64| {
            statuses
                .iter()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        };
        let mut travel = Vec::new();
        let mut currents = Vec::new();
        for (j, name) in JOINTS.iter().enumerate() {
            let (lo, hi) = range(&|s| f64::from(s.joints[j]));
            let t = hi - lo;
            travel.push(if j < 3 {
                format!("{:.1} mm", t * 1e3)
            } else {
                format!("{:.1} deg", t.to_degrees())
            });
            if t.is_nan() || t < MIN_TRAVEL[j] {
                missing.push(format!(
                    "encoder {name} {} / {}: its joint moved {t:.5} in the reports",
                    map.encoders[j].a, map.encoders[j].b
                ));
            }
            let (lo, hi) = range(&|s| f64::from(s.currents_a[j]));
            currents.push(format!("{lo:+.2}..{hi:+.2} A"));
            if hi < MIN_CURRENT_A || lo > -MIN_CURRENT_A {
                missing.push(format!(
                    "current sense {name} {}: read {lo:+.3}..{hi:+.3} A (both signs beyond {MIN_CURRENT_A} A wanted)",
                    map.current_sense[j].pin
                ));
            }
        }
        // The supply sense: the 24 V supply and the step's 22 V ([`supply_step`]).
        let (lo, hi) = range(&|s| f64::from(s.supply_v));
        let near = |v: f64, want: f64| (v - want).abs() <= SUPPLY_TOLERANCE_V;
        if !(near(hi, 24.0) && near(lo, STEPPED_SUPPLY_V)) {
            missing.push(format!(
                "supply sense {}: read {lo:.2}..{hi:.2} V (24 V and {STEPPED_SUPPLY_V} V wanted)",
                map.supply_sense.pin
            ));
        }
        let raised = |c: FaultCause| statuses.iter().any(|s| s.fault.cause == c);
        for (cause, what, pin) in [
            (FaultCause::EmergencyStopButton, "e-stop", map.estop),
            (
                FaultCause::SafetyRelayMismatch,
                "relay feedback",
                map.relay_feedback,
            ),
            (FaultCause::DriverFault, "driver nFAULT", map.driver_fault),
        ] {
            if !raised(cause) {
                missing.push(format!("{what} {pin}: never raised {cause:?}"));
            }
        }
        let seen = format!(
            "reported joint travel {}; currents {}; supply {lo:.2}..{hi:.2} V",
            travel.join(" / "),
            currents.join(" / ")
        );
        (missing, seen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use board_emulator::pins::{NUCLEO_F429ZI, REFERENCE};

    /// The reference board's registers are the ones RM0090 gives for its pins: PA10..PA12
    /// in `GPIOA_BSRR` (0x4002_0018), PC13 in `EXTICR4` bits 4..7, `EXTI15_10`, the PWM on
    /// TIM9 (two channels), TIM10, TIM11, TIM13, TIM14.
    #[test]
    fn the_reference_boards_registers() {
        let w = Wiring::of(REFERENCE);
        assert_eq!(w.driver_enable.bsrr(), 0x4002_0018);
        assert_eq!(w.driver_enable.reset(), 1 << 26);
        assert_eq!(w.brakes.map(|b| b.reset()), [1 << 27, 1 << 28]);
        assert_eq!(w.estop_exticr(), (0x4001_3814, 4));
        assert_eq!(w.estop_handler(), "EXTI15_10");
        assert_eq!(w.ports, vec![Port::A, Port::B, Port::C, Port::D]);
        let ccmr: Vec<(u64, bool)> = w.pwm_ccmr1.iter().map(|(_, a, t)| (*a, *t)).collect();
        assert_eq!(
            ccmr,
            vec![
                (0x4001_4018, true),
                (0x4001_4418, false),
                (0x4001_4818, false),
                (0x4000_1C18, false),
                (0x4000_2018, false),
            ]
        );
    }

    /// The NUCLEO-F429ZI's: PG2..PG4 in `GPIOG_BSRR` (0x4002_1818), PE15 in `EXTICR4` bits
    /// 12..15, `EXTI15_10`, ports A..G.
    #[test]
    fn the_nucleo_boards_registers() {
        let w = Wiring::of(NUCLEO_F429ZI);
        assert_eq!(w.driver_enable.bsrr(), 0x4002_1818);
        assert_eq!(w.driver_enable.name(false), "GPIOG_BSRR BR2");
        assert_eq!(w.brakes.map(|b| b.bsrr()), [0x4002_1818; 2]);
        assert_eq!(w.brakes.map(|b| b.set()), [1 << 3, 1 << 4]);
        assert_eq!(w.estop_exticr(), (0x4001_3814, 12));
        assert_eq!(w.estop_handler(), "EXTI15_10");
        assert_eq!(w.ports.len(), 7);
        assert!(w.driver_enable.written(0x4002_1818, 1 << 18, false));
        assert!(!w.driver_enable.written(0x4002_0018, 1 << 18, false));
        assert!(!w.driver_enable.written(0x4002_1818, 1 << 2, false));
    }

    /// The coverage names exactly what a run left out: with every output at both levels
    /// and every input read it finds nothing; without the DIR-low drive of one bridge, a
    /// current sense's negative reading or the supply's step it names that pin.
    #[test]
    fn the_coverage_names_what_was_not_exercised() {
        let w = Wiring::of(NUCLEO_F429ZI);
        let full = |skip_dir_low: Option<usize>| {
            let mut c = Coverage::default();
            for high in [false, true] {
                let mut o = Outputs::OFF;
                o.driver_enable = high;
                o.brakes_released = [high; 2];
                o.led = high;
                o.dir_positive = [high; 6];
                o.duty = std::array::from_fn(|j| {
                    if !high && skip_dir_low == Some(j) {
                        0.0
                    } else {
                        0.5
                    }
                });
                c.add(&o);
            }
            c
        };
        let report = |q: f32, i: f32, v: f64| StatusReport {
            joints: [q; 6],
            currents_a: [i; 6],
            supply_v: v as f32,
            ..StatusReport::default()
        };
        let mut statuses = vec![report(0.0, -0.5, 24.0), report(0.1, 0.5, STEPPED_SUPPLY_V)];
        for cause in [
            FaultCause::EmergencyStopButton,
            FaultCause::SafetyRelayMismatch,
            FaultCause::DriverFault,
        ] {
            let mut s = report(0.05, 0.0, 24.0);
            s.fault.cause = cause;
            statuses.push(s);
        }
        let (missing, _) = full(None).judge(&w, &statuses);
        assert!(missing.is_empty(), "{missing:?}");

        let (missing, _) = full(Some(4)).judge(&w, &statuses);
        assert_eq!(missing.len(), 1, "{missing:?}");
        assert!(
            missing[0].starts_with("PWM theta2 PF8 / DIR theta2 PG0"),
            "{missing:?}"
        );

        let mut no_step = statuses.clone();
        no_step[1].supply_v = 24.0;
        no_step[0].currents_a[2] = 0.0;
        let (missing, _) = full(None).judge(&w, &no_step);
        assert_eq!(missing.len(), 2, "{missing:?}");
        assert!(
            missing[0].starts_with("current sense l3 PC3"),
            "{missing:?}"
        );
        assert!(missing[1].starts_with("supply sense PB1"), "{missing:?}");
    }
}
