//! The event log's flash: sectors 9 and 10 of the STM32F405's flash, 2 x 128 KB at
//! 0x080A_0000, reserved in `memory.x` (`EVENTS`), as the ring of `control::event_log`
//! (4 096 records of 32 bytes per sector).
//!
//! **When it writes** (`board_tasks::run_control`, after each tick's outputs and status): at
//! most `event_log::WORDS_PER_PERIOD` (2) words per control period, only when the tick
//! finished within `PROGRAM_WINDOW_US`, so that the programming's stall (16 µs a word
//! typically, 100 µs at most: DS8626, "Flash memory programming", x32) ends long before
//! the next period; a sector's erase (1 s, 2 s at most for 128 KB) only with the drives off
//! and the brakes applied, with the watchdog's timeout raised for it
//! (`geometry_flash::with_watchdog_raised`) and the control schedule restarted after it.
//!
//! **What a probe sees**: before it programs, the driver puts the address and the words in
//! [`EVENT_FLASH_PROGRAM`] (RAM, a fixed symbol), so that a debugger or the board emulator
//! (`firmware/board-emulator`, whose flash model drops the core's stores to the array) can
//! tell which words the core is programming. The calibrated geometry's slot writes have a
//! mailbox of their own beside it (`geometry_flash::GEOMETRY_FLASH_PROGRAM`).

use core::ptr::addr_of_mut;

use control::event_log::record::RECORD_WORDS;
use control::event_log::EventFlash;
use control::geometry_store::FlashError;
use embassy_stm32::flash::{Blocking, Flash};

use crate::geometry_flash::with_watchdog_raised;

/// Offset of the ring's first sector from the flash base (sector 9; `memory.x`'s EVENTS).
pub const EVENTS_OFFSET: u32 = 0x000A_0000;
/// Bytes per sector (sectors 9 and 10: 128 KB each).
pub const SECTOR_LEN: u32 = 128 * 1024;
/// Sectors in the ring.
pub const SECTORS: usize = 2;
/// The flash's base address.
pub(crate) const FLASH_BASE: u32 = 0x0800_0000;
/// The tick must have finished within this part of the 1 000 µs period for words to be
/// programmed in it: two words at their worst (200 µs) still end 200 µs before the next
/// period begins.
pub const PROGRAM_WINDOW_US: u32 = 600;

/// What the driver is programming: the address of the first word and the words (a
/// debugger's and the emulator's view of a program operation).
#[repr(C)]
pub struct ProgramMailbox {
    /// The absolute address of `words[0]`.
    pub address: u32,
    /// Words in this operation.
    pub len: u32,
    /// The words.
    pub words: [u32; RECORD_WORDS],
}

/// The program operation under way (see the module documentation).
#[no_mangle]
pub static mut EVENT_FLASH_PROGRAM: ProgramMailbox = ProgramMailbox {
    address: 0,
    len: 0,
    words: [0; RECORD_WORDS],
};

fn stage(address: u32, words: &[u32]) {
    let mut staged = ProgramMailbox {
        address,
        len: words.len().min(RECORD_WORDS) as u32,
        words: [0; RECORD_WORDS],
    };
    for (d, w) in staged.words.iter_mut().zip(words) {
        *d = *w;
    }
    // SAFETY: only the control task programs the flash, and this is its one writer; the
    // volatile write keeps the words in RAM for a probe though nothing reads them here.
    unsafe { core::ptr::write_volatile(addr_of_mut!(EVENT_FLASH_PROGRAM), staged) }
}

/// The event log's sectors through embassy-stm32's blocking flash driver.
pub struct EventSectors<'a>(pub &'a mut Flash<'static, Blocking>);

impl EventSectors<'_> {
    fn offset(sector: usize, offset: usize) -> Result<u32, FlashError> {
        if sector >= SECTORS || offset >= SECTOR_LEN as usize {
            return Err(FlashError::Driver);
        }
        Ok(EVENTS_OFFSET + sector as u32 * SECTOR_LEN + offset as u32)
    }
}

impl EventFlash for EventSectors<'_> {
    fn sectors(&self) -> usize {
        SECTORS
    }
    fn sector_len(&self) -> usize {
        SECTOR_LEN as usize
    }
    fn read(
        &mut self,
        sector: usize,
        offset: usize,
        out: &mut [u32; RECORD_WORDS],
    ) -> Result<(), FlashError> {
        let at = Self::offset(sector, offset)?;
        let mut bytes = [0u8; 4 * RECORD_WORDS];
        self.0
            .blocking_read(at, &mut bytes)
            .map_err(|_| FlashError::Driver)?;
        for (w, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
            *w = <[u8; 4]>::try_from(b).map_or(0, u32::from_le_bytes);
        }
        Ok(())
    }
    fn program(&mut self, sector: usize, offset: usize, words: &[u32]) -> Result<(), FlashError> {
        let at = Self::offset(sector, offset)?;
        let mut bytes = [0u8; 4 * RECORD_WORDS];
        let n = 4 * words.len().min(RECORD_WORDS);
        for (b, w) in bytes.chunks_exact_mut(4).zip(words) {
            b.copy_from_slice(&w.to_le_bytes());
        }
        stage(FLASH_BASE + at, words);
        let bytes = bytes.get(..n).ok_or(FlashError::Driver)?;
        self.0
            .blocking_write(at, bytes)
            .map_err(|_| FlashError::Driver)
    }
    fn erase(&mut self, sector: usize) -> Result<(), FlashError> {
        let at = Self::offset(sector, 0)?;
        with_watchdog_raised(|| self.0.blocking_erase(at, at + SECTOR_LEN))
            .map_err(|_| FlashError::Driver)
    }
}
