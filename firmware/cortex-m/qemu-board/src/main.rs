//! The RSPR board application on QEMU's mps2-an386 (Cortex-M4F, 25 MHz): the tasks of
//! `board_tasks`, as on the board, with
//! * an embassy-time driver on SysTick (`time_driver`),
//! * the master link on the emulated CMSDK UART0 (`uart`; QEMU's first `-serial`),
//! * a software plant on the MCU behind the hardware traits (`plant`): the encoders read
//!   it, the PWM duties drive it.
//!
//! Interrupts and tasks, highest priority first: SysTick (time driver) and the UART0
//! receive interrupt; `control` on an interrupt executor (IRQ 31, a free line); `link_rx`,
//! `link_tx` in thread mode. Log lines (state changes, refused targets, timing every 5 s)
//! go to the host through semihosting.
#![no_std]
#![no_main]

mod plant;
mod time_driver;
mod uart;

use board_tasks::{firmware_version, run_control, run_link_rx, run_link_tx, ControlBoard, Shared};
use control::runtime::{reference_config_for, Runtime};
use control::service::{ServiceConfig, TickOutcome, TickService};
use cortex_m_rt::exception;
use cortex_m_semihosting::hprintln;
use embassy_executor::{InterruptExecutor, Spawner};
use hal::{QuadratureCounter, SafeOutputs};
use kinematics_core::{Branch, Mechanism, RsprGeometry};
use panic_semihosting as _;

use crate::plant::Plant;
use crate::time_driver::{now_us, CPU_HZ};
use crate::uart::Irq;

/// Control rate under the emulator, Hz. QEMU runs the guest on the host's clock (no
/// `-icount`): a tick of ~18 k instructions plus the software plant does not keep up at
/// 1 kHz under TCG, so the emulated board runs at 250 Hz.
const RATE_HZ: u32 = 250;
/// Control period, µs.
const PERIOD_US: u32 = 1_000_000 / RATE_HZ;
/// Telemetry period, ms.
const TELEMETRY_MS: u64 = 20;
/// Timing log period, ticks (5 s).
const LOG_EVERY_TICKS: u32 = 5 * RATE_HZ;

/// The interrupt line of the control executor (unused by the mps2-an386's devices).
const CONTROL_IRQ: u16 = 31;
/// NVIC / SysTick priorities (lower is more urgent).
const PRIO_TIME_AND_UART: u8 = 0x20;
const PRIO_CONTROL: u8 = 0x40;

static SHARED: Shared = Shared::new();
static EXECUTOR_CONTROL: InterruptExecutor = InterruptExecutor::new();

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
    let v = firmware_version!();
    hprintln!(
        "rspr-qemu-board {}.{}.{}: control at {} Hz, master link on UART0 at {} baud",
        v.major,
        v.minor,
        v.patch,
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

/// The emulated board around the control tick: the software plant as the hardware, the
/// time base as the cycle counter (QEMU has no DWT cycle counter), no e-stop input, no
/// watchdog.
struct Emulated {
    plant: Plant,
    ticks: u32,
    path_refused: u32,
}

impl ControlBoard<f32> for Emulated {
    type Hardware = Plant;
    fn hardware(&mut self) -> &mut Plant {
        &mut self.plant
    }
    fn cycles(&mut self) -> u32 {
        (now_us() as u32).wrapping_mul(CPU_HZ / 1_000_000)
    }
    fn feed_watchdog(&mut self) {}
    fn before_tick(&mut self, now_us: u64) {
        // The plant runs up to now with the duties of the last tick.
        self.plant.advance_to(now_us);
    }
    fn after_tick<M: Mechanism<f32> + Clone>(
        &mut self,
        service: &TickService<f32, M>,
        outcome: &TickOutcome,
    ) {
        let t_ms = now_us() / 1000;
        if let Some((from, to)) = outcome.state_change {
            hprintln!(
                "t={} ms: state {:?} -> {:?} (faults {:#x})",
                t_ms,
                from,
                to,
                outcome.status.faults.bits()
            );
        }
        // Targets refused by the supervisor's path check (after their Ack).
        if let Some(sup) = service.runtime().controller().map(|c| c.supervisor()) {
            let refused = sup.counters().path_refused;
            if refused > self.path_refused {
                if let Some(r) = sup.last_refusal() {
                    hprintln!("t={} ms: target refused by the path check: {:?}", t_ms, r);
                }
            }
            self.path_refused = refused;
        }
        self.ticks = self.ticks.wrapping_add(1);
        if self.ticks.is_multiple_of(LOG_EVERY_TICKS) {
            let t = service.timing();
            hprintln!(
                "t={} ms: {} ticks at {} Hz ({} missed), worst jitter {} us, worst exec {} us, last exec {} us, plant steps {} ({} ms frozen), rx dropped {}",
                t_ms,
                t.ticks,
                RATE_HZ,
                service.missed_periods(),
                t.worst_jitter_us,
                control::watchdog::TickTiming::cycles_to_us(t.worst_cycles, CPU_HZ),
                outcome.exec_us,
                self.plant.steps,
                self.plant.frozen_us / 1000,
                uart::RX_DROPPED.load(core::sync::atomic::Ordering::Relaxed)
            );
        }
    }
}

/// Where the emulated robot is at power-up: legs a few mm above their home switches,
/// links 0.15 .. 0.25 rad above their hard stops (the reference mechanics'); the raw
/// counters start at arbitrary values.
fn power_up_plant(central_q: &[f32; 6], now: u64) -> Plant {
    let mech = control::runtime::reference_mechanics(
        central_q,
        &kinematics_core::guards::Limits::reference(),
    );
    let stop =
        |j: usize| central_q.get(j).copied().unwrap_or(0.0) - mech.link_stop_below_central_rad;
    let stops = [stop(3), stop(4), stop(5)];
    let sw = mech.leg_switch_m;
    let q0 = [
        sw + 0.006,
        sw + 0.008,
        sw + 0.005,
        stops[0] + 0.20,
        stops[1] + 0.25,
        stops[2] + 0.15,
    ];
    let raw0 = [1234, 40_000, 65_000, 7, 30_000, 52_345];
    Plant::new(q0, raw0, sw, stops, now, 2 * u64::from(PERIOD_US))
}

/// The reference robot's runtime for the emulator, booted on the plant, in its tick
/// service. Differences from the board: the control rate; about one full guard evaluation
/// per tick (5 stages when the SVD starts warm: at 250 Hz one stage per tick verifies a
/// 100 Hz stream too slowly); a 200 ms target latency (the host may stall the guest by
/// tens of ms); no backlash compensation (the emulated joints have none); a quick park.
fn control_service() -> (Emulated, TickService<f32, RsprGeometry<f32>>) {
    let robot = RsprGeometry::<f32>::reference();
    let Ok(central) = kinematics_core::inverse(
        &robot,
        &kinematics_core::Pose::central(robot.hc),
        Branch::OUTER,
    ) else {
        halt("central configuration");
    };
    let central_q = control::drive::to_array(&central.q());
    let now = now_us();
    let mut plant = power_up_plant(&central_q, now);
    let rest = plant.positions();
    let Ok(mut cfg) = reference_config_for(&robot, Branch::OUTER, None, Some(rest)) else {
        halt("central configuration");
    };
    cfg.controller.rate_hz = RATE_HZ as f32;
    cfg.controller.supervisor.stages_per_tick = 5;
    cfg.controller.servo.backlash = servo::backlash::BacklashConfig::off();
    cfg.targets.max_latency_us = 200_000;
    cfg.park.speed = [0.01, 0.01, 0.01, 0.3, 0.3, 0.3];
    let Ok(mut rt) = Runtime::new(robot, cfg, now) else {
        halt("runtime configuration");
    };
    let _ = rt.boot_done(plant.counts(), now, master_link::ResetCause::PowerOn, None);
    hprintln!("boot done: {:?}", rt.state());
    let board = Emulated {
        plant,
        ticks: 0,
        path_refused: 0,
    };
    (board, TickService::new(rt, service_config()))
}

/// The tick service's settings here: QEMU does not run in real time (the host stalls the
/// guest by milliseconds to tens of milliseconds), so the deadline policy would fault on
/// the host's hiccups, not on the firmware's: a tick may start up to 100 ms late and
/// overruns are only warned about. The policy itself is tested on the host
/// (`firmware/control/tests/failsafe.rs`) and in the instruction-exact STM32 emulator.
fn service_config() -> ServiceConfig {
    let mut cfg = ServiceConfig::for_period(PERIOD_US, CPU_HZ, firmware_version!());
    cfg.watchdog.max_lateness_us = 100_000;
    cfg.overruns_to_fault = u32::MAX;
    cfg
}

#[embassy_executor::task]
async fn control() {
    let (mut board, mut service) = control_service();
    run_control(&SHARED, &mut board, &mut service).await
}

/// The master link's receiving side: the UART0 receive pipe.
struct UartRx;

impl board_tasks::ByteRx for UartRx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, ()> {
        Ok(uart::RX.read(buf).await)
    }
}

/// The master link's sending side: UART0, polled.
struct UartTx;

impl board_tasks::ByteTx for UartTx {
    async fn write_all(&mut self, frame: &[u8]) {
        uart::write_all(frame).await
    }
}

#[embassy_executor::task]
async fn link_rx() {
    run_link_rx(&SHARED, &mut UartRx, &mut plant::RawKill).await
}

#[embassy_executor::task]
async fn link_tx() {
    run_link_tx(&SHARED, &mut UartTx, TELEMETRY_MS).await
}
