//! The closed loop in virtual time: the image on the board, the mechanics stepped in lockstep
//! with it, and a handle the master drives it through.
//!
//! rigless runs the core on a thread of its own and calls a [`Driver`] at every instant it was
//! asked to reach. The driver ([`Lockstep`]) asks for one every plant step (100 µs): there it
//! steps the mechanics under the outputs read off the pins at the previous step, hands the
//! new signals to the board (the MCU applies them at that same instant, before the core runs
//! on), and reads the outputs for the next step; every millisecond it refreshes the tool's
//! loads and drains RTT as a probe would. The event log's flash sectors are kept in a
//! shadow the next run starts from ([`crate::flash`]: each programmed word also holds the
//! core for the programming time, as the part's single bank stalls it). When the run
//! reaches the instant the master asked for ([`Bench::run_until`]) it hands the master a
//! [`Report`] and waits for its next
//! [`Command`] (bytes for the link, changes of the surroundings, watches), so the master runs
//! on the caller's thread in strict alternation with the core: nothing depends on the wall
//! clock, and two runs are the same run.

use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use rigless::device::ResetCause;
use rigless::emulator::{self, Driver, HitKind, Host, Settled, Start, Stop, Watch};
use rigless::mcu::{Mcu, Operate};
use rigless::session::Session;
use rigless::soc::stm32f427::generated::rcc::Register as RccRegister;
use rigless::soc::Width;
use rigless::time::VirtualNanos;
use sha2::{Digest, Sha256};

use crate::board::{BoardError, Outputs, RsprBoard};
use crate::flash::{
    FlashOp, FlashShadow, Staged, EVENTS_BASE, FLASH_CR, GEOMETRY_BASE, GEOMETRY_SLOT_LEN,
    KEPT_LEN, MAILBOX_WORDS,
};
use crate::image::{Firmware, ImageError};
use crate::mechanics::{Mechanics, MechanicsConfig, MechanicsError, Surroundings};
use crate::stack::{StackRegion, StackUse};

/// Nanoseconds in a second.
pub const NANOS_PER_SECOND: u64 = 1_000_000_000;

/// The longest a 32-bit word takes to program on the F405, ns (DS8626, "Flash memory
/// programming", x32 parallelism: 16 µs typical, 100 µs maximum): the bench's default, the
/// worst case.
pub const FLASH_WORD_MAX_NS: u64 = 100_000;

/// Why the bench failed.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The image.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// The board.
    #[error(transparent)]
    Board(#[from] BoardError),
    /// The mechanics.
    #[error(transparent)]
    Mechanics(#[from] MechanicsError),
    /// rigless refused the session or the run.
    #[error("emulator: {0}")]
    Emulator(String),
    /// The emulator's thread ended (the run failed or finished) while the master waited.
    #[error("the emulator stopped: {0}")]
    Stopped(String),
    /// The second position channel asked of a board without it, or the other way round.
    #[error("bench setting position_channel = {position_channel} on the board {board:?}, which {}", if *position_channel { "has no second position channel (use pins::POSITION_CHANNEL)" } else { "has the second position channel (set position_channel)" })]
    PositionChannel {
        /// The setting.
        position_channel: bool,
        /// The board's name.
        board: &'static str,
    },
    /// A setting is out of range.
    #[error("bench setting {what}: {value}")]
    Setting {
        /// Which.
        what: &'static str,
        /// Its value.
        value: u64,
    },
}

/// How the bench is set up.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    /// The release ELF.
    pub firmware: PathBuf,
    /// The board the image is built for (its pins and current sense).
    pub board: crate::pins::BoardTarget,
    /// The plant step, ns.
    pub plant_step_ns: u64,
    /// Stops, switches, the tool and where the joints start.
    pub mechanics: MechanicsConfig,
    /// Record every peripheral access from the first instruction up to this instant, ns.
    pub record_until_ns: u64,
    /// The event log's flash sectors at power-up (from [`crate::flash::EVENTS_BASE`]; a
    /// previous run's [`Bench::flash`]), or erased.
    pub flash: Option<Vec<u8>>,
    /// How long each programmed word holds the core, ns (DS8626, "Flash memory
    /// programming", x32: 16 µs typical, 100 µs at most).
    pub flash_word_ns: u64,
    /// The board has the second position channel (the image built with
    /// `--features position-channel`, `board` = [`crate::pins::POSITION_CHANNEL`]): the
    /// plant's potentiometers on the AD7689 on SPI3 ([`crate::position_channel`]).
    pub position_channel: bool,
}

impl BenchConfig {
    /// The image at `firmware`, the reference robot at its central configuration without
    /// its tool (`Action::Tool` attaches it), a 100 µs plant step.
    pub fn reference(firmware: PathBuf) -> Result<Self, BenchError> {
        Ok(BenchConfig {
            firmware,
            board: crate::pins::REFERENCE,
            plant_step_ns: 100_000,
            mechanics: MechanicsConfig::reference(None)?,
            record_until_ns: 0,
            flash: None,
            flash_word_ns: FLASH_WORD_MAX_NS,
            position_channel: false,
        })
    }
}

/// What the master asks of the world; it happens at the instant of the report it answers.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Bytes onto the link (USART3 RX), paced by the port's baud from now.
    Send(Vec<u8>),
    /// The surroundings: e-stop, safety relay, supply, drivers.
    Surroundings(Surroundings),
    /// Attach the tool (`Some`) or take it off.
    Tool(Option<crate::mechanics::Tool>),
    /// Hold the core for `ns`: it executes nothing while the clock and every peripheral run
    /// on, as a bus stall does (a flash erase or program the core fetches from, RM0090 rev 19
    /// section 3.5; a debugger's halt with the timers not frozen).
    HoldCore(u64),
    /// Assert the e-stop `delay_ns` after the core next arrives at `address` (e.g. the control
    /// interrupt's handler), and record every peripheral access for `record_ns` from there.
    EstopAfterInstruction {
        /// The instruction.
        address: u64,
        /// Delay after the arrival, ns.
        delay_ns: u64,
        /// How long to record accesses, ns.
        record_ns: u64,
    },
    /// Record every peripheral access for the next `ns`.
    Record(u64),
    /// Read these 32-bit registers now, as a probe does (nothing in the run changes).
    Peek(Vec<u64>),
    /// Report each arrival at `address`.
    WatchInstruction(u64),
    /// Stop reporting arrivals at `address`.
    UnwatchInstruction(u64),
    /// Inject a fault of the plant into a joint (`plant::Fault`: an encoder that sticks or
    /// miscounts, a position sensor that sticks, ...).
    PlantFault {
        /// The joint, 0..6.
        joint: usize,
        /// The fault.
        fault: plant::Fault,
    },
    /// Measure the stack's low-water mark now (`crate::stack`; nothing in the run
    /// changes): the next report's `stack`.
    MeasureStack,
}

/// One peripheral access, as recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Recorded {
    /// Its instant.
    pub at: VirtualNanos,
    /// The instruction that made it.
    pub pc: Option<u64>,
    /// The address.
    pub address: u64,
    /// Write (else read).
    pub write: bool,
    /// The value read or written.
    pub value: u64,
}

/// A reset of the part.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ResetSeen {
    /// When.
    pub at: VirtualNanos,
    /// Why: `core`, `pin`, `power-on` or the instance (`IWDG`).
    pub cause: String,
}

/// What the master is handed at each of its turns.
#[derive(Debug, Clone)]
pub struct Report {
    /// The instant.
    pub at: VirtualNanos,
    /// Instructions retired so far.
    pub instructions: u64,
    /// Bytes the board sent since the last report, with the instant each arrived.
    pub received: Vec<(VirtualNanos, u8)>,
    /// The outputs as last read.
    pub outputs: Outputs,
    /// The outputs at every plant step where they changed (enable, brakes, LED, DIR, or a
    /// duty leaving or reaching zero) since the last report.
    pub edges: Vec<(VirtualNanos, Outputs)>,
    /// True joint positions (load side), m / rad.
    pub q: [f64; 6],
    /// Arrivals at watched instructions since the last report.
    pub hits: Vec<(VirtualNanos, u64)>,
    /// Accesses recorded since the last report.
    pub recorded: Vec<Recorded>,
    /// The e-stop assertion the last `EstopAfterInstruction` made, and the arrival it followed.
    pub estop_edge: Option<(VirtualNanos, VirtualNanos)>,
    /// Registers peeked since the last report: address, value (`None`: nothing answers).
    pub peeked: Vec<(u64, Option<u64>)>,
    /// The firmware's writes to the GPIO ports' `BSRR` and `ODR` since the last report (every
    /// one, whatever is recorded): the output pins' changes at their exact instants.
    pub pin_writes: Vec<Recorded>,
    /// Every reset of the part so far.
    pub resets: Vec<ResetSeen>,
    /// The event log's flash operations (programmed words, erased sectors) since the last
    /// report.
    pub flash_ops: Vec<FlashOp>,
    /// `RCC_CSR` (reset flags) now.
    pub rcc_csr: u64,
    /// RTT bytes (defmt frames) drained so far.
    pub rtt_bytes: u64,
    /// Digest of the run so far (outputs, signals, link bytes, RTT, resets at every step).
    pub digest: [u8; 32],
    /// Bytes still queued for the link.
    pub queued: usize,
    /// The stack's use as last measured (`Action::MeasureStack`; `None` before, or when
    /// the image has no stack symbols).
    pub stack: Option<StackUse>,
}

impl Report {
    /// A report of nothing, at 0.
    pub fn empty() -> Self {
        Report {
            at: VirtualNanos(0),
            instructions: 0,
            received: Vec::new(),
            outputs: Outputs::OFF,
            edges: Vec::new(),
            q: [0.0; 6],
            hits: Vec::new(),
            recorded: Vec::new(),
            estop_edge: None,
            peeked: Vec::new(),
            pin_writes: Vec::new(),
            resets: Vec::new(),
            flash_ops: Vec::new(),
            rcc_csr: 0,
            rtt_bytes: 0,
            digest: [0; 32],
            queued: 0,
            stack: None,
        }
    }
}

/// The master's answer.
#[derive(Debug)]
enum Command {
    /// Run on to `until` (the next report), doing `actions` now.
    Continue {
        until: VirtualNanos,
        actions: Vec<Action>,
    },
    /// End the run.
    Finish,
}

struct Armed {
    address: u64,
    delay: u64,
    record: u64,
}

/// The driver on the emulator's thread.
struct Lockstep {
    mechanics: Mechanics,
    plant_step: u64,
    next_plant: u64,
    next_ms: u64,
    master_at: u64,
    outputs: Outputs,
    edges: Vec<(VirtualNanos, Outputs)>,
    to_master: SyncSender<Report>,
    from_master: Receiver<Command>,
    hits: Vec<(VirtualNanos, u64)>,
    watched: Vec<u64>,
    armed: Option<Armed>,
    estop_at: Option<u64>,
    estop_edge: Option<(VirtualNanos, VirtualNanos)>,
    hold_until: Option<u64>,
    peeked: Vec<(u64, Option<u64>)>,
    pin_writes: Vec<Recorded>,
    record_until: u64,
    recorded: Vec<Recorded>,
    rtt_block: Option<u64>,
    rtt_bytes: u64,
    hasher: Sha256,
    failed: Option<String>,
    /// The event log's flash, shared with the master's handle.
    flash: Arc<Mutex<FlashShadow>>,
    /// The image's program mailbox, if it has one.
    mailbox: Option<u64>,
    /// The image's geometry slot mailbox, if it has one.
    geometry_mailbox: Option<u64>,
    flash_word_ns: u64,
    /// The board has the second position channel.
    position_channel: bool,
    /// The image's stack region (painted before the first instruction), if it names one.
    stack_region: Option<StackRegion>,
    /// The stack's use as last measured.
    stack: Option<StackUse>,
}

const MS: u64 = 1_000_000;

/// A GPIO port's `ODR` or `BSRR` (ports A..G, the boards' ports; RM0090 rev 19 section 8.4).
fn is_pin_write(address: u64) -> bool {
    (0x4002_0000..0x4002_1C00).contains(&address) && matches!(address & 0x3FF, 0x14 | 0x18)
}

fn cause_name(cause: &ResetCause) -> String {
    match cause {
        ResetCause::Core => "core".into(),
        ResetCause::Model(name) => (*name).into(),
        ResetCause::Pin => "pin".into(),
        ResetCause::PowerOn => "power-on".into(),
        _ => "other".into(),
    }
}

/// Whether two outputs differ in what the edge log keeps: the pins, and each duty's being
/// zero or not.
fn edge_between(a: &Outputs, b: &Outputs) -> bool {
    a.bits() != b.bits()
        || a.duty
            .iter()
            .zip(b.duty)
            .any(|(x, y)| (*x == 0.0) != (y == 0.0))
}

impl Lockstep {
    fn next_instant(&self) -> u64 {
        let mut next = self.next_plant.min(self.master_at);
        for t in [self.estop_at, self.hold_until].into_iter().flatten() {
            next = next.min(t);
        }
        next
    }

    /// Drains RTT up-channel 0 as a probe does (SEGGER RTT control block: ID, two counts,
    /// then the up-channel's name, buffer, size, write and read offsets).
    fn drain_rtt(&mut self, host: &mut dyn Host) {
        let Some(block) = self.rtt_block else { return };
        let up = block + 24;
        let word = |host: &mut dyn Host, at: u64| host.read(at, Width::W32).ok();
        let (Some(buffer), Some(size), Some(write), Some(read)) = (
            word(host, up + 4),
            word(host, up + 8),
            word(host, up + 12),
            word(host, up + 16),
        ) else {
            return;
        };
        if size == 0 || write >= size || read >= size {
            return;
        }
        let mut at = read;
        while at != write {
            if let Ok(b) = host.read(buffer + at, Width::W8) {
                self.hasher
                    .update([u8::try_from(b & 0xFF).unwrap_or_default()]);
                self.rtt_bytes += 1;
            }
            at = (at + 1) % size;
        }
        let _ = host.write(up + 16, Width::W32, write);
    }

    /// The image's program mailbox now (address, length, words), as a probe reads it.
    fn staged(&self, host: &mut dyn Host) -> Option<Staged> {
        let at = self.mailbox?;
        let word = |host: &mut dyn Host, a: u64| host.read(a, Width::W32).ok();
        let address = word(host, at)?;
        let len = usize::try_from(word(host, at + 4)?).ok()?;
        let mut words = [0u32; MAILBOX_WORDS];
        for (i, w) in words.iter_mut().enumerate() {
            *w = u32::try_from(word(host, at + 8 + 4 * i as u64)?).ok()?;
        }
        Some(Staged {
            address,
            len: len.min(MAILBOX_WORDS),
            words,
        })
    }

    /// The word the image's geometry mailbox holds for `address` (a store into the
    /// geometry's sector), as a probe reads it.
    fn geometry_staged(&self, host: &mut dyn Host, address: u64) -> Option<Staged> {
        let at = self.geometry_mailbox?;
        let base = host.read(at, Width::W32).ok()?;
        let off = address.checked_sub(base)?;
        if off >= GEOMETRY_SLOT_LEN || off % 4 != 0 {
            return None;
        }
        let word = u32::try_from(host.read(at + 4 + off, Width::W32).ok()?).ok()?;
        let mut words = [0u32; MAILBOX_WORDS];
        words[0] = word;
        Some(Staged {
            address,
            len: 1,
            words,
        })
    }

    /// A store landed in the event log's sectors: programmed into the shadow, and the core
    /// held for the word's programming time, the run stopping when it ends.
    fn flash_store(
        &mut self,
        session: &mut Session<RsprBoard>,
        host: &mut dyn Host,
        at: VirtualNanos,
        address: u64,
    ) {
        let staged = if address >= GEOMETRY_BASE {
            self.geometry_staged(host, address)
        } else {
            self.staged(host)
        };
        let word = match self.flash.lock() {
            Ok(mut f) => f.stored(at, address, staged),
            Err(_) => None,
        };
        if let Some(word) = word {
            self.hasher.update(at.0.to_le_bytes());
            self.hasher.update(address.to_le_bytes());
            self.hasher.update(word.to_le_bytes());
            if self.flash_word_ns > 0 {
                let until = at.0 + self.flash_word_ns;
                host.hold(true);
                self.hold_until = Some(self.hold_until.map_or(until, |h| h.max(until)));
                let next = session.until().0.min(until);
                session.run_until(VirtualNanos(next));
            }
        }
    }

    fn plant_step(&mut self, session: &mut Session<RsprBoard>, now: u64) {
        let dt = self.plant_step as f64 / NANOS_PER_SECOND as f64;
        if let Err(e) = self.mechanics.step(&self.outputs, dt) {
            self.failed.get_or_insert(e.to_string());
        }
        let signals = self.mechanics.signals();
        let positions = self
            .position_channel
            .then(|| self.mechanics.position_counts());
        let board = session.board_mut();
        board.sense(&signals);
        if let Some(counts) = positions {
            crate::position_channel::sense(&mut board.mcu, &counts);
        }
        let out = board.drive();
        if edge_between(&out, &self.outputs) {
            self.edges.push((VirtualNanos(now), out));
        }
        self.outputs = out;
        // The digest: the outputs and the signals of every step.
        for d in out.duty {
            self.hasher.update(d.to_bits().to_le_bytes());
        }
        self.hasher.update(out.bits().to_le_bytes());
        for c in signals.encoder_counts {
            self.hasher.update(c.to_le_bytes());
        }
        for i in signals.currents_a {
            self.hasher.update(i.to_bits().to_le_bytes());
        }
        for c in positions.iter().flatten() {
            self.hasher.update(c.to_le_bytes());
        }
    }

    fn sense_now(&mut self, session: &mut Session<RsprBoard>) {
        let s = self.mechanics.signals();
        session.board_mut().sense(&s);
    }

    fn apply(
        &mut self,
        session: &mut Session<RsprBoard>,
        host: &mut dyn Host,
        actions: Vec<Action>,
        now: u64,
    ) {
        for action in actions {
            match action {
                Action::Send(bytes) => {
                    self.hasher.update(now.to_le_bytes());
                    self.hasher.update(&bytes);
                    if let Some(wire) = session.board_mut().wire() {
                        wire.send(&bytes);
                    }
                }
                Action::Surroundings(s) => {
                    if let Err(e) = self.mechanics.set_surroundings(s) {
                        self.failed.get_or_insert(e.to_string());
                    }
                    self.sense_now(session);
                }
                Action::Tool(tool) => {
                    if let Err(e) = self.mechanics.set_tool(tool) {
                        self.failed.get_or_insert(e.to_string());
                    }
                }
                Action::HoldCore(ns) => {
                    host.hold(true);
                    self.hold_until = Some(now + ns.max(1));
                }
                Action::Peek(addresses) => {
                    let mcu = &mut session.board_mut().mcu;
                    for a in addresses {
                        let v = mcu.peek(VirtualNanos(now), a, Width::W32).ok();
                        self.peeked.push((a, v));
                    }
                }
                Action::Record(ns) => {
                    self.record_until = self.record_until.max(now + ns);
                }
                Action::EstopAfterInstruction {
                    address,
                    delay_ns,
                    record_ns,
                } => {
                    session.watch(Watch::Instruction(address));
                    self.armed = Some(Armed {
                        address,
                        delay: delay_ns,
                        record: record_ns,
                    });
                }
                Action::WatchInstruction(a) => {
                    session.watch(Watch::Instruction(a));
                    self.watched.push(a);
                }
                Action::UnwatchInstruction(a) => {
                    session.unwatch(Watch::Instruction(a));
                    self.watched.retain(|w| *w != a);
                }
                Action::PlantFault { joint, fault } => {
                    self.hasher.update(now.to_le_bytes());
                    self.hasher.update((joint as u64).to_le_bytes());
                    if let Err(e) = self.mechanics.inject(joint, fault) {
                        self.failed.get_or_insert(e.to_string());
                    }
                }
                Action::MeasureStack => {
                    self.stack = self.stack_region.map(|region| StackUse {
                        region,
                        lowest: region.low_water(|a| {
                            host.read(a, Width::W32)
                                .ok()
                                .and_then(|v| u32::try_from(v).ok())
                        }),
                    });
                }
            }
        }
    }

    fn report(&mut self, session: &mut Session<RsprBoard>, stop: &Stop) -> Report {
        let resets: Vec<ResetSeen> = session
            .resets()
            .iter()
            .map(|r| ResetSeen {
                at: r.at,
                cause: cause_name(&r.cause),
            })
            .collect();
        let board = session.board_mut();
        let rcc_csr = board
            .mcu
            .bus()
            .registers("RCC")
            .map_or(0, |r| r.get(RccRegister::Csr));
        let (received, queued) = match board.wire() {
            Some(w) => (w.take_received(), w.queued()),
            None => (Vec::new(), 0),
        };
        for (t, b) in &received {
            self.hasher.update(t.0.to_le_bytes());
            self.hasher.update([*b]);
        }
        self.hasher.update((resets.len() as u64).to_le_bytes());
        Report {
            at: stop.at,
            instructions: stop.instruction_count,
            received,
            outputs: self.outputs,
            edges: std::mem::take(&mut self.edges),
            q: self.mechanics.plant().joint_positions(),
            hits: std::mem::take(&mut self.hits),
            recorded: std::mem::take(&mut self.recorded),
            estop_edge: self.estop_edge.take(),
            peeked: std::mem::take(&mut self.peeked),
            pin_writes: std::mem::take(&mut self.pin_writes),
            resets,
            flash_ops: self
                .flash
                .lock()
                .map(|mut f| f.take_ops())
                .unwrap_or_default(),
            rcc_csr,
            rtt_bytes: self.rtt_bytes,
            digest: self.hasher.clone().finalize().into(),
            queued,
            stack: self.stack,
        }
    }
}

impl Driver<RsprBoard> for Lockstep {
    fn on_settled(
        &mut self,
        session: &mut Session<RsprBoard>,
        host: &mut dyn Host,
        settled: Settled,
    ) {
        match settled {
            Settled::Access { access, value } => {
                let r = Recorded {
                    at: access.virtual_time,
                    pc: access.program_counter,
                    address: access.address,
                    write: access.kind == rigless::emulator::AccessKind::Write,
                    value,
                };
                if r.write && is_pin_write(r.address) {
                    self.pin_writes.push(r);
                }
                if r.write && r.address == FLASH_CR {
                    if let Ok(mut f) = self.flash.lock() {
                        f.control_written(r.at, r.value);
                    }
                }
                if access.virtual_time.0 <= self.record_until {
                    self.recorded.push(r);
                }
            }
            Settled::Hit(hit) => {
                if hit.kind == HitKind::Write && FlashShadow::holds(hit.address) {
                    self.flash_store(session, host, hit.at, hit.address);
                    return;
                }
                if let Some(armed) = &self.armed {
                    if hit.address == armed.address && self.estop_at.is_none() {
                        let at = hit.at.0 + armed.delay;
                        self.estop_at = Some(at);
                        self.record_until = at + armed.record;
                        self.estop_edge = Some((VirtualNanos(at), hit.at));
                        session.unwatch(Watch::Instruction(armed.address));
                        self.armed = None;
                        // Stop at the edge's instant.
                        let until = session.until().0.min(at);
                        session.run_until(VirtualNanos(until));
                        return;
                    }
                }
                if self.watched.contains(&hit.address) {
                    self.hits.push((hit.at, hit.address));
                }
            }
            _ => {}
        }
    }

    fn on_stop(
        &mut self,
        session: &mut Session<RsprBoard>,
        stop: Stop,
        host: &mut dyn Host,
    ) -> Option<VirtualNanos> {
        let now = stop.at.0;
        if self.failed.is_some() {
            return None;
        }
        if self.hold_until.is_some_and(|h| now >= h) {
            self.hold_until = None;
            host.hold(false);
        }
        if self.estop_at.is_some_and(|e| now >= e) {
            self.estop_at = None;
            let s = Surroundings {
                estop_pressed: true,
                ..*self.mechanics.surroundings()
            };
            if let Err(e) = self.mechanics.set_surroundings(s) {
                self.failed.get_or_insert(e.to_string());
            }
            self.sense_now(session);
        }
        while now >= self.next_plant {
            let at = self.next_plant;
            self.plant_step(session, at);
            self.next_plant += self.plant_step;
        }
        if now >= self.next_ms {
            if let Err(e) = self.mechanics.refresh_loads() {
                self.failed.get_or_insert(e.to_string());
            }
            self.drain_rtt(host);
            self.next_ms = (now / MS + 1) * MS;
        }
        if now >= self.master_at {
            let report = self.report(session, &stop);
            if self.to_master.send(report).is_err() {
                return None;
            }
            match self.from_master.recv() {
                Ok(Command::Continue { until, actions }) => {
                    self.apply(session, host, actions, now);
                    self.master_at = until.0.max(now + 1);
                }
                Ok(Command::Finish) | Err(_) => return None,
            }
        }
        Some(VirtualNanos(self.next_instant()))
    }
}

/// The running bench, driven from the caller's thread.
pub struct Bench {
    to_driver: SyncSender<Command>,
    from_driver: Receiver<Report>,
    thread: Option<JoinHandle<Result<String, String>>>,
    now: VirtualNanos,
    pending: Vec<Action>,
    /// The last report (its logs moved to the bench's).
    pub last: Report,
    /// Bytes the board sent and the master has not taken, with their instants.
    pub received: Vec<(VirtualNanos, u8)>,
    /// The output edges not yet taken.
    pub edges: Vec<(VirtualNanos, Outputs)>,
    /// Watched arrivals not yet taken.
    pub hits: Vec<(VirtualNanos, u64)>,
    /// Recorded accesses not yet taken.
    pub recorded: Vec<Recorded>,
    /// The last e-stop edge armed by `EstopAfterInstruction`, not yet taken.
    pub estop_edge: Option<(VirtualNanos, VirtualNanos)>,
    /// Registers peeked, not yet taken.
    pub peeked: Vec<(u64, Option<u64>)>,
    /// The firmware's GPIO output writes, not yet taken.
    pub pin_writes: Vec<Recorded>,
    /// The image.
    pub firmware: Firmware,
    /// The event log's flash operations not yet taken.
    pub flash_ops: Vec<FlashOp>,
    /// The event log's flash, as the run has programmed it.
    flash: Arc<Mutex<FlashShadow>>,
    /// Wall time at the start (before the first instruction).
    pub started: Instant,
    /// Wall time at the first report.
    pub first_report: Option<Instant>,
}

impl std::fmt::Debug for Bench {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bench").field("now", &self.now).finish()
    }
}

impl Bench {
    /// Builds the board, loads the image and starts the core; returns at the first report
    /// (the first plant step).
    pub fn start(config: BenchConfig) -> Result<Self, BenchError> {
        if config.plant_step_ns == 0 {
            return Err(BenchError::Setting {
                what: "plant step (ns)",
                value: config.plant_step_ns,
            });
        }
        let firmware = Firmware::read(&config.firmware)?;
        let rtt_block = firmware.symbol("_SEGGER_RTT").ok();
        let mechanics = Mechanics::new(config.mechanics)?;
        if config.position_channel != config.board.position_channel {
            return Err(BenchError::PositionChannel {
                position_channel: config.position_channel,
                board: config.board.name,
            });
        }
        let mut board = RsprBoard::for_target(&config.board)?;
        if config.position_channel {
            crate::position_channel::attach(&mut board.mcu);
        }
        let flash = Arc::new(Mutex::new(FlashShadow::new(config.flash.as_deref())));
        let mailbox = firmware.symbol(crate::flash::MAILBOX_SYMBOL).ok();
        let geometry_mailbox = firmware.symbol(crate::flash::GEOMETRY_MAILBOX_SYMBOL).ok();
        let stack_region = StackRegion::of(&firmware).ok();
        let (to_master, from_driver) = sync_channel::<Report>(1);
        let (to_driver, from_master) = sync_channel::<Command>(1);
        let driver = Lockstep {
            mechanics,
            plant_step: config.plant_step_ns,
            next_plant: config.plant_step_ns,
            next_ms: MS,
            master_at: config.plant_step_ns,
            outputs: Outputs::OFF,
            edges: Vec::new(),
            to_master,
            from_master,
            hits: Vec::new(),
            watched: Vec::new(),
            armed: None,
            estop_at: None,
            estop_edge: None,
            hold_until: None,
            peeked: Vec::new(),
            pin_writes: Vec::new(),
            record_until: config.record_until_ns,
            recorded: Vec::new(),
            rtt_block,
            rtt_bytes: 0,
            hasher: Sha256::new(),
            failed: None,
            flash: Arc::clone(&flash),
            mailbox,
            geometry_mailbox,
            flash_word_ns: config.flash_word_ns,
            position_channel: config.position_channel,
            stack_region,
            stack: None,
        };
        let image = firmware
            .rigless_image()
            .map_err(|e| BenchError::Emulator(e.to_string()))?;
        // The event log's sectors as the last power cycle left them.
        let kept = match &config.flash {
            Some(bytes) => Some(
                rigless::image::Image::new(
                    std::path::Path::new("event-log-flash"),
                    bytes.clone(),
                    Some(EVENTS_BASE),
                )
                .map_err(|e| BenchError::Emulator(e.to_string()))?,
            ),
            None => None,
        };
        // The stack's region painted before the first instruction (`crate::stack`).
        let paint = match stack_region {
            Some(region) => Some(
                rigless::image::Image::new(
                    std::path::Path::new("stack-paint"),
                    region.paint(),
                    Some(region.floor),
                )
                .map_err(|e| BenchError::Emulator(e.to_string()))?,
            ),
            None => None,
        };
        let mut session = Session::new(Box::new(board), 0, VirtualNanos(config.plant_step_ns))
            .map_err(|e| BenchError::Emulator(e.to_string()))?;
        session.watch(Watch::Writes {
            address: EVENTS_BASE,
            length: KEPT_LEN as u64,
        });
        let started = Instant::now();
        let thread = std::thread::Builder::new()
            .name("board-emulator".into())
            .spawn(move || {
                let images: Vec<rigless::image::Image> =
                    std::iter::once(image).chain(kept).chain(paint).collect();
                let start = Start::new(&images);
                match emulator::run(session, &start, driver) {
                    Ok(finished) => {
                        let mut gaps = Vec::new();
                        for u in finished.session.unmapped() {
                            gaps.push(format!("unmapped {u}"));
                        }
                        for (i, u) in finished.session.unimplemented() {
                            gaps.push(format!("unimplemented {i:#x} {u:?}"));
                        }
                        for (i, n) in finished.session.unrouted() {
                            gaps.push(format!("unrouted {i} line {n}"));
                        }
                        if let Some(e) = finished.driver.failed {
                            gaps.push(format!("driver: {e}"));
                        }
                        Ok(gaps.join("; "))
                    }
                    Err(e) => Err(e.to_string()),
                }
            })
            .map_err(|e| BenchError::Emulator(e.to_string()))?;
        let mut bench = Bench {
            to_driver,
            from_driver,
            thread: Some(thread),
            now: VirtualNanos(0),
            pending: Vec::new(),
            last: Report::empty(),
            received: Vec::new(),
            edges: Vec::new(),
            hits: Vec::new(),
            recorded: Vec::new(),
            estop_edge: None,
            peeked: Vec::new(),
            pin_writes: Vec::new(),
            firmware,
            flash_ops: Vec::new(),
            flash,
            started,
            first_report: None,
        };
        bench.receive()?;
        bench.first_report = Some(Instant::now());
        Ok(bench)
    }

    fn receive(&mut self) -> Result<(), BenchError> {
        match self.from_driver.recv() {
            Ok(mut r) => {
                self.now = r.at;
                self.received.append(&mut r.received);
                self.edges.append(&mut r.edges);
                self.hits.append(&mut r.hits);
                self.recorded.append(&mut r.recorded);
                if let Some(e) = r.estop_edge.take() {
                    self.estop_edge = Some(e);
                }
                self.peeked.append(&mut r.peeked);
                self.pin_writes.append(&mut r.pin_writes);
                self.flash_ops.append(&mut r.flash_ops);
                self.last = r;
                Ok(())
            }
            Err(_) => {
                let why = match self.thread.take().map(JoinHandle::join) {
                    Some(Ok(Ok(gaps))) => format!("run ended; {gaps}"),
                    Some(Ok(Err(e))) => e,
                    Some(Err(_)) => "the emulator thread panicked".into(),
                    None => "no emulator thread".into(),
                };
                Err(BenchError::Stopped(why))
            }
        }
    }

    /// Virtual time now.
    pub fn now(&self) -> VirtualNanos {
        self.now
    }

    /// The event log's flash sectors as the run has programmed them (from
    /// [`crate::flash::EVENTS_BASE`]): what the next power-up starts from
    /// ([`BenchConfig::flash`]).
    pub fn flash(&self) -> Vec<u8> {
        self.flash
            .lock()
            .map(|f| f.bytes().to_vec())
            .unwrap_or_default()
    }

    /// The event log's flash counters: words programmed, sectors erased, stores with `PG`
    /// set whose word the image did not stage, stores with `PG` clear.
    pub fn flash_counts(&self) -> (u64, u64, u64, u64) {
        self.flash
            .lock()
            .map(|f| (f.programmed, f.erases, f.unknown, f.dropped))
            .unwrap_or_default()
    }

    /// Virtual time now, s.
    pub fn now_s(&self) -> f64 {
        self.now.0 as f64 / NANOS_PER_SECOND as f64
    }

    /// Queues an action for the next turn (it happens at the current instant).
    pub fn act(&mut self, action: Action) {
        self.pending.push(action);
    }

    /// Runs to `until` (at least 1 ns on), doing the queued actions first.
    pub fn run_until(&mut self, until: VirtualNanos) -> Result<(), BenchError> {
        let until = VirtualNanos(until.0.max(self.now.0 + 1));
        let actions = std::mem::take(&mut self.pending);
        self.to_driver
            .send(Command::Continue { until, actions })
            .map_err(|_| BenchError::Stopped("the emulator thread is gone".into()))?;
        self.receive()
    }

    /// Runs for `ns` of virtual time.
    pub fn run_for(&mut self, ns: u64) -> Result<(), BenchError> {
        self.run_until(VirtualNanos(self.now.0 + ns))
    }

    /// The stack's use so far (`crate::stack`): measured at the next instant, a
    /// microsecond on (`None` when the image names no stack region).
    pub fn stack_use(&mut self) -> Result<Option<StackUse>, BenchError> {
        self.act(Action::MeasureStack);
        self.run_for(1_000)?;
        Ok(self.last.stack)
    }

    /// Ends the run; returns the emulator's gaps (unmapped, unimplemented, unrouted).
    pub fn finish(&mut self) -> Result<String, BenchError> {
        let _ = self.to_driver.send(Command::Finish);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(gaps))) => Ok(gaps),
            Some(Ok(Err(e))) => Err(BenchError::Emulator(e)),
            Some(Err(_)) => Err(BenchError::Stopped("the emulator thread panicked".into())),
            None => Ok(String::new()),
        }
    }
}
