//! Linker scripts of the NUCLEO-F429ZI image: cortex-m-rt's `link.x` with the reference
//! board's `memory.x` (the STM32F429ZI's flash bank 1 has the STM32F405's sectors 0..11 at
//! the same addresses, and its SRAM1 + SRAM2 the same 128 KB: one memory map, one owner)
//! and defmt's.

use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    let memory = "../board/memory.x";
    // A build script reports its failures by panicking (cargo prints the message).
    #[allow(clippy::expect_used)]
    std::fs::copy(memory, out.join("memory.x")).expect("copy memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={memory}");
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
