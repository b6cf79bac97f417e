//! The board: STM32F405RG (LQFP64) pin map, clock tree and peripheral setup, in one place.
//!
//! Joint order everywhere: `l1, l2, l3, theta1, theta2, theta3`.
//!
//! | function                 | pin        | peripheral            |
//! |--------------------------|------------|-----------------------|
//! | encoder l1 A / B         | PA8 / PA9  | TIM1 CH1 / CH2 (QEI)  |
//! | encoder l2 A / B         | PA15 / PB3 | TIM2 CH1 / CH2 (QEI)  |
//! | encoder l3 A / B         | PB4 / PB5  | TIM3 CH1 / CH2 (QEI)  |
//! | encoder theta1 A / B     | PB6 / PB7  | TIM4 CH1 / CH2 (QEI)  |
//! | encoder theta2 A / B     | PA0 / PA1  | TIM5 CH1 / CH2 (QEI)  |
//! | encoder theta3 A / B     | PC6 / PC7  | TIM8 CH1 / CH2 (QEI)  |
//! | PWM l1 / l2              | PA2 / PA3  | TIM9 CH1 / CH2        |
//! | PWM l3                   | PB8        | TIM10 CH1             |
//! | PWM theta1               | PB9        | TIM11 CH1             |
//! | PWM theta2               | PA6        | TIM13 CH1             |
//! | PWM theta3               | PA7        | TIM14 CH1             |
//! | DIR l1, l2, l3           | PB12, PB13, PB14 | GPIO out        |
//! | DIR theta1, 2, 3         | PB15, PC8, PC9   | GPIO out        |
//! | driver enable (all)      | PA10       | GPIO out, high = on   |
//! | driver fault (nFAULT, wired-OR of the six drivers) | PC15 | GPIO in, low = fault |
//! | supply voltage sense     | PB0        | ADC1 IN8, divider 12:1 |
//! | brakes, legs l1..l3      | PA11       | GPIO out, high = released |
//! | brakes, links theta1..3  | PA12       | GPIO out, high = released |
//! | emergency stop           | PC13       | GPIO in + EXTI13      |
//! | safety relay feedback    | PC14       | GPIO in, high = relay open |
//! | home switch l1, l2, l3   | PC10, PC11, PC12 | GPIO in         |
//! | home switch theta1, 2, 3 | PD2, PA4, PB1    | GPIO in         |
//! | motor current l1..theta3 | PC0..PC5   | ADC1 IN10..IN15       |
//! | master link TX / RX      | PB10 / PB11| USART3, DMA1 S3 / S1  |
//! | status LED               | PA5        | GPIO out              |
//! | SWD                      | PA13 / PA14| debug (keep free)     |
//! | HSE 8 MHz crystal        | PH0 / PH1  | RCC                   |
//! | time driver              | -          | TIM12 (no pins)       |
//! | position channel converter SCK / MISO / MOSI (`position-channel` boards only) | PC10 / PC11 / PC12 | SPI3 (AF6), AD7689 |
//! | position channel converter CNV (`position-channel` boards only) | PD0 | GPIO out |
//! | home switch l1, l2, l3 (`position-channel` boards: SPI3 has PC10..PC12) | PD3, PD4, PD5 | GPIO in |
//!
//! The six PWM channels fit exactly on TIM9 (2 channels) + TIM10/11/13/14 (1 each):
//! sign-magnitude drive, one PWM and one direction pin per H-bridge.
//!
//! **Brakes in two groups.** Each joint has a spring-applied brake on its motor (unpowered
//! = holding); the coils are switched in two groups, the legs (PA11) and the links (PA12),
//! each through a low-side MOSFET. The firmware always applies and releases all six
//! together (a stop holds the whole platform, an enable releases it under servo), so one
//! output per joint would buy nothing but pins; two groups keep the legs' larger coils on
//! their own switch. The safety relay's second pole cuts the coils' supply, so the
//! hard-wired e-stop applies the brakes without the MCU.
//!
//! **Power stage.** The six drivers' nFAULT outputs (open drain) share PC15 with a
//! pull-up: low = some driver latched a fault (short circuit, over-temperature,
//! under-voltage). The bridges' supply is divided 12:1 (110 kΩ over 10 kΩ: 24 V -> 2.0 V,
//! 39.6 V full scale) onto PB0. The drivers regulate their current cycle by cycle at the
//! joints' rated effort (ITRIP resistor: 5.2 A on the legs, 0.66 A on the links).
//!
//! **Second position channel (absolute position sensors).** A board with the channel has a
//! conductive-plastic potentiometer per joint on the load side (a linear one per leg, a
//! single-turn one per link), each on an input of an AD7689 (16 bits, 8 channels, SPI;
//! IN0..IN5 in joint order) whose reference supplies them (ratiometric: the reference
//! cancels), each input behind a 1.6 kHz RC filter. Sixteen bits because the channel's
//! cross-check needs them: the STM32F405's own 12-bit ADC would make a link's step
//! 0.083 deg, three times the check's bound (`board_profile::position_channel`).
//! The STM32F405RG (LQFP64) has no SPI whose pins are all free: SPI1 (PA5..PA7 or
//! PB3..PB5), SPI2 (PB10/PB13, PB14/PC2, PB15/PC3) and SPI3 (PB3..PB5 or PC10..PC12) each
//! meet an encoder, a PWM, a direction pin, a current sense, the link or the switches. The
//! channel is therefore fitted on the STM32F405ZG (LQFP144: the same die, memory and
//! firmware) with SPI3 on PC10..PC12 and the legs' home switches moved to PD3..PD5 (port D
//! is brought out on the LQFP144), the converter's `CNV` on PD0; every other pin as above.
//! The image for it is built with `--no-default-features --features position-channel` (the
//! chip's feature and the pins); the default image is the prototype's board, without the
//! channel, and says so (`hal::AbsolutePositions::absolute_fitted`, the status report's
//! `position_channel`).
//!
//! **Safety relay feedback.** The relay's force-guided auxiliary contact is closed to
//! ground while the relay holds its main contacts closed (drivers powered); with the
//! pull-up, high = relay open, and a broken feedback wire also reads open, which the
//! firmware sees as a mismatch with the released button and refuses to enable.

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

/// The board: its period, clock and drive trains (the one owner of those facts).
pub const PROFILE: board_profile::BoardProfile = board_profile::BoardProfile::REFERENCE;
/// CPU clock, Hz (DWT cycles per second): the profile's, which the clock tree below must
/// produce (checked at compile time).
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
/// Motor current sense: bidirectional amplifier (e.g. INA240, gain 20) on a 10 mΩ shunt,
/// zero current at mid-supply: amps per ADC count and the zero-current count.
pub const CURRENT_A_PER_COUNT: f32 = 3.3 / 4096.0 / (20.0 * 0.010);
/// ADC count at zero current.
pub const CURRENT_ZERO_COUNT: f32 = 2048.0;
/// Supply sense: volts of the bridges' supply per ADC count (3.3 V reference, 12:1
/// divider).
pub const SUPPLY_V_PER_COUNT: f32 = 3.3 / 4096.0 * 12.0;

/// A position sensor (the second channel's potentiometer) wired the other way round: its
/// reading is inverted, `65535 - raw` (hal sign convention: counts up towards +q).
pub const INVERT_POSITION_SENSOR: [bool; 6] = [false; 6];

/// The driver-enable pin at register level (for the interrupt-safe kill): GPIOA pin 10.
const DRV_EN_PORT: pac::gpio::Gpio = pac::GPIOA;
const DRV_EN_PIN: usize = 10;
/// The brake outputs at register level: GPIOA pins 11 (legs) and 12 (links).
const BRAKE_PORT: pac::gpio::Gpio = pac::GPIOA;
const BRAKE_PINS: [usize; 2] = [11, 12];

/// The clock tree: the 8 MHz crystal (HSE oscillator) -> 168 MHz (`stm32f4::clock_config`).
pub fn clock_config() -> embassy_stm32::Config {
    stm32f4::clock_config(embassy_stm32::rcc::HseMode::Oscillator)
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

/// The second position channel: a potentiometer per joint on the AD7689's IN0..IN5 (joint
/// order), the converter on SPI3.
pub type Potentiometers = crate::ad7689::Ad7689;

/// Home switches, motor currents, the supply, the drivers' fault line, the relay feedback,
/// and the second position channel where the board has it.
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
    /// The flash, for the calibrated geometry's sector.
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
        // Driver enable first, low, and the brakes applied: nothing can drive or let go
        // before the state machine says so.
        let driver_enable = Output::new(p.PA10, Level::Low, Speed::Low);
        let brakes = [
            Output::new(p.PA11, Level::Low, Speed::Low),
            Output::new(p.PA12, Level::Low, Speed::Low),
        ];

        let qc = qei::Config::default();
        let encoders = Encoders {
            l1: Qei::new(p.TIM1, p.PA8, p.PA9, qc),
            l2: Qei::new(p.TIM2, p.PA15, p.PB3, qc),
            l3: Qei::new(p.TIM3, p.PB4, p.PB5, qc),
            t1: Qei::new(p.TIM4, p.PB6, p.PB7, qc),
            t2: Qei::new(p.TIM5, p.PA0, p.PA1, qc),
            t3: Qei::new(p.TIM8, p.PC6, p.PC7, qc),
        };

        let f = Hertz(PWM_HZ);
        let up = CountingMode::EdgeAlignedUp;
        let pp = OutputType::PushPull;
        let motors = Motors {
            pwm9: SimplePwm::new(
                p.TIM9,
                Some(PwmPin::new(p.PA2, pp)),
                Some(PwmPin::new(p.PA3, pp)),
                None,
                None,
                f,
                up,
            ),
            pwm10: SimplePwm::new(
                p.TIM10,
                Some(PwmPin::new(p.PB8, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm11: SimplePwm::new(
                p.TIM11,
                Some(PwmPin::new(p.PB9, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm13: SimplePwm::new(
                p.TIM13,
                Some(PwmPin::new(p.PA6, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            pwm14: SimplePwm::new(
                p.TIM14,
                Some(PwmPin::new(p.PA7, pp)),
                None,
                None,
                None,
                f,
                up,
            ),
            dir: [
                Output::new(p.PB12, Level::Low, Speed::Low),
                Output::new(p.PB13, Level::Low, Speed::Low),
                Output::new(p.PB14, Level::Low, Speed::Low),
                Output::new(p.PB15, Level::Low, Speed::Low),
                Output::new(p.PC8, Level::Low, Speed::Low),
                Output::new(p.PC9, Level::Low, Speed::Low),
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
            #[cfg(not(feature = "position-channel"))]
            switches: [
                Input::new(p.PC10, sw_pull),
                Input::new(p.PC11, sw_pull),
                Input::new(p.PC12, sw_pull),
                Input::new(p.PD2, sw_pull),
                Input::new(p.PA4, sw_pull),
                Input::new(p.PB1, sw_pull),
            ],
            // SPI3 takes PC10..PC12: the legs' switches move to PD3..PD5.
            #[cfg(feature = "position-channel")]
            switches: [
                Input::new(p.PD3, sw_pull),
                Input::new(p.PD4, sw_pull),
                Input::new(p.PD5, sw_pull),
                Input::new(p.PD2, sw_pull),
                Input::new(p.PA4, sw_pull),
                Input::new(p.PB1, sw_pull),
            ],
            adc: Adc::new(p.ADC1),
            current: [
                p.PC0.degrade_adc(),
                p.PC1.degrade_adc(),
                p.PC2.degrade_adc(),
                p.PC3.degrade_adc(),
                p.PC4.degrade_adc(),
                p.PC5.degrade_adc(),
            ],
            supply: p.PB0.degrade_adc(),
            driver_fault: Input::new(p.PC15, Pull::Up),
            relay_feedback: Input::new(p.PC14, Pull::Up),
            #[cfg(feature = "position-channel")]
            absolute: Some(crate::ad7689::Ad7689::new(Output::new(
                p.PD0,
                Level::Low,
                Speed::VeryHigh,
            ))),
            #[cfg(not(feature = "position-channel"))]
            absolute: None,
        };

        let estop_pull = if ESTOP_ACTIVE_HIGH {
            Pull::Up
        } else {
            Pull::Down
        };
        let estop = Input::new(p.PC13, estop_pull);
        let led = Output::new(p.PA5, Level::Low, Speed::Low);

        let mut uc = usart::Config::default();
        uc.baudrate = LINK_BAUD;
        let uart = Uart::new(p.USART3, p.PB11, p.PB10, p.DMA1_CH3, p.DMA1_CH1, Irqs, uc)
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

/// Routes PC13 to EXTI13 (rising edge when the e-stop is asserted, falling when active
/// low) and unmasks it; the caller sets the NVIC priority and enables `EXTI15_10`.
pub fn configure_estop_exti() {
    // Port C is 2.
    stm32f4::exti_configure(2, 13, ESTOP_ACTIVE_HIGH);
}

/// Clears the e-stop's EXTI pending bit (in its interrupt).
pub fn clear_estop_pending() {
    stm32f4::exti_clear(13);
}

/// Whether the e-stop input is asserted at register level.
pub fn estop_asserted_raw() -> bool {
    let high = pac::GPIOC.idr().read().idr(13) == pac::gpio::vals::Idr::HIGH;
    high == ESTOP_ACTIVE_HIGH
}

/// Every PWM output forced low and duty 0, the driver enable low, the brakes applied:
/// plain register writes, callable from any context (interrupt, panic and fault handlers,
/// before the drivers exist).
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
