//! Register behaviour of what this crate adds to rigless's STM32F427, checked against RM0090
//! rev 19 (the STM32F405/F427 reference manual): TIM9..TIM14 (chapter 19), EXTI (chapter 12)
//! and SYSCFG (chapter 9). No firmware: the tests write the registers as a firmware would.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use board_emulator::exti::vector_of;
use board_emulator::mcu::BoardMcu;
use board_emulator::pins::{PinId, Port, PwmWiring, SmallTimer};
use proptest::prelude::*;
use rigless::device::Level;
use rigless::mcu::Operate;
use rigless::soc::Width;
use rigless::time::VirtualNanos;

const RCC: u64 = 0x4002_3800;
const RCC_CFGR: u64 = RCC + 0x08;
const RCC_AHB1ENR: u64 = RCC + 0x30;
const RCC_APB1ENR: u64 = RCC + 0x40;
const RCC_APB2ENR: u64 = RCC + 0x44;
const GPIOA: u64 = 0x4002_0000;
const SYSCFG_EXTICR1: u64 = 0x4001_3808;
const EXTI: u64 = 0x4001_3C00;
const IMR: u64 = EXTI;
const RTSR: u64 = EXTI + 0x08;
const FTSR: u64 = EXTI + 0x0C;
const SWIER: u64 = EXTI + 0x10;
const PR: u64 = EXTI + 0x14;
/// TIMx register offsets, RM0090 rev 19 sections 19.4 and 19.5.
const CR1: u64 = 0x00;
const SR: u64 = 0x10;
const EGR: u64 = 0x14;
const CCMR1: u64 = 0x18;
const CCER: u64 = 0x20;
const CNT: u64 = 0x24;
const PSC: u64 = 0x28;
const ARR: u64 = 0x2C;
const CCR1: u64 = 0x34;
/// The clock every bus runs at out of reset: the 16 MHz HSI (RM0090 rev 19 section 6.2).
const HSI_HZ: u64 = 16_000_000;

fn config(cases: u32) -> ProptestConfig {
    proptest_config::cases(cases)
}

fn at(ns: u64) -> VirtualNanos {
    VirtualNanos(ns)
}

fn write(m: &mut BoardMcu, t: u64, address: u64, value: u64) {
    m.write(at(t), address, Width::W32, value)
        .unwrap_or_else(|e| panic!("write {address:#x}: {e:?}"));
}

fn read(m: &mut BoardMcu, t: u64, address: u64) -> u64 {
    m.read(at(t), address, Width::W32)
        .unwrap_or_else(|e| panic!("read {address:#x}: {e:?}"))
}

fn base(timer: SmallTimer) -> u64 {
    match timer {
        SmallTimer::Tim9 => 0x4001_4000,
        SmallTimer::Tim10 => 0x4001_4400,
        SmallTimer::Tim11 => 0x4001_4800,
        SmallTimer::Tim12 => 0x4000_1800,
        SmallTimer::Tim13 => 0x4000_1C00,
        SmallTimer::Tim14 => 0x4000_2000,
    }
}

/// The RCC enable bit of a timer (RM0090 rev 19 sections 6.3.13 and 6.3.14).
fn enable(m: &mut BoardMcu, timer: SmallTimer) {
    let (register, bit) = match timer {
        SmallTimer::Tim9 => (RCC_APB2ENR, 16),
        SmallTimer::Tim10 => (RCC_APB2ENR, 17),
        SmallTimer::Tim11 => (RCC_APB2ENR, 18),
        SmallTimer::Tim12 => (RCC_APB1ENR, 6),
        SmallTimer::Tim13 => (RCC_APB1ENR, 7),
        SmallTimer::Tim14 => (RCC_APB1ENR, 8),
    };
    let v = read(m, 0, register);
    write(m, 0, register, v | (1 << bit));
}

/// PWM mode 1 on channel 1 with the pin in the timer's alternate function.
fn pwm(m: &mut BoardMcu, wiring: &PwmWiring, psc: u64, arr: u64, ccr: u64) {
    enable(m, wiring.timer);
    // GPIOA clock, PA2 (TIM9_CH1) in alternate function 3 (RM0090 rev 19 section 8.4).
    write(m, 0, RCC_AHB1ENR, 1);
    let pin = u64::from(wiring.pin.number);
    write(m, 0, GPIOA, 0b10 << (2 * pin));
    let af = u64::from(wiring.timer.alternate_function());
    write(m, 0, GPIOA + 0x20, af << (4 * pin));
    let b = base(wiring.timer);
    write(m, 0, b + PSC, psc);
    write(m, 0, b + ARR, arr);
    write(m, 0, b + CCR1, ccr);
    // OC1M = 110: PWM mode 1 (RM0090 rev 19 section 19.4.7).
    write(m, 0, b + CCMR1, 0b110 << 4);
    // UG loads the prescaler (19.3.1).
    write(m, 0, b + EGR, 1);
    write(m, 0, b + CCER, 1);
    write(m, 0, b + CR1, 1);
}

fn expected_ns(cycles: u64, hz: u64) -> u64 {
    u64::try_from(u128::from(cycles) * 1_000_000_000 / u128::from(hz)).unwrap()
}

const PA2: PwmWiring = PwmWiring {
    timer: SmallTimer::Tim9,
    channel: 1,
    pin: PinId::new(Port::A, 2),
};

proptest! {
    #![proptest_config(config(48))]

    /// RM0090 rev 19 section 19.3.9 (PWM mode): the period is (PSC + 1)(ARR + 1) timer-clock
    /// cycles, the output high while CNT < CCR1 (PWM mode 1, up-counting), 100 % when
    /// CCR1 > ARR; the duty the board reads off the pin is that high time over the period.
    #[test]
    fn pwm_period_and_duty_follow_psc_arr_ccr(psc in 0u64..200, arr in 1u64..2000, ccr in 0u64..2100) {
        let mut m = BoardMcu::new().unwrap();
        pwm(&mut m, &PA2, psc, arr, ccr);
        let (width, period) = m.pulse_ns(SmallTimer::Tim9, 1).unwrap();
        let per = psc + 1;
        prop_assert_eq!(period, expected_ns((arr + 1) * per, HSI_HZ));
        prop_assert_eq!(width, expected_ns(ccr.min(arr + 1) * per, HSI_HZ));
        let duty = m.pwm_duty(&PA2);
        prop_assert!((duty - width as f64 / period as f64).abs() < 1e-12);
    }
}

/// The timers run on their bus's timer clock as the tree sets it (RM0090 rev 19 section 6.2,
/// "timer clock frequencies": PCLKx when the APBx prescaler is 1, else 2 x PCLKx): halving
/// HCLK halves the count rate, an APB2 prescaler of 2 doesn't (2 x PCLK2 = HCLK), and TIM13 on
/// APB1 with prescaler 4 counts at 2 x HCLK / 4.
#[test]
fn the_timer_clock_follows_the_clock_tree() {
    let mut m = BoardMcu::new().unwrap();
    pwm(&mut m, &PA2, 15, 999, 250);
    let period = |m: &mut BoardMcu| {
        let _ = read(m, 10, base(SmallTimer::Tim9) + CNT);
        m.pulse_ns(SmallTimer::Tim9, 1).unwrap().1
    };
    assert_eq!(period(&mut m), 1_000_000, "16 MHz / 16 / 1000 = 1 kHz");
    assert_eq!(m.timer_clock_hz(SmallTimer::Tim9), HSI_HZ);
    // HPRE = 1000: HCLK = SYSCLK / 2 (6.3.3).
    write(&mut m, 10, RCC_CFGR, 0b1000 << 4);
    assert_eq!(m.timer_clock_hz(SmallTimer::Tim9), HSI_HZ / 2);
    assert_eq!(period(&mut m), 2_000_000);
    // HPRE = 1, PPRE2 = 100: PCLK2 = HCLK / 2, the timers 2 x PCLK2.
    write(&mut m, 10, RCC_CFGR, 0b100 << 13);
    assert_eq!(m.timer_clock_hz(SmallTimer::Tim9), HSI_HZ);
    assert_eq!(period(&mut m), 1_000_000);
    // PPRE1 = 101: PCLK1 = HCLK / 4, TIM13 at 2 x PCLK1 = 8 MHz.
    write(&mut m, 10, RCC_CFGR, 0b101 << 10);
    let pa6 = PwmWiring {
        timer: SmallTimer::Tim13,
        channel: 1,
        pin: PinId::new(Port::A, 6),
    };
    pwm(&mut m, &pa6, 7, 999, 500);
    assert_eq!(m.timer_clock_hz(SmallTimer::Tim13), HSI_HZ / 2);
    let (w, p) = m.pulse_ns(SmallTimer::Tim13, 1).unwrap();
    assert_eq!((w, p), (500_000, 1_000_000), "8 MHz / 8 / 1000, half duty");
    assert!((m.pwm_duty(&pa6) - 0.5).abs() < 1e-12);
    // A timer whose enable bit is clear counts nothing.
    assert_eq!(m.timer_clock_hz(SmallTimer::Tim14), 0);
}

/// RM0090 rev 19 sections 19.4.4 and 19.5.3: `TIMx_SR` flags are rc_w0, "cleared by software
/// writing it to 0"; a written 1 leaves a flag as it is. The update (UIF) and the compare
/// (CC1IF) flags rise as the counter passes ARR and CCR1.
#[test]
fn status_flags_clear_on_a_written_zero() {
    for timer in [
        SmallTimer::Tim9,
        SmallTimer::Tim10,
        SmallTimer::Tim11,
        SmallTimer::Tim14,
    ] {
        let mut m = BoardMcu::new().unwrap();
        enable(&mut m, timer);
        let b = base(timer);
        write(&mut m, 0, b + ARR, 99);
        write(&mut m, 0, b + CCR1, 50);
        write(&mut m, 0, b + CR1, 1);
        // 100 cycles of 62.5 ns: the update at 6.25 us.
        let t = 10_000;
        m.advance_to(at(t));
        let flags = read(&mut m, t, b + SR) & 0b11;
        assert_eq!(flags, 0b11, "{}: UIF and CC1IF set", timer.name());
        write(&mut m, t, b + SR, 0xFFFF);
        assert_eq!(
            read(&mut m, t, b + SR) & 0b11,
            0b11,
            "a written 1 leaves them"
        );
        write(&mut m, t, b + SR, !1 & 0xFFFF);
        assert_eq!(
            read(&mut m, t, b + SR) & 0b11,
            0b10,
            "UIF cleared, CC1IF left"
        );
        write(&mut m, t, b + SR, !0b10 & 0xFFFF);
        assert_eq!(read(&mut m, t, b + SR) & 0b11, 0, "CC1IF cleared");
    }
}

fn exti_lines_raised(m: &mut BoardMcu) -> Vec<(u16, Level)> {
    m.drain_interrupts()
        .into_iter()
        .filter(|c| c.instance == "EXTI")
        .map(|c| (c.interrupt, c.level))
        .collect()
}

fn route(m: &mut BoardMcu, line: u8, port: Port) {
    let register = SYSCFG_EXTICR1 + 4 * u64::from(line / 4);
    let shift = 4 * u64::from(line % 4);
    let v = read(m, 0, register) & !(0xF << shift);
    write(m, 0, register, v | ((port.index() as u64) << shift));
}

/// RM0090 rev 19 section 12.2.5 and 12.3: an edge selected in RTSR/FTSR sets the line's
/// pending bit; the request to the NVIC is the pending bit under IMR (EXTI15_10 is IRQ 40);
/// EXTI_PR is rc_w1 (a written 1 clears, a 0 leaves); SWIER sets the pending bit of an
/// unmasked line and reads 1 until it is cleared through PR.
#[test]
fn exti_detects_the_selected_edges_and_pending_clears_by_writing_one() {
    let mut m = BoardMcu::new().unwrap();
    let pc13 = PinId::new(Port::C, 13);
    route(&mut m, 13, Port::C);
    write(&mut m, 0, RTSR, 1 << 13);
    write(&mut m, 0, IMR, 1 << 13);
    let _ = exti_lines_raised(&mut m);
    // Closed contact: low. Opened: high (driven high here; a pull-up does the same).
    m.set_pin(pc13, Some(Level::Low));
    m.apply_inputs(at(1_000));
    assert_eq!(read(&mut m, 1_000, PR), 0, "a falling edge is not selected");
    m.set_pin(pc13, Some(Level::High));
    m.apply_inputs(at(2_000));
    assert_eq!(
        read(&mut m, 2_000, PR),
        1 << 13,
        "the rising edge is pending"
    );
    assert_eq!(exti_lines_raised(&mut m), vec![(40, Level::High)]);
    write(&mut m, 2_000, PR, 0);
    assert_eq!(read(&mut m, 2_000, PR), 1 << 13, "a written 0 leaves it");
    write(&mut m, 2_000, PR, 1 << 13);
    assert_eq!(read(&mut m, 2_000, PR), 0, "a written 1 clears it");
    assert_eq!(exti_lines_raised(&mut m), vec![(40, Level::Low)]);
    // Falling edges once FTSR selects them; a masked line is pending without a request.
    write(&mut m, 3_000, FTSR, 1 << 13);
    write(&mut m, 3_000, IMR, 0);
    m.set_pin(pc13, Some(Level::Low));
    m.apply_inputs(at(4_000));
    assert_eq!(read(&mut m, 4_000, PR), 1 << 13);
    assert_eq!(exti_lines_raised(&mut m), vec![]);
    write(&mut m, 4_000, IMR, 1 << 13);
    assert_eq!(exti_lines_raised(&mut m), vec![(40, Level::High)]);
    write(&mut m, 4_000, PR, 1 << 13);
    let _ = exti_lines_raised(&mut m);
    // SWIER on an unmasked line.
    write(&mut m, 5_000, SWIER, 1 << 13);
    assert_eq!(read(&mut m, 5_000, PR), 1 << 13);
    assert_eq!(read(&mut m, 5_000, SWIER), 1 << 13);
    assert_eq!(exti_lines_raised(&mut m), vec![(40, Level::High)]);
    write(&mut m, 5_000, SWIER, 0);
    assert_eq!(
        read(&mut m, 5_000, SWIER),
        1 << 13,
        "a written 0 leaves SWIER"
    );
    write(&mut m, 5_000, PR, 1 << 13);
    assert_eq!(
        read(&mut m, 5_000, SWIER),
        0,
        "cleared with its pending bit"
    );
    // SWIER on a masked line sets nothing pending.
    write(&mut m, 6_000, IMR, 0);
    write(&mut m, 6_000, PR, 0xFFFF);
    write(&mut m, 6_000, SWIER, 1 << 12);
    assert_eq!(read(&mut m, 6_000, PR), 0);
}

proptest! {
    #![proptest_config(config(64))]

    /// RM0090 rev 19 sections 9.2.3..9.2.6: SYSCFG_EXTICRx field EXTIy picks the port whose
    /// pin y drives EXTI line y: an edge on that port's pin is pending on the line, the same
    /// pin of another port is not; the line raises its vector (12.2.5: EXTI0..4 on IRQ 6..10,
    /// EXTI9_5 on 23, EXTI15_10 on 40).
    #[test]
    fn syscfg_routes_each_line_to_the_port_it_selects(line in 0u8..16, routed in 0usize..4, edged in 0usize..4) {
        let ports = [Port::A, Port::B, Port::C, Port::D];
        let mut m = BoardMcu::new().unwrap();
        route(&mut m, line, ports[routed]);
        write(&mut m, 0, RTSR, 1 << line);
        write(&mut m, 0, IMR, 1 << line);
        let _ = exti_lines_raised(&mut m);
        let pin = PinId::new(ports[edged], line);
        m.set_pin(pin, Some(Level::Low));
        m.apply_inputs(at(1_000));
        m.set_pin(pin, Some(Level::High));
        m.apply_inputs(at(2_000));
        let pending = read(&mut m, 2_000, PR) & (1 << line) != 0;
        prop_assert_eq!(pending, routed == edged);
        let raised = exti_lines_raised(&mut m);
        if routed == edged {
            prop_assert_eq!(raised, vec![(vector_of(u32::from(line)).unwrap(), Level::High)]);
        } else {
            prop_assert!(raised.is_empty());
        }
    }
}

/// RM0090 rev 19 section 9.2.3: bits 31:16 of SYSCFG_EXTICRx are reserved (read 0).
#[test]
fn exticr_reserved_bits_read_zero() {
    let mut m = BoardMcu::new().unwrap();
    write(&mut m, 0, SYSCFG_EXTICR1, 0xFFFF_FFFF);
    assert_eq!(read(&mut m, 0, SYSCFG_EXTICR1), 0xFFFF);
}
