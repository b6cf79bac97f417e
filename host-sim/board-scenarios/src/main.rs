//! `board-scenarios`: every closed-loop scenario of the board's release image on the
//! emulated STM32F4 (`firmware/board-emulator`) against the host's master (`teleop`):
//! prints each check with its figures and (with `--runs 2`, the default) runs them a
//! second time at once in a child process and compares the two runs' digests; exits 1
//! when a check fails or the digests differ.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, ExitCode, Stdio};
use std::time::Instant;

use board_emulator::image::default_path;
use board_emulator::pins::{BoardTarget, NUCLEO_F429ZI, REFERENCE};
use board_scenarios::scenarios::{run_all, List, Options};
use clap::{Parser, ValueEnum};
use teleop::PathChoice;

#[derive(Parser)]
#[command(
    about = "Every closed-loop scenario of the board's release image on the emulated STM32F4, against the host's master; exit 1 when a check fails or two runs differ"
)]
struct Cli {
    /// The release ELF [default: for the reference board $RSPR_BOARD_ELF, else
    /// firmware/cortex-m/target/thumbv7em-none-eabihf/release/rspr-board; for the
    /// NUCLEO-F429ZI $RSPR_NUCLEO_ELF, else rspr-nucleo-f429zi in the same directory].
    #[arg(long)]
    firmware: Option<PathBuf>,
    /// The board the image is built for: its pin map and current sense around the MCU.
    #[arg(long, value_enum, default_value = "reference")]
    board: BoardArg,
    /// Which scenarios: all, or the ones that drive or read every pin of the board.
    #[arg(long, value_enum, default_value = "all")]
    scenarios: ListArg,
    /// The path streamed.
    #[arg(long, value_enum, default_value = "fast")]
    path: PathArg,
    /// 2: a second run at once in a child process, its digest compared; 1: one run.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    runs: u8,
    /// Where the master's telemetry goes (status.csv; the second run's in second/)
    /// [default: target/scenarios in this crate].
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum BoardArg {
    /// The reference board (STM32F405RG).
    Reference,
    /// ST's NUCLEO-F429ZI (firmware/cortex-m/nucleo-f429zi).
    NucleoF429zi,
}

impl BoardArg {
    fn target(self) -> BoardTarget {
        match self {
            BoardArg::Reference => REFERENCE,
            BoardArg::NucleoF429zi => NUCLEO_F429ZI,
        }
    }

    /// The image's default path.
    fn default_firmware(self) -> PathBuf {
        match self {
            BoardArg::Reference => default_path(),
            BoardArg::NucleoF429zi => match std::env::var_os("RSPR_NUCLEO_ELF") {
                Some(p) if !p.is_empty() => PathBuf::from(p),
                _ => Path::new(env!("CARGO_MANIFEST_DIR")).join(
                    "../../firmware/cortex-m/target/thumbv7em-none-eabihf/release/rspr-nucleo-f429zi",
                ),
            },
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum ListArg {
    /// Every scenario.
    All,
    /// The scenarios that drive or read every pin (no watchdog reset, refused target and
    /// garbage, tool or heartbeat loss).
    Wiring,
}

#[derive(Clone, Copy, ValueEnum)]
enum PathArg {
    /// The laparoscope figure-eight's 25 mm/s pass.
    Fast,
    /// The whole laparoscope path (2.5 and 25 mm/s passes).
    Laparoscope,
    /// A 10 mm line and back at 10 mm/s.
    Line,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let firmware = cli
        .firmware
        .clone()
        .unwrap_or_else(|| cli.board.default_firmware());
    let out = cli
        .out
        .clone()
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/scenarios"));
    match scenarios(&firmware, &cli, &out) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("board-scenarios: {e}");
            ExitCode::FAILURE
        }
    }
}

fn path_choice(path: PathArg) -> (PathChoice, &'static str) {
    match path {
        PathArg::Fast => (PathChoice::Fast, "fast"),
        PathArg::Laparoscope => (PathChoice::Laparoscope, "laparoscope"),
        PathArg::Line => (PathChoice::Line, "line"),
    }
}

/// The figures of the second run, read from its output.
struct Second {
    digest: Option<String>,
    passed: Option<String>,
    ok: bool,
    wall_s: f64,
}

fn second_run(firmware: &Path, cli: &Cli, out: &Path) -> Result<std::process::Child, String> {
    let exe = std::env::current_exe().map_err(|e| format!("own executable: {e}"))?;
    let name = |v: Option<clap::builder::PossibleValue>| {
        v.map(|p| p.get_name().to_string()).unwrap_or_default()
    };
    Process::new(exe)
        .arg("--firmware")
        .arg(firmware)
        .args(["--runs", "1", "--path", path_choice(cli.path).1])
        .args(["--board", &name(cli.board.to_possible_value())])
        .args(["--scenarios", &name(cli.scenarios.to_possible_value())])
        .arg("--out")
        .arg(out.join("second"))
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("starting the second run: {e}"))
}

fn collect_second(mut child: std::process::Child, started: Instant) -> Result<Second, String> {
    let mut digest = None;
    let mut passed = None;
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.map_err(|e| format!("reading the second run: {e}"))?;
            if let Some(d) = line.strip_prefix("trace digest ") {
                digest = Some(d.trim().to_string());
            }
            if line.starts_with("checks: ") {
                passed = Some(line);
            }
        }
    }
    let status = child
        .wait()
        .map_err(|e| format!("waiting for the second run: {e}"))?;
    Ok(Second {
        digest,
        passed,
        ok: status.success(),
        wall_s: started.elapsed().as_secs_f64(),
    })
}

fn scenarios(firmware: &Path, cli: &Cli, out: &Path) -> Result<bool, String> {
    let (choice, _) = path_choice(cli.path);
    let started = Instant::now();
    let child = if cli.runs == 2 {
        Some(second_run(firmware, cli, out)?)
    } else {
        None
    };
    let options = Options {
        path: choice,
        out: Some(out.to_path_buf()),
        board: cli.board.target(),
        list: match cli.scenarios {
            ListArg::All => List::All,
            ListArg::Wiring => List::Wiring,
        },
    };
    let o = run_all(firmware, options).map_err(|e| e.to_string())?;
    let passed = o.checks.iter().filter(|c| c.ok).count();
    println!(
        "virtual {:.2} s, wall {:.2} s (start-up and JIT warm-up to the first plant step: {:.2} s), {:.2} virtual s per wall s",
        o.virtual_s,
        o.wall_s,
        o.warmup_s,
        o.speed()
    );
    println!("emulator gaps: {}", o.gaps);
    println!("trace digest {}", o.digest_hex());
    println!(
        "checks: {passed} passed, {} failed",
        o.checks.len() - passed
    );
    let mut ok = o.all_ok();
    if let Some(child) = child {
        let second = collect_second(child, started)?;
        let same = second.digest.as_deref() == Some(o.digest_hex().as_str());
        println!(
            "[{}] two runs of the closed loop (this process and a child process, at once) give identical digests: this run {}, the second {} (second run: {}, exit {}; its wall time {:.1} s)",
            if same { "PASS" } else { "FAIL" },
            o.digest_hex(),
            second.digest.as_deref().unwrap_or("none"),
            second.passed.as_deref().unwrap_or("no result"),
            if second.ok { "success" } else { "failure" },
            second.wall_s
        );
        ok &= same && second.ok;
    }
    println!(
        "board-scenarios: {} (wall {:.1} s)",
        if ok { "all passed" } else { "FAILED" },
        started.elapsed().as_secs_f64()
    );
    Ok(ok)
}
