//! The board's kept flash as the bench keeps it across a power cycle: the event log's
//! sectors 9 and 10 of the STM32F405 (0x080A_0000, 2 x 128 KiB, `memory.x`'s `EVENTS`) and
//! the calibrated geometry's sector 11 (0x080E_0000, 128 KiB, `GEOMETRY`).
//!
//! rigless 0.4's STM32F427 flash interface times a sector erase (`FLASH_SR.BSY` for the
//! sector's erase time) but leaves programming out: the core's stores into the flash array
//! are dropped before any model sees them, and nothing changes the array during a run
//! (`rigless::soc::stm32f427::peripherals::flash`, "What the model leaves out"). So the
//! bench models what a power cycle must keep, beside the array the core reads:
//!
//! * **program**: a write watch on the sectors gives each store's address and instant;
//!   `FLASH_CR.PG` (the control register's writes, as every peripheral access, reach the
//!   bench) says whether the flash interface programs; the word comes from the image's
//!   program mailbox (`EVENT_FLASH_PROGRAM`: the address and the words its driver is
//!   programming, which it fills before it programs; `GEOMETRY_FLASH_PROGRAM` likewise
//!   holds the geometry's slot and its address). The shadow's word becomes the old one AND the new one
//!   (programming clears bits only, RM0090 section 3.6.4). A store whose word the mailbox
//!   does not hold is counted, never guessed.
//! * **erase**: a `FLASH_CR` write with `SER` and `STRT` set erases sector `SNB` (every byte
//!   0xFF) when it is one of these.
//! * **the stall**: each programmed word holds the core for the bench's programming time (the
//!   bench does it: `BenchConfig::flash_word_ns`), as the single-bank F405 stalls its fetches
//!   while it programs (RM0090 section 3.5). The erase's stall is the firmware's own wait
//!   on `BSY`, which the rigless model times.
//!
//! The shadow is the next run's flash (`BenchConfig::flash`: an image of the sectors placed
//! before the first instruction). Within a run the array the core reads does not change:
//! the board's event log reads its sectors only at boot and checks a write by the flash
//! interface's error flags, not by reading it back, so the image runs as on the part. The
//! geometry's store reads its slot back after programming it: within the run it reads the
//! array unchanged (erased) and answers `GeometryRefused { reason: Flash }`, where the part
//! answers `GeometryStored`; the record is in the shadow, and the next power-up boots with it
//! (`tests/store_geometry.rs`).

use rigless::time::VirtualNanos;

/// The first byte of the event log's sectors.
pub const EVENTS_BASE: u64 = 0x080A_0000;
/// The event log's bytes.
pub const EVENTS_LEN: usize = 256 * 1024;
/// The calibrated geometry's sector (sector 11).
pub const GEOMETRY_BASE: u64 = 0x080E_0000;
/// The bytes the shadow keeps, from [`EVENTS_BASE`]: the event log's two sectors and the
/// geometry's.
pub const KEPT_LEN: usize = EVENTS_LEN + SECTOR_LEN;
/// The F405's sector numbers of the kept sectors, with their bases.
pub const KEPT_SECTORS: [(u32, u64); 3] =
    [(9, 0x080A_0000), (10, 0x080C_0000), (11, GEOMETRY_BASE)];
/// Bytes per sector.
pub const SECTOR_LEN: usize = 128 * 1024;
/// `FLASH_CR` (RM0090 rev 19 section 3.9.7).
pub const FLASH_CR: u64 = 0x4002_3C10;
/// The image's program mailbox.
pub const MAILBOX_SYMBOL: &str = "EVENT_FLASH_PROGRAM";
/// The image's mailbox of the geometry slot it programs: the slot's absolute address (a
/// word), then its [`GEOMETRY_SLOT_LEN`] bytes.
pub const GEOMETRY_MAILBOX_SYMBOL: &str = "GEOMETRY_FLASH_PROGRAM";
/// Bytes of a geometry slot (`control::geometry_store::SLOT_LEN`).
pub const GEOMETRY_SLOT_LEN: u64 = 256;
/// Words the mailbox holds.
pub const MAILBOX_WORDS: usize = 8;

const CR_PG: u64 = 1 << 0;
const CR_SER: u64 = 1 << 1;
const CR_STRT: u64 = 1 << 16;

/// What happened to the flash, when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashOp {
    /// A word programmed at the address: the word stored.
    Program {
        /// The instant.
        at: VirtualNanos,
        /// The address.
        address: u64,
        /// The word.
        word: u32,
    },
    /// A sector erased (its F405 number).
    Erase {
        /// The instant.
        at: VirtualNanos,
        /// The sector.
        sector: u32,
    },
}

impl FlashOp {
    /// Its instant.
    pub fn at(&self) -> VirtualNanos {
        match self {
            FlashOp::Program { at, .. } | FlashOp::Erase { at, .. } => *at,
        }
    }
}

/// The mailbox as read at a store: the address of its first word and its words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Staged {
    /// The first word's address.
    pub address: u64,
    /// Words valid.
    pub len: usize,
    /// The words.
    pub words: [u32; MAILBOX_WORDS],
}

impl Staged {
    /// The word staged for `address`, if the mailbox holds one.
    pub fn word_at(&self, address: u64) -> Option<u32> {
        let off = address.checked_sub(self.address)?;
        if off % 4 != 0 {
            return None;
        }
        let i = usize::try_from(off / 4).ok()?;
        (i < self.len).then(|| self.words.get(i).copied()).flatten()
    }
}

/// The kept sectors as the bench keeps them (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FlashShadow {
    bytes: Vec<u8>,
    /// The last value written to `FLASH_CR`.
    control: u64,
    /// Words programmed.
    pub programmed: u64,
    /// Sectors erased.
    pub erases: u64,
    /// Stores into the sectors with `PG` set whose word the mailbox did not hold.
    pub unknown: u64,
    /// Stores into the sectors with `PG` clear (dropped by the part).
    pub dropped: u64,
    /// Every operation, in order (taken by the master with [`FlashShadow::take_ops`]).
    ops: Vec<FlashOp>,
}

impl FlashShadow {
    /// The sectors as `initial` holds them (from `EVENTS_BASE`; the rest erased), or all
    /// erased.
    pub fn new(initial: Option<&[u8]>) -> Self {
        let mut bytes = vec![0xFF; KEPT_LEN];
        if let Some(init) = initial {
            for (d, s) in bytes.iter_mut().zip(init) {
                *d = *s;
            }
        }
        FlashShadow {
            bytes,
            control: 0,
            programmed: 0,
            erases: 0,
            unknown: 0,
            dropped: 0,
            ops: Vec::new(),
        }
    }

    /// The sectors' bytes (from `EVENTS_BASE`).
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Whether `address` is in the sectors.
    pub fn holds(address: u64) -> bool {
        (EVENTS_BASE..EVENTS_BASE + KEPT_LEN as u64).contains(&address)
    }

    /// The operations since the last take.
    pub fn take_ops(&mut self) -> Vec<FlashOp> {
        std::mem::take(&mut self.ops)
    }

    /// The firmware wrote `value` to `FLASH_CR` at `at`: programming on or off; a sector
    /// erase started.
    pub fn control_written(&mut self, at: VirtualNanos, value: u64) {
        self.control = value;
        if value & CR_SER != 0 && value & CR_STRT != 0 {
            let snb = ((value >> 3) & 0x1F) as u32;
            if let Some((_, base)) = KEPT_SECTORS.iter().find(|(n, _)| *n == snb) {
                let start = usize::try_from(base - EVENTS_BASE).unwrap_or(usize::MAX);
                if let Some(s) = self.bytes.get_mut(start..start + SECTOR_LEN) {
                    s.fill(0xFF);
                    self.erases += 1;
                    self.ops.push(FlashOp::Erase { at, sector: snb });
                }
            }
        }
    }

    /// The core stored a word at `address` (in the sectors) at `at`, with `staged` in the
    /// mailbox: the word programmed (when `PG` is set and the mailbox holds it).
    pub fn stored(
        &mut self,
        at: VirtualNanos,
        address: u64,
        staged: Option<Staged>,
    ) -> Option<u32> {
        if self.control & CR_PG == 0 {
            self.dropped += 1;
            return None;
        }
        let Some(word) = staged.and_then(|s| s.word_at(address)) else {
            self.unknown += 1;
            return None;
        };
        let start = usize::try_from(address - EVENTS_BASE).ok()?;
        let cells = self.bytes.get_mut(start..start + 4)?;
        for (c, b) in cells.iter_mut().zip(word.to_le_bytes()) {
            *c &= b;
        }
        self.programmed += 1;
        self.ops.push(FlashOp::Program { at, address, word });
        Some(word)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn staged(address: u64, words: &[u32]) -> Staged {
        let mut w = [0u32; MAILBOX_WORDS];
        w[..words.len()].copy_from_slice(words);
        Staged {
            address,
            len: words.len(),
            words: w,
        }
    }

    /// A store programs only with PG set and a staged word for its address, clearing bits
    /// only; SER with STRT erases sector 9, 10 or 11 (not 8), the rest untouched; a word of
    /// the geometry's sector programs like the event log's.
    #[test]
    fn programs_with_pg_and_a_staged_word_and_erases_its_sectors() {
        let mut f = FlashShadow::new(None);
        let t = VirtualNanos(5);
        let a = EVENTS_BASE + 0x20;
        assert_eq!(f.stored(t, a, Some(staged(a, &[0x1234_5678]))), None);
        assert_eq!(f.dropped, 1);
        f.control_written(t, CR_PG | (2 << 8));
        assert_eq!(f.stored(t, a, None), None);
        assert_eq!(f.unknown, 1);
        assert_eq!(f.stored(t, a + 4, Some(staged(a, &[1]))), None);
        assert_eq!(
            f.stored(t, a, Some(staged(a, &[0x1234_5678]))),
            Some(0x1234_5678)
        );
        assert_eq!(&f.bytes()[0x20..0x24], &0x1234_5678u32.to_le_bytes());
        f.stored(t, a, Some(staged(a, &[0xFFFF_0000])));
        assert_eq!(&f.bytes()[0x20..0x24], &0x1234_0000u32.to_le_bytes());
        let g = GEOMETRY_BASE + 0x100;
        f.control_written(t, CR_PG | (2 << 8));
        assert_eq!(
            f.stored(t, g, Some(staged(g, &[0xA5A5_0F0F]))),
            Some(0xA5A5_0F0F)
        );
        let off = (g - EVENTS_BASE) as usize;
        assert_eq!(&f.bytes()[off..off + 4], &0xA5A5_0F0Fu32.to_le_bytes());
        f.control_written(t, CR_SER | (8 << 3));
        f.control_written(t, CR_SER | (8 << 3) | CR_STRT);
        assert_eq!(f.erases, 0, "sector 8 is the image's");
        f.control_written(t, CR_SER | (9 << 3) | CR_STRT);
        assert_eq!(f.erases, 1);
        assert!(f.bytes()[..SECTOR_LEN].iter().all(|b| *b == 0xFF));
        assert_eq!(&f.bytes()[off..off + 4], &0xA5A5_0F0Fu32.to_le_bytes());
        f.control_written(t, CR_SER | (11 << 3) | CR_STRT);
        assert_eq!(f.erases, 2);
        assert!(f.bytes()[EVENTS_LEN..].iter().all(|b| *b == 0xFF));
        assert_eq!(f.take_ops().len(), 5);
    }
}
