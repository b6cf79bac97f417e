//! The board's last line of defence, and the fault log's home across resets.
//!
//! * **Panic and HardFault**: interrupts off (no task or handler can drive again), the
//!   outputs forced safe at register level (PWM off, driver enable low, brakes applied),
//!   the fault recorded as `Internal` (value 1: a panic, 2: a HardFault) in the log kept
//!   across resets, then nothing: the independent watchdog, no longer fed, resets the chip
//!   within its 10 ms timeout. After the reset the board reports the watchdog reset and the
//!   logged fault, and waits for the master to acknowledge before it enables.
//! * **The fault log** lives in `.uninit` RAM, which cortex-m-rt's start-up code does not
//!   clear: [`persist`] writes it after every tick that logged a fault (or counted a
//!   repeat), [`take`] reads it back at boot ([`FaultLog::restore`] accepts only what
//!   `persist` wrote: after a power-on the RAM holds garbage and the log starts empty).
//! * **The event log's RAM view** is kept the same way ([`persist_events`],
//!   [`take_events`]): after a watchdog reset it is newer than the flash (the entries not
//!   written yet are written then). A panic or a HardFault records its `Internal` fault in
//!   both.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use control::event_log::{EventLog, KeptEvents};
use control::faults::{FaultLog, Persisted};
use master_link::{EventKind, FaultCause, FaultRecord, StopStatus, NO_JOINT};

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

/// The event log's view: not initialised by the start-up code.
#[link_section = ".uninit.rspr_event_log"]
static mut EVENTS: MaybeUninit<KeptEvents> = MaybeUninit::uninit();

/// `KeptEvents` in 32-bit words.
const EVENT_WORDS: usize = core::mem::size_of::<KeptEvents>() / 4;

fn read_events() -> KeptEvents {
    let mut out = KeptEvents::ZERO;
    let from = addr_of_mut!(EVENTS).cast::<u32>();
    let to = core::ptr::addr_of_mut!(out).cast::<u32>();
    for i in 0..EVENT_WORDS {
        // SAFETY: as `read`: one writer (the control task, or a handler that never returns
        // with interrupts off); every bit pattern is a valid `KeptEvents` (plain words,
        // `repr(C)`, EVENT_WORDS of them); a word at a time, so that the copy stays a loop.
        unsafe { to.add(i).write(core::ptr::read_volatile(from.add(i))) }
    }
    out
}

fn write_events(words: &KeptEvents) {
    let from = core::ptr::addr_of!(*words).cast::<u32>();
    let to = addr_of_mut!(EVENTS).cast::<u32>();
    for i in 0..EVENT_WORDS {
        // SAFETY: see `read_events`.
        unsafe { core::ptr::write_volatile(to.add(i), from.add(i).read()) }
    }
}

/// The event log's view kept across the last reset, if there is a valid one.
pub fn take_events() -> Option<EventLog> {
    EventLog::restore(&read_events())
}

/// Keeps the event log's view for the next reset.
pub fn persist_events(log: &EventLog) {
    let mut words = KeptEvents::ZERO;
    log.persist(&mut words);
    write_events(&words);
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
    // The event log's view, when this boot kept one (it does from its start).
    if let Some(mut events) = take_events() {
        events.record(
            EventKind::Fault {
                cause: FaultCause::Internal,
                joint: NO_JOINT,
                value: code,
                stop: StopStatus::SafeTorqueOff,
            },
            time_ms,
        );
        persist_events(&events);
    }
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
