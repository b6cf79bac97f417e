//! Instruction-count markers for the QEMU TCG plugin (`plugin/insncount.c`).
//!
//! The plugin is given the addresses of [`bench_start`] and [`bench_stop`]; it counts the
//! guest instructions executed from the first instruction of `bench_start` to the first
//! instruction of `bench_stop` and prints each count. [`measure`] wraps a call between
//! the two markers (through a `dyn FnMut` hidden from the optimiser, so the measured work
//! cannot be moved across them); `measure(&mut || {})` gives the fixed overhead that the
//! report subtracts. After each region the firmware prints `@label <label>`, so that
//! run.sh can match the k-th count with the k-th label.

use core::hint::black_box;
use cortex_m_semihosting::hprintln;

/// Start marker (the plugin starts counting at its first instruction).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    // Different bodies keep the two markers from being merged into one function; no
    // `nomem`, so they are also compiler barriers for memory.
    unsafe { core::arch::asm!("/* bench_start */", options(nostack, preserves_flags)) }
}

/// Stop marker (the plugin stops counting at its first instruction).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_stop() {
    unsafe { core::arch::asm!("/* bench_stop */ nop", options(nostack, preserves_flags)) }
}

/// Profile window: the plugin attributes counted instructions to functions only between
/// `bench_profile_on` and `bench_profile_off`.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_profile_on() {
    unsafe {
        core::arch::asm!(
            "/* bench_profile_on */ nop; nop",
            options(nostack, preserves_flags)
        )
    }
}

/// See [`bench_profile_on`].
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_profile_off() {
    unsafe {
        core::arch::asm!(
            "/* bench_profile_off */ nop; nop; nop",
            options(nostack, preserves_flags)
        )
    }
}

/// Runs `f` between the markers (the caller then prints the region's `@label`).
#[inline(never)]
pub fn measure(f: &mut dyn FnMut()) {
    let f = black_box(f);
    bench_start();
    f();
    bench_stop();
}

/// The empty region, three times: its count is the fixed overhead of [`measure`].
pub fn calibrate() {
    for _ in 0..3 {
        measure(&mut || {});
        hprintln!("@label overhead");
    }
}
