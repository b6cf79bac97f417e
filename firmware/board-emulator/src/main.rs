//! `board-emulator`: the board's release image on the emulated STM32F4 with the plant.
//! (The closed-loop scenarios with the host's master are `host-sim/board-scenarios`.)
//!
//! * `serve --socket PATH`: boots the image with the plant and serves its master link
//!   (USART3) on a Unix socket, virtual time paced to the wall clock, so that
//!   `host-sim teleop --connect PATH` talks to it as to a board on a desk.
//! * `fit`: whether the image fits the real STM32F405 (flash, SRAM, CCM).

use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::image::{default_path, Firmware};
use clap::{Parser, Subcommand};
use master_link::{BoardToMaster, MasterDecoder};

/// `serve` reports a master that sent nothing for longer than this by the board's clock,
/// s: its heartbeats are due every 20 ms, and the board holds after 100 ms without one.
const MASTER_QUIET_S: f64 = 0.1;

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

#[derive(Subcommand)]
enum Command {
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
        /// Catch up at most this far: when virtual time falls further behind the wall clock
        /// (at `--speed`), the board's clock slips (the board and the plant go on from
        /// where they are) instead of running faster than `--speed` until it has caught
        /// up (default: no limit, always catch up). A master on the wall clock then sees
        /// the board pause, its clock with it, where catching up would show it a board
        /// whose clock runs fast (heartbeats late, targets stale).
        #[arg(long, value_name = "MS")]
        catch_up_ms: Option<f64>,
        /// Report the pacing: a line when virtual time falls behind the wall clock (at
        /// `--speed`) by more than this many ms ("behind the wall clock by more than"),
        /// one when it is back within half of that ("on time again": the largest lag, how
        /// long, what the clock slipped), and, when a master goes, the largest lag while it
        /// was connected. Counted from the first time the board is on time (after the
        /// boot's JIT warm-up). A board behind the wall clock answers late: what a master
        /// on the wall clock measures then is the emulator's host, not the board.
        #[arg(long, value_name = "MS")]
        report_lag_ms: Option<f64>,
    },
    /// Check that the image fits the STM32F405; exit 1 when it does not.
    Fit,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let firmware = cli.firmware.unwrap_or_else(default_path);
    let result = match cli.command {
        Command::Serve {
            socket,
            speed,
            seconds,
            without_tool,
            catch_up_ms,
            report_lag_ms,
        } => serve(
            firmware,
            &socket,
            speed,
            seconds,
            !without_tool,
            Pacing::new(speed, catch_up_ms, report_lag_ms),
        ),
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

fn serve(
    firmware: PathBuf,
    socket: &Path,
    speed: f64,
    seconds: Option<f64>,
    with_tool: bool,
    pacing: Result<Pacing, String>,
) -> Result<bool, String> {
    if !(speed.is_finite() && speed > 0.0) {
        return Err(format!("--speed must be positive, got {speed}"));
    }
    let mut pacing = pacing?;
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
    pacing.start();
    let virtual0 = bench.now_s();
    let mut stream: Option<UnixStream> = None;
    let mut decoder = MasterDecoder::new();
    let mut state = None;
    let mut tool_on = !with_tool;
    let mut buf = [0u8; 4096];
    let mut last_rx_s = bench.now_s();
    loop {
        if stream.is_none() {
            if let Ok((s, _)) = listener.accept() {
                s.set_nonblocking(true).map_err(|e| e.to_string())?;
                println!("{:.3} s: master connected", bench.now_s());
                last_rx_s = bench.now_s();
                stream = Some(s);
                pacing.master_connected();
            }
        }
        if let Some(s) = stream.as_mut() {
            match s.read(&mut buf) {
                Ok(0) => {
                    println!(
                        "{:.3} s: master gone{}",
                        bench.now_s(),
                        pacing.master_gone()
                    );
                    stream = None;
                }
                Ok(n) => {
                    let quiet = bench.now_s() - last_rx_s;
                    if quiet > MASTER_QUIET_S {
                        println!(
                            "{:.3} s: nothing from the master for {:.1} ms of the board's time",
                            bench.now_s(),
                            quiet * 1e3
                        );
                    }
                    last_rx_s = bench.now_s();
                    bench.act(Action::Send(buf.get(..n).unwrap_or_default().to_vec()))
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(e) => {
                    println!(
                        "{:.3} s: master gone ({e}){}",
                        bench.now_s(),
                        pacing.master_gone()
                    );
                    stream = None;
                }
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
                if let Err(e) = s.write_all(&bytes) {
                    println!(
                        "{:.3} s: master gone ({e}){}",
                        bench.now_s(),
                        pacing.master_gone()
                    );
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
        pacing.step(virtual_s, bench.now_s(), stream.is_some());
    }
    let gaps = bench.finish().map_err(|e| e.to_string())?;
    println!("emulator gaps: {gaps}");
    Ok(true)
}

/// How `serve` paces virtual time against the wall clock, and what it reports of it.
struct Pacing {
    speed: f64,
    /// How far behind the board catches up at most, s (`--catch-up-ms`).
    catch_up_s: Option<f64>,
    /// Report spells behind the wall clock beyond this, s (`--report-lag-ms`).
    report_s: Option<f64>,
    /// The wall instant of virtual time 0, moved on by what the clock slipped.
    origin: Instant,
    /// On time once yet (the lag is counted from then on).
    on_time: bool,
    /// The current spell behind the wall clock: its virtual start, its largest lag, what
    /// the clock slipped during it, s.
    spell: Option<(f64, f64, f64)>,
    /// The largest lag and the slip while the current master is connected, s.
    master: (f64, f64),
}

impl Pacing {
    fn new(
        speed: f64,
        catch_up_ms: Option<f64>,
        report_lag_ms: Option<f64>,
    ) -> Result<Self, String> {
        let ms = |name: &str, v: Option<f64>| match v {
            Some(ms) if !(ms.is_finite() && ms >= 0.0) => {
                Err(format!("{name} must be a number of ms >= 0, got {ms}"))
            }
            v => Ok(v.map(|ms| ms * 1e-3)),
        };
        Ok(Pacing {
            speed,
            catch_up_s: ms("--catch-up-ms", catch_up_ms)?,
            report_s: ms("--report-lag-ms", report_lag_ms)?,
            origin: Instant::now(),
            on_time: false,
            spell: None,
            master: (0.0, 0.0),
        })
    }

    /// Virtual time 0 is now.
    fn start(&mut self) {
        self.origin = Instant::now();
    }

    fn master_connected(&mut self) {
        self.master = (0.0, 0.0);
    }

    /// What the pacing was while the master that goes was connected.
    fn master_gone(&self) -> String {
        match (self.report_s, self.catch_up_s) {
            (None, _) => String::new(),
            (Some(_), None) => format!(
                " (largest lag behind the wall clock meanwhile {:.1} ms)",
                self.master.0 * 1e3
            ),
            (Some(_), Some(_)) => format!(
                " (largest lag behind the wall clock meanwhile {:.1} ms; the board's clock slipped {:.1} ms)",
                self.master.0 * 1e3,
                self.master.1 * 1e3
            ),
        }
    }

    /// After a step of the board to `virtual_s` (from virtual time 0; the board's clock
    /// reads `now_s`): waits while the board is ahead of the wall clock; when it is
    /// further behind than it may catch up, its clock slips; reports.
    fn step(&mut self, virtual_s: f64, now_s: f64, master: bool) {
        let due = Duration::from_secs_f64(virtual_s / self.speed);
        let elapsed = self.origin.elapsed();
        if due > elapsed {
            std::thread::sleep(due - elapsed);
        }
        let mut lag = elapsed.saturating_sub(due).as_secs_f64();
        let mut slip = 0.0;
        if let Some(most) = self.catch_up_s {
            if lag > most {
                slip = lag - most;
                self.origin += Duration::from_secs_f64(slip);
                lag = most;
            }
        }
        let Some(limit) = self.report_s else {
            return;
        };
        self.on_time |= lag == 0.0;
        if !self.on_time {
            return;
        }
        let slipped = self.spell.map_or(0.0, |(_, _, s)| s) + slip;
        let behind = lag + slipped;
        if master {
            self.master.0 = self.master.0.max(behind);
            self.master.1 += slip;
        }
        match self.spell {
            None if behind > limit => {
                println!(
                    "{now_s:.3} s: behind the wall clock by more than {:.1} ms (the emulator slower than {}x real time here)",
                    limit * 1e3,
                    self.speed
                );
                self.spell = Some((now_s, behind, slipped));
            }
            Some((t, worst, _)) if lag <= limit / 2.0 && slip == 0.0 => {
                let slipped = if self.catch_up_s.is_some() {
                    format!("; the board's clock slipped {:.1} ms", slipped * 1e3)
                } else {
                    String::new()
                };
                println!(
                    "{now_s:.3} s: on time again: behind the wall clock by up to {:.1} ms for {:.3} s{slipped}",
                    worst.max(behind) * 1e3,
                    now_s - t
                );
                self.spell = None;
            }
            Some((t, worst, _)) => self.spell = Some((t, worst.max(behind), slipped)),
            None => {}
        }
    }
}
