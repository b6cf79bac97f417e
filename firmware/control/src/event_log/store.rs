//! The event log in flash: a ring of erasable sectors (at least two), each a sequence of
//! [`RECORD_LEN`]-byte slots written in order, never rewritten until the sector is erased.
//!
//! * **Append**: the writer takes the oldest entry of the RAM view whose count the flash
//!   does not hold ([`EventLog::pending`]) and programs it as one record into the active
//!   sector's next slot, a few words per call ([`EventStore::step`]), the CRC word last.
//!   A repeat writes its entry again (same seq, the new count): the newest record of a
//!   seq wins.
//! * **Rotation**: when the active sector is full, the next sector of the ring is erased
//!   (its records, the oldest, are dropped) and becomes the active one. An erase runs only
//!   when the caller allows it (`may_erase`: the drives off and the brakes applied); until
//!   then the entries wait in the view.
//! * **Mount** ([`mount`]): in each sector, the first erased slot by bisection (slots are
//!   written in order, so the written ones come first), then backwards to its newest valid
//!   record; the active sector is the one whose newest record has the largest serial.
//!   From the newest records backwards, the newest [`EVENT_VIEW`] distinct entries (the
//!   first record met of a seq is its newest count) make the RAM view; the entry counter
//!   comes from the newest record, the boot counter is the largest boot among them, the
//!   relay test's state the newest entry's.
//! * **A cut at any instant** leaves a torn record (not erased, CRC wrong) that every read
//!   skips and the writer never reuses, and every earlier record valid; a cut during an
//!   erase leaves the sector being erased in any state, which only a rotation uses, and
//!   it erases first.

use master_link::EventEntry;

use super::log::{EventLog, EVENT_VIEW};
use super::record::{self, Record, Slot, RECORD_LEN, RECORD_WORDS};
use crate::geometry_store::FlashError;

/// The event log's flash sectors (the target's driver).
pub trait EventFlash {
    /// Sectors in the ring (2 to [`MAX_SECTORS`]).
    fn sectors(&self) -> usize;
    /// Bytes per sector.
    fn sector_len(&self) -> usize;
    /// Reads the record-sized words at `offset` (a multiple of [`RECORD_LEN`]) of `sector`.
    fn read(
        &mut self,
        sector: usize,
        offset: usize,
        out: &mut [u32; RECORD_WORDS],
    ) -> Result<(), FlashError>;
    /// Programs `words` at `offset` (a multiple of 4) of `sector`; they were erased.
    fn program(&mut self, sector: usize, offset: usize, words: &[u32]) -> Result<(), FlashError>;
    /// Erases `sector` (every word reads 0xFFFF_FFFF).
    fn erase(&mut self, sector: usize) -> Result<(), FlashError>;
}

/// Consecutive failed operations after which the writer gives up for this boot.
pub const GIVE_UP_AFTER: u32 = 8;

/// The most sectors a ring may have.
pub const MAX_SECTORS: usize = 4;

/// A record being programmed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Writing {
    words: [u32; RECORD_WORDS],
    done: usize,
    seq: u32,
    count: u16,
}

/// What one call of [`EventStore::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Nothing to write.
    Idle,
    /// Programmed words; `record_done`: the record is whole (its CRC written).
    Programmed {
        /// Words programmed.
        words: usize,
        /// The record is whole.
        record_done: bool,
    },
    /// The active sector is full (or must be erased first): waiting for a call that may
    /// erase.
    Waiting,
    /// Erased `sector`, the active one from now on (the long operation).
    Erased {
        /// The sector.
        sector: usize,
    },
    /// The flash refused an operation (the slot is skipped, the record written again).
    Failed(FlashError),
    /// The writer gave up after [`GIVE_UP_AFTER`] failures in a row.
    GaveUp,
}

/// The writer of the event log's flash ring (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EventStore {
    sectors: usize,
    slots: usize,
    active: usize,
    /// The next slot of the active sector.
    next: usize,
    /// The next record's serial.
    serial: u32,
    /// The active sector holds something other than records: erase it before writing.
    erase_first: bool,
    writing: Option<Writing>,
    failures_in_row: u32,
    failures: u32,
    written: u32,
    erases: u32,
}

impl EventStore {
    /// The active sector and its next slot.
    pub fn position(&self) -> (usize, usize) {
        (self.active, self.next)
    }
    /// Slots per sector.
    pub fn slots_per_sector(&self) -> usize {
        self.slots
    }
    /// Records written whole since boot.
    pub fn written(&self) -> u32 {
        self.written
    }
    /// Sectors erased since boot.
    pub fn erases(&self) -> u32 {
        self.erases
    }
    /// Failed operations since boot.
    pub fn failures(&self) -> u32 {
        self.failures
    }
    /// A record is half written.
    pub fn busy(&self) -> bool {
        self.writing.is_some()
    }
    /// The next write needs an erase first (the active sector is full, or was never
    /// erased).
    pub fn needs_erase(&self) -> bool {
        self.erase_first || self.next >= self.slots
    }

    fn fail(&mut self, e: FlashError) -> Step {
        self.failures = self.failures.saturating_add(1);
        self.failures_in_row = self.failures_in_row.saturating_add(1);
        Step::Failed(e)
    }

    /// Erases the sector the next write needs, if it needs one (at boot, with the drives
    /// off): the sector erased.
    pub fn prepare<F: EventFlash>(&mut self, flash: &mut F) -> Result<Option<usize>, FlashError> {
        if self.writing.is_some() || !self.needs_erase() {
            return Ok(None);
        }
        let target = if self.erase_first {
            self.active
        } else {
            (self.active + 1) % self.sectors
        };
        flash.erase(target)?;
        self.active = target;
        self.next = 0;
        self.erase_first = false;
        self.erases = self.erases.saturating_add(1);
        Ok(Some(target))
    }

    /// Programs at most `words` words of the oldest pending entry of `log` (a new record
    /// is started when none is half written; `words` 0: nothing is programmed); when the
    /// sector is full and `may_erase`, erases the next one instead (and programs nothing).
    /// With nothing pending, records the entries lost so far as a `Lost` entry at `now_ms`
    /// first.
    pub fn step<F: EventFlash>(
        &mut self,
        flash: &mut F,
        log: &mut EventLog,
        now_ms: u32,
        words: usize,
        may_erase: bool,
    ) -> Step {
        if self.failures_in_row >= GIVE_UP_AFTER {
            return Step::GaveUp;
        }
        if self.writing.is_none() {
            if log.pending().is_none() {
                log.record_lost(now_ms);
            }
            let Some(entry) = log.pending() else {
                return Step::Idle;
            };
            if self.needs_erase() {
                if !may_erase {
                    return Step::Waiting;
                }
                return match self.prepare(flash) {
                    Ok(Some(sector)) => {
                        self.failures_in_row = 0;
                        Step::Erased { sector }
                    }
                    Ok(None) => Step::Idle,
                    Err(e) => self.fail(e),
                };
            }
            if words == 0 {
                return Step::Idle;
            }
            let record = Record {
                serial: self.serial,
                entry,
                entries: log.next_seq(),
            };
            self.serial = self.serial.wrapping_add(1) % record::ERASED;
            self.writing = Some(Writing {
                words: record::encode(&record),
                done: 0,
                seq: entry.seq,
                count: entry.count,
            });
        }
        let Some(w) = self.writing.as_mut().filter(|_| words > 0) else {
            return Step::Idle;
        };
        let n = words.min(RECORD_WORDS - w.done);
        let offset = self.next * RECORD_LEN + 4 * w.done;
        let Some(chunk) = w.words.get(w.done..w.done + n) else {
            self.writing = None;
            return Step::Idle;
        };
        if let Err(e) = flash.program(self.active, offset, chunk) {
            // The slot may hold part of the record: skip it, write the record again.
            self.writing = None;
            self.next += 1;
            return self.fail(e);
        }
        self.failures_in_row = 0;
        w.done += n;
        if w.done < RECORD_WORDS {
            return Step::Programmed {
                words: n,
                record_done: false,
            };
        }
        let (seq, count) = (w.seq, w.count);
        self.writing = None;
        self.next += 1;
        self.written = self.written.saturating_add(1);
        log.mark_stored(seq, count);
        Step::Programmed {
            words: n,
            record_done: true,
        }
    }
}

#[inline(never)]
fn read_slot<F: EventFlash>(flash: &mut F, sector: usize, slot: usize) -> Result<Slot, FlashError> {
    let mut w = [0u32; RECORD_WORDS];
    flash.read(sector, slot * RECORD_LEN, &mut w)?;
    Ok(record::decode(&w))
}

/// The first erased slot of `sector`, assuming the written slots come first.
fn first_erased<F: EventFlash>(
    flash: &mut F,
    sector: usize,
    slots: usize,
) -> Result<usize, FlashError> {
    let (mut lo, mut hi) = (0, slots);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if read_slot(flash, sector, mid)? == Slot::Erased {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    Ok(lo)
}

/// Sector `sector`'s newest valid record below slot `end`.
fn newest_below<F: EventFlash>(
    flash: &mut F,
    sector: usize,
    end: usize,
) -> Result<Option<Record>, FlashError> {
    for slot in (0..end).rev() {
        if let Slot::Valid(r) = read_slot(flash, sector, slot)? {
            return Ok(Some(r));
        }
    }
    Ok(None)
}

/// Reads the flash at boot: the writer positioned after the newest record, and the RAM
/// view of the newest entries (see the module documentation). A new boot is not started
/// here ([`super::boot`] does).
#[inline(never)]
pub fn mount<F: EventFlash>(flash: &mut F) -> Result<(EventStore, EventLog), FlashError> {
    let sectors = flash.sectors();
    let slots = flash.sector_len() / RECORD_LEN;
    if !(2..=MAX_SECTORS).contains(&sectors) || slots == 0 {
        return Err(FlashError::Driver);
    }
    // Each sector's write position and newest record, newest sector first.
    let mut order: [(usize, usize, Option<u32>); MAX_SECTORS] = [(0, 0, None); MAX_SECTORS];
    let mut known = 0;
    let mut newest: Option<Record> = None;
    let mut active = None;
    for s in 0..sectors {
        let end = first_erased(flash, s, slots)?;
        let r = newest_below(flash, s, end)?;
        if let Some(r) = r {
            if newest.is_none_or(|n| r.serial > n.serial) {
                newest = Some(r);
                active = Some((s, end));
            }
        }
        if let Some(o) = order.get_mut(known) {
            *o = (s, end, r.map(|r| r.serial));
            known += 1;
        }
    }
    let order = order.get_mut(..known).unwrap_or_default();
    // Newest sector first (a few sectors: insertion sort).
    for i in 1..order.len() {
        let mut j = i;
        while j > 0 && order.get(j - 1).map(|x| x.2) < order.get(j).map(|x| x.2) {
            order.swap(j - 1, j);
            j -= 1;
        }
    }
    let (active, next, erase_first) = match active {
        Some((s, end)) => (s, end, false),
        None => {
            // Nothing valid anywhere: the first sector is used, erased first unless it is.
            let mut blank = true;
            for slot in 0..slots {
                if read_slot(flash, 0, slot)? != Slot::Erased {
                    blank = false;
                    break;
                }
            }
            (0, 0, !blank)
        }
    };
    let store = EventStore {
        sectors,
        slots,
        active,
        next,
        serial: newest.map_or(0, |r| r.serial.wrapping_add(1) % record::ERASED),
        erase_first,
        writing: None,
        failures_in_row: 0,
        failures: 0,
        written: 0,
        erases: 0,
    };
    // The newest distinct entries, newest record first.
    let mut view = [EventEntry::EMPTY; EVENT_VIEW];
    let mut n = 0;
    'sectors: for &(s, end, serial) in order.iter() {
        if serial.is_none() {
            continue;
        }
        for slot in (0..end).rev() {
            let Slot::Valid(r) = read_slot(flash, s, slot)? else {
                continue;
            };
            let known = view.get(..n).unwrap_or_default();
            if known.iter().any(|e| e.seq == r.entry.seq) {
                continue;
            }
            if let Some(v) = view.get_mut(n) {
                *v = r.entry;
                n += 1;
            }
            if n == EVENT_VIEW {
                break 'sectors;
            }
        }
    }
    let view = view.get_mut(..n).unwrap_or_default();
    // Oldest entry first (at most EVENT_VIEW: insertion sort).
    for i in 1..view.len() {
        let mut j = i;
        while j > 0 && view.get(j - 1).map(|e| e.seq) > view.get(j).map(|e| e.seq) {
            view.swap(j - 1, j);
            j -= 1;
        }
    }
    let last_boot = view.iter().map(|e| e.boot).max().unwrap_or(0);
    let relay = view.last().is_some_and(|e| e.relay_test_pending);
    let next_seq = newest
        .map_or(0, |r| r.entries)
        .max(view.last().map_or(0, |e| e.seq.wrapping_add(1)));
    Ok((
        store,
        EventLog::from_flash(view, last_boot, next_seq, relay),
    ))
}

/// Visits every slot of every sector up to its first erased one (the written part):
/// `visit(sector, slot, what it holds)`. For tools that dump the flash (and tests).
pub fn scan<F: EventFlash>(
    flash: &mut F,
    mut visit: impl FnMut(usize, usize, Slot),
) -> Result<(), FlashError> {
    let slots = flash.sector_len() / RECORD_LEN;
    for s in 0..flash.sectors() {
        let end = first_erased(flash, s, slots)?;
        for slot in 0..end {
            visit(s, slot, read_slot(flash, s, slot)?);
        }
    }
    Ok(())
}
