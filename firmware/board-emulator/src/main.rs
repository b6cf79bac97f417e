//! `board-emulator`: the board's release image on the emulated STM32F4 with the plant.
//!
//! * `scenarios`: runs every closed-loop scenario, prints each check with its figures, and
//!   (with `--runs 2`, the default) runs them a second time at once in a child process and
//!   compares the two runs' digests; exits 1 when a check fails or the digests differ.
//! * `serve --socket PATH`: boots the image with the plant and serves its master link
//!   (USART3) on a Unix socket, virtual time paced to the wall clock, so that
//!   `host-sim teleop --connect PATH` talks to it as to a board on a desk.
//! * `fit`: whether the image fits the real STM32F405 (flash, SRAM, CCM).

use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, ExitCode, Stdio};
use std::time::{Duration, Instant};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::image::{default_path, Firmware};
use board_emulator::scenarios::{run_all, Options};
use clap::{Parser, Subcommand, ValueEnum};
use master_link::{BoardToMaster, MasterDecoder};
use teleop::PathChoice;

#[derive(Parser)]
#[command(
    about = "The board's release image on an emulated STM32F4, in closed loop with the plant"
)]
struct Cli {
    /// The release ELF [default: $RSPR_BOARD_ELF, else
    /// firmware/cortex-m/target/thumbv7em-none-eabihf/release/rspr-board].
    #[arg(long, global = true)]
    firmware: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
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

#[derive(Subcommand)]
enum Command {
    /// Run every scenario; exit 1 when a check fails or two runs differ.
    Scenarios {
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
    },
    /// Serve the board's master link on a Unix socket, virtual time paced to the wall clock.
    Serve {
        /// The socket to listen on (replaced if it exists).
        #[arg(long)]
        socket: PathBuf,
        /// Virtual seconds per wall second at most (1 = real time).
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// Stop after this many seconds of virtual time (default: run until killed).
        #[arg(long)]
        seconds: Option<f64>,
        /// Leave the tool off (by default it goes on once the board is first Ready).
        #[arg(long)]
        without_tool: bool,
    },
    /// Check that the image fits the STM32F405; exit 1 when it does not.
    Fit,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let firmware = cli.firmware.unwrap_or_else(default_path);
    let result = match cli.command {
        Command::Scenarios { path, runs, out } => {
            let out = out
                .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/scenarios"));
            scenarios(&firmware, path, runs, &out)
        }
        Command::Serve {
            socket,
            speed,
            seconds,
            without_tool,
        } => serve(firmware, &socket, speed, seconds, !without_tool),
        Command::Fit => fit(&firmware),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("board-emulator: {e}");
            ExitCode::FAILURE
        }
    }
}

fn fit(firmware: &Path) -> Result<bool, String> {
    let f = Firmware::read(firmware).map_err(|e| e.to_string())?;
    let fit = f.fit();
    println!("{}: {fit}", firmware.display());
    println!("fits the STM32F405RG: {}", fit.fits());
    Ok(fit.fits())
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

fn second_run(firmware: &Path, path: &str, out: &Path) -> Result<std::process::Child, String> {
    let exe = std::env::current_exe().map_err(|e| format!("own executable: {e}"))?;
    Process::new(exe)
        .arg("--firmware")
        .arg(firmware)
        .args(["scenarios", "--runs", "1", "--path", path, "--out"])
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

fn scenarios(firmware: &Path, path: PathArg, runs: u8, out: &Path) -> Result<bool, String> {
    let (choice, name) = path_choice(path);
    let started = Instant::now();
    let child = if runs == 2 {
        Some(second_run(firmware, name, out)?)
    } else {
        None
    };
    let options = Options {
        path: choice,
        out: Some(out.to_path_buf()),
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
        "board-emulator scenarios: {} (wall {:.1} s)",
        if ok { "all passed" } else { "FAILED" },
        started.elapsed().as_secs_f64()
    );
    Ok(ok)
}

fn serve(
    firmware: PathBuf,
    socket: &Path,
    speed: f64,
    seconds: Option<f64>,
    with_tool: bool,
) -> Result<bool, String> {
    if !(speed.is_finite() && speed > 0.0) {
        return Err(format!("--speed must be positive, got {speed}"));
    }
    if socket.exists() {
        std::fs::remove_file(socket).map_err(|e| format!("{}: {e}", socket.display()))?;
    }
    let listener = UnixListener::bind(socket).map_err(|e| format!("{}: {e}", socket.display()))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| format!("{}: {e}", socket.display()))?;
    let config = BenchConfig::reference(firmware).map_err(|e| e.to_string())?;
    let mut bench = Bench::start(config).map_err(|e| e.to_string())?;
    println!(
        "board on {} (virtual time paced to {speed}x the wall clock); connect with: host-sim teleop --connect {}",
        socket.display(),
        socket.display()
    );
    let wall0 = Instant::now();
    let virtual0 = bench.now_s();
    let mut stream: Option<UnixStream> = None;
    let mut decoder = MasterDecoder::new();
    let mut state = None;
    let mut tool_on = !with_tool;
    let mut buf = [0u8; 4096];
    loop {
        if stream.is_none() {
            if let Ok((s, _)) = listener.accept() {
                s.set_nonblocking(true).map_err(|e| e.to_string())?;
                println!("{:.3} s: master connected", bench.now_s());
                stream = Some(s);
            }
        }
        if let Some(s) = stream.as_mut() {
            match s.read(&mut buf) {
                Ok(0) => {
                    println!("{:.3} s: master gone", bench.now_s());
                    stream = None;
                }
                Ok(n) => bench.act(Action::Send(buf.get(..n).unwrap_or_default().to_vec())),
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(_) => stream = None,
            }
        }
        bench.run_for(1_000_000).map_err(|e| e.to_string())?;
        let bytes: Vec<u8> = std::mem::take(&mut bench.received)
            .into_iter()
            .map(|(_, b)| b)
            .collect();
        bench.edges.clear();
        bench.pin_writes.clear();
        for b in &bytes {
            if let Some(Ok((_, BoardToMaster::Status(s)))) = decoder.push(*b) {
                if s.state == master_link::RobotState::Ready && !tool_on {
                    // The tool goes on once the robot is homed and parked.
                    bench.act(Action::Tool(Some(board_emulator::mechanics::Tool::THESIS)));
                    tool_on = true;
                    println!("{:.3} s: tool attached (1.2 kg on 0.1 m)", bench.now_s());
                }
                if state != Some(s.state) {
                    println!(
                        "{:.3} s: board {:?} (stop {:?}, fault {:?})",
                        bench.now_s(),
                        s.state,
                        s.stop,
                        s.fault.cause
                    );
                    state = Some(s.state);
                }
            }
        }
        if let Some(s) = stream.as_mut() {
            if !bytes.is_empty() {
                let _ = s.set_nonblocking(false);
                if s.write_all(&bytes).is_err() {
                    stream = None;
                } else {
                    let _ = s.set_nonblocking(true);
                }
            }
        }
        let virtual_s = bench.now_s() - virtual0;
        if seconds.is_some_and(|limit| virtual_s >= limit) {
            break;
        }
        let due = Duration::from_secs_f64(virtual_s / speed);
        let elapsed = wall0.elapsed();
        if due > elapsed {
            std::thread::sleep(due - elapsed);
        }
    }
    let gaps = bench.finish().map_err(|e| e.to_string())?;
    println!("emulator gaps: {gaps}");
    Ok(true)
}
