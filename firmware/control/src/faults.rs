//! The fault log: a ring buffer of the faults the board detected, with when (ms since
//! boot), what (cause, joint, value), the stop it caused and how many times it repeated.
//! The master reads it page by page (`FaultLogRequest`); the board keeps the latest
//! entries across a watchdog reset in RAM that the start-up code does not clear
//! ([`Persisted`]: plain words with a checksum, so that garbage after a power-on is
//! recognised, never misread).

use master_link::{
    FaultCause, FaultLogEntry, FaultLogPage, FaultRecord, StopStatus, FAULT_LOG_PAGE,
};

/// Entries the log keeps (the oldest are overwritten).
pub const FAULT_LOG_LEN: usize = 32;

/// The fault log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultLog {
    entries: [FaultLogEntry; FAULT_LOG_LEN],
    /// Index of the oldest entry.
    head: usize,
    /// Entries kept.
    len: usize,
    /// Entries ever logged.
    total: u32,
}

impl Default for FaultLog {
    fn default() -> Self {
        Self::new()
    }
}

impl FaultLog {
    /// Empty.
    pub const fn new() -> Self {
        FaultLog {
            entries: [FaultLogEntry {
                record: FaultRecord::NONE,
                stop: StopStatus::None,
                count: 0,
            }; FAULT_LOG_LEN],
            head: 0,
            len: 0,
            total: 0,
        }
    }

    /// Logs a fault and the stop it caused. The same cause on the same joint as the newest
    /// entry counts as a repeat of it (its count goes up, saturating), so a fault that
    /// recurs every tick cannot flush the log.
    pub fn record(&mut self, record: FaultRecord, stop: StopStatus) {
        if let Some(last) = self.newest_mut() {
            if last.record.cause == record.cause && last.record.joint == record.joint {
                last.count = last.count.saturating_add(1);
                return;
            }
        }
        let slot = (self.head + self.len) % FAULT_LOG_LEN;
        if let Some(e) = self.entries.get_mut(slot) {
            *e = FaultLogEntry {
                record,
                stop,
                count: 1,
            };
        }
        if self.len < FAULT_LOG_LEN {
            self.len += 1;
        } else {
            self.head = (self.head + 1) % FAULT_LOG_LEN;
        }
        self.total = self.total.wrapping_add(1);
    }

    fn newest_mut(&mut self) -> Option<&mut FaultLogEntry> {
        if self.len == 0 {
            return None;
        }
        let i = (self.head + self.len - 1) % FAULT_LOG_LEN;
        self.entries.get_mut(i)
    }

    /// Entries kept.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Nothing logged.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Entries ever logged.
    pub fn total(&self) -> u32 {
        self.total
    }

    /// Entry `i`, oldest first.
    pub fn get(&self, i: usize) -> Option<&FaultLogEntry> {
        if i >= self.len {
            return None;
        }
        self.entries.get((self.head + i) % FAULT_LOG_LEN)
    }

    /// The newest entry.
    pub fn newest(&self) -> Option<&FaultLogEntry> {
        self.len.checked_sub(1).and_then(|i| self.get(i))
    }

    /// The page of entries from `first` (oldest = 0) for the master.
    pub fn page(&self, first: u16) -> FaultLogPage {
        let mut page = FaultLogPage {
            len: u16::try_from(self.len).unwrap_or(u16::MAX),
            total: self.total,
            first,
            ..FaultLogPage::default()
        };
        let mut count = 0u8;
        for (k, slot) in page.entries.iter_mut().enumerate().take(FAULT_LOG_PAGE) {
            match self.get(usize::from(first) + k) {
                Some(e) => {
                    *slot = *e;
                    count += 1;
                }
                None => break,
            }
        }
        page.count = count;
        page
    }

    /// The log as plain words (see [`Persisted`]).
    pub fn persist(&self, out: &mut Persisted) {
        let mut sum = PERSIST_MAGIC ^ self.total;
        out.magic = PERSIST_MAGIC;
        out.total = self.total;
        out.len = self.len as u32;
        for (i, w) in out.entries.iter_mut().enumerate() {
            *w = self.get(i).map_or([0; 4], encode_entry);
            for x in w.iter() {
                sum = sum.rotate_left(5) ^ *x;
            }
        }
        out.check = sum ^ out.len;
    }

    /// The log kept in `words`, if they hold a valid one (else None: power-on garbage, or a
    /// log of another firmware).
    pub fn restore(words: &Persisted) -> Option<Self> {
        if words.magic != PERSIST_MAGIC || words.len as usize > FAULT_LOG_LEN {
            return None;
        }
        let mut sum = PERSIST_MAGIC ^ words.total;
        for w in words.entries.iter() {
            for x in w.iter() {
                sum = sum.rotate_left(5) ^ *x;
            }
        }
        if sum ^ words.len != words.check {
            return None;
        }
        let mut log = FaultLog::new();
        for w in words.entries.iter().take(words.len as usize) {
            let e = decode_entry(w)?;
            if let Some(slot) = log.entries.get_mut(log.len) {
                *slot = e;
                log.len += 1;
            }
        }
        log.total = words.total;
        Some(log)
    }
}

/// The fault log as plain 32-bit words, for RAM that survives a watchdog reset (not
/// cleared at start-up): any bit pattern is a valid `Persisted`, and [`FaultLog::restore`]
/// accepts only one written by [`FaultLog::persist`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Persisted {
    /// [`PERSIST_MAGIC`].
    pub magic: u32,
    /// Entries ever logged.
    pub total: u32,
    /// Entries kept, oldest first in `entries`.
    pub len: u32,
    /// Entries: cause and joint and stop, value bits, time, count.
    pub entries: [[u32; 4]; FAULT_LOG_LEN],
    /// Checksum of the rest.
    pub check: u32,
}

impl Persisted {
    /// All zero (not a valid log).
    pub const ZERO: Persisted = Persisted {
        magic: 0,
        total: 0,
        len: 0,
        entries: [[0; 4]; FAULT_LOG_LEN],
        check: 0,
    };
}

/// Marks a persisted log of this layout.
pub const PERSIST_MAGIC: u32 = 0x464C_4F47; // "FLOG"

/// A fault cause's code in a persisted record (0: none; then `FaultCause::ALL`'s order),
/// shared by the fault log and the event log.
pub(crate) fn cause_code(c: FaultCause) -> u32 {
    FaultCause::ALL
        .iter()
        .position(|x| *x == c)
        .map_or(0, |i| i as u32 + 1)
}

/// The cause of a persisted code (`None`: not a code of this firmware).
pub(crate) fn cause_of(code: u32) -> Option<FaultCause> {
    match code {
        0 => Some(FaultCause::None),
        n => FaultCause::ALL.get(n as usize - 1).copied(),
    }
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

fn encode_entry(e: &FaultLogEntry) -> [u32; 4] {
    let stop = STOPS.iter().position(|s| *s == e.stop).unwrap_or(0) as u32;
    [
        cause_code(e.record.cause) | (u32::from(e.record.joint) << 8) | (stop << 16),
        e.record.value.to_bits(),
        e.record.time_ms,
        u32::from(e.count),
    ]
}

fn decode_entry(w: &[u32; 4]) -> Option<FaultLogEntry> {
    let [a, value, time_ms, count] = *w;
    Some(FaultLogEntry {
        record: FaultRecord {
            cause: cause_of(a & 0xFF)?,
            joint: ((a >> 8) & 0xFF) as u8,
            value: f32::from_bits(value),
            time_ms,
        },
        stop: *STOPS.get(((a >> 16) & 0xFF) as usize)?,
        count: u16::try_from(count).ok()?,
    })
}
