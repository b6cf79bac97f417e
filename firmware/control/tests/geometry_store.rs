#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The flash log of calibrated geometries: records survive the slot encoding, the last
//! valid slot wins, a torn write leaves the previous record, a full sector is erased
//! before the next store, and every record is read back.

use control::geometry_store::*;
use kinematics_core::{Branch, Chain, PerChainGeometry, RsprGeometry};
use master_link::GeometryRecord;

/// NOR flash in RAM: erase sets 0xFF, programming can only clear bits.
struct RamFlash {
    bytes: Vec<u8>,
    erases: usize,
    /// Fail the next write after this many bytes (a reset in the middle of a store).
    tear_after: Option<usize>,
}

impl RamFlash {
    fn new(slots: usize) -> Self {
        RamFlash {
            bytes: vec![0xFF; slots * SLOT_LEN],
            erases: 0,
            tear_after: None,
        }
    }
}

impl GeometryFlash for RamFlash {
    fn slots(&self) -> usize {
        self.bytes.len() / SLOT_LEN
    }
    fn read_slot(&mut self, i: usize, out: &mut [u8; SLOT_LEN]) -> Result<(), FlashError> {
        out.copy_from_slice(
            self.bytes
                .get(i * SLOT_LEN..(i + 1) * SLOT_LEN)
                .ok_or(FlashError::Driver)?,
        );
        Ok(())
    }
    fn write_slot(&mut self, i: usize, bytes: &[u8; SLOT_LEN]) -> Result<(), FlashError> {
        let n = self.tear_after.take().unwrap_or(SLOT_LEN);
        let slot = self
            .bytes
            .get_mut(i * SLOT_LEN..(i + 1) * SLOT_LEN)
            .ok_or(FlashError::Driver)?;
        for (d, s) in slot.iter_mut().zip(bytes.iter()).take(n) {
            *d &= *s;
        }
        if n < SLOT_LEN {
            Err(FlashError::Driver)
        } else {
            Ok(())
        }
    }
    fn erase(&mut self) -> Result<(), FlashError> {
        self.bytes.fill(0xFF);
        self.erases += 1;
        Ok(())
    }
}

fn record(version: u32) -> GeometryRecord {
    let g = RsprGeometry::<f64>::reference();
    let mut chains = *PerChainGeometry::from(g).chains();
    chains[Chain::Three].link_zero = 1e-4 * f64::from(version);
    record_of(&PerChainGeometry::new(g, chains).unwrap(), version)
}

#[test]
fn a_record_survives_its_slot_and_its_checks() {
    let r = record(5);
    assert_eq!(decode_slot(&encode_slot(&r)), Some(r));
    // Every single-bit flip of a written slot is detected (the CRC or the magic).
    let bytes = encode_slot(&r);
    for bit in 0..RECORD_BYTES * 8 {
        let mut b = bytes;
        b[bit / 8] ^= 1 << (bit % 8);
        assert_eq!(decode_slot(&b), None, "bit {bit}");
    }
    // The f32 record checks against the board's nominal robot in f32.
    let g = check(
        &r,
        &RsprGeometry::<f32>::reference(),
        Branch::OUTER,
        &Plausible::default(),
    )
    .unwrap();
    assert!((g.chains()[Chain::Three].link_zero - 5e-4).abs() < 1e-7);
}

#[test]
fn the_last_valid_record_wins_and_a_full_sector_is_erased() {
    let mut f = RamFlash::new(3);
    assert_eq!(load_latest(&mut f).unwrap(), None);
    for v in 1..=3 {
        let s = store(&mut f, &record(v)).unwrap();
        assert_eq!(
            s,
            Stored {
                slot: v as usize - 1,
                erased: false
            }
        );
        assert_eq!(load_latest(&mut f).unwrap().map(|x| x.1.version), Some(v));
    }
    let s = store(&mut f, &record(4)).unwrap();
    assert_eq!(
        s,
        Stored {
            slot: 0,
            erased: true
        }
    );
    assert_eq!(f.erases, 1);
    assert_eq!(load_latest(&mut f).unwrap().map(|x| x.1.version), Some(4));
    // A store torn half way: an error, and the previous record stays.
    f.tear_after = Some(100);
    assert!(store(&mut f, &record(5)).is_err());
    assert_eq!(load_latest(&mut f).unwrap().map(|x| x.1.version), Some(4));
    // The next store goes after the torn slot.
    let s = store(&mut f, &record(6)).unwrap();
    assert_eq!(s.slot, 2);
    assert_eq!(load_latest(&mut f).unwrap().map(|x| x.1.version), Some(6));
}
