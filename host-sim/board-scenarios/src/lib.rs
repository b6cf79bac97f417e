//! # board-scenarios: the board's release image against the host's master
//!
//! The closed-loop scenarios of the emulated board (`firmware/board-emulator`: the release
//! ELF on rigless's STM32F4 with the board and the robot of `sim/` around it, in lockstep,
//! in virtual time) driven by the master of `host-sim teleop` ([`master`]: the `teleop`
//! crate's session on its link, over the emulated USART3); [`scenarios`] are the checks.
//! See README.md.

pub mod master;
pub mod scenarios;
