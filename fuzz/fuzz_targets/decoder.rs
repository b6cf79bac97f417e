//! Arbitrary bytes, one at a time, into the board's and the master's frame decoders, with
//! every check of `rspr_fuzz::decoder`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = rspr_fuzz::decoder::check(data);
});
