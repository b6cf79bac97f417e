//! Helpers shared by the integration tests.
#![allow(dead_code)]

use proptest::test_runner::Config as ProptestConfig;

/// Proptest settings: the project's one configuration (`tests/proptest-config`: a fixed
/// seed unless `RSPR_PROPTEST_FRESH=1`).
pub fn proptest_config(cases: u32) -> ProptestConfig {
    proptest_config::cases(cases)
}

/// Bytes from a hex string (test vectors).
pub fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}
