//! What every board target on an STM32F405/F42x does the same at register level, whatever
//! its pins: the clock tree (8 MHz HSE -> 168 MHz, the board profile's), the six PWM
//! channels' timers (TIM9 CH1/CH2, TIM10/11/13/14 CH1: the same timers on every target,
//! on the target's pins), and the reset cause. A target's `board` module calls these with
//! its own pins.

use embassy_stm32::pac;
use embassy_stm32::time::Hertz;
use master_link::ResetCause;

/// The crystal or oscillator on OSC_IN, Hz.
const HSE_HZ: u32 = 8_000_000;
/// The PLL: divide the HSE to 1 MHz, multiply to 336 MHz, SYSCLK its half (P), USB its
/// seventh (Q: 48 MHz).
const PLL_PREDIV: u32 = 8;
const PLL_MUL: u32 = 336;
const PLL_DIVP: u32 = 2;
// The clock tree gives the profile's core clock.
const _: () = assert!(
    HSE_HZ / PLL_PREDIV * PLL_MUL / PLL_DIVP == board_profile::BoardProfile::REFERENCE.cpu_hz
);

/// The clock tree: 8 MHz HSE (a crystal, `HseMode::Oscillator`, or a clock fed to OSC_IN,
/// `HseMode::Bypass`) -> PLL 168 MHz SYSCLK, APB1 42 MHz (timers 84 MHz), APB2 84 MHz
/// (timers 168 MHz), 48 MHz for USB.
pub fn clock_config(hse: embassy_stm32::rcc::HseMode) -> embassy_stm32::Config {
    use embassy_stm32::rcc::*;
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(HSE_HZ),
        mode: hse,
    });
    config.rcc.pll_src = PllSource::HSE;
    config.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV8,
        mul: PllMul::MUL336,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV4;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.sys = Sysclk::PLL1_P;
    // The link's DMA interrupts below the control executor and the e-stop.
    config.dma_interrupt_priority = embassy_stm32::interrupt::Priority::P4;
    config
}

/// The single-channel PWM timers (channel 1 each; TIM9 has both of its channels used).
const PWM_SINGLE: [pac::timer::Tim1ch; 4] = [pac::TIM10, pac::TIM11, pac::TIM13, pac::TIM14];

/// Every PWM compare output forced inactive, duty 0.
pub fn pwm_force_inactive() {
    use pac::timer::vals::Ocm;
    pac::TIM9.ccmr_output(0).modify(|w| {
        w.set_ocm(0, Ocm::FORCE_INACTIVE);
        w.set_ocm(1, Ocm::FORCE_INACTIVE);
    });
    pac::TIM9.ccr(0).write(|w| w.set_ccr(0));
    pac::TIM9.ccr(1).write(|w| w.set_ccr(0));
    for t in PWM_SINGLE {
        t.ccmr_output(0)
            .modify(|w| w.set_ocm(0, Ocm::FORCE_INACTIVE));
        t.ccr(0).write(|w| w.set_ccr(0));
    }
}

/// PWM mode back on every channel, duty 0.
pub fn pwm_restore() {
    use pac::timer::vals::Ocm;
    pac::TIM9.ccr(0).write(|w| w.set_ccr(0));
    pac::TIM9.ccr(1).write(|w| w.set_ccr(0));
    pac::TIM9.ccmr_output(0).modify(|w| {
        w.set_ocm(0, Ocm::PWM_MODE1);
        w.set_ocm(1, Ocm::PWM_MODE1);
    });
    for t in PWM_SINGLE {
        t.ccr(0).write(|w| w.set_ccr(0));
        t.ccmr_output(0).modify(|w| w.set_ocm(0, Ocm::PWM_MODE1));
    }
}

/// Every PWM channel's output enabled (`CCxE`).
pub fn pwm_enable_channels() {
    pac::TIM9.ccer().modify(|w| {
        w.set_cce(0, true);
        w.set_cce(1, true);
    });
    for t in PWM_SINGLE {
        t.ccer().modify(|w| w.set_cce(0, true));
    }
}

/// Routes EXTI line `line` to GPIO port `port` (A = 0), on the rising edge (`rising`) or
/// the falling one, clears it and unmasks it; the caller sets the NVIC priority and
/// enables the line's vector.
pub fn exti_configure(port: u8, line: usize, rising: bool) {
    pac::RCC.apb2enr().modify(|w| w.set_syscfgen(true));
    // EXTICRn holds lines 4n..4n+3.
    pac::SYSCFG
        .exticr(line / 4)
        .modify(|w| w.set_exti(line % 4, port));
    if rising {
        pac::EXTI.rtsr(0).modify(|w| w.set_line(line, true));
    } else {
        pac::EXTI.ftsr(0).modify(|w| w.set_line(line, true));
    }
    pac::EXTI.pr(0).write(|w| w.set_line(line, true));
    pac::EXTI.imr(0).modify(|w| w.set_line(line, true));
}

/// Clears EXTI line `line`'s pending bit.
pub fn exti_clear(line: usize) {
    pac::EXTI.pr(0).write(|w| w.set_line(line, true));
}

/// Why the chip last reset, from the RCC's reset flags (RM0090 7.3.21, `RCC_CSR`), which
/// are then cleared so that the next reset reads its own. Order matters: an internal reset
/// also pulls NRST low (the pin flag is set with it), and a power-on sets the brown-out
/// flag too.
pub fn take_reset_cause() -> ResetCause {
    let csr = pac::RCC.csr().read();
    let cause = if csr.wdgrstf() {
        ResetCause::Watchdog
    } else if csr.wwdgrstf() {
        ResetCause::WindowWatchdog
    } else if csr.lpwrrstf() {
        ResetCause::LowPower
    } else if csr.sftrstf() {
        ResetCause::Software
    } else if csr.porrstf() {
        ResetCause::PowerOn
    } else if csr.borrstf() {
        ResetCause::BrownOut
    } else if csr.padrstf() {
        ResetCause::Pin
    } else {
        ResetCause::PowerOn
    };
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    cause
}
