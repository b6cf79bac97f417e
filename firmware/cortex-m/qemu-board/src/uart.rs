//! A small driver of the CMSDK APB UART0 of the mps2-an386 (QEMU connects the first
//! `-serial` to it): receive by interrupt into a byte pipe, transmit polled (the emulated
//! UART has a one-byte buffer on each side and sends at once).
//!
//! Registers (CMSDK TRM, DDI0479C): DATA 0x00, STATE 0x04 (bit 0 TX full, bit 1 RX full,
//! bits 2/3 overruns, write 1 to clear), CTRL 0x08 (bit 0 TX enable, bit 1 RX enable,
//! bit 3 RX interrupt enable), INTSTATUS/INTCLEAR 0x0C (bit 1 RX, write 1 to clear),
//! BAUDDIV 0x10 (>= 16). Interrupts: UART0 RX = IRQ 0, TX = IRQ 1.

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

use crate::time_driver::CPU_HZ;

const BASE: usize = 0x4000_4000;
const DATA: usize = BASE;
const STATE: usize = BASE + 0x04;
const CTRL: usize = BASE + 0x08;
const INTSTATUS: usize = BASE + 0x0C;
const BAUDDIV: usize = BASE + 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_OVERRUNS: u32 = 0b1100;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_RX_INTEN: u32 = 1 << 3;
const INT_RX: u32 = 1 << 1;

/// The NVIC line of UART0's receive interrupt.
pub const RX_IRQ: u16 = 0;

/// Line rate, baud (the board's master link runs 1 Mbaud; QEMU does not pace it).
pub const BAUD: u32 = 1_000_000;

/// Received bytes, from the interrupt to the link task. QEMU hands over the bytes queued
/// on its socket as fast as the interrupt reads them (no baud-rate pacing), e.g. after the
/// host stalled the emulator, while the link task waits for the control tick: room for
/// about half a second of the master's traffic.
pub static RX: Pipe<CriticalSectionRawMutex, 16384> = Pipe::new();
/// Bytes lost because the pipe was full.
pub static RX_DROPPED: AtomicU32 = AtomicU32::new(0);

fn read(addr: usize) -> u32 {
    // SAFETY: a register of the UART0 block, always mapped on this machine.
    unsafe { read_volatile(addr as *const u32) }
}

fn write(addr: usize, v: u32) {
    // SAFETY: as `read`.
    unsafe { write_volatile(addr as *mut u32, v) }
}

/// A device interrupt line for the NVIC.
#[derive(Clone, Copy)]
pub struct Irq(pub u16);

// SAFETY: the numbers used are lines of the mps2-an386's NVIC (32 lines).
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0
    }
}

/// Sets the baud rate, enables transmit, receive and the receive interrupt at `priority`.
pub fn init(nvic: &mut NVIC, priority: u8) {
    write(CTRL, 0);
    write(BAUDDIV, CPU_HZ / BAUD);
    write(STATE, STATE_OVERRUNS);
    write(INTSTATUS, 0xF);
    write(CTRL, CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INTEN);
    // SAFETY: the handler (`on_rx_interrupt`, dispatched from DefaultHandler) only touches
    // the pipe and the counter, both interrupt-safe.
    unsafe {
        nvic.set_priority(Irq(RX_IRQ), priority);
        NVIC::unmask(Irq(RX_IRQ));
    }
}

/// The receive interrupt: moves every waiting byte into [`RX`].
pub fn on_rx_interrupt() {
    write(INTSTATUS, INT_RX);
    while read(STATE) & STATE_RX_FULL != 0 {
        let byte = (read(DATA) & 0xFF) as u8;
        if RX.try_write(&[byte]).is_err() {
            RX_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Sends `bytes`, yielding to the other tasks while the transmit buffer is full.
pub async fn write_all(bytes: &[u8]) {
    for b in bytes {
        while read(STATE) & STATE_TX_FULL != 0 {
            embassy_futures::yield_now().await;
        }
        write(DATA, u32::from(*b));
    }
}
