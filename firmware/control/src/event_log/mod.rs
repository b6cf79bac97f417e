//! The board's non-volatile event log: faults (cause, joint, value, the stop), the stops
//! that are not faults (a disable, the holds), resets (the cause), a master taking
//! charge, geometries stored and the safety chain's relay test, each with its boot (the
//! board counts its boots) and the time in that boot, and a repeat count.
//!
//! Three parts, all host-tested; the targets supply the flash:
//!
//! * [`record`]: one record as the flash holds it (eight words, CRC-32 last);
//! * [`EventLog`] (`log`): the runtime's RAM view of the newest [`EVENT_VIEW`] entries,
//!   what the link reads (`EventLogRequest`), and what is still to be written;
//! * [`EventStore`] (`store`): the writer of a ring of flash sectors and its mount at
//!   boot.
//!
//! **Repeats.** An event that repeats the newest entry of its kind in the same boot (the
//! same fault on the same joint, the same stop reason, the same master, ...) counts on that
//! entry instead of making a new one; the entry is written again with its new count, and
//! the newest record of an entry is the one that counts. So a count reaches the flash
//! like any entry.
//!
//! **Writing without missing a control period.** The STM32F405 has one flash bank: while
//! it programs or erases, every fetch from flash stalls the core, interrupts included
//! (RM0090 section 3.5). Programming takes 16 µs per 32-bit word typically and 100 µs at
//! most (DS8626, "Flash memory programming", x32 parallelism: the 256-byte geometry slot,
//! 64 words, takes about 1 ms); erasing a 128 KB sector 1 s, 2 s at most. The control
//! period is 1 000 µs and its work at most 20 000 instructions, the budget the on-target
//! run enforces (about 155 µs at 168 MHz with 1.3 cycles per instruction; the measured
//! worst: `FIGURES.md`, `firmware/cortex-m/on-target/README.md`), and a tick
//! that starts more than 250 µs late is a missed deadline. So the board programs at most
//! [`WORDS_PER_PERIOD`] words per period, after the tick's outputs and its status: at most
//! 200 µs of stall (32 µs typically), which ends long before the next period; a record
//! (8 words) is whole 4 periods after it starts, while the robot moves or holds as well as
//! at rest. An erase (the ring's rotation, once per 4 096 records) runs only with the
//! drives off and the brakes applied, as the geometry's store does: the watchdog's
//! timeout raised for it and the schedule restarted after it. The entries wait in the RAM
//! view meanwhile.
//!
//! **At boot** ([`boot`]): the flash is mounted; after a watchdog reset the view kept in
//! RAM ([`KeptEvents`], written by the target after every tick that changed the log) is
//! newer and is taken instead (with the counts the flash did not hold yet, which are
//! written then); a new boot starts. The relay test's state of the newest entry is the
//! last power cycle's: the target calls `Runtime::require_relay_test` when it is pending
//! (`Runtime::restore_events` does).

pub mod record;

mod log;
mod store;

pub use log::{EventLog, KeptEvents, ViewEntry, EVENT_VIEW, KEPT_MAGIC};
pub use store::{mount, scan, EventFlash, EventStore, Step, GIVE_UP_AFTER, MAX_SECTORS};

/// Words the board programs per control period at most (see the module documentation).
pub const WORDS_PER_PERIOD: usize = 2;

/// At boot: the flash mounted (`None` for the writer when the flash cannot be read: the
/// log then lives in RAM only), the view kept across a watchdog reset taken when it is at
/// least as new as the flash's, and a new boot started.
pub fn boot<F: EventFlash>(
    flash: &mut F,
    kept: Option<EventLog>,
) -> (Option<EventStore>, EventLog) {
    let (store, from_flash) = match mount(flash) {
        Ok((s, l)) => (Some(s), l),
        Err(_) => (None, EventLog::new()),
    };
    let mut log = match kept {
        Some(k) if k.boot() >= from_flash.boot() && k.next_seq() >= from_flash.next_seq() => k,
        _ => from_flash,
    };
    log.start_boot();
    (store, log)
}
