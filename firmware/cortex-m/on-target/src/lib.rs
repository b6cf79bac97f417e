//! Shared pieces of the on-target binaries for QEMU's mps2-an386 (Cortex-M4F):
//! a tiny test harness over semihosting, the instruction-count markers, a software
//! hardware stub behind the `hal` traits and the host-computed f64 reference table.
#![no_std]
// Test code on the target: a panic is a failed test (semihosting exits non-zero).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

pub mod bench;
pub mod harness;
pub mod stub;

/// f64 reference values computed on the host by build.rs (task grid, joints, Jacobians).
pub mod reference {
    include!(concat!(env!("OUT_DIR"), "/reference.rs"));
}

pub use cortex_m_semihosting::{hprint, hprintln};
