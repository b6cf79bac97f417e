//! The closed-loop scenarios, in one run of the image (one JIT warm-up), in this order:
//!
//! 1. The image's fit on the STM32F405; [`boot`]: reset to the 1 kHz control tick with the
//!    IWDG fed every tick; every pin configured as the board's pin map
//!    ([`board_emulator::pins::BoardTarget`], [`Options::board`]) says; Hello (session,
//!    reset cause PowerOn); [`wiring::supply_step`]: the supply sense following a step.
//! 2. [`watchdog::starved`]: the core stalled, the deadline missed and logged, the IWDG
//!    reset; the reset cause and the fault log reported after it (before the homing, so
//!    that one homing serves the whole run); nothing moves until the reset is acknowledged
//!    ([`watchdog::acknowledge`]: Home refused until then).
//! 3. [`motion`]: homing against the switches and stops, then the park move; enable (the
//!    brake check);
//!    a target outside the workspace refused while the robot holds; garbage on the link
//!    counted and ignored; the tool put on; the laparoscope path within the tracking limits,
//!    with the lag of the setpoint behind the master's targets (the master's steps are
//!    `host-sim teleop`'s own, `teleop::ci`).
//! 4. [`stops`]: heartbeat loss (hold, then SS1 with the brakes before the drivers); Disable
//!    while moving (SS1); the e-stop edge (outputs safe within 10 µs, preempting the control
//!    interrupt); a driver's nFAULT (STO); enable and Disable ([`watchdog::disable`]);
//!    last, the safety relay disagreeing with the button (the chain stays untrusted for the
//!    rest of the power cycle).
//! 5. Last, [`wiring::Coverage`]: every output of the board's pin map seen at both levels
//!    and every input read by the firmware over the run.
//!
//! [`List::Wiring`] runs the ones that drive or read a pin, for a second board's image.
//! Each check prints its figures; [`Outcome::all_ok`] says whether every one passed.

pub mod boot;
pub mod motion;
pub mod stops;
pub mod watchdog;
pub mod wiring;

use std::path::Path;
use std::time::Instant;

use kinematics_core::{Pose, RsprGeometry};
use master_link::{RobotState, StatusReport};
use nalgebra::Vector3;
use rigless::time::VirtualNanos;
use teleop::session::{Session, StatusRow};
use teleop::{PathChoice, TeleopError};

use crate::master::{Rig, SharedRig};
use board_emulator::bench::{Action, Bench, BenchConfig, BenchError};
use board_emulator::board::Outputs;
use board_emulator::image::{Firmware, ImageError};
use board_emulator::mechanics::{central_q, MechanicsError, Surroundings};
use board_emulator::pins::{BoardTarget, REFERENCE};
use wiring::Wiring;

/// Why a scenario could not run (a failed check is not an error: it is in the outcome).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The bench.
    #[error(transparent)]
    Bench(#[from] BenchError),
    /// The master (teleop's session).
    #[error("master: {0}")]
    Teleop(#[from] TeleopError),
    /// The image.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// The mechanics.
    #[error(transparent)]
    Mechanics(#[from] MechanicsError),
    /// The master's settings (the simulation's default.toml).
    #[error("the master's settings: {0}")]
    Settings(String),
}

/// One check.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Check {
    /// What it checks.
    pub name: String,
    /// Passed.
    pub ok: bool,
    /// What was measured.
    pub figures: String,
}

/// What a run of the scenarios gives.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The checks, in order.
    pub checks: Vec<Check>,
    /// Digest of the whole run's trace (outputs and signals at every plant step, link bytes
    /// both ways with their instants, RTT bytes, resets).
    pub digest: [u8; 32],
    /// Virtual time run, s.
    pub virtual_s: f64,
    /// Wall time, s (start to end).
    pub wall_s: f64,
    /// Wall time to the first report (the JIT's first translations), s.
    pub warmup_s: f64,
    /// The emulator's gaps at the end (unmapped, unimplemented, unrouted).
    pub gaps: String,
    /// Per check: its name, the virtual and the wall time since the previous check, s.
    pub phases: Vec<(String, f64, f64)>,
}

impl Outcome {
    /// Every check passed.
    pub fn all_ok(&self) -> bool {
        !self.checks.is_empty() && self.checks.iter().all(|c| c.ok)
    }

    /// Virtual seconds per wall second after the first report.
    pub fn speed(&self) -> f64 {
        self.virtual_s / (self.wall_s - self.warmup_s).max(1e-9)
    }

    /// The digest in hex.
    pub fn digest_hex(&self) -> String {
        self.digest.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// Options of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The path streamed.
    pub path: PathChoice,
    /// Where the master's telemetry goes (`status.csv`, as `host-sim teleop` writes it).
    pub out: Option<std::path::PathBuf>,
    /// The board the image is built for: its pins, as the emulator drives and reads them
    /// and as the checks watch them ([`wiring`]).
    pub board: BoardTarget,
    /// Which scenarios.
    pub list: List,
}

/// Which scenarios a run does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum List {
    /// Every scenario (see the module's documentation).
    All,
    /// The ones that drive or read every pin of the board: boot and tick, the pins, Hello,
    /// homing (every encoder, PWM, DIR, the currents, the home switches), enable (the
    /// driver enable, the brakes), the path, Disable while moving (SS1 on the pins), the
    /// e-stop edge, a driver's nFAULT, enable and Disable, the safety relay's feedback;
    /// without the watchdog reset, the refused target and garbage, the tool and the
    /// heartbeat loss, which exercise the firmware and the link, not the wiring.
    Wiring,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            path: PathChoice::Fast,
            out: None,
            board: REFERENCE,
            list: List::All,
        }
    }
}

/// The image's symbols the scenarios watch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Symbols {
    /// The `UART4` handler: the interrupt executor that runs the control tick.
    pub uart4: u64,
    /// The e-stop line's EXTI handler ([`Wiring::estop_handler`]): the e-stop edge.
    pub estop_handler: u64,
}

/// Register addresses the checks look at on every board (RM0090 rev 19 memory map; the
/// board's pins: [`wiring`]).
pub mod addr {
    /// `IWDG_KR`.
    pub const IWDG_KR: u64 = 0x4000_3000;
    /// `DWT_CYCCNT`.
    pub const DWT_CYCCNT: u64 = 0xE000_1004;
}

/// A run: the rig, teleop's session on it, the checks.
pub struct Run {
    /// The bench and the master's end of the wire.
    pub rig: SharedRig,
    /// The master: `host-sim teleop`'s session.
    pub s: Session,
    /// The checks of teleop's steps.
    pub ci: teleop::ci::Checks,
    /// Every check, in order.
    pub checks: Vec<Check>,
    mark: (f64, Instant),
    /// Per check: name, virtual and wall time since the previous one.
    pub phases: Vec<(String, f64, f64)>,
    /// The image's symbols.
    pub symbols: Symbols,
    /// The surroundings as last set.
    pub surroundings: Surroundings,
    /// The reference robot's central joints.
    pub central_q: [f64; 6],
    /// The central pose.
    pub centre: Pose<f64>,
    /// The run's options.
    pub options: Options,
    /// The board's registers the checks watch.
    pub wiring: Wiring,
    /// The outputs' levels seen so far (every edge of the run).
    pub coverage: wiring::Coverage,
}

fn mm(m: f64) -> String {
    format!("{:.3} mm", m * 1e3)
}

fn ms(ns: u64) -> String {
    format!("{:.3} ms", ns as f64 / 1e6)
}

/// The measured position of a status.
pub fn position(s: &StatusReport) -> Vector3<f64> {
    let [x, y, z] = s.position_m.map(f64::from);
    Vector3::new(x, y, z)
}

impl Run {
    /// Records and prints a check with the virtual and wall time since the last one.
    pub fn check(&mut self, name: &str, ok: bool, figures: String) {
        let (virtual_s, wall) = (self.s.now_s(), Instant::now());
        let dv = virtual_s - self.mark.0;
        let dw = wall.duration_since(self.mark.1).as_secs_f64();
        self.mark = (virtual_s, wall);
        self.phases.push((name.to_string(), dv, dw));
        println!(
            "[{}] {name}: {figures} [{dv:.2} virtual s in {dw:.2} wall s]",
            if ok { "PASS" } else { "FAIL" }
        );
        self.checks.push(Check {
            name: name.to_string(),
            ok,
            figures,
        });
    }

    /// Takes the checks teleop's steps made since the last call into the run's (teleop
    /// printed their figures as `check NAME: ok` above).
    pub fn adopt_teleop_checks(&mut self) {
        let new: Vec<teleop::ci::Check> = std::mem::take(&mut self.ci.list);
        for c in new {
            self.check(&format!("teleop: {}", c.name), c.ok, c.figures);
        }
    }

    /// Queues an action for the bench (at the current instant).
    pub fn act(&self, action: Action) {
        self.rig.lock().bench.act(action);
    }

    /// Changes the surroundings at the current instant.
    pub fn set_surroundings(&mut self, s: Surroundings) {
        self.surroundings = s;
        self.act(Action::Surroundings(s));
    }

    /// Virtual time, s.
    pub fn now_s(&self) -> f64 {
        self.s.now_s()
    }

    /// Virtual time, ns.
    pub fn now_ns(&self) -> u64 {
        self.rig.lock().bench.now().0
    }

    /// Runs the session (heartbeats, telemetry) for `seconds`.
    pub fn wait(&mut self, seconds: f64) -> Result<(), ScenarioError> {
        Ok(self.s.wait(seconds)?)
    }

    /// The output edges since the last take (added to the run's pin coverage).
    pub fn take_edges(&mut self) -> Vec<(VirtualNanos, Outputs)> {
        let edges = std::mem::take(&mut self.rig.lock().bench.edges);
        for (_, o) in &edges {
            self.coverage.add(o);
        }
        edges
    }

    /// The firmware's GPIO output writes since the last take.
    pub fn take_pin_writes(&self) -> Vec<board_emulator::bench::Recorded> {
        std::mem::take(&mut self.rig.lock().bench.pin_writes)
    }

    /// The statuses received from index `since` on.
    pub fn rows_since(&self, since: usize) -> Vec<StatusRow> {
        self.s.statuses.get(since..).unwrap_or_default().to_vec()
    }

    /// The last status.
    pub fn last_status(&self) -> Option<StatusReport> {
        self.s.last_status().map(|r| r.status)
    }

    /// Waits (at most `timeout_s`) for a status from index `since` on that satisfies `pred`.
    pub fn wait_for(
        &mut self,
        since: usize,
        timeout_s: f64,
        pred: impl Fn(&StatusReport) -> bool,
    ) -> Result<Option<StatusRow>, ScenarioError> {
        Ok(self.s.wait_for(since, timeout_s, pred)?)
    }

    /// Sends `Enable` until it is not refused `Busy` (a stop still applying the brakes), at
    /// most 1 s, then waits for `Enabled`; the refusal, if any.
    pub fn enable(&mut self) -> Result<Option<master_link::NackReason>, ScenarioError> {
        let end = self.now_s() + 1.0;
        let nack = loop {
            let nack = self.s.request(master_link::MasterToBoard::Enable, 1.0)?;
            if nack != Some(master_link::NackReason::Busy) || self.now_s() >= end {
                break nack;
            }
            self.wait(0.05)?;
        };
        if nack.is_none() {
            let since = self.s.statuses.len();
            self.wait_for(since, 1.0, |st| st.state == RobotState::Enabled)?;
        }
        Ok(nack)
    }
}

/// The laparoscope path and the master's limits of the simulation's default settings
/// (`host-sim/simulation/default.toml`, as `host-sim teleop` takes them), read without the
/// simulation crate.
pub fn master_settings(
) -> Result<(trajectory::Laparoscope, trajectory::MasterLimits), ScenarioError> {
    #[derive(serde::Deserialize)]
    struct Master {
        accel_mm_s2: f64,
        angular_speed_deg_s: f64,
        angular_accel_deg_s2: f64,
    }
    #[derive(serde::Deserialize)]
    struct Scenario {
        laparoscope: trajectory::Laparoscope,
    }
    #[derive(serde::Deserialize)]
    struct Settings {
        master: Master,
        scenario: Scenario,
    }
    const DEFAULT_TOML: &str = include_str!("../../../../host-sim/simulation/default.toml");
    let s: Settings =
        toml::from_str(DEFAULT_TOML).map_err(|e| ScenarioError::Settings(e.to_string()))?;
    Ok((
        s.scenario.laparoscope,
        trajectory::MasterLimits {
            accel_mm_s2: s.master.accel_mm_s2,
            angular_speed_deg_s: s.master.angular_speed_deg_s,
            angular_accel_deg_s2: s.master.angular_accel_deg_s2,
        },
    ))
}

/// Runs every scenario on the image at `firmware`.
pub fn run_all(firmware: &Path, options: Options) -> Result<Outcome, ScenarioError> {
    let wall = Instant::now();
    let image = Firmware::read(firmware)?;
    let fit = image.fit();
    let wiring = Wiring::of(options.board);
    let symbols = Symbols {
        uart4: image.function("UART4")?,
        estop_handler: image.function(wiring.estop_handler())?,
    };
    let mut config = BenchConfig::reference(firmware.to_path_buf())?;
    config.board = options.board;
    // Every peripheral access of the first 0.3 s (the boot and 200 ticks).
    config.record_until_ns = 300_000_000;
    let bench = Bench::start(config)?;
    let warmup_s = bench
        .first_report
        .map_or(0.0, |t| t.duration_since(bench.started).as_secs_f64());
    let rig = SharedRig::new(Rig::new(bench));
    let s = rig.session();
    let g = RsprGeometry::<f64>::reference();
    let mut run = Run {
        rig,
        s,
        ci: teleop::ci::Checks::default(),
        checks: Vec::new(),
        mark: (0.0, Instant::now()),
        phases: Vec::new(),
        symbols,
        surroundings: Surroundings::default(),
        central_q: central_q()?,
        centre: Pose::central(g.hc),
        options,
        wiring,
        coverage: wiring::Coverage::default(),
    };
    println!(
        "board {} ({} scenarios)",
        run.options.board.name,
        match run.options.list {
            List::All => "all",
            List::Wiring => "the wiring's",
        }
    );
    run.check(
        "the image fits the STM32F405RG (1 MiB flash, 128 KiB SRAM, 64 KiB CCM: every board target's budget)",
        fit.fits(),
        format!("{}: {fit}", firmware.display()),
    );
    let result = scenarios(&mut run);
    if let Err(e) = &result {
        run.check("the run", false, format!("stopped: {e}"));
    }
    pins_exercised(&mut run);
    stack_depth(&mut run, "over the whole run");
    let virtual_s = run.now_s();
    let digest = run.rig.lock().bench.last.digest;
    if let Some(out) = &run.options.out {
        match teleop::write_csv(&run.s, out) {
            Ok(p) => println!("telemetry: {}", p.display()),
            Err(e) => println!("telemetry not written: {e}"),
        }
    }
    let gaps = run.rig.lock().bench.finish()?;
    Ok(Outcome {
        checks: run.checks,
        digest,
        virtual_s,
        wall_s: wall.elapsed().as_secs_f64(),
        warmup_s,
        gaps,
        phases: run.phases,
    })
}

/// The deepest the image's stack went so far (the emulator's painted stack,
/// `board_emulator::stack`), against its budget: after the boot, and after every scenario
/// (the deepest paths: the end of the park move, a stop or a fault from inside a
/// transition, the e-stop's interrupt on top). The budget must also fit the region the
/// image leaves for the stack.
fn stack_depth(run: &mut Run, when: &str) {
    let name = format!("the stack stays within its budget {when}");
    let used = run.rig.lock().bench.stack_use();
    let budget = board_emulator::stack::STACK_BUDGET;
    match used {
        Err(e) => run.check(&name, false, format!("not measured: {e}")),
        Ok(Some(u)) => run.check(
            &name,
            u.depth() <= budget && budget <= u.region.room() && !u.overflowed(),
            format!("{u}; budget {budget} B"),
        ),
        Ok(None) => run.check(
            &name,
            false,
            "the image names no stack region (_stack_end, _stack_start)".into(),
        ),
    }
}

/// The scenarios in their order.
fn scenarios(run: &mut Run) -> Result<(), ScenarioError> {
    if run.options.list == List::Wiring {
        return wiring_scenarios(run);
    }
    boot::tick(run)?;
    boot::pins(run)?;
    boot::hello(run)?;
    wiring::supply_step(run)?;
    stack_depth(run, "to the first session");
    watchdog::starved(run)?;
    watchdog::acknowledge(run)?;
    if !motion::home(run)? {
        return Ok(());
    }
    motion::enable(run)?;
    motion::refuse_and_garbage(run)?;
    motion::attach_tool(run)?;
    motion::path(run)?;
    stops::heartbeat_loss(run)?;
    stops::disable_while_moving(run)?;
    stops::estop(run)?;
    stops::driver_fault(run)?;
    watchdog::disable(run)?;
    // Last: the safety chain stays untrusted for the rest of the power cycle.
    stops::relay_mismatch(run)?;
    Ok(())
}

/// The last check: every wired pin driven at both levels or read by the firmware
/// ([`wiring::Coverage`]).
fn pins_exercised(run: &mut Run) {
    let _ = run.take_edges();
    let statuses: Vec<StatusReport> = run.s.statuses.iter().map(|r| r.status).collect();
    let (missing, seen) = run.coverage.judge(&run.wiring, &statuses);
    run.check(
        "every wired pin was driven at both levels or read by the firmware",
        missing.is_empty(),
        format!(
            "{}: {}; {seen}",
            run.wiring.target.name,
            if missing.is_empty() {
                "every PWM with DIR high and low, driver enable, both brake outputs, the LED; every encoder, current sense, the supply sense, the e-stop, relay feedback and nFAULT inputs".to_string()
            } else {
                format!("not exercised: {}", missing.join("; "))
            }
        ),
    );
}

/// The scenarios of [`List::Wiring`], in the same order as in the full list.
fn wiring_scenarios(run: &mut Run) -> Result<(), ScenarioError> {
    boot::tick(run)?;
    boot::pins(run)?;
    boot::hello(run)?;
    wiring::supply_step(run)?;
    if !motion::home(run)? {
        return Ok(());
    }
    motion::enable(run)?;
    motion::path(run)?;
    stops::disable_while_moving(run)?;
    stops::estop(run)?;
    stops::driver_fault(run)?;
    watchdog::disable(run)?;
    stops::relay_mismatch(run)?;
    Ok(())
}
