//! Board firmware of the RSPR surgical robot controller: STM32F405RG at 168 MHz, embassy.
//!
//! Tasks and priorities (highest first):
//! * `EXTI15_10` (P0): the e-stop interrupt forces every output off at once and trips the
//!   latch the control tick turns into the state machine's `EmergencyStop`.
//! * TIM12 time driver (P1).
//! * `control` on an interrupt executor (`UART4` vector, P2): the 1 kHz control tick
//!   (state machine, fail-safe timers, homing, controller in f32 with the reference
//!   geometry), its jitter and execution time (DWT), the watchdog feeding policy.
//! * USART3 and its DMA (P4).
//! * `link_rx`, `link_tx` in thread mode: bytes -> decoder -> requests for the control
//!   tick; replies and 50 Hz telemetry (with the singularity margins) -> UART.
#![no_std]
#![no_main]

mod board;
mod hw;

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller::failsafe::{
    emergency_stop_isr, EStopLatch, SafeOutputs, TickTiming, WatchdogConfig, WatchdogPolicy,
};
use controller::link::{complete_status, Inbound, LinkRx, LinkTx, Request};
use controller::state::{reference_config, Event, Runtime, State};
use cortex_m::peripheral::DWT;
use defmt::{error, info, warn};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::gpio::{Input, Output};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Instant, Ticker};
use kinematics_core::guards::Limits;
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::{
    BoardToMaster, FirmwareVersion, LinkCounters, NackReason, StatusReport, Warnings, MAX_FRAME_LEN,
};
use {defmt_rtt as _, panic_probe as _};

/// This firmware's version (from Cargo.toml), sent in `HelloReply`.
const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    patch: parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
};

const fn parse_u8(s: &str) -> u8 {
    let b = s.as_bytes();
    let mut v: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        v = v * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    if v > 255 {
        255
    } else {
        v as u8
    }
}

/// Control period.
const PERIOD_US: u32 = 1000;
/// Execution time above which the status warns `CYCLE_OVERRUN`, µs.
const EXEC_WARN_US: u32 = 800;
/// Telemetry period.
const TELEMETRY_MS: u64 = 20;

static ESTOP: EStopLatch = EStopLatch::new();
static EXECUTOR_CONTROL: InterruptExecutor = InterruptExecutor::new();
/// Master requests for the control tick.
static COMMANDS: Channel<CriticalSectionRawMutex, Request, 8> = Channel::new();
/// Replies for the link.
static REPLIES: Channel<CriticalSectionRawMutex, BoardToMaster, 8> = Channel::new();
/// The latest status from the control tick.
static STATUS: Mutex<CriticalSectionRawMutex, Cell<Option<StatusReport>>> =
    Mutex::new(Cell::new(None));
/// The control tick's timing.
static TIMING: Mutex<CriticalSectionRawMutex, Cell<TickTiming>> =
    Mutex::new(Cell::new(TickTiming {
        ticks: 0,
        worst_jitter_us: 0,
        last_jitter_us: 0,
        worst_cycles: 0,
        last_cycles: 0,
    }));
/// The receive side's counters.
static LINK: Mutex<CriticalSectionRawMutex, Cell<Option<LinkCounters>>> =
    Mutex::new(Cell::new(None));
/// A `Hello` was received: telemetry flows.
static CONNECTED: AtomicBool = AtomicBool::new(false);
/// Replies dropped because the reply queue was full.
static REPLIES_DROPPED: AtomicU32 = AtomicU32::new(0);

#[interrupt]
unsafe fn UART4() {
    // SAFETY: the executor was started on this interrupt before it was unmasked.
    unsafe { EXECUTOR_CONTROL.on_interrupt() }
}

#[interrupt]
fn EXTI15_10() {
    board::clear_estop_pending();
    emergency_stop_isr(&mut hw::RawKill, &ESTOP);
}

/// The defined halt: outputs safe, error logged, nothing else runs.
fn halt(reason: &str) -> ! {
    critical_section::with(|_| hw::RawKill.force_safe());
    error!("HALT: {}", reason);
    loop {
        cortex_m::asm::wfi();
    }
}

/// Moves a value into a task on the interrupt executor. The hardware drivers are not
/// `Send`; each is moved here once and only ever used by that task afterwards.
struct Owned<T>(T);
// SAFETY: see above; the value is never shared.
unsafe impl<T> Send for Owned<T> {}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(board::clock_config());
    info!(
        "rspr-board {}.{}.{}",
        FIRMWARE_VERSION.major, FIRMWARE_VERSION.minor, FIRMWARE_VERSION.patch
    );

    let Some(mut cp) = cortex_m::Peripherals::take() else {
        halt("core peripherals taken");
    };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let b = match board::Board::new(p) {
        Ok(b) => b,
        Err(e) => {
            error!("board setup: {}", e);
            halt("board setup");
        }
    };

    // Priorities: e-stop > time driver > control > link.
    interrupt::EXTI15_10.set_priority(Priority::P0);
    interrupt::TIM8_BRK_TIM12.set_priority(Priority::P1);
    interrupt::UART4.set_priority(Priority::P2);
    interrupt::USART3.set_priority(Priority::P4);
    board::configure_estop_exti();
    // SAFETY: the handler above is defined; enabling it cannot break a critical section.
    unsafe { interrupt::EXTI15_10.enable() };

    let hardware = hw::Hardware::new(b.encoders, b.motors, b.sensors, &ESTOP);
    let control_spawner = EXECUTOR_CONTROL.start(interrupt::UART4);
    match control(Owned((hardware, b.estop, b.led, b.iwdg))) {
        Ok(t) => control_spawner.spawn(t),
        Err(_) => halt("spawn control"),
    }

    let (tx, rx) = b.uart.split();
    let Some(dma_buf) = cortex_m::singleton!(: [u8; 512] = [0; 512]) else {
        halt("rx buffer");
    };
    let rx = rx.into_ring_buffered(dma_buf);
    match link_rx(rx) {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_rx"),
    }
    match link_tx(tx) {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_tx"),
    }
}

type ControlParts = (
    hw::Hardware,
    Input<'static>,
    Output<'static>,
    IndependentWatchdog<'static, IWDG>,
);

#[embassy_executor::task]
async fn control(parts: Owned<ControlParts>) {
    let (mut hw, estop, mut led, mut iwdg) = parts.0;
    let geometry = RsprGeometry::<f32>::reference();
    let Ok(central) = inverse(&geometry, &Pose::central(geometry.hc), Branch::OUTER) else {
        halt("central configuration");
    };
    let q = central.q();
    let central_q = [q.x, q.y, q.z, q.w, q.a, q.b];
    let cfg = reference_config::<f32>(central_q);
    let t0 = Instant::now().as_micros();
    let mut rt = match Runtime::new(geometry, cfg, t0) {
        Ok(rt) => rt,
        Err(_) => halt("runtime configuration"),
    };
    let raw = servo::hal::QuadratureCounter::counts(&mut hw);
    let _ = rt.boot_done(raw, t0);
    info!("boot done: {}", rt.state());

    let mut watchdog = WatchdogPolicy::new(WatchdogConfig::default());
    let mut timing = TickTiming::default();
    let mut last_start: Option<u64> = None;
    let mut last_state = rt.state();
    let mut led_count = 0u32;
    iwdg.unleash();
    let mut ticker = Ticker::every(Duration::from_micros(u64::from(PERIOD_US)));
    loop {
        ticker.next().await;
        let c0 = DWT::cycle_count();
        let now = Instant::now().as_micros();
        let jitter = match last_start {
            Some(prev) => now.saturating_sub(prev).abs_diff(u64::from(PERIOD_US)),
            None => 0,
        };
        last_start = Some(now);

        if ESTOP.take() {
            let _ = rt.event(Event::EmergencyStop, now);
        }
        rt.set_estop_input(estop.is_high() == board::ESTOP_ACTIVE_HIGH, now);
        while let Ok(req) = COMMANDS.try_receive() {
            let result = rt.command(&req.command, now);
            let reply = req.reply(result, &rt.status());
            if REPLIES.try_send(reply).is_err() {
                REPLIES_DROPPED.fetch_add(1, Ordering::Relaxed);
            }
        }
        rt.tick(&mut hw, now);

        let cycles = DWT::cycle_count().wrapping_sub(c0);
        let jitter_us = u32::try_from(jitter).unwrap_or(u32::MAX);
        timing.record(jitter_us, cycles);
        let exec_us = TickTiming::cycles_to_us(cycles, board::CPU_HZ);
        rt.set_warning(Warnings::CYCLE_OVERRUN, exec_us > EXEC_WARN_US);
        rt.set_tick_timing(
            timing.worst_jitter_us,
            TickTiming::cycles_to_us(timing.worst_cycles, board::CPU_HZ),
        );
        let status = rt.status();
        STATUS.lock(|s| s.set(Some(status)));
        TIMING.lock(|t| t.set(timing));
        if watchdog.on_tick(now, exec_us).feed() {
            iwdg.pet();
        }

        let state = rt.state();
        if state != last_state {
            info!(
                "state {} -> {} (faults {:x})",
                last_state,
                state,
                status.faults.bits()
            );
            last_state = state;
        }
        // LED: solid in Fault, fast blink enabled or homing, slow otherwise.
        led_count = led_count.wrapping_add(1);
        let half_period = match state {
            State::Fault => 0,
            State::Enabled | State::Homing => 100,
            _ => 500,
        };
        if half_period == 0 {
            led.set_high();
        } else if led_count % half_period == 0 {
            led.toggle();
        }
    }
}

#[embassy_executor::task]
async fn link_rx(mut rx: RingBufferedUartRx<'static>) {
    let mut link = LinkRx::new(FIRMWARE_VERSION);
    let mut buf = [0u8; 64];
    loop {
        match rx.read(&mut buf).await {
            Ok(n) => {
                for byte in buf.iter().take(n) {
                    match link.push(*byte) {
                        Some(Inbound::Reply(reply)) if REPLIES.try_send(reply).is_err() => {
                            REPLIES_DROPPED.fetch_add(1, Ordering::Relaxed);
                        }
                        Some(Inbound::Reply(_)) => {}
                        Some(Inbound::Request(req)) => {
                            if req.command == controller::link::Command::EmergencyStop {
                                // Do not wait for the next tick.
                                critical_section::with(|_| {
                                    emergency_stop_isr(&mut hw::RawKill, &ESTOP)
                                });
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
            }
            Err(e) => {
                warn!("uart rx: {}", e);
                link.resync();
            }
        }
        CONNECTED.store(link.connected(), Ordering::Relaxed);
        let counters = link.counters();
        LINK.lock(|c| c.set(Some(counters)));
    }
}

#[embassy_executor::task]
async fn link_tx(mut tx: UartTx<'static, Async>) {
    let mut link = LinkTx::new();
    let geometry = RsprGeometry::<f32>::reference();
    let limits = Limits::<f32>::reference();
    let warn_levels = (limits.serial.warn, limits.parallel.warn);
    let mut telemetry = Ticker::every(Duration::from_millis(TELEMETRY_MS));
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut sent_since_log = 0u32;
    loop {
        let msg = match select(REPLIES.receive(), telemetry.next()).await {
            Either::First(m) => m,
            Either::Second(()) => {
                sent_since_log += 1;
                if sent_since_log >= 50 {
                    sent_since_log = 0;
                    let t = TIMING.lock(|t| t.get());
                    info!(
                        "tick: worst jitter {} us, worst exec {} us, last exec {} us, replies dropped {}",
                        t.worst_jitter_us,
                        TickTiming::cycles_to_us(t.worst_cycles, board::CPU_HZ),
                        TickTiming::cycles_to_us(t.last_cycles, board::CPU_HZ),
                        REPLIES_DROPPED.load(Ordering::Relaxed)
                    );
                }
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
                    if let Err(e) = tx.write(frame).await {
                        warn!("uart tx: {}", e);
                    }
                }
            }
            Err(e) => warn!("encode: {}", e),
        }
    }
}
