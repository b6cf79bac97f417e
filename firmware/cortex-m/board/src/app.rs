//! The board application's bring-up and tasks, written once for every board target: the
//! interrupt handlers (the e-stop line, the control executor), the defined halt, the
//! runtime booted on the calibrated geometry, and the three tasks around `board_tasks`.
//! Each target's `main.rs` initialises the chip with its clock tree and calls [`run`]; the
//! target's own module `board` (its pin map) is the only thing that differs, and this file
//! is compiled into each target against it (one chip per build: embassy-stm32 selects the
//! chip by a Cargo feature, so every target is a crate of its own).
//!
//! Interrupts and tasks, highest priority first:
//! * `EXTI15_10` (P0): the e-stop edge forces every output safe (PWM off, driver enable
//!   low, brakes applied) and trips the latch (the button's second channel: its first
//!   opens the safety relay without the MCU);
//! * TIM12 time driver (P1);
//! * `control` on an interrupt executor (`UART4` vector, P2): the 1 kHz control tick;
//! * USART3 and its DMA (P4);
//! * `link_rx`, `link_tx` in thread mode.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

use crate::{board, event_flash, geometry_flash, hw, safe_halt};
use board_tasks::{firmware_version, run_control, run_link_rx, run_link_tx, Shared};
use control::estop::emergency_stop_isr;
use control::event_log::EventLog;
use control::faults::FaultLog;
use control::runtime::{reference_config_for, Runtime};
use control::service::{ServiceConfig, TickService};
use defmt::{error, info};
use defmt_rtt as _;
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::Instant;
use hal::{QuadratureCounter, SafeOutputs};
use kinematics_core::{Branch, PerChainGeometry, RsprGeometry};
use master_link::ResetCause;

/// Control period, µs: the board profile's.
const PERIOD_US: u32 = board::PROFILE.control_period_us;
/// Telemetry period, ms (50 Hz).
const TELEMETRY_MS: u64 = 20;

/// The link key of this board's profile: 64 hexadecimal digits in `RSPR_LINK_KEY` when
/// the image is built (a board whose link leaves the desk), or none (a board on a desk:
/// frames without tags). Never logged.
const LINK_KEY_HEX: Option<&str> = option_env!("RSPR_LINK_KEY");

/// The link key of the board's profile, if it has one.
fn link_key() -> Option<master_link::LinkKey> {
    match LINK_KEY_HEX.map(master_link::LinkKey::from_hex) {
        None => None,
        Some(Ok(k)) => Some(k),
        Some(Err(_)) => halt("RSPR_LINK_KEY is not 64 hexadecimal digits"),
    }
}

static SHARED: Shared = Shared::new();
static EXECUTOR_CONTROL: InterruptExecutor = InterruptExecutor::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: the executor was started on this interrupt before it was unmasked.
    unsafe { EXECUTOR_CONTROL.on_interrupt() }
}

#[interrupt]
fn EXTI15_10() {
    board::clear_estop_pending();
    emergency_stop_isr(&mut hw::RawKill, &SHARED.estop);
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

/// Everything after the chip's initialisation: the version logged, the cycle counter, the
/// reset cause and the logs kept across the reset, the board's pins and peripherals
/// (`board::Board::new`), the event log's flash, the interrupt priorities and the e-stop
/// line, the watchdog, and the three tasks spawned.
pub fn run(spawner: Spawner, p: embassy_stm32::Peripherals) {
    let version = firmware_version!();
    info!(
        "rspr-board {}.{}.{}",
        version.major, version.minor, version.patch
    );
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        halt("core peripherals taken");
    };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    // Before anything else can reset: why the last reset, and the fault log it kept.
    let reset = board::take_reset_cause();
    let kept_log = safe_halt::take();
    let mut b = match board::Board::new(p) {
        Ok(b) => b,
        Err(e) => {
            error!("board setup: {}", e);
            halt("board setup");
        }
    };
    // The event log, before the watchdog runs: its flash mounted (the view kept across a
    // watchdog reset taken when newer), a sector erased if the next record needs one (the
    // drives are off), and the view kept from now on for the panic handler.
    let (event_store, events) = {
        let mut sectors = event_flash::EventSectors(&mut b.flash);
        let (mut store, events) = control::event_log::boot(&mut sectors, safe_halt::take_events());
        if let Some(s) = store.as_mut() {
            if s.prepare(&mut sectors).is_err() {
                store = None;
            }
        }
        (store, events)
    };
    safe_halt::persist_events(&events);

    // Priorities: e-stop > time driver > control > link.
    interrupt::EXTI15_10.set_priority(Priority::P0);
    interrupt::TIM8_BRK_TIM12.set_priority(Priority::P1);
    interrupt::UART4.set_priority(Priority::P2);
    interrupt::USART3.set_priority(Priority::P4);
    board::configure_estop_exti();
    // SAFETY: the handler above is defined; enabling it cannot break a critical section.
    unsafe { interrupt::EXTI15_10.enable() };

    let mut iwdg = b.iwdg;
    iwdg.unleash();
    let control_board = hw::Control {
        hw: hw::Hardware::new(b.encoders, b.motors, b.sensors, b.estop, &SHARED.estop),
        led: b.led,
        iwdg,
        ticks: 0,
        flash: b.flash,
        events: event_store,
    };
    let control_spawner = EXECUTOR_CONTROL.start(interrupt::UART4);
    match control(Owned(control_board), reset, kept_log, Owned(events)) {
        Ok(t) => control_spawner.spawn(t),
        Err(_) => halt("spawn control"),
    }
    let (tx, rx) = b.uart.split();
    let Some(dma_buf) = cortex_m::singleton!(: [u8; 512] = [0; 512]) else {
        halt("rx buffer");
    };
    let key = link_key();
    // The session ids' seed: the chip's unique id, and the key's secret when there is one.
    let identity = control::link::BoardIdentity::new(&embassy_stm32::uid::uid(), key.as_ref());
    info!(
        "master link: {}",
        if key.is_some() {
            "authenticated (key)"
        } else {
            "no key"
        }
    );
    match link_rx(
        hw::LinkRx(rx.into_ring_buffered(dma_buf)),
        identity,
        key.clone(),
    ) {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_rx"),
    }
    match link_tx(hw::LinkTx(tx), key) {
        Ok(t) => spawner.spawn(t),
        Err(_) => halt("spawn link_tx"),
    }
}

/// The robot's runtime, booted on the encoders as they read now with the reset cause, the
/// kept fault log and the event log (the relay test required again when it was pending at
/// the end of the last power cycle), in its tick service: on the calibrated geometry
/// stored in flash when one passes its checks, else on the symmetric reference robot (both
/// as a `PerChainGeometry`; a geometry stored while running takes effect at the next
/// reset). (A plain function: the intermediate values stay off the task's future.)
fn control_service(
    board: &mut hw::Control,
    reset: ResetCause,
    log: Option<FaultLog>,
    events: EventLog,
) -> TickService<f32, PerChainGeometry<f32>> {
    let nominal = RsprGeometry::<f32>::reference();
    let (robot, version) = geometry_flash::stored(&mut board.flash, &nominal, Branch::OUTER)
        .unwrap_or((PerChainGeometry::from(nominal), 0));
    let Ok(cfg) = reference_config_for(&robot, Branch::OUTER, None, None) else {
        halt("central configuration");
    };
    let now = Instant::now().as_micros();
    let Ok(mut rt) = Runtime::new(robot, cfg, now) else {
        halt("runtime configuration");
    };
    rt.restore_events(events);
    let _ = rt.boot_done(board.hw.counts(), now, reset, log);
    // The calibrated geometry's version for the hello reply (0: the reference robot).
    rt.set_geometry_version(version);
    info!(
        "boot done: {}, reset {}, {} faults kept, boot {} with {} events, relay test pending {}",
        rt.state(),
        reset,
        rt.fault_log().len(),
        rt.events().boot(),
        rt.events().len(),
        rt.relay_test_pending()
    );
    let cfg = ServiceConfig::for_period(PERIOD_US, board::CPU_HZ, firmware_version!());
    TickService::new(rt, cfg)
}

/// The control task's tick service: a static of its own, not a value in the task's future.
/// Built on the task's first poll by [`boot_service`].
struct ServiceSlot(UnsafeCell<MaybeUninit<TickService<f32, PerChainGeometry<f32>>>>);
// SAFETY: written once and then lent as the one `&mut` (`SERVICE_TAKEN`), to the control
// task only.
unsafe impl Sync for ServiceSlot {}
static SERVICE: ServiceSlot = ServiceSlot(UnsafeCell::new(MaybeUninit::uninit()));
static SERVICE_TAKEN: AtomicBool = AtomicBool::new(false);

/// The tick service booted (`control_service`) into its static, lent to the control task.
///
/// Its own function, never inlined: booting the runtime builds the configuration, the
/// runtime and the service as temporaries (tens of KiB on the stack). Inlined into the
/// task's poll they would be part of that poll's frame, which is on the stack under every
/// control tick; here they are gone once the service is built.
#[inline(never)]
fn boot_service(
    board: &mut hw::Control,
    reset: ResetCause,
    log: Option<FaultLog>,
    events: EventLog,
) -> &'static mut TickService<f32, PerChainGeometry<f32>> {
    if SERVICE_TAKEN.swap(true, Ordering::AcqRel) {
        halt("control service booted twice");
    }
    let service = control_service(board, reset, log, events);
    // SAFETY: `SERVICE_TAKEN` was false: no reference to the slot exists, and this is the
    // only one ever made.
    unsafe { (*SERVICE.0.get()).write(service) }
}

#[embassy_executor::task]
async fn control(
    board: Owned<hw::Control>,
    reset: ResetCause,
    log: Option<FaultLog>,
    events: Owned<EventLog>,
) {
    let mut board = board.0;
    let service = boot_service(&mut board, reset, log, events.0);
    run_control(&SHARED, &mut board, service).await
}

#[embassy_executor::task]
async fn link_rx(
    mut rx: hw::LinkRx,
    identity: control::link::BoardIdentity,
    key: Option<master_link::LinkKey>,
) {
    run_link_rx(&SHARED, &mut rx, &mut hw::RawKill, identity, key).await
}

#[embassy_executor::task]
async fn link_tx(mut tx: hw::LinkTx, key: Option<master_link::LinkKey>) {
    run_link_tx(&SHARED, &mut tx, TELEMETRY_MS, key).await
}
