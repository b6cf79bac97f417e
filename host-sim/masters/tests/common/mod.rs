//! Shared helpers of the integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use proptest::test_runner::Config;
use std::path::PathBuf;

/// Proptest settings: the project's one configuration (`tests/proptest-config`: a fixed
/// seed unless `RSPR_PROPTEST_FRESH=1`).
pub fn proptest_config(cases: u32) -> Config {
    proptest_config::cases(cases)
}

/// A fixture file's bytes.
pub fn fixture(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `expected.json`, the values the fixtures were built from.
pub fn expected() -> serde_json::Value {
    serde_json::from_slice(&fixture("expected.json")).expect("expected.json")
}

/// An expected integer array.
pub fn ints(v: &serde_json::Value) -> Vec<i64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_i64().expect("integer"))
        .collect()
}
