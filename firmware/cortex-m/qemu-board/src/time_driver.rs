//! The embassy-time driver: SysTick interrupts at 10 kHz serve the embassy-time-queue-utils
//! timer queue (wake-ups at the SysTick period, 100 µs); the time base is a 64-bit count
//! of core clock cycles, all in a critical section.
//!
//! The count is not the number of SysTick exceptions: QEMU without `-icount` runs its
//! timers on the host's clock and, when the host is busy, folds several SysTick wraps into
//! one pending exception (measured here: the firmware's clock lost ~40 % against the
//! master's on a loaded machine). It extends the CMSDK APB TIMER0 of the mps2-an386 (a
//! 32-bit down-counter at the core clock whose value QEMU computes from its clock at every
//! read) to 64 bits at every reading; a reading at least every 171 s (2^32 cycles) keeps it
//! exact, and the SysTick exception reads it 10 000 times a second.

use core::cell::RefCell;
use core::task::Waker;

use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;
use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

/// Core clock of the mps2-an386 (SysTick counts it), Hz.
pub const CPU_HZ: u32 = 25_000_000;
/// SysTick interrupt rate, Hz.
const SYSTICK_HZ: u32 = 10_000;
/// Core cycles per SysTick period.
const RELOAD: u32 = CPU_HZ / SYSTICK_HZ;
/// Core cycles per embassy tick (1 µs).
const CYCLES_PER_TICK: u64 = (CPU_HZ / 1_000_000) as u64;

/// CMSDK APB TIMER0: CTRL (bit 0 enable), VALUE, RELOAD.
const TIMER0_CTRL: usize = 0x4000_0000;
const TIMER0_VALUE: usize = 0x4000_0004;
const TIMER0_RELOAD: usize = 0x4000_0008;

struct State {
    /// Core cycles since start.
    cycles: u64,
    /// TIMER0's value at the last reading.
    last_raw: u32,
    /// The next wake-up, µs.
    alarm: u64,
    queue: Queue,
}

/// The driver.
pub struct SysTickDriver {
    state: Mutex<RefCell<State>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    state: Mutex::new(RefCell::new(State {
        cycles: 0,
        last_raw: u32::MAX,
        alarm: u64::MAX,
        queue: Queue::new(),
    })),
});

impl SysTickDriver {
    /// Microseconds since start (TIMER0 read and extended, in a critical section).
    fn now_locked(s: &mut State) -> u64 {
        // SAFETY: TIMER0's VALUE register, always mapped on this machine.
        let raw = unsafe { core::ptr::read_volatile(TIMER0_VALUE as *const u32) };
        // A down-counter over the full 32 bits: the cycles since the last reading.
        s.cycles += u64::from(s.last_raw.wrapping_sub(raw));
        s.last_raw = raw;
        s.cycles / CYCLES_PER_TICK
    }

    fn on_systick(&self, cs: CriticalSection<'_>) {
        let mut s = self.state.borrow_ref_mut(cs);
        let now = Self::now_locked(&mut s);
        if now >= s.alarm {
            s.alarm = s.queue.next_expiration(now);
        }
    }
}

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| Self::now_locked(&mut self.state.borrow_ref_mut(cs)))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let mut s = self.state.borrow_ref_mut(cs);
            if s.queue.schedule_wake(at, waker) {
                let now = Self::now_locked(&mut s);
                s.alarm = s.queue.next_expiration(now);
            }
        })
    }
}

/// Starts TIMER0 (the time base) and SysTick at `SYSTICK_HZ` with exception priority
/// `priority`.
pub fn init(mut syst: SYST, scb: &mut SCB, priority: u8) {
    // SAFETY: TIMER0's registers; writing RELOAD also loads VALUE.
    unsafe {
        core::ptr::write_volatile(TIMER0_CTRL as *mut u32, 0);
        core::ptr::write_volatile(TIMER0_RELOAD as *mut u32, u32::MAX);
        core::ptr::write_volatile(TIMER0_CTRL as *mut u32, 1);
    }
    critical_section::with(|cs| {
        let mut s = DRIVER.state.borrow_ref_mut(cs);
        // SAFETY: as above.
        s.last_raw = unsafe { core::ptr::read_volatile(TIMER0_VALUE as *const u32) };
        s.cycles = 0;
    });
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD - 1);
    syst.clear_current();
    // SAFETY: set before the counter and its exception are enabled.
    unsafe { scb.set_priority(SystemHandler::SysTick, priority) };
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Microseconds since start.
pub fn now_us() -> u64 {
    DRIVER.now()
}

#[exception]
fn SysTick() {
    critical_section::with(|cs| DRIVER.on_systick(cs));
}
