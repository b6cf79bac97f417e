//! The RSPR board firmware on QEMU's mps2-an386 (Cortex-M4F, 25 MHz): the application of
//! `firmware/board` (a control task ticking `controller::state::Runtime` at a fixed rate,
//! a link receive task and a link transmit task using `controller::link`) on an embassy
//! executor, with
//! * an embassy-time driver on SysTick (`time_driver`),
//! * the master link on the emulated CMSDK UART0 (`uart`; QEMU's first `-serial`),
//! * a software plant on the MCU behind the controller's hardware traits (`plant`): the
//!   encoders read it, the PWM duties drive it.
//!
//! Tasks and priorities (highest first):
//! * SysTick (time driver) and the UART0 receive interrupt;
//! * `control` on an interrupt executor (IRQ 31, a free line): the control tick at
//!   `RATE_HZ` (the plant is advanced to the tick's time first), its jitter and execution
//!   time;
//! * `link_rx`, `link_tx` in thread mode: bytes -> `LinkRx` -> requests for the control
//!   tick; replies and 50 Hz telemetry -> UART.
//!
//! Log lines (state changes, timing every 5 s, refused targets) go to the host through
//! semihosting.
#![no_std]
#![no_main]

mod plant;
mod time_driver;
mod uart;

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller::failsafe::{emergency_stop_isr, EStopLatch, SafeOutputs, TickTiming};
use controller::link::{complete_status, Inbound, LinkRx, LinkTx, Request};
use controller::state::{reference_config, Event, Runtime};
use cortex_m_rt::exception;
use cortex_m_semihosting::hprintln;
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Instant, Ticker, Timer};
use kinematics_core::guards::Limits;
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::{
    BoardToMaster, FirmwareVersion, LinkCounters, NackReason, StatusReport, Warnings, MAX_FRAME_LEN,
};
use panic_semihosting as _;
use servo::hal::QuadratureCounter;

use crate::plant::Plant;
use crate::time_driver::{now_us, CPU_HZ};
use crate::uart::Irq;

/// This firmware's version (from Cargo.toml), sent in `HelloReply`.
const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u32(env!("CARGO_PKG_VERSION_MAJOR"), 0) as u8,
    minor: parse_u32(env!("CARGO_PKG_VERSION_MINOR"), 0) as u8,
    patch: parse_u32(env!("CARGO_PKG_VERSION_PATCH"), 0) as u8,
};

/// A decimal number, or `default` if `s` is not one (or above 65535).
const fn parse_u32(s: &str, default: u32) -> u32 {
    let b = s.as_bytes();
    if b.is_empty() {
        return default;
    }
    let mut v: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        let d = b[i];
        if d < b'0' || d > b'9' || v > 6553 {
            return default;
        }
        v = v * 10 + (d - b'0') as u32;
        i += 1;
    }
    v
}

/// Control rate under the emulator, Hz: `RSPR_QEMU_RATE_HZ` at build time (default 250,
/// within 100 .. 1000).
const RATE_HZ: u32 = {
    let r = match option_env!("RSPR_QEMU_RATE_HZ") {
        Some(s) => parse_u32(s, 250),
        None => 250,
    };
    if r < 100 {
        100
    } else if r > 1000 {
        1000
    } else {
        r
    }
};
/// Control period, µs.
const PERIOD_US: u32 = 1_000_000 / RATE_HZ;
/// Execution time above which the status warns `CYCLE_OVERRUN`, µs (80 % of the period).
const EXEC_WARN_US: u32 = PERIOD_US / 5 * 4;
/// Telemetry period.
const TELEMETRY_MS: u64 = 20;
/// Timing log period, µs.
const LOG_EVERY_US: u64 = 5_000_000;

/// The interrupt line of the control executor (unused by the mps2-an386's devices).
const CONTROL_IRQ: u16 = 31;
/// NVIC / SysTick priorities (lower is more urgent).
const PRIO_TIME_AND_UART: u8 = 0x20;
const PRIO_CONTROL: u8 = 0x40;

/// The emergency-stop latch (tripped by an `EmergencyStop` message at once).
pub static ESTOP: EStopLatch = EStopLatch::new();
static EXECUTOR_CONTROL: InterruptExecutor = InterruptExecutor::new();
/// Master requests for the control tick (room for ~150 ms of a 100 Hz target stream with
/// heartbeats, as the emulator's host may stall a tick).
static COMMANDS: Channel<CriticalSectionRawMutex, Request, 32> = Channel::new();
/// Replies for the link.
static REPLIES: Channel<CriticalSectionRawMutex, BoardToMaster, 32> = Channel::new();
/// The latest status from the control tick.
static STATUS: Mutex<CriticalSectionRawMutex, Cell<Option<StatusReport>>> =
    Mutex::new(Cell::new(None));
/// The receive side's counters.
static LINK: Mutex<CriticalSectionRawMutex, Cell<Option<LinkCounters>>> =
    Mutex::new(Cell::new(None));
/// A `Hello` was received: telemetry flows.
static CONNECTED: AtomicBool = AtomicBool::new(false);
/// Replies dropped because the reply queue was full.
static REPLIES_DROPPED: AtomicU32 = AtomicU32::new(0);

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        0 => uart::on_rx_interrupt(),
        // SAFETY: the executor was started on this line before it was unmasked.
        31 => unsafe { EXECUTOR_CONTROL.on_interrupt() },
        _ => {}
    }
}

/// The defined halt: outputs safe, reason logged, nothing else runs.
fn halt(reason: &str) -> ! {
    critical_section::with(|_| plant::RawKill.force_safe());
    hprintln!("HALT: {}", reason);
    loop {
        cortex_m::asm::wfi();
    }
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    hprintln!(
        "rspr-qemu-board {}.{}.{}: control at {} Hz, master link on UART0 at {} baud",
        FIRMWARE_VERSION.major,
        FIRMWARE_VERSION.minor,
        FIRMWARE_VERSION.patch,
        RATE_HZ,
        uart::BAUD
    );
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        halt("core peripherals taken");
    };
    time_driver::init(cp.SYST, &mut cp.SCB, PRIO_TIME_AND_UART);
    uart::init(&mut cp.NVIC, PRIO_TIME_AND_UART);
    // SAFETY: set before the executor unmasks its line.
    unsafe { cp.NVIC.set_priority(Irq(CONTROL_IRQ), PRIO_CONTROL) };

    let control_spawner = EXECUTOR_CONTROL.start(Irq(CONTROL_IRQ));
    match control() {
        Ok(t) => control_spawner.spawn(t),
        Err(_) => halt("spawn control"),
    }
    match link_rx() {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_rx"),
    }
    match link_tx() {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_tx"),
    }
}

/// Where the emulated robot is at power-up: legs a few mm above their home switches
/// (150 mm), links 0.15 .. 0.25 rad above their hard stops (60 deg below the central
/// angles); the raw counters start at arbitrary values.
fn power_up_plant(central_q: &[f32; 6], now: u64) -> Plant {
    let stop = |j: usize| central_q.get(j).copied().unwrap_or(0.0) - 60f32.to_radians();
    let stops = [stop(3), stop(4), stop(5)];
    let q0 = [
        0.156,
        0.158,
        0.155,
        stops[0] + 0.20,
        stops[1] + 0.25,
        stops[2] + 0.15,
    ];
    let raw0 = [1234, 40_000, 65_000, 7, 30_000, 52_345];
    Plant::new(q0, raw0, 0.150, stops, now, 2 * u64::from(PERIOD_US))
}

#[embassy_executor::task]
async fn control() {
    let geometry = RsprGeometry::<f32>::reference();
    let Ok(central) = inverse(&geometry, &Pose::central(geometry.hc), Branch::OUTER) else {
        halt("central configuration");
    };
    let q = central.q();
    let central_q = [q.x, q.y, q.z, q.w, q.a, q.b];
    let mut cfg = reference_config::<f32>(central_q);
    cfg.controller.rate_hz = RATE_HZ as f32;
    // About one full guard evaluation per tick (5 stages when the SVD starts warm; the
    // board runs 1 stage per tick at 1 kHz): at 250 Hz with fewer the supervisor verifies a 100 Hz stream at 25 mm/s too
    // slowly, targets are superseded and the path's curves cut by millimetres.
    cfg.controller.supervisor.stages_per_tick = 5;
    // The emulated joints have no backlash: compensating one would offset them by it.
    cfg.controller.servo.backlash = servo::backlash::BacklashConfig::off();
    // Under the emulator the host may stall the guest by tens of ms (QEMU runs on the
    // host's clock, shared with other work): a target may queue that long. The board
    // keeps 50 ms.
    cfg.targets.max_latency_us = 200_000;
    // A quick park after homing (the emulated joints carry no load).
    cfg.homing.park_speed = [0.01, 0.01, 0.01, 0.3, 0.3, 0.3];
    let t0 = now_us();
    let mut hw = power_up_plant(&central_q, t0);
    let mut rt = match Runtime::new(geometry, cfg, t0) {
        Ok(rt) => rt,
        Err(_) => halt("runtime configuration"),
    };
    let raw = hw.counts();
    let _ = rt.boot_done(raw, t0);
    hprintln!("boot done: {:?}", rt.state());

    let mut timing = TickTiming::default();
    let mut last_start: Option<u64> = None;
    let mut last_state = rt.state();
    let mut last_log = t0;
    let mut overruns = 0u32;
    let mut path_refused = 0u32;
    let period = u64::from(PERIOD_US);
    let mut next = t0 + period;
    let mut skipped = 0u64;
    loop {
        Timer::at(Instant::from_micros(next)).await;
        let now = now_us();
        // A tick later than a whole period (the emulator's host stalled) skips the missed
        // ones instead of running them back to back, which would starve the link tasks.
        next += period;
        if now >= next {
            let missed = (now - next) / period + 1;
            skipped += missed;
            next += missed * period;
            // The emulator stalled: let the link tasks (thread mode, below this executor)
            // hand over what arrived meanwhile, heartbeats included, before the tick
            // judges the master's silence.
            Timer::after(Duration::from_micros(500)).await;
        }
        let now = now_us();
        let jitter = match last_start {
            Some(prev) => now.saturating_sub(prev).abs_diff(u64::from(PERIOD_US)),
            None => 0,
        };
        last_start = Some(now);

        // The plant runs up to now with the duties of the last tick.
        hw.advance_to(now);
        if ESTOP.take() {
            let _ = rt.event(Event::EmergencyStop, now);
        }
        while let Ok(req) = COMMANDS.try_receive() {
            let result = rt.command(&req.command, now);
            let reply = req.reply(result, &rt.status());
            if REPLIES.try_send(reply).is_err() {
                REPLIES_DROPPED.fetch_add(1, Ordering::Relaxed);
            }
        }
        let report = rt.tick(&mut hw, now);
        if let Some(controller::state::HomingStatus::Failed(e)) = report.homing {
            hprintln!("t={} ms: homing failed: {:?}", now / 1000, e);
        }

        // Execution time: emulated time, i.e. the host's real time under QEMU (no DWT
        // cycle counter in the emulator); recorded as core cycles at 25 MHz.
        let exec_us = u32::try_from(now_us().saturating_sub(now)).unwrap_or(u32::MAX);
        if exec_us > PERIOD_US {
            overruns = overruns.wrapping_add(1);
        }
        let jitter_us = u32::try_from(jitter).unwrap_or(u32::MAX);
        timing.record(jitter_us, exec_us.saturating_mul(CPU_HZ / 1_000_000));
        rt.set_warning(Warnings::CYCLE_OVERRUN, exec_us > EXEC_WARN_US);
        rt.set_tick_timing(
            timing.worst_jitter_us,
            TickTiming::cycles_to_us(timing.worst_cycles, CPU_HZ),
        );
        let status = rt.status();
        STATUS.lock(|s| s.set(Some(status)));

        let state = rt.state();
        if state != last_state {
            hprintln!(
                "t={} ms: state {:?} -> {:?} (faults {:#x})",
                now / 1000,
                last_state,
                state,
                status.faults.bits()
            );
            last_state = state;
        }
        // Targets refused by the supervisor's path check (after their Ack).
        let (refused, last) = match rt.controller() {
            Some(c) => (
                c.supervisor().counters().path_refused,
                c.supervisor().last_refusal().copied(),
            ),
            None => (0, None),
        };
        if refused > path_refused {
            if let Some(r) = last {
                hprintln!(
                    "t={} ms: target refused by the path check: {:?}",
                    now / 1000,
                    r
                );
            }
        }
        path_refused = refused;
        if now.saturating_sub(last_log) >= LOG_EVERY_US {
            last_log = now;
            hprintln!(
                "t={} ms: {} ticks at {} Hz ({} skipped), worst jitter {} us, worst exec {} us, last exec {} us, overruns {}, plant steps {} ({} ms frozen), rx dropped {}, replies dropped {}",
                now / 1000,
                timing.ticks,
                RATE_HZ,
                skipped,
                timing.worst_jitter_us,
                TickTiming::cycles_to_us(timing.worst_cycles, CPU_HZ),
                exec_us,
                overruns,
                hw.steps,
                hw.frozen_us / 1000,
                uart::RX_DROPPED.load(Ordering::Relaxed),
                REPLIES_DROPPED.load(Ordering::Relaxed)
            );
        }
    }
}

#[embassy_executor::task]
async fn link_rx() {
    let mut link = LinkRx::new(FIRMWARE_VERSION);
    let mut buf = [0u8; 64];
    loop {
        let n = uart::RX.read(&mut buf).await;
        for byte in buf.iter().take(n) {
            match link.push(*byte) {
                Some(Inbound::Reply(reply)) if REPLIES.try_send(reply).is_err() => {
                    REPLIES_DROPPED.fetch_add(1, Ordering::Relaxed);
                }
                Some(Inbound::Reply(_)) => {}
                Some(Inbound::Request(req)) => {
                    if req.command == controller::link::Command::EmergencyStop {
                        // Do not wait for the next tick.
                        critical_section::with(|_| emergency_stop_isr(&mut plant::RawKill, &ESTOP));
                    }
                    if COMMANDS.try_send(req).is_err() {
                        let busy = BoardToMaster::Nack {
                            seq: req.seq,
                            reason: NackReason::Busy,
                        };
                        let _ = REPLIES.try_send(busy);
                    }
                }
                None => {}
            }
        }
        CONNECTED.store(link.connected(), Ordering::Relaxed);
        let counters = link.counters();
        LINK.lock(|c| c.set(Some(counters)));
    }
}

#[embassy_executor::task]
async fn link_tx() {
    let mut link = LinkTx::new();
    let geometry = RsprGeometry::<f32>::reference();
    let limits = Limits::<f32>::reference();
    let warn_levels = (limits.serial.warn, limits.parallel.warn);
    let mut telemetry = Ticker::every(Duration::from_millis(TELEMETRY_MS));
    let mut buf = [0u8; MAX_FRAME_LEN];
    loop {
        let msg = match select(REPLIES.receive(), telemetry.next()).await {
            Either::First(m) => m,
            Either::Second(()) => {
                if !CONNECTED.load(Ordering::Relaxed) {
                    continue;
                }
                match STATUS.lock(|s| s.get()) {
                    Some(s) => BoardToMaster::Status(s),
                    None => continue,
                }
            }
        };
        let msg = match msg {
            BoardToMaster::Status(mut s) => {
                let counters = LINK.lock(|c| c.get());
                complete_status(&mut s, &geometry, Branch::OUTER, warn_levels, counters);
                BoardToMaster::Status(s)
            }
            other => other,
        };
        match link.encode(&msg, &mut buf) {
            Ok(n) => {
                if let Some(frame) = buf.get(..n) {
                    uart::write_all(frame).await;
                }
            }
            Err(e) => hprintln!("encode: {:?}", e),
        }
    }
}
