#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The event log's format, its RAM view and its flash ring: every kind round-trips through
//! a record; repeats count on their entry and the count reaches the flash; a torn write
//! (cut at any byte, any bit of the byte being programmed) leaves every earlier record
//! readable and the writer going on; a cut erase leaves the other sector's records; the
//! ring drops the oldest and keeps its size; an erase waits for permission; the view kept
//! across a watchdog reset round-trips and garbage is refused; a boot counts up and keeps
//! the relay test's latch.

use control::event_log::record::{self, Record, Slot, RECORD_LEN, RECORD_WORDS};
use control::event_log::{
    boot, mount, scan, EventFlash, EventLog, EventStore, KeptEvents, Step, EVENT_VIEW,
};
use control::geometry_store::FlashError;
use master_link::{
    EventEntry, EventKind, FaultCause, ResetCause, StopReason, StopStatus, NO_JOINT,
};
use proptest::prelude::*;

/// NOR flash in RAM: erased to all ones, programming clears bits only. A cut (the power
/// lost) after `budget` more bytes programmed: the byte being programmed when it runs out
/// gets only the bits `partial` allows cleared, the rest of the operation nothing, and
/// every later operation fails.
#[derive(Clone, Debug)]
struct Nor {
    sectors: Vec<Vec<u8>>,
    budget: Option<usize>,
    partial: u8,
    cut: bool,
    erases: usize,
}

impl Nor {
    fn new(sectors: usize, sector_len: usize) -> Self {
        Nor {
            sectors: vec![vec![0xFF; sector_len]; sectors],
            budget: None,
            partial: 0xFF,
            cut: false,
            erases: 0,
        }
    }
    /// The same contents after a power cycle (no cut pending).
    fn powered_again(&self) -> Self {
        Nor {
            budget: None,
            cut: false,
            ..self.clone()
        }
    }
}

impl EventFlash for Nor {
    fn sectors(&self) -> usize {
        self.sectors.len()
    }
    fn sector_len(&self) -> usize {
        self.sectors[0].len()
    }
    fn read(
        &mut self,
        sector: usize,
        offset: usize,
        out: &mut [u32; RECORD_WORDS],
    ) -> Result<(), FlashError> {
        let s = self.sectors.get(sector).ok_or(FlashError::Driver)?;
        for (k, w) in out.iter_mut().enumerate() {
            let at = offset + 4 * k;
            let b = s.get(at..at + 4).ok_or(FlashError::Driver)?;
            *w = u32::from_le_bytes(b.try_into().unwrap());
        }
        Ok(())
    }
    fn program(&mut self, sector: usize, offset: usize, words: &[u32]) -> Result<(), FlashError> {
        if self.cut {
            return Err(FlashError::Driver);
        }
        let s = self.sectors.get_mut(sector).ok_or(FlashError::Driver)?;
        for (k, w) in words.iter().enumerate() {
            for (i, b) in w.to_le_bytes().iter().enumerate() {
                let at = offset + 4 * k + i;
                if let Some(left) = self.budget.as_mut() {
                    if *left == 0 {
                        // The byte being programmed as the power goes: some bits.
                        s[at] &= *b | self.partial;
                        self.cut = true;
                        return Err(FlashError::Driver);
                    }
                    *left -= 1;
                }
                s[at] &= *b;
            }
        }
        Ok(())
    }
    fn erase(&mut self, sector: usize) -> Result<(), FlashError> {
        if self.cut {
            return Err(FlashError::Driver);
        }
        self.erases += 1;
        self.sectors
            .get_mut(sector)
            .ok_or(FlashError::Driver)?
            .fill(0xFF);
        Ok(())
    }
}

fn fault(cause: FaultCause, joint: u8) -> EventKind {
    EventKind::Fault {
        cause,
        joint,
        value: 1.5,
        stop: StopStatus::SafeTorqueOff,
    }
}

/// Every kind of event, with the values of its fields.
fn kinds() -> Vec<EventKind> {
    let mut v: Vec<EventKind> = FaultCause::ALL
        .iter()
        .map(|c| EventKind::Fault {
            cause: *c,
            joint: 3,
            value: -2.25e-3,
            stop: StopStatus::SafeStop1Braking,
        })
        .collect();
    v.extend(StopReason::ALL.iter().map(|r| EventKind::Stop {
        reason: *r,
        stop: StopStatus::SafeStop2Decelerating,
    }));
    v.extend(
        [
            ResetCause::PowerOn,
            ResetCause::Pin,
            ResetCause::Software,
            ResetCause::Watchdog,
            ResetCause::WindowWatchdog,
            ResetCause::BrownOut,
            ResetCause::LowPower,
        ]
        .map(|cause| EventKind::Reset { cause }),
    );
    v.extend([
        EventKind::Master { id: 0xDEAD_BEEF },
        EventKind::GeometryStored { version: 7 },
        EventKind::RelayTest { pending: true },
        EventKind::RelayTest { pending: false },
        EventKind::Lost { count: 12 },
        fault(FaultCause::Internal, NO_JOINT),
    ]);
    v
}

/// Every record written whole, newest count per seq, by a scan of the flash.
fn on_flash(nor: &mut Nor) -> Vec<Record> {
    let mut all: Vec<Record> = Vec::new();
    scan(nor, |_, _, slot| {
        if let Slot::Valid(r) = slot {
            all.push(r);
        }
    })
    .unwrap();
    all.sort_by_key(|r| r.serial);
    all
}

/// Steps the writer until nothing is pending (erases allowed), at most `periods`.
fn drain(store: &mut EventStore, nor: &mut Nor, log: &mut EventLog, periods: usize) {
    for _ in 0..periods {
        if store.step(nor, log, 0, 2, true) == Step::Idle {
            return;
        }
    }
}

/// Every kind of event is written as a record and read back as it was (a torn copy, one
/// bit flipped in any word, is refused).
#[test]
fn every_kind_round_trips_through_a_record() {
    for (i, event) in kinds().into_iter().enumerate() {
        let r = Record {
            serial: 40 + i as u32,
            entry: EventEntry {
                seq: 1000 + i as u32,
                boot: 12,
                time_ms: 123_456,
                event,
                count: 3,
                relay_test_pending: i % 2 == 0,
            },
            entries: 2000,
        };
        let w = record::encode(&r);
        assert_eq!(record::decode(&w), Slot::Valid(r), "{event:?}");
        for k in 0..RECORD_WORDS {
            let mut bad = w;
            bad[k] ^= 1 << (k * 3);
            assert_eq!(record::decode(&bad), Slot::Torn, "{event:?}, word {k}");
        }
    }
    assert_eq!(record::decode(&[u32::MAX; RECORD_WORDS]), Slot::Erased);
    assert_eq!(RECORD_LEN, 32);
}

/// A repeat of the newest entry of its kind in the same boot counts on it (not a new
/// entry), the flash gets the new count, and a mount reads the count back; in the next
/// boot the same fault is a new entry.
#[test]
fn repeats_count_on_their_entry_and_the_count_reaches_the_flash() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    assert_eq!(log.boot(), 1);
    log.record(
        EventKind::Reset {
            cause: ResetCause::PowerOn,
        },
        0,
    );
    let a = log.record(fault(FaultCause::Overcurrent, 2), 10);
    drain(&mut store, &mut nor, &mut log, 100);
    // A stop in between is of another kind: the fault still repeats.
    log.record(
        EventKind::Stop {
            reason: StopReason::Disable,
            stop: StopStatus::SafeStop1Decelerating,
        },
        20,
    );
    assert_eq!(log.record(fault(FaultCause::Overcurrent, 2), 30), a);
    assert_eq!(log.record(fault(FaultCause::Overcurrent, 2), 40), a);
    // Another joint is another fault.
    let b = log.record(fault(FaultCause::Overcurrent, 4), 50);
    assert_ne!(a, b);
    assert_eq!(log.len(), 4);
    assert_eq!(
        log.pending_len(),
        3,
        "the repeated fault, the stop, the new fault"
    );
    drain(&mut store, &mut nor, &mut log, 100);
    assert_eq!(log.pending_len(), 0);
    let (_, mounted) = mount(&mut nor.powered_again()).unwrap();
    let counts: Vec<(u32, u16)> = mounted.entries().map(|e| (e.seq, e.count)).collect();
    assert_eq!(counts, vec![(0, 1), (a, 3), (2, 1), (b, 1)]);
    // The next boot: the same fault again is a new entry.
    let (_, mut next) = boot(&mut nor.powered_again(), None);
    assert_eq!(next.boot(), 2);
    let c = next.record(fault(FaultCause::Overcurrent, 2), 5);
    assert_eq!(c, b + 1);
}

/// The writer programs at most the words it is allowed per call, the record's CRC last:
/// a record is whole after four calls of two words.
#[test]
fn a_record_takes_four_periods_of_two_words() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    log.record(fault(FaultCause::DriverFault, NO_JOINT), 1);
    let steps: Vec<Step> = (0..5)
        .map(|_| store.step(&mut nor, &mut log, 0, 2, false))
        .collect();
    assert_eq!(
        steps,
        vec![
            Step::Programmed {
                words: 2,
                record_done: false
            },
            Step::Programmed {
                words: 2,
                record_done: false
            },
            Step::Programmed {
                words: 2,
                record_done: false
            },
            Step::Programmed {
                words: 2,
                record_done: true
            },
            Step::Idle
        ]
    );
    assert_eq!(on_flash(&mut nor).len(), 1);
}

/// The ring: with small sectors, the writer rotates through them, erasing only when it
/// may; the flash keeps between one and two sectors' worth of the newest records, and the
/// view after a mount holds the newest entries in order.
#[test]
fn the_ring_drops_the_oldest_and_erases_only_when_allowed() {
    let per_sector = 5;
    let mut nor = Nor::new(2, per_sector * RECORD_LEN + 8);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    let mut waited = 0;
    for i in 0..40u32 {
        log.record(EventKind::Master { id: i }, i);
        // Drives on: no erase.
        for _ in 0..4 {
            if store.step(&mut nor, &mut log, i, 2, false) == Step::Waiting {
                waited += 1;
                // Drives off: the erase may run.
                assert!(matches!(
                    store.step(&mut nor, &mut log, i, 2, true),
                    Step::Erased { .. }
                ));
            }
        }
        drain(&mut store, &mut nor, &mut log, 8);
    }
    assert!(waited >= 6, "{waited} waits for an erase");
    let records = on_flash(&mut nor);
    assert!(
        (per_sector..=2 * per_sector).contains(&records.len()),
        "{} records kept",
        records.len()
    );
    assert_eq!(records.last().unwrap().entry.seq, 39);
    let (_, view) = mount(&mut nor.powered_again()).unwrap();
    let seqs: Vec<u32> = view.entries().map(|e| e.seq).collect();
    let kept: Vec<u32> = records.iter().map(|r| r.entry.seq).collect();
    assert_eq!(seqs, kept);
    assert_eq!(view.next_seq(), 40);
}

/// The view holds the newest `EVENT_VIEW` entries; an entry that leaves it before the
/// flash held it is counted lost, and once the flash catches up a `Lost` entry records
/// how many.
#[test]
fn entries_that_leave_the_view_unwritten_are_counted_and_logged() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    for i in 0..(EVENT_VIEW as u32 + 5) {
        log.record(EventKind::Master { id: i }, i);
    }
    assert_eq!(log.len(), EVENT_VIEW);
    assert_eq!(log.lost(), 5);
    drain(&mut store, &mut nor, &mut log, 1000);
    let newest = log.newest().unwrap();
    assert_eq!(newest.event, EventKind::Lost { count: 5 });
    assert_eq!(log.lost(), 5, "the boot's count stays");
    assert_eq!(log.pending_len(), 0);
}

/// A full sector waits for the erase: nothing is written and nothing lost meanwhile.
#[test]
fn a_full_sector_waits_for_an_erase() {
    let mut nor = Nor::new(2, 2 * RECORD_LEN);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    for i in 0..2 {
        log.record(EventKind::Master { id: i }, 0);
    }
    drain(&mut store, &mut nor, &mut log, 100);
    log.record(EventKind::Master { id: 9 }, 0);
    assert!(store.needs_erase());
    for _ in 0..10 {
        assert_eq!(store.step(&mut nor, &mut log, 0, 2, false), Step::Waiting);
    }
    assert_eq!(nor.erases, 0);
    assert_eq!(log.pending_len(), 1);
    assert_eq!(
        store.step(&mut nor, &mut log, 0, 2, true),
        Step::Erased { sector: 1 }
    );
    drain(&mut store, &mut nor, &mut log, 100);
    assert_eq!(log.pending_len(), 0);
    assert_eq!(store.position(), (1, 1));
}

/// The view kept across a watchdog reset round-trips with the counts the flash holds;
/// zeros, a flipped bit and another magic are refused.
#[test]
fn the_kept_view_round_trips_and_garbage_is_refused() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    for k in kinds().into_iter().take(EVENT_VIEW + 3) {
        log.record(k, 77);
        store.step(&mut nor, &mut log, 0, 2, true);
    }
    log.set_relay_test_pending(true);
    let mut words = KeptEvents::ZERO;
    log.persist(&mut words);
    let back = EventLog::restore(&words).expect("valid");
    assert_eq!(
        back.entries().collect::<Vec<_>>(),
        log.entries().collect::<Vec<_>>()
    );
    assert_eq!(back.pending_len(), log.pending_len());
    assert_eq!(back.boot(), log.boot());
    assert_eq!(back.next_seq(), log.next_seq());
    assert_eq!(back.lost(), log.lost());
    assert!(back.relay_test_pending());
    assert_eq!(EventLog::restore(&KeptEvents::ZERO), None);
    let mut bad = words;
    bad.entries[3][2] ^= 0x40;
    assert_eq!(EventLog::restore(&bad), None);
    let mut bad = words;
    bad.magic ^= 1;
    assert_eq!(EventLog::restore(&bad), None);
}

/// At boot after a watchdog reset the kept view (newer than the flash) is taken: what the
/// flash did not hold yet is written then; after a power cycle (no kept view) the flash's
/// view is taken. Either way a new boot starts, and the relay test's latch of the newest
/// entry survives.
#[test]
fn a_boot_takes_the_newest_view_and_keeps_the_relay_latch() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    log.record(
        EventKind::Reset {
            cause: ResetCause::PowerOn,
        },
        0,
    );
    log.set_relay_test_pending(true);
    log.record(EventKind::RelayTest { pending: true }, 3);
    log.record(fault(FaultCause::SafetyRelayMismatch, NO_JOINT), 3);
    drain(&mut store, &mut nor, &mut log, 100);
    log.record(fault(FaultCause::DeadlineMissed, NO_JOINT), 9);
    // The watchdog resets the board before the last fault reached the flash.
    let mut kept = KeptEvents::ZERO;
    log.persist(&mut kept);
    let (store2, after_reset) = boot(&mut nor, EventLog::restore(&kept));
    assert_eq!(after_reset.boot(), 2);
    assert_eq!(after_reset.pending_len(), 1);
    assert!(after_reset.relay_test_pending());
    let mut after_reset = after_reset;
    drain(&mut store2.unwrap(), &mut nor, &mut after_reset, 100);
    // A power cycle: the flash alone.
    let (_, after_power) = boot(&mut nor.powered_again(), None);
    assert_eq!(after_power.boot(), 2, "boot 2 wrote nothing of its own yet");
    assert!(after_power.relay_test_pending());
    let causes: Vec<EventKind> = after_power.entries().map(|e| e.event).collect();
    assert_eq!(causes.len(), 4);
    assert_eq!(causes[3], fault(FaultCause::DeadlineMissed, NO_JOINT));
    // A stale kept view (an older boot than the flash's) is not taken.
    let mut older = KeptEvents::ZERO;
    EventLog::new().persist(&mut older);
    let (_, fresh) = boot(&mut nor.powered_again(), EventLog::restore(&older));
    assert_eq!(fresh.len(), 4);
}

/// A flash with something other than records (never erased) is erased before the first
/// record; an empty flash is used as it is.
#[test]
fn a_flash_of_garbage_is_erased_before_use() {
    let mut nor = Nor::new(2, 1024);
    nor.sectors[0][100] = 0x12;
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    assert!(store.needs_erase());
    log.record(EventKind::Master { id: 1 }, 0);
    assert_eq!(store.step(&mut nor, &mut log, 0, 2, false), Step::Waiting);
    assert_eq!(
        store.step(&mut nor, &mut log, 0, 2, true),
        Step::Erased { sector: 0 }
    );
    drain(&mut store, &mut nor, &mut log, 10);
    assert_eq!(on_flash(&mut nor).len(), 1);
    let (clean, _) = mount(&mut Nor::new(2, 1024)).unwrap();
    assert!(!clean.needs_erase());
}

/// A flash that fails every operation: the writer skips the slot, tries again, and gives
/// up after `GIVE_UP_AFTER` failures in a row, the entries staying in the view.
#[test]
fn a_failing_flash_is_given_up() {
    let mut nor = Nor::new(2, 4096);
    let (store, mut log) = boot(&mut nor, None);
    let mut store = store.unwrap();
    log.record(EventKind::Master { id: 1 }, 0);
    nor.cut = true;
    let mut failed = 0;
    for _ in 0..20 {
        match store.step(&mut nor, &mut log, 0, 2, true) {
            Step::Failed(_) => failed += 1,
            Step::GaveUp => break,
            s => panic!("{s:?}"),
        }
    }
    assert_eq!(failed, control::event_log::GIVE_UP_AFTER);
    assert_eq!(log.pending_len(), 1);
}

/// One scripted run: events (new ones and repeats) and writer steps.
#[derive(Clone, Debug)]
enum Op {
    Event(u8),
    Steps(u8),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![(0u8..12).prop_map(Op::Event), (1u8..12).prop_map(Op::Steps),]
}

fn event_of(k: u8) -> EventKind {
    match k % 4 {
        0 => fault(FaultCause::ALL[usize::from(k) % 26], k % 6),
        1 => EventKind::Master { id: u32::from(k) },
        2 => EventKind::Stop {
            reason: StopReason::ALL[usize::from(k) % 4],
            stop: StopStatus::SafeOperatingStop,
        },
        _ => EventKind::GeometryStored {
            version: u32::from(k),
        },
    }
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// A torn write: the power goes after any byte of the records programmed (and any
    /// bits of the byte being programmed then), in a ring of small sectors that rotates.
    /// Every record written whole before the cut is still read back by a scan of the
    /// flash, the cut record is not (or is whole), the view after the mount holds the
    /// newest count of the newest entries, and the writer goes on after the reboot: the
    /// records it writes then are read back too.
    #[test]
    fn a_torn_write_leaves_every_earlier_record_readable(
        ops in proptest::collection::vec(op(), 1..60),
        cut in 0usize..600,
        partial in any::<u8>(),
    ) {
        let mut nor = Nor::new(3, 6 * RECORD_LEN + 12);
        let (store, mut log) = boot(&mut nor, None);
        let mut store = store.unwrap();
        nor.budget = Some(cut);
        nor.partial = partial;
        let mut whole: Vec<(u32, u32, u16)> = Vec::new();
        let mut cut_at = None;
        'run: for op in &ops {
            match *op {
                Op::Event(k) => {
                    log.record(event_of(k), 1);
                }
                Op::Steps(n) => {
                    for _ in 0..n {
                        let (sector, slot) = store.position();
                        match store.step(&mut nor, &mut log, 1, 2, true) {
                            Step::Programmed { record_done: true, .. } => {
                                let mut w = [0u32; RECORD_WORDS];
                                nor.read(sector, slot * RECORD_LEN, &mut w).unwrap();
                                let Slot::Valid(r) = record::decode(&w) else {
                                    panic!("a whole record does not read back");
                                };
                                whole.push((r.serial, r.entry.seq, r.entry.count));
                            }
                            Step::Failed(_) if nor.cut => {
                                cut_at = Some((sector, slot));
                                break 'run;
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
        let mut after = nor.powered_again();
        let records = on_flash(&mut after);
        // Records of sectors the ring erased since are gone; every other one is there.
        let oldest = records.first().map_or(u32::MAX, |r| r.serial);
        for (serial, seq, count) in whole.iter().filter(|w| w.0 >= oldest) {
            prop_assert!(
                records.iter().any(|r| r.serial == *serial && r.entry.seq == *seq && r.entry.count == *count),
                "record {serial} (seq {seq}, count {count}) lost; on flash {:?}",
                records.iter().map(|r| r.serial).collect::<Vec<_>>()
            );
        }
        // Nothing valid but what was written whole, or the record being written at the
        // cut if its last byte happened to be programmed whole (a torn record is never
        // read).
        let mut at_cut = None;
        scan(&mut after, |s, slot, what| {
            if Some((s, slot)) == cut_at {
                at_cut = Some(what);
            }
        })
        .unwrap();
        for r in &records {
            prop_assert!(
                whole.iter().any(|w| w.0 == r.serial) || at_cut == Some(Slot::Valid(*r)),
                "record {} was never whole", r.serial
            );
        }
        // The mounted view: the newest count of each entry it holds.
        let (store2, view) = boot(&mut after, None);
        for e in view.entries() {
            let newest = records.iter().filter(|r| r.entry.seq == e.seq).map(|r| r.entry.count).max();
            prop_assert_eq!(Some(e.count), newest);
        }
        // The writer goes on after the reboot.
        let mut store2 = store2.unwrap();
        let mut view = view;
        let seq = view.record(EventKind::Master { id: 4242 }, 0);
        drain(&mut store2, &mut after, &mut view, 100);
        let records = on_flash(&mut after);
        prop_assert!(records.iter().any(|r| r.entry.seq == seq));
        let kept: Vec<u32> = records.iter().map(|r| r.serial).collect();
        let mut sorted = kept.clone();
        sorted.dedup();
        prop_assert_eq!(kept, sorted, "serials unique");
    }

    /// The power goes during an erase (any words of the sector erased, the rest as they
    /// were): the other sectors' records are all read back, and the writer erases that
    /// sector again before it uses it.
    #[test]
    fn a_cut_erase_leaves_the_other_sectors(
        events in 8usize..30,
        erased in proptest::collection::vec(any::<bool>(), 7 * 8),
    ) {
        let mut nor = Nor::new(2, 7 * RECORD_LEN);
        let (store, mut log) = boot(&mut nor, None);
        let mut store = store.unwrap();
        let mut i = 0u32;
        // Fill until the active sector is full and the next must be erased.
        loop {
            log.record(EventKind::Master { id: i }, 0);
            i += 1;
            while let Step::Programmed { .. } = store.step(&mut nor, &mut log, 0, 2, false) {}
            if store.needs_erase() && i as usize >= events {
                break;
            }
            if store.needs_erase() {
                store.step(&mut nor, &mut log, 0, 2, true);
            }
        }
        let (active, _) = store.position();
        let other = 1 - active;
        let in_sector = |nor: &mut Nor, sector: usize| {
            let mut v = Vec::new();
            scan(nor, |s, _, slot| {
                if let (true, Slot::Valid(r)) = (s == sector, slot) {
                    v.push(r);
                }
            })
            .unwrap();
            v
        };
        let before = in_sector(&mut nor, active);
        prop_assert!(!before.is_empty());
        // The cut erase of the other sector: some of its words erased.
        for (k, e) in erased.iter().enumerate() {
            if *e {
                nor.sectors[other][4 * k..4 * k + 4].fill(0xFF);
            }
        }
        let mut after = nor.powered_again();
        prop_assert_eq!(in_sector(&mut after, active), before);
        let (mut store2, mut view) = {
            let (s, v) = boot(&mut after, None);
            (s.unwrap(), v)
        };
        prop_assert!(store2.needs_erase());
        let seq = view.record(EventKind::Master { id: 999 }, 0);
        drain(&mut store2, &mut after, &mut view, 100);
        prop_assert!(on_flash(&mut after).iter().any(|r| r.entry.seq == seq));
    }
}
