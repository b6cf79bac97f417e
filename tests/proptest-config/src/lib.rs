//! The one configuration of every property test of the project.
//!
//! By default a property test runs its stated number of cases from a **fixed seed**, so a
//! run (CI's included) is reproducible: the same cases every time, a failure seen once is
//! seen again. With `RSPR_PROPTEST_FRESH=1` it draws fresh random seeds and runs
//! `RSPR_PROPTEST_SCALE` times the cases (default 10), to look for new failures; proptest
//! writes a failure found that way to the test's `*.proptest-regressions` file, which is
//! committed, so the case is replayed by every later run, fixed seed or not.
//!
//! ```ignore
//! use proptest::prelude::*;
//! proptest! {
//!     #![proptest_config(proptest_config::cases(256))]
//!     #[test]
//!     fn addition_commutes(a in 0u32..1000, b in 0u32..1000) {
//!         prop_assert_eq!(a + b, b + a);
//!     }
//! }
//! ```

use proptest::test_runner::{Config, RngSeed};

/// The seed of reproducible runs.
pub const SEED: u64 = 0x5253_5052_2020_2611;

/// Runs with fresh random seeds (`RSPR_PROPTEST_FRESH=1`).
pub fn fresh() -> bool {
    std::env::var("RSPR_PROPTEST_FRESH").is_ok_and(|v| v == "1")
}

/// The case multiplier of fresh runs (`RSPR_PROPTEST_SCALE`, default 10).
pub fn scale() -> u32 {
    std::env::var("RSPR_PROPTEST_SCALE")
        .ok()
        .and_then(|v| v.parse::<u32>().ok())
        .filter(|s| *s > 0)
        .unwrap_or(10)
}

/// The configuration of a property test of `n` cases (see the crate's documentation).
pub fn cases(n: u32) -> Config {
    if fresh() {
        Config {
            cases: n.saturating_mul(scale()),
            rng_seed: RngSeed::Random,
            ..Config::default()
        }
    } else {
        Config {
            cases: n,
            rng_seed: RngSeed::Fixed(SEED),
            ..Config::default()
        }
    }
}
