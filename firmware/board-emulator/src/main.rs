//! `board-emulator`: the board's release image on the emulated STM32F4 with the plant.
//! (The closed-loop scenarios with the host's master are `host-sim/board-scenarios`.)
//!
//! * `serve --socket PATH`: boots the image with the plant and serves its master link
//!   (USART3) on a Unix socket, virtual time paced to the wall clock, so that
//!   `host-sim teleop --connect PATH` talks to it as to a board on a desk. With
//!   `--master-lead-ms`, virtual time is also paced by the master (see [`MasterLead`]):
//!   the board never runs further than that beyond the master's last message, so that a
//!   master its host holds up is not taken for a lost one; tests run it so. With
//!   `--clock-lead-ms`, the board shares its clock with the master in a file beside the
//!   socket (`master_link::shared_clock`, see [`SharedClock`]) and runs at most that far
//!   beyond the board time the master last read there: the two in lockstep.
//! * `fit`: whether the image fits the real STM32F405 (flash, SRAM, CCM).

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::fs::FileExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use board_emulator::bench::{Action, Bench, BenchConfig};
use board_emulator::image::{default_path, Firmware};
use board_emulator::miswiring;
use clap::{Parser, Subcommand};
use master_link::{shared_clock, BoardToMaster, MasterDecoder};

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
        /// Pace the board by its master too: while a master is connected, the board's clock
        /// runs at most this many ms beyond the instant (board time) it last received
        /// anything from the master, then waits for the master's next bytes. A master that
        /// its host holds up (a loaded machine) then holds the board with it, and the board
        /// sees its heartbeats on time by its own clock. Keep it below the board's
        /// heartbeat hold (100 ms) and above the master's heartbeat period (20 ms); 50 is
        /// what the tests use. Default: off (the board runs whatever the master does).
        #[arg(long, value_name = "MS")]
        master_lead_ms: Option<f64>,
        /// With `--master-lead-ms`: how long, by the host's clock, the board waits for a
        /// silent master before it runs on without it (a master that stopped its
        /// heartbeats on purpose, or died with the socket open): a failure detector, not a
        /// deadline of the board's.
        #[arg(long, value_name = "MS", default_value_t = 2000.0)]
        master_wait_ms: f64,
        /// Share the board's clock with the master in the file SOCKET.clock
        /// (`master_link::shared_clock`) and, while the connected master writes back the
        /// board time it read there, run at most this many ms beyond its last reading (a
        /// master that reads the clock every millisecond or so: the operator's `Board`).
        /// Such a master's clock is the board's, and the board never runs on while its host
        /// holds the master up: the two in lockstep, so that what the master measures does
        /// not depend on the host's load. A master that does not write readings is paced by
        /// its bytes (`--master-lead-ms`), or not at all. Default: no shared clock.
        #[arg(long, value_name = "MS")]
        clock_lead_ms: Option<f64>,
        /// The image has the second position channel (built with `--features
        /// position-channel`, `rspr-board-position-channel`): the plant's potentiometers on
        /// ADC3.
        #[arg(long)]
        position_channel: bool,
        /// Miswire the robot (repeat for several; see `board_emulator::miswiring`):
        /// motor-reversed=J, encoder-reversed=J, encoders-swapped=J,K, gear-scale=J:1.1,
        /// switch-normally-open=J, brake-inverted=J; J is l1, l2, l3, theta1, theta2,
        /// theta3 or 0..5. Default: wired as the pin map says.
        #[arg(long = "miswire", value_name = "KIND=JOINT")]
        miswire: Vec<String>,
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
            master_lead_ms,
            master_wait_ms,
            clock_lead_ms,
            position_channel,
            miswire,
        } => board_config(firmware, position_channel, &miswire).and_then(|config| {
            serve(
                config,
                &socket,
                speed,
                seconds,
                !without_tool,
                Pacing::new(speed, catch_up_ms, report_lag_ms),
                MasterLead::new(master_lead_ms, clock_lead_ms, master_wait_ms),
            )
        }),
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

/// The bench of `serve`: the reference robot, the image at `firmware`, with the position
/// channel where the image has it, wired as `miswire` says.
fn board_config(
    firmware: PathBuf,
    position_channel: bool,
    miswire: &[String],
) -> Result<BenchConfig, String> {
    let mut config = BenchConfig::reference(firmware).map_err(|e| e.to_string())?;
    if position_channel {
        // The position-channel image's board: the converter on SPI3, the legs' switches
        // moved to make room for it.
        config.board = board_emulator::pins::POSITION_CHANNEL;
    }
    config.position_channel = position_channel;
    config.mechanics.wiring = miswiring::parse(miswire).map_err(|e| format!("--miswire: {e}"))?;
    Ok(config)
}

fn serve(
    config: BenchConfig,
    socket: &Path,
    speed: f64,
    seconds: Option<f64>,
    with_tool: bool,
    pacing: Result<Pacing, String>,
    lead: Result<Option<MasterLead>, String>,
) -> Result<bool, String> {
    if !(speed.is_finite() && speed > 0.0) {
        return Err(format!("--speed must be positive, got {speed}"));
    }
    let mut pacing = pacing?;
    let mut lead = lead?;
    if socket.exists() {
        std::fs::remove_file(socket).map_err(|e| format!("{}: {e}", socket.display()))?;
    }
    // The shared clock before the socket: a master that connects finds it there.
    let clock = match lead.as_ref().and_then(|l| l.clock_lead_s) {
        Some(_) => Some(SharedClock::create(socket)?),
        None => None,
    };
    let listener = UnixListener::bind(socket).map_err(|e| format!("{}: {e}", socket.display()))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| format!("{}: {e}", socket.display()))?;
    let miswired = miswiring::describe(&config.mechanics.wiring);
    if !miswired.is_empty() {
        println!("the robot is miswired: {}", miswired.join(" "));
    }
    let mut bench = Bench::start(config).map_err(|e| e.to_string())?;
    println!(
        "board on {} (virtual time paced to {speed}x the wall clock{}); connect with: host-sim teleop --connect {}",
        socket.display(),
        lead.as_ref().map_or(String::new(), MasterLead::describe),
        socket.display()
    );
    pacing.start();
    let virtual0 = bench.now_s();
    if let Some(c) = &clock {
        c.publish(bench.now_s())?;
    }
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
                if let Some(l) = lead.as_mut() {
                    l.master_connected();
                }
                if let Some(c) = &clock {
                    c.forget_master()?;
                }
            }
        }
        if let Some(s) = stream.as_mut() {
            match s.read(&mut buf) {
                Ok(0) => {
                    println!(
                        "{:.3} s: master gone{}{}",
                        bench.now_s(),
                        pacing.master_gone(),
                        lead.as_ref().map_or(String::new(), MasterLead::report)
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
                    if let Some(l) = lead.as_mut() {
                        l.received();
                    }
                    bench.act(Action::Send(buf.get(..n).unwrap_or_default().to_vec()))
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(e) => {
                    println!(
                        "{:.3} s: master gone ({e}){}{}",
                        bench.now_s(),
                        pacing.master_gone(),
                        lead.as_ref().map_or(String::new(), MasterLead::report)
                    );
                    stream = None;
                }
            }
        }
        if let Some(l) = lead.as_mut() {
            let reading = clock.as_ref().and_then(SharedClock::master_reading_s);
            if stream.is_some() && l.hold(bench.now_s(), last_rx_s, reading) {
                // The board waits for its master: its clock stands, and the wall time
                // this takes is not a lag of the board's.
                let t0 = Instant::now();
                std::thread::sleep(Duration::from_micros(200));
                let held = t0.elapsed();
                l.held(held);
                pacing.hold(held);
                continue;
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
                        "{:.3} s: master gone ({e}){}{}",
                        bench.now_s(),
                        pacing.master_gone(),
                        lead.as_ref().map_or(String::new(), MasterLead::report)
                    );
                    stream = None;
                } else {
                    let _ = s.set_nonblocking(true);
                }
            }
        }
        // The board's time once what it sent until then is on its way: a master that reads
        // it has what the board said before it.
        if let Some(c) = &clock {
            c.publish(bench.now_s())?;
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

/// How `serve` paces virtual time by its master (`--master-lead-ms`): the board and the
/// master each run on the other's clock. The master (`teleop::pacing`) advances its clock
/// by the board's statuses; the board runs at most `lead_s` of its own time beyond the
/// instant it last heard from the master. Neither then sees the other late because their
/// host held one of them up: a master held up for 600 ms of wall time holds the board at
/// `lead_s` past its last heartbeat, and the board's heartbeat watch (hold after 100 ms,
/// `HeartbeatTimeout` after 500 ms, by the board's clock) sees no gap. A master that stays
/// silent longer than `wait` of wall time is let go: the board runs on, and its own
/// heartbeat watch judges the silence.
///
/// No deadlock: the master's heartbeats are due every 20 ms of its clock, which the
/// board's statuses (every 20 ms of board time) advance, so the master's next heartbeat is
/// due before the board reaches `lead_s` (50 ms) beyond the last one.
///
/// With the shared clock (`--clock-lead-ms`, [`SharedClock`]) a master that writes back
/// its readings is paced by them instead: the board runs at most `clock_lead_s` beyond the
/// board time the master last read. Such a master reads the clock whenever it runs (the
/// operator's `Board` waits at most a millisecond at a time) and waits for the board's
/// time itself, so the board stands only while the master's host holds it up: no deadlock,
/// and neither side runs ahead of the other by more than its lead.
struct MasterLead {
    /// The lead beyond the master's last bytes, s (`--master-lead-ms`).
    lead_s: Option<f64>,
    /// The lead beyond the master's last reading of the shared clock, s
    /// (`--clock-lead-ms`): for a master that writes readings, instead of `lead_s`.
    clock_lead_s: Option<f64>,
    /// The master's last reading of the shared clock, board s.
    last_reading_s: Option<f64>,
    wait: Duration,
    /// Host time of the master's last bytes.
    last_rx: Instant,
    /// Since the current master connected: how often the board waited for it (spells),
    /// the total and the longest wait, s; waiting now.
    spells: u32,
    total_s: f64,
    longest_s: f64,
    spell_s: f64,
    waiting: bool,
    /// The master was let go (silent beyond `wait`) this many times.
    let_go: u32,
}

impl MasterLead {
    fn new(
        lead_ms: Option<f64>,
        clock_lead_ms: Option<f64>,
        wait_ms: f64,
    ) -> Result<Option<Self>, String> {
        if lead_ms.is_none() && clock_lead_ms.is_none() {
            return Ok(None);
        }
        let positive = |name: &str, v: Option<f64>| match v {
            Some(ms) if !(ms.is_finite() && ms > 0.0) => {
                Err(format!("{name} must be a number of ms > 0, got {ms}"))
            }
            v => Ok(v.map(|ms| ms * 1e-3)),
        };
        let lead_s = positive("--master-lead-ms", lead_ms)?;
        let clock_lead_s = positive("--clock-lead-ms", clock_lead_ms)?;
        if !(wait_ms.is_finite() && wait_ms >= 0.0) {
            return Err(format!(
                "--master-wait-ms must be a number of ms >= 0, got {wait_ms}"
            ));
        }
        Ok(Some(MasterLead::fresh(
            lead_s,
            clock_lead_s,
            Duration::from_secs_f64(wait_ms * 1e-3),
        )))
    }

    fn fresh(lead_s: Option<f64>, clock_lead_s: Option<f64>, wait: Duration) -> Self {
        MasterLead {
            lead_s,
            clock_lead_s,
            last_reading_s: None,
            wait,
            last_rx: Instant::now(),
            spells: 0,
            total_s: 0.0,
            longest_s: 0.0,
            spell_s: 0.0,
            waiting: false,
            let_go: 0,
        }
    }

    fn master_connected(&mut self) {
        *self = MasterLead::fresh(self.lead_s, self.clock_lead_s, self.wait);
    }

    /// The pacing by the master, for the start-up line.
    fn describe(&self) -> String {
        let mut s = String::new();
        if let Some(l) = self.lead_s {
            s += &format!(
                " and to at most {:.0} ms beyond the master's last message",
                l * 1e3
            );
        }
        if let Some(l) = self.clock_lead_s {
            s +=
                &format!(
                "{} to at most {:.0} ms beyond a master's last reading of the clock shared in {}{}",
                if self.lead_s.is_some() { ", or" } else { " and" },
                l * 1e3,
                "SOCKET",
                shared_clock::SUFFIX
            );
        }
        s
    }

    /// Bytes from the master arrived.
    fn received(&mut self) {
        self.last_rx = Instant::now();
        self.waiting = false;
    }

    /// Whether the board waits at board time `now_s`: the master's last bytes came at
    /// `last_rx_s`, and `reading_s` is its last reading of the shared clock (None: it
    /// writes none). A master that writes readings is paced by them, others by their bytes.
    fn hold(&mut self, now_s: f64, last_rx_s: f64, reading_s: Option<f64>) -> bool {
        let (quiet_s, lead_s) = match (self.clock_lead_s, reading_s) {
            (Some(lead), Some(r)) => {
                if self.last_reading_s != Some(r) {
                    // A new reading: the master runs (the wait below counts from here).
                    self.last_reading_s = Some(r);
                    self.received();
                }
                (now_s - r, lead)
            }
            _ => match self.lead_s {
                Some(lead) => (now_s - last_rx_s, lead),
                None => return false,
            },
        };
        if quiet_s < lead_s {
            return false;
        }
        if self.last_rx.elapsed() >= self.wait {
            if self.waiting {
                self.let_go += 1;
                self.waiting = false;
            }
            return false;
        }
        if !self.waiting {
            self.waiting = true;
            self.spells += 1;
            self.spell_s = 0.0;
        }
        true
    }

    /// The board waited `d` more.
    fn held(&mut self, d: Duration) {
        self.spell_s += d.as_secs_f64();
        self.total_s += d.as_secs_f64();
        self.longest_s = self.longest_s.max(self.spell_s);
    }

    /// What the board waited for the master that goes.
    fn report(&self) -> String {
        format!(
            " (the board waited for it {} times, {:.1} ms in all, longest {:.1} ms; let it go {} times)",
            self.spells,
            self.total_s * 1e3,
            self.longest_s * 1e3,
            self.let_go
        )
    }
}

/// The board's clock shared with its master (`master_link::shared_clock`): the file
/// SOCKET.clock, created afresh by `serve` and removed when it ends.
struct SharedClock {
    file: File,
    path: PathBuf,
}

impl SharedClock {
    fn create(socket: &Path) -> Result<Self, String> {
        let mut name = socket.as_os_str().to_owned();
        name.push(shared_clock::SUFFIX);
        let path = PathBuf::from(name);
        let err = |e: std::io::Error| format!("the shared clock {}: {e}", path.display());
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(err)?;
        file.set_len(shared_clock::LEN).map_err(err)?;
        Ok(SharedClock { file, path })
    }

    /// Writes the board's time, s.
    fn publish(&self, now_s: f64) -> Result<(), String> {
        let us = (now_s * 1e6).round() as u64;
        self.file
            .write_all_at(&shared_clock::encode(us), shared_clock::BOARD_US)
            .map_err(|e| format!("the shared clock {}: {e}", self.path.display()))
    }

    /// Forgets the last master's readings (a new master connected).
    fn forget_master(&self) -> Result<(), String> {
        self.file
            .write_all_at(&shared_clock::encode(0), shared_clock::MASTER_US)
            .map_err(|e| format!("the shared clock {}: {e}", self.path.display()))
    }

    /// The board time the master last read, s (None: none written, or unreadable now).
    fn master_reading_s(&self) -> Option<f64> {
        let read = || {
            let mut b = [0u8; 8];
            self.file
                .read_exact_at(&mut b, shared_clock::MASTER_US)
                .ok()?;
            Some(shared_clock::decode(b))
        };
        // Two reads in a row that agree (a write may race a read).
        let mut last = read()?;
        for _ in 0..4 {
            let again = read()?;
            if again == last {
                return (again != 0).then_some(again as f64 * 1e-6);
            }
            last = again;
        }
        None
    }
}

impl Drop for SharedClock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
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

    /// The board's clock stood for `d` of wall time, waiting for its master: virtual time
    /// 0 moves on by as much (a wait is not a lag).
    fn hold(&mut self, d: Duration) {
        self.origin += d;
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// A wait for the master that no test reaches (the let-go is host time).
    const FOREVER: Duration = Duration::from_secs(3600);

    /// A master that does not use the shared clock (a real master, or one on a serial
    /// device): without `--master-lead-ms` and `--clock-lead-ms` the board never waits for
    /// it (the wall clock alone, as before the shared clock); with `--master-lead-ms` alone
    /// it waits exactly from `lead` beyond the master's last bytes, whatever a clock file
    /// may say (without `--clock-lead-ms` a reading is not looked at).
    #[test]
    fn without_the_shared_clock_the_board_runs_on_the_wall_clock_or_the_masters_bytes() {
        assert!(MasterLead::new(None, None, 2000.0).unwrap().is_none());
        let mut l = MasterLead::new(Some(50.0), None, 2000.0).unwrap().unwrap();
        l.wait = FOREVER;
        for reading in [None, Some(1.0), Some(1.049)] {
            assert!(!l.hold(1.0499, 1.0, reading), "{reading:?}");
            assert!(l.hold(1.0501, 1.0, reading), "{reading:?}");
        }
        // New bytes move the bound.
        l.received();
        assert!(!l.hold(1.0501, 1.03, None));
    }

    /// With `--clock-lead-ms`, a master that writes back its readings is paced by them
    /// (not by its bytes): the board waits from `clock_lead` beyond the last reading, even
    /// right after the master's bytes, and not before, even long after them. One that
    /// writes none (None: a real master, the console, the bridge) is paced by its bytes
    /// as without the shared clock, or not at all without `--master-lead-ms`.
    #[test]
    fn with_the_shared_clock_readings_pace_and_masters_without_readings_are_paced_by_bytes() {
        let mut l = MasterLead::fresh(Some(0.05), Some(0.002), FOREVER);
        assert!(!l.hold(1.0019, 1.0019, Some(1.0)));
        assert!(l.hold(1.0021, 1.0021, Some(1.0)), "bytes just now");
        assert!(!l.hold(1.0999, 1.0, Some(1.098)), "bytes 100 ms ago");
        assert!(!l.hold(1.0499, 1.0, None));
        assert!(l.hold(1.0501, 1.0, None));
        let mut l = MasterLead::fresh(None, Some(0.002), FOREVER);
        assert!(!l.hold(100.0, 1.0, None), "no reading, no --master-lead-ms");
        assert!(l.hold(100.0, 1.0, Some(99.0)));
    }

    /// A master silent for `--master-wait-ms` of host time is let go: the board runs on.
    #[test]
    fn a_master_silent_beyond_the_wait_is_let_go() {
        let mut l = MasterLead::fresh(Some(0.05), Some(0.002), Duration::ZERO);
        assert!(!l.hold(2.0, 1.0, None));
        assert!(!l.hold(2.0, 1.0, Some(1.0)));
    }

    /// The clock file: created at the board's socket's path with the suffix, the board's
    /// time written where a master reads it, the master's reading read back (none when
    /// nothing or 0 is written: a new master's slate is clean), removed with the board.
    #[test]
    fn the_shared_clock_file_carries_both_times_and_goes_with_the_board() {
        let socket = std::env::temp_dir().join(format!("rspr-emu-{}.sock", std::process::id()));
        let clock = SharedClock::create(&socket).unwrap();
        let mut path = socket.as_os_str().to_owned();
        path.push(shared_clock::SUFFIX);
        let path = PathBuf::from(path);
        let file = File::options().read(true).write(true).open(&path).unwrap();
        assert_eq!(file.metadata().unwrap().len(), shared_clock::LEN);
        clock.publish(1.234_567).unwrap();
        let mut b = [0u8; 8];
        file.read_exact_at(&mut b, shared_clock::BOARD_US).unwrap();
        assert_eq!(shared_clock::decode(b), 1_234_567);
        assert_eq!(clock.master_reading_s(), None);
        file.write_all_at(&shared_clock::encode(1_230_000), shared_clock::MASTER_US)
            .unwrap();
        let r = clock.master_reading_s().unwrap();
        assert!((r - 1.23).abs() < 1e-9, "{r}");
        clock.forget_master().unwrap();
        assert_eq!(clock.master_reading_s(), None);
        drop(clock);
        assert!(!path.exists());
    }
}
