//! Board firmware of the RSPR surgical robot controller on ST's NUCLEO-F429ZI (STM32F429ZI
//! at 168 MHz), embassy. The chip brought up on this board's clock tree, then the board
//! application shared with every board target (`app`: interrupts, priorities, the runtime
//! and the tasks of `board_tasks`; `hw`: the hardware traits) on this board's pin map
//! (`board`). The shared modules are the reference board's files, compiled here against
//! this board's `board` module.
#![no_std]
#![no_main]

#[path = "../../board/src/ad7689.rs"]
mod ad7689;
#[path = "../../board/src/app.rs"]
mod app;
mod board;
#[path = "../../board/src/event_flash.rs"]
mod event_flash;
#[path = "../../board/src/geometry_flash.rs"]
mod geometry_flash;
#[path = "../../board/src/hw.rs"]
mod hw;
#[path = "../../board/src/safe_halt.rs"]
mod safe_halt;
#[path = "../../board/src/stm32f4.rs"]
mod stm32f4;

#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    app::run(spawner, embassy_stm32::init(board::clock_config()));
}
