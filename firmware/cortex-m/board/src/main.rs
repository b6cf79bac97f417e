//! Board firmware of the RSPR surgical robot controller: the STM32F405RG board at 168 MHz,
//! embassy. The chip brought up on this board's clock tree, then the board application
//! (`app`: interrupts, priorities, the runtime and the tasks of `board_tasks`, shared with
//! every board target) on this board's pin map (`board`); the hardware traits are `hw`'s.
#![no_std]
#![no_main]

mod ad7689;
mod app;
mod board;
mod event_flash;
mod geometry_flash;
mod hw;
mod safe_halt;
mod stm32f4;

#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    app::run(spawner, embassy_stm32::init(board::clock_config()));
}
