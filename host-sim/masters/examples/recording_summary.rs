//! Prints the summary of a recorded session (what `host-sim replay FILE` prints first):
//! `cargo run -p masters --example recording_summary -- FILE.mcap`.

use masters::Recording;
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let Some(path) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: recording_summary FILE.mcap");
        return ExitCode::from(2);
    };
    match Recording::open(&path) {
        Ok(r) => {
            print!("{}", r.summary());
            if let Some(why) = r.stopped_by() {
                println!("read stopped early: {why}");
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}
