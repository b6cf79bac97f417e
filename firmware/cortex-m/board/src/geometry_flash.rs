//! The calibrated geometry's flash sector: sector 11 of the STM32F405's flash,
//! 128 KB at 0x080E_0000, reserved in `memory.x` (the image's FLASH region ends below
//! it), as the slots of `control::geometry_store` (512 slots of 256 bytes: a store writes
//! one, the sector is erased only when all are used).
//!
//! **Timing.** The F405 has one flash bank: while it programs or erases, every fetch from
//! flash stalls the core, interrupts included (the hard-wired e-stop chain does not depend
//! on the MCU). Writing a slot takes about 1 ms, erasing the sector 1 to 2 s (RM0090,
//! DS8626: 128 KB sector erase, x32 parallelism). The runtime accepts a geometry only with
//! the drives off, and for the duration the independent watchdog's timeout is raised to
//! its maximum (about 32 s) and restored afterwards (its prescaler and reload can be
//! rewritten at any time after the 0x5555 key; only stopping it is impossible).

use control::geometry_store::{self, FlashError, GeometryFlash, SLOT_LEN};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};
use master_link::{GeometryRecord, GeometryRefusal};

use crate::event_flash::FLASH_BASE;

/// Offset of the reserved sector from the flash base (sector 11; `memory.x`'s GEOMETRY).
pub const SECTOR_OFFSET: u32 = 0x000E_0000;
/// Its size.
pub const SECTOR_LEN: u32 = 128 * 1024;

/// The slot being programmed: its absolute address and its bytes (a debugger's and the
/// board emulator's view of a geometry write, as `event_flash::EVENT_FLASH_PROGRAM` is of
/// the event log's; the emulator's flash model drops the core's stores to the array).
#[repr(C)]
pub struct SlotMailbox {
    /// The absolute address of `bytes[0]`.
    pub address: u32,
    /// The slot's bytes.
    pub bytes: [u8; SLOT_LEN],
}

/// The geometry write under way (see [`SlotMailbox`]).
#[no_mangle]
pub static mut GEOMETRY_FLASH_PROGRAM: SlotMailbox = SlotMailbox {
    address: 0,
    bytes: [0; SLOT_LEN],
};

/// The reserved sector through embassy-stm32's blocking flash driver.
pub struct GeometrySector<'a>(pub &'a mut Flash<'static, Blocking>);

impl GeometryFlash for GeometrySector<'_> {
    fn slots(&self) -> usize {
        (SECTOR_LEN as usize) / SLOT_LEN
    }
    fn read_slot(&mut self, i: usize, out: &mut [u8; SLOT_LEN]) -> Result<(), FlashError> {
        self.0
            .blocking_read(SECTOR_OFFSET + (i * SLOT_LEN) as u32, out)
            .map_err(|_| FlashError::Driver)
    }
    /// The slot, first staged in [`GEOMETRY_FLASH_PROGRAM`].
    fn write_slot(&mut self, i: usize, bytes: &[u8; SLOT_LEN]) -> Result<(), FlashError> {
        let at = SECTOR_OFFSET + (i * SLOT_LEN) as u32;
        let staged = SlotMailbox {
            address: FLASH_BASE + at,
            bytes: *bytes,
        };
        // SAFETY: only the control task programs the flash, and this is the mailbox's one
        // writer; the volatile write keeps the bytes in RAM for a probe though nothing
        // reads them here.
        unsafe {
            core::ptr::write_volatile(core::ptr::addr_of_mut!(GEOMETRY_FLASH_PROGRAM), staged)
        }
        self.0
            .blocking_write(at, bytes)
            .map_err(|_| FlashError::Driver)
    }
    fn erase(&mut self) -> Result<(), FlashError> {
        self.0
            .blocking_erase(SECTOR_OFFSET, SECTOR_OFFSET + SECTOR_LEN)
            .map_err(|_| FlashError::Driver)
    }
}

fn iwdg_wait_idle() {
    while {
        let sr = pac::IWDG.sr().read();
        sr.pvu() || sr.rvu()
    } {}
}

/// Sets the independent watchdog's prescaler and reload, then reloads it.
fn iwdg_set(pr: Pr, rl: u16) {
    iwdg_wait_idle();
    pac::IWDG.kr().write(|w| w.set_key(Key::ENABLE));
    pac::IWDG.pr().write(|w| w.set_pr(pr));
    pac::IWDG.rlr().write(|w| w.set_rl(rl));
    iwdg_wait_idle();
    pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
}

/// Runs `f` (a flash operation that stalls the core for up to seconds, with the drives
/// off) with the independent watchdog's timeout raised to its maximum (about 32 s), then
/// restores it.
pub fn with_watchdog_raised<T>(f: impl FnOnce() -> T) -> T {
    let (pr, rl) = (pac::IWDG.pr().read().pr(), pac::IWDG.rlr().read().rl());
    iwdg_set(Pr::DIVIDE_BY256, 0x0FFF);
    let result = f();
    iwdg_set(pr, rl);
    result
}

/// Stores `record` (accepted by the runtime) with the watchdog's timeout raised for the
/// duration.
pub fn store(
    flash: &mut Flash<'static, Blocking>,
    record: &GeometryRecord,
) -> Result<(), GeometryRefusal> {
    with_watchdog_raised(|| geometry_store::store(&mut GeometrySector(flash), record))
        .map(|_| ())
        .map_err(|_| GeometryRefusal::Flash)
}

/// The stored calibrated geometry at boot and its version, when its record is valid and
/// still passes the checks against the board's nominal robot (None: none stored, or it
/// fails them).
pub fn stored(
    flash: &mut Flash<'static, Blocking>,
    nominal: &kinematics_core::RsprGeometry<f32>,
    branch: kinematics_core::Branch,
) -> Option<(kinematics_core::PerChainGeometry<f32>, u32)> {
    match geometry_store::load_latest(&mut GeometrySector(flash)) {
        Ok(Some((_, rec))) => {
            let plausible = geometry_store::Plausible::default();
            geometry_store::check(&rec, nominal, branch, &plausible)
                .ok()
                .map(|g| (g, rec.version))
        }
        _ => None,
    }
}
