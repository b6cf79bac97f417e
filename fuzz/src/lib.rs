//! The fuzz harnesses of the board's master link, as a library so that the libFuzzer
//! targets (`fuzz_targets/`), the seed generator (`examples/seeds.rs`) and the unit tests run
//! the same code.
//!
//! * [`decoder`]: arbitrary bytes, one at a time, into `master_link::BoardDecoder` and
//!   `MasterDecoder`, checked against a model of the documented framing, session and
//!   sequence rules and the counters.
//! * [`commands`]: a structured scenario (link bytes, well-formed master frames, control
//!   ticks, hardware inputs) driving the board's link and a booted
//!   `control::service::TickService` on a cheap fake hardware ([`fake_hw`]), started from
//!   snapshots taken on the plant model ([`snapshots`]).
//! * [`frames`]: one sample of every message, encoded: the seeds and the dictionary.
//!
//! Every invariant is an `assert!`: a violation panics, which libFuzzer reports as a crash
//! with the input that caused it.

pub mod commands;
pub mod decoder;
pub mod fake_hw;
pub mod frames;
pub mod snapshots;
