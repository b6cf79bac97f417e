//! The board: ST's NUCLEO-F429ZI (STM32F429ZI, LQFP144) with off-the-shelf drivers and
//! sensors (bill of materials and wiring: `../README.md`): pin map, clock and peripheral
//! setup, in one place. The same public items as the reference board's `board` module
//! (`firmware/cortex-m/board/src/board.rs`), so that the shared modules (`app`, `hw`,
//! `safe_halt`, the flash stores) compile against either.
//!
//! Joint order everywhere: `l1, l2, l3, theta1, theta2, theta3`.
//!
//! | function                 | pin        | peripheral            |
//! |--------------------------|------------|-----------------------|
//! | encoder l1 A / B         | PE9 / PE11 | TIM1 CH1 / CH2 (QEI)  |
//! | encoder l2 A / B         | PA15 / PB3 | TIM2 CH1 / CH2 (QEI)  |
//! | encoder l3 A / B         | PB4 / PB5  | TIM3 CH1 / CH2 (QEI)  |
//! | encoder theta1 A / B     | PD12 / PD13 | TIM4 CH1 / CH2 (QEI) |
//! | encoder theta2 A / B     | PA0 / PA1  | TIM5 CH1 / CH2 (QEI)  |
//! | encoder theta3 A / B     | PC6 / PC7  | TIM8 CH1 / CH2 (QEI)  |
//! | PWM l1 / l2              | PE5 / PE6  | TIM9 CH1 / CH2        |
//! | PWM l3                   | PF6        | TIM10 CH1             |
//! | PWM theta1               | PF7        | TIM11 CH1             |
//! | PWM theta2               | PF8        | TIM13 CH1             |
//! | PWM theta3               | PF9        | TIM14 CH1             |
//! | DIR l1, l2, l3           | PF12, PF13, PF14 | GPIO out        |
//! | DIR theta1, 2, 3         | PF15, PG0, PG1   | GPIO out        |
//! | driver enable (all)      | PG2        | GPIO out, high = on   |
//! | driver fault (nFAULT, wired-OR of the six drivers) | PG5 | GPIO in, low = fault |
//! | supply voltage sense     | PB1        | ADC1 IN9, divider 12:1 |
//! | brakes, legs l1..l3      | PG3        | GPIO out, high = released |
//! | brakes, links theta1..3  | PG4        | GPIO out, high = released |
//! | emergency stop           | PE15       | GPIO in + EXTI15      |
//! | safety relay feedback    | PE14       | GPIO in, high = relay open |
//! | home switch l1, l2, l3   | PD0, PD1, PD2 | GPIO in            |
//! | home switch theta1, 2, 3 | PD3, PD4, PD5 | GPIO in            |
//! | motor current l1, l2, l3 | PA3, PC0, PC3 | ADC1 IN3, IN10, IN13 |
//! | motor current theta1, 2, 3 | PC2, PA5, PA6 | ADC1 IN12, IN5, IN6 |
//! | master link TX / RX      | PD8 / PD9  | USART3, DMA1 S3 / S1 (the ST-LINK's virtual COM port) |
//! | status LED               | PB14       | GPIO out (LD3, red)   |
//! | SWD                      | PA13 / PA14| the on-board ST-LINK  |
//! | HSE 8 MHz                | PH0        | RCC, bypass: the ST-LINK's MCO |
//! | time driver              | -          | TIM12 (no pins)       |
//!
//! **Why these pins.** The timers are the reference board's (encoders on TIM1/2/3/4/5/8,
//! the only timers with the encoder interface; PWM on TIM9 and TIM10/11/13/14; the time
//! driver on TIM12), so every shared module runs unchanged; the pins avoid what the
//! NUCLEO-144 board already wires (UM1974): the Ethernet PHY's RMII lines (PA1, PA2, PA7,
//! PB13, PC1, PC4, PC5, PG11, PG13), USB OTG (PA8..PA12, PG6, PG7), the LEDs LD1 / LD2
//! (PB0, PB7), the user button (PC13), the 32 kHz crystal (PC14, PC15), SWD and the HSE.
//! Two compromises: TIM5's channel 2 exists only on PA1 in the LQFP144 package, and PA1 is
//! the PHY's 50 MHz reference clock output: the solder bridge between them must be opened
//! (the board's Ethernet is then unusable; this firmware does not use it); TIM2's channel 2
//! is PA1 or PB3, and PB3 also reaches the ST-LINK's SWO input (SWO tracing is then
//! unusable; defmt runs over RTT through SWD).
//!
//! **Drivers and sensors** (the bill of materials in `../README.md`): one sign-magnitude
//! H-bridge carrier per joint (PWM on the bridge's enable input, DIR on its phase input,
//! the common driver enable on every bridge's sleep input, the open-drain fault outputs
//! wired together on PG5 with the internal pull-up), a bidirectional Hall current sensor
//! per motor (0 A at half the 3.3 V supply, 90 mV/A), the supply divided 12:1 onto PB1,
//! switches and e-stop normally closed to ground with the internal pull-ups, the brakes
//! and the relay as on the reference board.

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::gpio::{Input, Level, Output, OutputType, Pull, Speed};
use embassy_stm32::peripherals::{
    ADC1, IWDG, TIM1, TIM10, TIM11, TIM13, TIM14, TIM2, TIM3, TIM4, TIM5, TIM8, TIM9,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::usart::{self, Uart};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, dma, pac, peripherals, Peripherals};
use master_link::ResetCause;

use crate::stm32f4;

bind_interrupts!(pub struct Irqs {
    USART3 => usart::InterruptHandler<peripherals::USART3>;
    DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_STREAM3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
});

/// The board: its period, clock and drive trains: the reference profile (the same robot).
pub const PROFILE: board_profile::BoardProfile = board_profile::BoardProfile::REFERENCE;
/// CPU clock, Hz (DWT cycles per second): the profile's (`stm32f4::clock_config`).
pub const CPU_HZ: u32 = PROFILE.cpu_hz;
/// PWM frequency of the H-bridges (above hearing, within the bridges' switching limits).
pub const PWM_HZ: u32 = 20_000;
/// Master link baud rate (exact on APB1 = 42 MHz with 16x oversampling).
pub const LINK_BAUD: u32 = 1_000_000;
/// Independent watchdog timeout, µs (10 control periods).
pub const IWDG_TIMEOUT_US: u32 = 10_000;

/// Motor wired the other way round: the duty is negated (hal sign convention: positive
/// duty drives towards +q).
pub const INVERT_MOTOR: [bool; 6] = [false; 6];
/// Encoder counting down for +q: the count is negated.
pub const INVERT_ENCODER: [bool; 6] = [false; 6];
/// Home switches are normally closed to ground with the internal pull-up: open (high)
/// means actuated, so a broken wire reads as actuated.
pub const SWITCH_ACTIVE_HIGH: bool = true;
/// The e-stop chain is normally closed to ground with the internal pull-up: open
/// (pressed or broken wire) reads high = asserted.
pub const ESTOP_ACTIVE_HIGH: bool = true;
/// Motor current sense: a bidirectional Hall sensor per motor (ACS711, the +-15.5 A part,
/// 90 mV/A on its 3.3 V supply, 0 A at half of it): amps per ADC count.
pub const CURRENT_A_PER_COUNT: f32 = 3.3 / 4096.0 / 0.090;
/// ADC count at zero current.
pub const CURRENT_ZERO_COUNT: f32 = 2048.0;
/// Supply sense: volts of the bridges' supply per ADC count (3.3 V reference, 12:1
/// divider).
pub const SUPPLY_V_PER_COUNT: f32 = 3.3 / 4096.0 * 12.0;
/// A position sensor wired the other way round (no second channel on this board).
pub const INVERT_POSITION_SENSOR: [bool; 6] = [false; 6];

/// The driver-enable pin at register level (for the interrupt-safe kill): GPIOG pin 2.
const DRV_EN_PORT: pac::gpio::Gpio = pac::GPIOG;
const DRV_EN_PIN: usize = 2;
/// The brake outputs at register level: GPIOG pins 3 (legs) and 4 (links).
const BRAKE_PORT: pac::gpio::Gpio = pac::GPIOG;
const BRAKE_PINS: [usize; 2] = [3, 4];
/// The e-stop input at register level: GPIOE pin 15, EXTI line 15 (port E = 4).
const ESTOP_PORT: pac::gpio::Gpio = pac::GPIOE;
const ESTOP_PORT_INDEX: u8 = 4;
const ESTOP_LINE: usize = 15;

/// The clock tree: the ST-LINK's 8 MHz MCO on OSC_IN (HSE bypass, the board's default).
pub fn clock_config() -> embassy_stm32::Config {
    stm32f4::clock_config(embassy_stm32::rcc::HseMode::Bypass)
}

/// The six quadrature decoders.
pub struct Encoders {
    pub l1: Qei<'static, TIM1>,
    pub l2: Qei<'static, TIM2>,
    pub l3: Qei<'static, TIM3>,
    pub t1: Qei<'static, TIM4>,
    pub t2: Qei<'static, TIM5>,
    pub t3: Qei<'static, TIM8>,
}

/// The six H-bridges: PWM timers, direction pins, the common driver enable, and the
/// brake outputs.
pub struct Motors {
    pub pwm9: SimplePwm<'static, TIM9>,
    pub pwm10: SimplePwm<'static, TIM10>,
    pub pwm11: SimplePwm<'static, TIM11>,
    pub pwm13: SimplePwm<'static, TIM13>,
    pub pwm14: SimplePwm<'static, TIM14>,
    pub dir: [Output<'static>; 6],
    pub driver_enable: Output<'static>,
    /// Brake coils: legs, links (high = released).
    pub brakes: [Output<'static>; 2],
}

/// The second position channel's type (never fitted on this board).
pub type Potentiometers = crate::ad7689::Ad7689;

/// Home switches, motor currents, the supply, the drivers' fault line, the relay feedback.
pub struct Sensors {
    pub switches: [Input<'static>; 6],
    pub adc: Adc<'static, ADC1>,
    pub current: [AnyAdcChannel<'static, ADC1>; 6],
    pub supply: AnyAdcChannel<'static, ADC1>,
    pub driver_fault: Input<'static>,
    pub relay_feedback: Input<'static>,
    pub absolute: Option<Potentiometers>,
}

/// Everything the firmware uses.
pub struct Board {
    pub encoders: Encoders,
    pub motors: Motors,
    pub sensors: Sensors,
    pub estop: Input<'static>,
    pub led: Output<'static>,
    pub uart: Uart<'static, embassy_stm32::mode::Async>,
    pub iwdg: IndependentWatchdog<'static, IWDG>,
    /// The flash, for the calibrated geometry's sector and the event log's.
    pub flash: Flash<'static, Blocking>,
}

/// Setup failure.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum BoardError {
    /// The USART configuration was refused.
    Uart,
}

impl Board {
    /// Takes the peripherals and sets every pin up; the outputs start in the safe state.
    pub fn new(p: Peripherals) -> Result<Self, BoardError> {
        // Driver enable first, low, and the brakes applied.
        let driver_enable = Output::new(p.PG2, Level::Low, Speed::Low);
        let brakes = [
            Output::new(p.PG3, Level::Low, Speed::Low),
            Output::new(p.PG4, Level::Low, Speed::Low),
        ];

        let qc = qei::Config::default();
        let encoders = Encoders {
            l1: Qei::new(p.TIM1, p.PE9, p.PE11, qc),
            l2: Qei::new(p.TIM2, p.PA15, p.PB3, qc),
            l3: Qei::new(p.TIM3, p.PB4, p.PB5, qc),
            t1: Qei::new(p.TIM4, p.PD12, p.PD13, qc),
            t2: Qei::new(p.TIM5, p.PA0, p.PA1, qc),
            t3: Qei::new(p.TIM8, p.PC6, p.PC7, qc),
        };

        let f = Hertz(PWM_HZ);
        let up = CountingMode::EdgeAlignedUp;
        let pp = OutputType::PushPull;
        let motors = Motors {
            pwm9: SimplePwm::new(
                p.TIM9,
                Some(PwmPin::new(p.PE5, pp)),
                Some(PwmPin::new(p.PE6, pp)),
                None,
                None,
                f,
                up,
            ),
            pwm10: SimplePwm::new(
                p.TIM10,
                Some(PwmPin::new(p.PF6, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm11: SimplePwm::new(
                p.TIM11,
                Some(PwmPin::new(p.PF7, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm13: SimplePwm::new(
                p.TIM13,
                Some(PwmPin::new(p.PF8, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm14: SimplePwm::new(
                p.TIM14,
                Some(PwmPin::new(p.PF9, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            dir: [
                Output::new(p.PF12, Level::Low, Speed::Low),
                Output::new(p.PF13, Level::Low, Speed::Low),
                Output::new(p.PF14, Level::Low, Speed::Low),
                Output::new(p.PF15, Level::Low, Speed::Low),
                Output::new(p.PG0, Level::Low, Speed::Low),
                Output::new(p.PG1, Level::Low, Speed::Low),
            ],
            driver_enable,
            brakes,
        };
        // PWM outputs: forced inactive until enabled, channel outputs on.
        force_outputs_safe();
        stm32f4::pwm_enable_channels();

        let sw_pull = if SWITCH_ACTIVE_HIGH {
            Pull::Up
        } else {
            Pull::Down
        };
        let sensors = Sensors {
            switches: [
                Input::new(p.PD0, sw_pull),
                Input::new(p.PD1, sw_pull),
                Input::new(p.PD2, sw_pull),
                Input::new(p.PD3, sw_pull),
                Input::new(p.PD4, sw_pull),
                Input::new(p.PD5, sw_pull),
            ],
            adc: Adc::new(p.ADC1),
            current: [
                p.PA3.degrade_adc(),
                p.PC0.degrade_adc(),
                p.PC3.degrade_adc(),
                p.PC2.degrade_adc(),
                p.PA5.degrade_adc(),
                p.PA6.degrade_adc(),
            ],
            supply: p.PB1.degrade_adc(),
            driver_fault: Input::new(p.PG5, Pull::Up),
            relay_feedback: Input::new(p.PE14, Pull::Up),
            absolute: None,
        };

        let estop_pull = if ESTOP_ACTIVE_HIGH {
            Pull::Up
        } else {
            Pull::Down
        };
        let estop = Input::new(p.PE15, estop_pull);
        let led = Output::new(p.PB14, Level::Low, Speed::Low);

        let mut uc = usart::Config::default();
        uc.baudrate = LINK_BAUD;
        let uart = Uart::new(p.USART3, p.PD9, p.PD8, p.DMA1_CH3, p.DMA1_CH1, Irqs, uc)
            .map_err(|_| BoardError::Uart)?;

        let iwdg = IndependentWatchdog::new(p.IWDG, IWDG_TIMEOUT_US);
        let flash = Flash::new_blocking(p.FLASH);

        Ok(Board {
            encoders,
            motors,
            sensors,
            estop,
            led,
            uart,
            iwdg,
            flash,
        })
    }
}

/// Routes PE15 to EXTI15 (rising edge when the e-stop is asserted, falling when active
/// low) and unmasks it; the caller sets the NVIC priority and enables `EXTI15_10`.
pub fn configure_estop_exti() {
    stm32f4::exti_configure(ESTOP_PORT_INDEX, ESTOP_LINE, ESTOP_ACTIVE_HIGH);
}

/// Clears the e-stop's EXTI pending bit (in its interrupt).
pub fn clear_estop_pending() {
    stm32f4::exti_clear(ESTOP_LINE);
}

/// Whether the e-stop input is asserted at register level.
pub fn estop_asserted_raw() -> bool {
    let high = ESTOP_PORT.idr().read().idr(ESTOP_LINE) == pac::gpio::vals::Idr::HIGH;
    high == ESTOP_ACTIVE_HIGH
}

/// Every PWM output forced low and duty 0, the driver enable low, the brakes applied:
/// plain register writes, callable from any context.
pub fn force_outputs_safe() {
    DRV_EN_PORT.bsrr().write(|w| w.set_br(DRV_EN_PIN, true));
    BRAKE_PORT.bsrr().write(|w| {
        for pin in BRAKE_PINS {
            w.set_br(pin, true);
        }
    });
    stm32f4::pwm_force_inactive();
}

/// PWM mode back on every channel (duty 0) and the driver enable high.
pub fn restore_outputs() {
    stm32f4::pwm_restore();
    DRV_EN_PORT.bsrr().write(|w| w.set_bs(DRV_EN_PIN, true));
}

/// Why the chip last reset (`RCC_CSR`), the flags then cleared.
pub fn take_reset_cause() -> ResetCause {
    stm32f4::take_reset_cause()
}
