//! Writes the seed corpora and the dictionary of the fuzz targets (generated, never
//! committed): `seeds [DIR]` (default `seeds`) writes
//! * `DIR/decoder/`: every master and every board message as a frame, both as whole
//!   sessions (also tagged with the fuzzing key), and a stream with garbage, an over-long
//!   frame, a replay, a frame of another session, an emergency stop of another session and
//!   a frame beyond the sequence window;
//! * `DIR/link.dict`: libFuzzer dictionary (the delimiter, the version byte, every master
//!   frame of at most 64 bytes);
//! * `DIR/commands/`: scenarios drawn from a fixed-seed generator, each kept when it reaches
//!   something no earlier one did (a state, a reply kind, a Nack reason), at most
//!   `SAMPLES` tried. The target's input is `arbitrary`-structured, so its seeds are found
//!   by running the target's own code rather than written by hand.

use std::path::{Path, PathBuf};

use arbitrary::{Arbitrary, Unstructured};
use master_link::{Header, MasterToBoard, PROTOCOL_VERSION};
use rspr_fuzz::commands::{Board, Scenario, Strict};
use rspr_fuzz::frames::{self, SESSION};

/// Scenarios tried for the `commands` seeds.
const SAMPLES: u32 = 3000;

fn write(path: &Path, bytes: &[u8]) {
    if let Err(e) = std::fs::write(path, bytes) {
        eprintln!("seeds: cannot write {}: {e}", path.display());
        std::process::exit(1);
    }
}

fn mkdir(path: &Path) {
    if let Err(e) = std::fs::create_dir_all(path) {
        eprintln!("seeds: cannot create {}: {e}", path.display());
        std::process::exit(1);
    }
}

fn decoder_seeds(dir: &Path) -> usize {
    mkdir(dir);
    let mut n = 0;
    let mut put = |name: String, bytes: &[u8]| {
        write(&dir.join(name), bytes);
        n += 1;
    };
    let master = frames::master_messages();
    let board = frames::board_messages();
    for (i, m) in master.iter().enumerate() {
        let f = frames::frame(
            m,
            Header {
                session: SESSION,
                seq: 1,
            },
        );
        put(format!("master-{i:02}"), &f);
    }
    for (i, m) in board.iter().enumerate() {
        let f = frames::frame(
            m,
            Header {
                session: SESSION,
                seq: 1,
            },
        );
        put(format!("board-{i:02}"), &f);
    }
    put("master-session".into(), &frames::stream(&master, 100));
    put("board-session".into(), &frames::stream(&board, 100));
    // Garbage, an over-long frame, a replay, another session, an e-stop of another session.
    let mut mixed = vec![0x55, 0xAA, 0x00];
    mixed.extend(vec![0x42; 300]);
    mixed.push(0);
    mixed.extend(frames::stream(&master[..3], 10));
    mixed.extend(frames::frame(
        &MasterToBoard::Heartbeat,
        Header {
            session: SESSION,
            seq: 10,
        },
    ));
    mixed.extend(frames::frame(
        &MasterToBoard::Heartbeat,
        Header {
            session: 7,
            seq: 20,
        },
    ));
    mixed.extend(frames::frame(
        &MasterToBoard::EmergencyStop,
        Header { session: 7, seq: 3 },
    ));
    mixed.extend(frames::frame(
        &MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION - 1,
            nonce: 9,
            clock_us: 0,
        },
        Header { session: 0, seq: 0 },
    ));
    // A frame far beyond the sequence window.
    mixed.extend(frames::frame(
        &MasterToBoard::Heartbeat,
        Header {
            session: SESSION,
            seq: 30_013,
        },
    ));
    put("mixed".into(), &mixed);
    // The sessions again, tagged with the fuzzing key (the keyed decoders' seeds).
    let key = rspr_fuzz::decoder::fuzz_key();
    put(
        "master-session-keyed".into(),
        &frames::stream_keyed(&master, 100, Some(&key)),
    );
    put(
        "board-session-keyed".into(),
        &frames::stream_keyed(&board, 100, Some(&key)),
    );
    n
}

fn dictionary(path: &Path) -> usize {
    let entries = frames::dictionary();
    let text: Vec<String> = entries
        .iter()
        .enumerate()
        .map(|(i, e)| frames::dictionary_line(&format!("kw{i}"), e))
        .collect();
    write(path, (text.join("\n") + "\n").as_bytes());
    entries.len()
}

/// A xorshift64* generator: the seeds are the same on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

fn commands_seeds(dir: &Path) -> usize {
    mkdir(dir);
    let mut rng = Rng(0x5eed_0fc0_11a5);
    let mut seen: Vec<String> = Vec::new();
    let mut kept = 0;
    for i in 0..SAMPLES {
        let len = 32 + (rng.next() % 480) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        let Ok(scenario) = Scenario::arbitrary_take_rest(Unstructured::new(&bytes)) else {
            continue;
        };
        let outcome =
            match std::panic::catch_unwind(|| Board::run_with(&scenario, Strict::default())) {
                Ok(o) => o,
                Err(_) => {
                    // A check failed on a drawn scenario: not a seed (the fuzzer finds it).
                    eprintln!("seeds: sample {i} fails a check (not kept)");
                    continue;
                }
            };
        let mut keys: Vec<String> = outcome
            .states
            .iter()
            .map(|s| format!("state {s:?} from {:?}", scenario.start))
            .collect();
        keys.extend(outcome.nacks.iter().map(|r| format!("nack {r:?}")));
        keys.extend(
            outcome
                .replies
                .iter()
                .enumerate()
                .filter(|(_, n)| **n > 0)
                .map(|(k, _)| format!("reply {k}")),
        );
        let new: Vec<String> = keys.into_iter().filter(|k| !seen.contains(k)).collect();
        if !new.is_empty() {
            write(&dir.join(format!("sample-{i:04}")), &bytes);
            seen.extend(new);
            kept += 1;
        }
    }
    kept
}

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "seeds".into()));
    let d = decoder_seeds(&dir.join("decoder"));
    let k = dictionary(&dir.join("link.dict"));
    let c = commands_seeds(&dir.join("commands"));
    println!(
        "seeds: {d} decoder seeds, {k} dictionary entries, {c} commands seeds in {}",
        dir.display()
    );
}
