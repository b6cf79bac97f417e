//! # board-emulator: the board's release image on an emulated STM32F4, in closed loop
//!
//! The flashed release ELF of `firmware/cortex-m/board` (STM32F405RG, embassy-stm32 0.6,
//! bin `rspr-board`) runs unmodified on rigless's STM32F427 model ([`mcu::BoardMcu`], with
//! TIM9..TIM14, EXTI and SYSCFG added here), on the RSPR board ([`board::RsprBoard`]: 8 MHz
//! crystal, the master link on USART3, the pins of [`pins`]), stepped in lockstep with the
//! host's plant model ([`mechanics`], [`bench`]) and driven by the master of
//! `host-sim teleop` ([`master`]) in virtual time; [`scenarios`] are the checks. See
//! README.md.

pub mod bench;
pub mod board;
pub mod exti;
pub mod image;
pub mod master;
pub mod mcu;
pub mod mechanics;
pub mod pins;
pub mod scenarios;
pub mod timers;
