//! One record of the event log as the flash holds it: eight little-endian 32-bit words,
//! the last a CRC-32 over the other seven.
//!
//! ```text
//! word 0  serial        this write's number (increases by one per record written; never
//!                       0xFFFF_FFFF, so that a programmed record is never all ones)
//! word 1  seq           the entry it writes (a repeat writes its entry again, same seq)
//! word 2  time_ms       when the entry first happened, ms since its boot
//! word 3  value         the kind's 32-bit value: f32 bits of a fault's value, a master's
//!                       id, a geometry's version, a lost count
//! word 4  boot | count  the entry's boot (low half) and its count (high half)
//! word 5  kind | code << 8 | joint << 16 | stop << 24 | flags << 28
//!                       kind 1..=7 (fault, stop, reset, master, geometry, relay test,
//!                       lost); code: the fault cause, stop reason, reset cause or the
//!                       relay test's state; stop: the stop status; flags bit 0: the relay
//!                       test was pending
//! word 6  entries       the log's entry counter when the record was written (the next
//!                       entry's seq), so that a boot continues the numbering from the
//!                       newest record alone
//! word 7  crc           CRC-32/ISO-HDLC of words 0..=6 (the link's)
//! ```
//!
//! A slot whose eight words all read 0xFFFF_FFFF is erased; any other content whose CRC
//! does not match is a torn record (a write cut by a reset or a power loss), skipped; the
//! words are programmed in order and the CRC last, so a record is valid only once whole.

use crate::faults::{cause_code, cause_of};
use master_link::{EventEntry, EventKind, ResetCause, StopReason, StopStatus, CRC32};

/// Words per record.
pub const RECORD_WORDS: usize = 8;
/// Bytes per record.
pub const RECORD_LEN: usize = 4 * RECORD_WORDS;
/// The erased word.
pub const ERASED: u32 = u32::MAX;

/// One record: the entry, the write's serial and the log's entry counter at the write.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// This write's number.
    pub serial: u32,
    /// The entry written.
    pub entry: EventEntry,
    /// The log's entry counter when it was written (the next entry's seq).
    pub entries: u32,
}

/// What a slot holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// Erased: every word reads all ones.
    Erased,
    /// Something whose CRC does not match (a write cut short), or a kind this firmware does
    /// not know.
    Torn,
    /// A whole record.
    Valid(Record),
}

const STOPS: [StopStatus; 7] = [
    StopStatus::None,
    StopStatus::SafeTorqueOff,
    StopStatus::SafeStop1Decelerating,
    StopStatus::SafeStop1Braking,
    StopStatus::SafeStop1Done,
    StopStatus::SafeStop2Decelerating,
    StopStatus::SafeOperatingStop,
];

const RESETS: [ResetCause; 7] = [
    ResetCause::PowerOn,
    ResetCause::Pin,
    ResetCause::Software,
    ResetCause::Watchdog,
    ResetCause::WindowWatchdog,
    ResetCause::BrownOut,
    ResetCause::LowPower,
];

fn index_of<T: PartialEq>(all: &[T], x: &T) -> u32 {
    all.iter().position(|a| a == x).map_or(0, |i| i as u32)
}

/// The kind's (kind, code, joint, stop, value) fields.
fn fields(event: &EventKind) -> (u32, u32, u32, u32, u32) {
    match *event {
        EventKind::Fault {
            cause,
            joint,
            value,
            stop,
        } => (
            1,
            cause_code(cause),
            u32::from(joint),
            index_of(&STOPS, &stop),
            value.to_bits(),
        ),
        EventKind::Stop { reason, stop } => (
            2,
            index_of(&StopReason::ALL, &reason),
            0,
            index_of(&STOPS, &stop),
            0,
        ),
        EventKind::Reset { cause } => (3, index_of(&RESETS, &cause), 0, 0, 0),
        EventKind::Master { id } => (4, 0, 0, 0, id),
        EventKind::GeometryStored { version } => (5, 0, 0, 0, version),
        EventKind::RelayTest { pending } => (6, u32::from(pending), 0, 0, 0),
        EventKind::Lost { count } => (7, 0, 0, 0, count),
    }
}

fn kind_of(kind: u32, code: u32, joint: u32, stop: u32, value: u32) -> Option<EventKind> {
    let stop = STOPS.get(stop as usize).copied();
    Some(match kind {
        1 => EventKind::Fault {
            cause: cause_of(code)?,
            joint: u8::try_from(joint).ok()?,
            value: f32::from_bits(value),
            stop: stop?,
        },
        2 => EventKind::Stop {
            reason: StopReason::ALL.get(code as usize).copied()?,
            stop: stop?,
        },
        3 => EventKind::Reset {
            cause: RESETS.get(code as usize).copied()?,
        },
        4 => EventKind::Master { id: value },
        5 => EventKind::GeometryStored { version: value },
        6 => EventKind::RelayTest {
            pending: match code {
                0 => false,
                1 => true,
                _ => return None,
            },
        },
        7 => EventKind::Lost { count: value },
        _ => return None,
    })
}

fn crc(words: &[u32]) -> u32 {
    let mut digest = CRC32.digest();
    for w in words {
        digest.update(&w.to_le_bytes());
    }
    digest.finalize()
}

/// The words of a record (the serial is kept below 0xFFFF_FFFF by the writer).
#[inline(never)]
pub fn encode(r: &Record) -> [u32; RECORD_WORDS] {
    let e = &r.entry;
    let (kind, code, joint, stop, value) = fields(&e.event);
    let mut w = [
        r.serial,
        e.seq,
        e.time_ms,
        value,
        u32::from(e.boot) | (u32::from(e.count) << 16),
        kind | (code << 8) | (joint << 16) | (stop << 24) | (u32::from(e.relay_test_pending) << 28),
        r.entries,
        0,
    ];
    if let Some((last, body)) = w.split_last_mut() {
        *last = crc(body);
    }
    w
}

/// What the words of a slot hold.
#[inline(never)]
pub fn decode(w: &[u32; RECORD_WORDS]) -> Slot {
    if w.iter().all(|x| *x == ERASED) {
        return Slot::Erased;
    }
    let [serial, seq, time_ms, value, boot_count, packed, entries, check] = *w;
    if w.split_last().map(|(_, body)| crc(body)) != Some(check) {
        return Slot::Torn;
    }
    let flags = packed >> 28;
    let kind = kind_of(
        packed & 0xFF,
        (packed >> 8) & 0xFF,
        (packed >> 16) & 0xFF,
        (packed >> 24) & 0x0F,
        value,
    );
    match kind {
        Some(event) if flags <= 1 => Slot::Valid(Record {
            serial,
            entry: EventEntry {
                seq,
                boot: (boot_count & 0xFFFF) as u16,
                time_ms,
                event,
                count: (boot_count >> 16) as u16,
                relay_test_pending: flags == 1,
            },
            entries,
        }),
        _ => Slot::Torn,
    }
}
