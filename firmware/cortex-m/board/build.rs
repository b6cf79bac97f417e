//! Linker scripts of the board image: cortex-m-rt's `link.x` with this crate's `memory.x`
//! (the STM32F405RG's map with the last three flash sectors reserved: two for the event
//! log, one for the calibrated geometry) and defmt's.

use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    // A build script reports its failures by panicking (cargo prints the message).
    #[allow(clippy::expect_used)]
    std::fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
