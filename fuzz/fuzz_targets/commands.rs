//! A scenario of link bytes, master frames, control ticks and hardware inputs driving the
//! board's link and runtime on the fake hardware, with every check of
//! `rspr_fuzz::commands`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rspr_fuzz::commands::{snapshots, Board, Scenario};

fuzz_target!(
    init: {
        // The snapshots (homing on the plant model) once, before the first input.
        let _ = snapshots();
    },
    |scenario: Scenario| {
        Board::run(&scenario);
    }
);
