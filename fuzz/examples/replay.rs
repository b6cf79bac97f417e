//! Replays inputs through a target's checks (uninstrumented) and summarises them:
//! `replay decoder|commands PATH...` (files or directories). Prints the inputs run, the
//! slowest with its time, and for `commands` what the scenarios reached (states, reply
//! kinds, Nack reasons, ticks, the known findings' occurrences). Exits
//! non-zero when a check fails (the panic message names it).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use arbitrary::{Arbitrary, Unstructured};
use rspr_fuzz::commands::{Board, Scenario};

fn files(paths: &[String]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for p in paths {
        let p = PathBuf::from(p);
        match std::fs::read_dir(&p) {
            Ok(dir) => out.extend(dir.flatten().map(|e| e.path()).filter(|f| f.is_file())),
            Err(_) => out.push(p),
        }
    }
    out.sort();
    out
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((target, paths)) = args.split_first() else {
        eprintln!("usage: replay decoder|commands PATH...");
        std::process::exit(2);
    };
    if target == "commands" {
        // The snapshots (homing on the plant) before the first timed input.
        let _ = rspr_fuzz::commands::snapshots();
    }
    let mut slowest = (Duration::ZERO, PathBuf::new());
    let mut total = Duration::ZERO;
    let mut states = std::collections::BTreeMap::<String, u32>::new();
    let mut nacks = std::collections::BTreeMap::<String, u32>::new();
    let mut replies = [0u64; 5];
    let (mut ticks, mut over, mut masked, mut n) = (0u64, 0u64, 0u64, 0u32);
    let mut link = [[0u64; 8]; 2];
    for f in files(paths) {
        let Ok(data) = std::fs::read(&f) else {
            eprintln!("replay: cannot read {}", f.display());
            std::process::exit(2);
        };
        let t0 = Instant::now();
        match target.as_str() {
            "decoder" => {
                for (sum, c) in link.iter_mut().zip(rspr_fuzz::decoder::check(&data)) {
                    let add = |a: &mut u64, b: u32| *a += u64::from(b);
                    add(&mut sum[0], c.frames_ok);
                    add(&mut sum[1], c.bad_checksum);
                    add(&mut sum[2], c.malformed);
                    add(&mut sum[3], c.oversized);
                    add(&mut sum[4], c.wrong_version);
                    add(&mut sum[5], c.out_of_order);
                    add(&mut sum[6], c.wrong_session);
                    add(&mut sum[7], c.dropped);
                }
            }
            "commands" => {
                let Ok(s) = Scenario::arbitrary_take_rest(Unstructured::new(&data)) else {
                    continue;
                };
                let o = Board::run(&s);
                for st in &o.states {
                    *states
                        .entry(format!("{:?} from {:?}", st, s.start))
                        .or_default() += 1;
                }
                for r in &o.nacks {
                    *nacks.entry(format!("{r:?}")).or_default() += 1;
                }
                for (a, b) in replies.iter_mut().zip(o.replies) {
                    *a += u64::from(b);
                }
                ticks += u64::from(o.ticks);
                over += u64::from(o.duty_over_range);
                masked += u64::from(o.masked_stops);
            }
            other => {
                eprintln!("replay: unknown target {other}");
                std::process::exit(2);
            }
        }
        let dt = t0.elapsed();
        total += dt;
        n += 1;
        if dt > slowest.0 {
            slowest = (dt, f.clone());
        }
    }
    println!(
        "replay {target}: {n} inputs in {:.3} s, slowest {:.3} ms ({})",
        total.as_secs_f64(),
        slowest.0.as_secs_f64() * 1e3,
        slowest.1.display()
    );
    if target == "decoder" {
        for (who, c) in ["BoardDecoder", "MasterDecoder"].iter().zip(link) {
            println!(
                "  {who}: ok {}, bad_checksum {}, malformed {}, oversized {}, wrong_version {}, out_of_order {}, wrong_session {}, dropped {}",
                c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
            );
        }
    }
    if target == "commands" {
        println!("  ticks {ticks}; replies (HelloReply, Ack, Nack, Status, FaultLog/EventLog, Geometry) {replies:?}");
        println!("  duty outside [-1, 1] from the current limit (finding 1): {over} joint-ticks");
        println!("  STO rows masked by a latched OverTemperature (finding 2): {masked} ticks");
        println!("  states reached (inputs): {states:?}");
        println!("  Nack reasons (inputs): {nacks:?}");
    }
}
