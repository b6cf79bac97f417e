//! The release image fits the real STM32F405RG (flash 1 MiB, SRAM 128 KiB, CCM 64 KiB), from
//! the ELF's sections and segments: the emulated STM32F427 is larger (2 MiB, 192 KiB), so a
//! run proves nothing about the fit.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use board_emulator::image::{default_path, Firmware};

#[test]
fn the_release_image_fits_the_stm32f405() {
    let path = default_path();
    let firmware = Firmware::read(&path).unwrap_or_else(|e| {
        panic!("{e}: build it with `firmware/cortex-m/board/build-and-size.sh` (or set RSPR_BOARD_ELF)")
    });
    let fit = firmware.fit();
    println!("{}: {fit}", path.display());
    assert!(fit.flash_used > 0 && fit.sram_used > 0);
    assert!(fit.fits(), "{fit}");
    assert_eq!(
        fit.stack_top,
        Some(0x2002_0000),
        "the stack starts at the top of the 128 KiB SRAM"
    );
}
