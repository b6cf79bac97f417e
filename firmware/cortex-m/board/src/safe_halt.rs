//! The board's last line of defence, and the fault log's home across resets.
//!
//! * **Panic and HardFault**: interrupts off (no task or handler can drive again), the
//!   outputs forced safe at register level (PWM off, driver enable low, brakes applied),
//!   the fault recorded as `Internal` (value 1: a panic, 2: a HardFault) in the log kept
//!   across resets, then nothing: the independent watchdog, no longer fed, resets the chip
//!   within its 10 ms timeout. After the reset the board reports the watchdog reset and the
//!   logged fault, and waits for the master to acknowledge before it enables.
//! * **The fault log** lives in `.uninit` RAM, which cortex-m-rt's start-up code does not
//!   clear: [`persist`] writes it after every tick that logged a fault, [`take`] reads it
//!   back at boot ([`FaultLog::restore`] accepts only what `persist` wrote: after a
//!   power-on the RAM holds garbage and the log starts empty).

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use control::faults::{FaultLog, Persisted};
use master_link::{FaultCause, FaultRecord, StopStatus, NO_JOINT};

use crate::board;

/// The persisted log: not initialised by the start-up code.
#[link_section = ".uninit.rspr_fault_log"]
static mut LOG: MaybeUninit<Persisted> = MaybeUninit::uninit();

fn read() -> Persisted {
    // SAFETY: `LOG` is only accessed through these two functions, from the control task
    // (one writer) or from a handler that runs with interrupts off and never returns;
    // every bit pattern is a valid `Persisted` (plain words), whatever the RAM held.
    unsafe { core::ptr::read_volatile(addr_of_mut!(LOG).cast::<Persisted>()) }
}

fn write(words: &Persisted) {
    // SAFETY: see `read`.
    unsafe { core::ptr::write_volatile(addr_of_mut!(LOG).cast::<Persisted>(), *words) }
}

/// The log kept across the last reset, if there is a valid one.
pub fn take() -> Option<FaultLog> {
    FaultLog::restore(&read())
}

/// Keeps `log` for the next reset.
pub fn persist(log: &FaultLog) {
    let mut words = Persisted::ZERO;
    log.persist(&mut words);
    write(&words);
}

/// Records an internal fault (`code`) in the kept log, at `time_ms`.
fn record(code: f32, time_ms: u32) {
    let mut log = take().unwrap_or_default();
    let record = FaultRecord {
        cause: FaultCause::Internal,
        joint: NO_JOINT,
        value: code,
        time_ms,
    };
    log.record(record, StopStatus::SafeTorqueOff);
    persist(&log);
}

/// Interrupts off, outputs safe, the fault recorded; then wait for the watchdog.
fn halt(code: f32, time_ms: u32) -> ! {
    cortex_m::interrupt::disable();
    board::force_outputs_safe();
    record(code, time_ms);
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    board::force_outputs_safe();
    let ms = u32::try_from(embassy_time::Instant::now().as_millis()).unwrap_or(u32::MAX);
    defmt::error!("panic: {}", defmt::Display2Format(info));
    halt(1.0, ms)
}

#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    // No clock here: the time driver may be what faulted.
    halt(2.0, 0)
}
