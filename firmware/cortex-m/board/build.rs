//! Linker scripts of the board image: cortex-m-rt's `link.x` (with the memory map that
//! embassy-stm32's `memory-x` feature generates for the STM32F405RG) and defmt's.

fn main() {
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
