//! The event log as the runtime keeps it: the newest [`EVENT_VIEW`] entries in RAM, each
//! with the count the flash holds of it, the boot counter and the entry counter. The
//! runtime records into it; the link reads it page by page; the target's writer takes the
//! entries whose count the flash does not hold yet ([`EventLog::pending`]) and marks them
//! stored ([`EventLog::mark_stored`]). [`KeptEvents`] is its image in RAM that a watchdog
//! reset keeps.

use master_link::{EventEntry, EventKind, EventLogPage, EVENT_LOG_PAGE};

use super::record::{self, Record, Slot, RECORD_WORDS};

/// Entries the RAM view holds (the flash holds many more; an entry that leaves the view
/// before its count reached the flash is lost, and counted).
pub const EVENT_VIEW: usize = 32;

/// An entry of the view and the count of it the flash holds (0: none yet).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewEntry {
    /// The entry.
    pub entry: EventEntry,
    /// Its count in flash.
    pub stored: u16,
}

impl ViewEntry {
    const EMPTY: ViewEntry = ViewEntry {
        entry: EventEntry::EMPTY,
        stored: 0,
    };
    /// The flash does not hold this count yet.
    pub fn pending(&self) -> bool {
        self.entry.count != self.stored
    }
}

/// Whether a new event is a repeat of `older` (an entry of the same kind, the newest of its
/// kind): the same fault (cause and joint), stop reason, master, geometry version or relay
/// test state. A reset or a lost count is never a repeat.
fn repeats(older: &EventKind, new: &EventKind) -> bool {
    match (older, new) {
        (
            EventKind::Fault {
                cause: c0,
                joint: j0,
                ..
            },
            EventKind::Fault {
                cause: c1,
                joint: j1,
                ..
            },
        ) => c0 == c1 && j0 == j1,
        (EventKind::Stop { reason: r0, .. }, EventKind::Stop { reason: r1, .. }) => r0 == r1,
        (EventKind::Master { id: a }, EventKind::Master { id: b }) => a == b,
        (EventKind::GeometryStored { version: a }, EventKind::GeometryStored { version: b }) => {
            a == b
        }
        (EventKind::RelayTest { pending: a }, EventKind::RelayTest { pending: b }) => a == b,
        _ => false,
    }
}

fn same_kind(a: &EventKind, b: &EventKind) -> bool {
    core::mem::discriminant(a) == core::mem::discriminant(b)
}

/// The event log's RAM view (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EventLog {
    slots: [ViewEntry; EVENT_VIEW],
    /// Index of the oldest entry.
    head: usize,
    /// Entries held.
    len: usize,
    /// This boot's number (0: none started).
    boot: u16,
    /// The next entry's seq (entries ever logged).
    next_seq: u32,
    /// Entries of this boot that left the view before the flash held them.
    lost: u32,
    /// Lost entries not yet recorded as a `Lost` entry.
    unlogged_lost: u32,
    /// The safety chain's relay test is pending (stamped on every entry recorded).
    relay_test_pending: bool,
    /// Changes so far (a new entry, a repeat, a stored mark): the target keeps the view
    /// across a watchdog reset when it changed.
    changes: u32,
}

impl Default for EventLog {
    fn default() -> Self {
        Self::new()
    }
}

impl EventLog {
    /// Empty, no boot started, nothing in flash.
    pub const fn new() -> Self {
        EventLog {
            slots: [ViewEntry::EMPTY; EVENT_VIEW],
            head: 0,
            len: 0,
            boot: 0,
            next_seq: 0,
            lost: 0,
            unlogged_lost: 0,
            relay_test_pending: false,
            changes: 0,
        }
    }

    /// The view of what the flash holds: `entries` (oldest first; the newest
    /// [`EVENT_VIEW`] are kept, each stored), the last boot, the entry counter and the relay
    /// test's state of the newest record.
    pub fn from_flash(
        entries: &[EventEntry],
        last_boot: u16,
        next_seq: u32,
        relay_test_pending: bool,
    ) -> Self {
        let mut log = EventLog {
            boot: last_boot,
            next_seq,
            relay_test_pending,
            ..EventLog::new()
        };
        let skip = entries.len().saturating_sub(EVENT_VIEW);
        for e in entries.iter().skip(skip) {
            log.push(ViewEntry {
                entry: *e,
                stored: e.count,
            });
        }
        log
    }

    /// A new boot begins: the boot counter goes up and this boot's lost count starts at 0
    /// (lost entries not yet recorded stay to be recorded).
    pub fn start_boot(&mut self) {
        self.boot = self.boot.wrapping_add(1);
        self.lost = 0;
        self.changes = self.changes.wrapping_add(1);
    }

    fn index(&self, i: usize) -> usize {
        (self.head + i) % EVENT_VIEW
    }

    /// Appends `v` as the newest entry; the oldest leaves a full view (counted lost when
    /// the flash did not hold its count yet).
    fn push(&mut self, v: ViewEntry) {
        let at = self.index(self.len);
        if self.len == EVENT_VIEW {
            if self.slots.get(at).is_some_and(ViewEntry::pending) {
                self.lost = self.lost.saturating_add(1);
                self.unlogged_lost = self.unlogged_lost.saturating_add(1);
            }
            self.head = (self.head + 1) % EVENT_VIEW;
        } else {
            self.len += 1;
        }
        if let Some(s) = self.slots.get_mut(at) {
            *s = v;
        }
        self.changes = self.changes.wrapping_add(1);
    }

    /// Records `event` at `time_ms` of this boot: a repeat of the newest entry of its kind
    /// in this boot counts on that entry (saturating), anything else is a new entry. The
    /// entry's seq.
    pub fn record(&mut self, event: EventKind, time_ms: u32) -> u32 {
        let boot = self.boot;
        let newest_of_kind = (0..self.len).rev().map(|i| self.index(i)).find(|&k| {
            self.slots
                .get(k)
                .is_some_and(|s| same_kind(&s.entry.event, &event))
        });
        if let Some(slot) = newest_of_kind.and_then(|k| self.slots.get_mut(k)) {
            if slot.entry.boot == boot && repeats(&slot.entry.event, &event) {
                slot.entry.count = slot.entry.count.saturating_add(1);
                self.changes = self.changes.wrapping_add(1);
                return slot.entry.seq;
            }
        }
        let seq = self.next_seq;
        self.next_seq = self.next_seq.wrapping_add(1);
        self.push(ViewEntry {
            entry: EventEntry {
                seq,
                boot,
                time_ms,
                event,
                count: 1,
                relay_test_pending: self.relay_test_pending,
            },
            stored: 0,
        });
        seq
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Nothing held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Entry `i`, oldest first, with its count in flash.
    pub fn get(&self, i: usize) -> Option<&ViewEntry> {
        if i >= self.len {
            return None;
        }
        self.slots.get(self.index(i))
    }
    /// The newest entry.
    pub fn newest(&self) -> Option<&EventEntry> {
        self.len
            .checked_sub(1)
            .and_then(|i| self.get(i))
            .map(|v| &v.entry)
    }
    /// The entries, oldest first.
    pub fn entries(&self) -> impl Iterator<Item = &EventEntry> + '_ {
        (0..self.len).filter_map(|i| self.get(i)).map(|v| &v.entry)
    }
    /// This boot's number (0: none started).
    pub fn boot(&self) -> u16 {
        self.boot
    }
    /// The next entry's seq (entries ever logged).
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }
    /// Entries of this boot that left the view before the flash held them.
    pub fn lost(&self) -> u32 {
        self.lost
    }
    /// Changes so far (see [`KeptEvents`]).
    pub fn changes(&self) -> u32 {
        self.changes
    }
    /// The safety chain's relay test is pending, as the newest entry says (at boot: the
    /// last power cycle's state; then the runtime's).
    pub fn relay_test_pending(&self) -> bool {
        self.relay_test_pending
    }
    /// Sets the relay test's state stamped on the entries recorded from now on.
    pub fn set_relay_test_pending(&mut self, pending: bool) {
        if self.relay_test_pending != pending {
            self.relay_test_pending = pending;
            self.changes = self.changes.wrapping_add(1);
        }
    }

    /// The oldest entry whose count the flash does not hold yet.
    pub fn pending(&self) -> Option<EventEntry> {
        (0..self.len)
            .filter_map(|i| self.get(i))
            .find(|v| v.pending())
            .map(|v| v.entry)
    }
    /// Entries whose count the flash does not hold yet.
    pub fn pending_len(&self) -> usize {
        (0..self.len)
            .filter_map(|i| self.get(i))
            .filter(|v| v.pending())
            .count()
    }
    /// The flash holds entry `seq` with `count` (a record written whole).
    pub fn mark_stored(&mut self, seq: u32, count: u16) {
        let k = (0..self.len)
            .map(|i| self.index(i))
            .find(|&k| self.slots.get(k).is_some_and(|s| s.entry.seq == seq));
        if let Some(s) = k.and_then(|k| self.slots.get_mut(k)) {
            s.stored = s.stored.max(count);
            self.changes = self.changes.wrapping_add(1);
        }
    }
    /// Records the lost entries not recorded yet as one `Lost` entry (when the flash has
    /// caught up), at `time_ms`.
    pub fn record_lost(&mut self, time_ms: u32) {
        if self.unlogged_lost > 0 {
            let count = core::mem::take(&mut self.unlogged_lost);
            self.record(EventKind::Lost { count }, time_ms);
        }
    }

    /// The page of entries from `first` (oldest held = 0) for the master.
    pub fn page(&self, first: u16) -> EventLogPage {
        let mut page = EventLogPage {
            len: u16::try_from(self.len).unwrap_or(u16::MAX),
            total: self.next_seq,
            first,
            lost: self.lost,
            ..EventLogPage::default()
        };
        let mut count = 0u8;
        for (k, slot) in page.entries.iter_mut().enumerate().take(EVENT_LOG_PAGE) {
            match self.get(usize::from(first) + k) {
                Some(v) => {
                    *slot = v.entry;
                    count += 1;
                }
                None => break,
            }
        }
        page.count = count;
        page
    }

    /// The view as plain words (see [`KeptEvents`]).
    #[inline(never)]
    pub fn persist(&self, out: &mut KeptEvents) {
        out.magic = KEPT_MAGIC;
        out.boot = u32::from(self.boot);
        out.next_seq = self.next_seq;
        out.lost = self.lost;
        out.unlogged_lost = self.unlogged_lost;
        out.flags = u32::from(self.relay_test_pending);
        out.len = self.len as u32;
        for (i, w) in out.entries.iter_mut().enumerate() {
            *w = self.get(i).map_or([record::ERASED; RECORD_WORDS], |v| {
                record::encode(&Record {
                    serial: u32::from(v.stored),
                    entry: v.entry,
                    entries: self.next_seq,
                })
            });
        }
        out.check = out.checksum();
    }

    /// The view kept in `words`, if they hold a valid one (else None: power-on garbage, a
    /// view of another firmware).
    #[inline(never)]
    pub fn restore(words: &KeptEvents) -> Option<Self> {
        if words.magic != KEPT_MAGIC
            || words.len as usize > EVENT_VIEW
            || words.flags > 1
            || words.check != words.checksum()
        {
            return None;
        }
        let mut log = EventLog {
            boot: u16::try_from(words.boot).ok()?,
            next_seq: words.next_seq,
            lost: words.lost,
            unlogged_lost: words.unlogged_lost,
            relay_test_pending: words.flags == 1,
            ..EventLog::new()
        };
        for w in words.entries.iter().take(words.len as usize) {
            let Slot::Valid(r) = record::decode(w) else {
                return None;
            };
            log.push(ViewEntry {
                entry: r.entry,
                stored: u16::try_from(r.serial).ok()?,
            });
        }
        log.lost = words.lost;
        log.unlogged_lost = words.unlogged_lost;
        log.changes = 0;
        Some(log)
    }
}

/// Marks kept words of this layout.
pub const KEPT_MAGIC: u32 = 0x4556_4C47; // "EVLG"

/// The event log's view as plain 32-bit words, for RAM that a watchdog reset keeps (not
/// cleared at start-up): any bit pattern is a valid `KeptEvents`, and
/// [`EventLog::restore`] accepts only one [`EventLog::persist`] wrote. Each entry is a
/// flash record whose serial word holds the count the flash held of it.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeptEvents {
    /// [`KEPT_MAGIC`].
    pub magic: u32,
    /// The boot.
    pub boot: u32,
    /// The next entry's seq.
    pub next_seq: u32,
    /// Lost in this boot.
    pub lost: u32,
    /// Lost, not yet recorded.
    pub unlogged_lost: u32,
    /// Bit 0: the relay test is pending.
    pub flags: u32,
    /// Entries held, oldest first in `entries`.
    pub len: u32,
    /// The entries.
    pub entries: [[u32; RECORD_WORDS]; EVENT_VIEW],
    /// Checksum of the rest.
    pub check: u32,
}

impl KeptEvents {
    /// All zero (not a valid view).
    pub const ZERO: KeptEvents = KeptEvents {
        magic: 0,
        boot: 0,
        next_seq: 0,
        lost: 0,
        unlogged_lost: 0,
        flags: 0,
        len: 0,
        entries: [[0; RECORD_WORDS]; EVENT_VIEW],
        check: 0,
    };

    fn checksum(&self) -> u32 {
        let head = [
            self.magic,
            self.boot,
            self.next_seq,
            self.lost,
            self.unlogged_lost,
            self.flags,
            self.len,
        ];
        head.iter()
            .chain(self.entries.iter().flatten())
            .fold(KEPT_MAGIC, |sum, x| sum.rotate_left(5) ^ *x)
    }
}
