//! # board-emulator: the board's release image on an emulated STM32F4, in closed loop
//!
//! The flashed release ELF of `firmware/cortex-m/board` (STM32F405RG, embassy-stm32 0.6,
//! bin `rspr-board`) runs unmodified on rigless's STM32F427 model ([`mcu::BoardMcu`], with
//! TIM9..TIM14, EXTI and SYSCFG added here), on the RSPR board ([`board::RsprBoard`]: 8 MHz
//! crystal, the master link on USART3, the pins of [`pins`]), stepped in lockstep with the
//! robot of `sim/` ([`mechanics`]: the plant and the board's surroundings of
//! `sim/board-on-plant` at pin level; [`bench`]) in virtual time, with the event log's
//! flash kept across a power cycle ([`flash`]); on the board built with the second
//! position channel, its potentiometers on an AD7689 on SPI3 ([`position_channel`],
//! [`ad7689`]). A master drives it through the bench's
//! handle: `host-sim/board-scenarios` runs the host's master against it, `serve` a master
//! on a socket. See README.md.

pub mod ad7689;
pub mod bench;
pub mod board;
pub mod exti;
pub mod flash;
pub mod image;
pub mod mcu;
pub mod mechanics;
pub mod miswiring;
pub mod pins;
pub mod position_channel;
pub mod stack;
pub mod timers;
