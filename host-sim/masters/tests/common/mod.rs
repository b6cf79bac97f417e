//! Shared helpers of the integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use proptest::test_runner::Config;
use std::path::PathBuf;

/// Proptest settings: the project's one configuration (`tests/proptest-config`: a fixed
/// seed unless `RSPR_PROPTEST_FRESH=1`).
pub fn proptest_config(cases: u32) -> Config {
    proptest_config::cases(cases)
}

/// The directory of the byte fixtures: generated once per test process by
/// `tests/fixtures/make_fixtures.py` (from literal values, with Python's `struct`) into the
/// build's temporary directory; never committed.
pub fn fixtures_dir() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("masters-fixtures-{}", std::process::id()));
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/make_fixtures.py");
        let out = std::process::Command::new("python3")
            .arg(&script)
            .arg(&dir)
            .output()
            .unwrap_or_else(|e| panic!("python3 {}: {e}", script.display()));
        assert!(
            out.status.success(),
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    })
    .clone()
}

/// A fixture file's bytes.
pub fn fixture(name: &str) -> Vec<u8> {
    let p = fixtures_dir().join(name);
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
