//! The board's peripherals behind the control application's hardware traits (`hal`), the
//! board around the control tick (`board_tasks::ControlBoard`: cycle counter, watchdog,
//! status LED, the fault log kept across resets, logs) and the master link's serial port
//! (`board_tasks::{ByteRx, ByteTx}`).

use board_tasks::{ByteRx, ByteTx, ControlBoard};
use control::estop::EStopLatch;
use control::service::{Indicator, TickOutcome, TickService};
use cortex_m::peripheral::DWT;
use defmt::{info, warn};
use embassy_stm32::adc::SampleTime;
use embassy_stm32::gpio::{Input, Level, Output};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
use embassy_stm32::wdg::IndependentWatchdog;
use hal::{
    AbsolutePositions, Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage,
    QuadratureCounter, SafeOutputs, SafetyChain,
};
use kinematics_core::Mechanism;

use crate::board::{self, Encoders, Motors, Sensors};

/// The interrupt-safe kill: register writes only.
pub struct RawKill;

impl SafeOutputs for RawKill {
    fn force_safe(&mut self) {
        board::force_outputs_safe();
    }
}

/// Encoders, bridges, brakes, switches, current and supply sense, the drivers' fault line
/// and the safety chain as the controller sees them.
pub struct Hardware {
    encoders: Encoders,
    motors: Motors,
    sensors: Sensors,
    estop_input: Input<'static>,
    estop: &'static EStopLatch,
    max_duty: [u32; 6],
}

impl Hardware {
    /// Wraps the peripherals; the outputs stay safe until [`MotorOutputs::enable`].
    pub fn new(
        encoders: Encoders,
        mut motors: Motors,
        sensors: Sensors,
        estop_input: Input<'static>,
        estop: &'static EStopLatch,
    ) -> Self {
        let max_duty = [
            motors.pwm9.max_duty_cycle(),
            motors.pwm9.max_duty_cycle(),
            motors.pwm10.max_duty_cycle(),
            motors.pwm11.max_duty_cycle(),
            motors.pwm13.max_duty_cycle(),
            motors.pwm14.max_duty_cycle(),
        ];
        motors.driver_enable.set_low();
        Hardware {
            encoders,
            motors,
            sensors,
            estop_input,
            estop,
            max_duty,
        }
    }
}

fn signed(raw: u16, invert: bool) -> u16 {
    if invert {
        0u16.wrapping_sub(raw)
    } else {
        raw
    }
}

impl QuadratureCounter for Hardware {
    fn counts(&mut self) -> [u16; 6] {
        let e = &self.encoders;
        let raw = [
            e.l1.count(),
            e.l2.count(),
            e.l3.count(),
            e.t1.count(),
            e.t2.count(),
            e.t3.count(),
        ];
        let mut out = [0u16; 6];
        for ((o, r), inv) in out.iter_mut().zip(raw).zip(board::INVERT_ENCODER) {
            *o = signed(r, inv);
        }
        out
    }
}

impl MotorOutputs<f32> for Hardware {
    fn set_duties(&mut self, duty: &[f32; 6]) {
        let mut counts = [0u32; 6];
        for (j, (d, inv)) in duty.iter().zip(board::INVERT_MOTOR).enumerate() {
            let d = if d.is_finite() {
                d.clamp(-1.0, 1.0)
            } else {
                0.0
            };
            let d = if inv { -d } else { d };
            let max = self.max_duty.get(j).copied().unwrap_or(0);
            if let Some(c) = counts.get_mut(j) {
                *c = ((d.abs() * max as f32) as u32).min(max);
            }
            if let Some(pin) = self.motors.dir.get_mut(j) {
                pin.set_level(if d >= 0.0 { Level::High } else { Level::Low });
            }
        }
        let m = &mut self.motors;
        let [c0, c1, c2, c3, c4, c5] = counts;
        m.pwm9.ch1().set_duty_cycle(c0);
        m.pwm9.ch2().set_duty_cycle(c1);
        m.pwm10.ch1().set_duty_cycle(c2);
        m.pwm11.ch1().set_duty_cycle(c3);
        m.pwm13.ch1().set_duty_cycle(c4);
        m.pwm14.ch1().set_duty_cycle(c5);
    }

    fn disable(&mut self) {
        critical_section::with(|_| board::force_outputs_safe());
    }

    fn enable(&mut self) {
        // Atomic against the e-stop interrupt: never re-enable over a pending or present
        // emergency stop.
        critical_section::with(|_| {
            if !self.estop.is_tripped() && !board::estop_asserted_raw() {
                board::restore_outputs();
            }
        });
    }
}

impl LimitSwitches for Hardware {
    fn switches(&mut self) -> [bool; 6] {
        let mut out = [false; 6];
        for (o, s) in out.iter_mut().zip(self.sensors.switches.iter()) {
            *o = s.is_high() == board::SWITCH_ACTIVE_HIGH;
        }
        out
    }
}

impl CurrentSense<f32> for Hardware {
    fn currents(&mut self) -> [f32; 6] {
        let mut out = [0f32; 6];
        let s = &mut self.sensors;
        for ((o, ch), inv) in out
            .iter_mut()
            .zip(s.current.iter_mut())
            .zip(board::INVERT_MOTOR)
        {
            let raw = f32::from(s.adc.blocking_read(ch, SampleTime::CYCLES15));
            let i = (raw - board::CURRENT_ZERO_COUNT) * board::CURRENT_A_PER_COUNT;
            *o = if inv { -i } else { i };
        }
        out
    }
}

impl AbsolutePositions for Hardware {
    fn absolute_fitted(&self) -> bool {
        self.sensors.absolute.is_some()
    }
    /// The six potentiometers through the AD7689, one conversion each
    /// (`ad7689::Ad7689::read`).
    fn absolute_counts(&mut self) -> Option<[u16; 6]> {
        let raw = self.sensors.absolute.as_mut()?.read();
        let mut out = [0u16; 6];
        for ((o, r), inv) in out.iter_mut().zip(raw).zip(board::INVERT_POSITION_SENSOR) {
            *o = if inv { u16::MAX - r } else { r };
        }
        Some(out)
    }
}

impl Brakes for Hardware {
    fn set_brakes_released(&mut self, released: bool) {
        let level = if released { Level::High } else { Level::Low };
        // Never release over a pending or present emergency stop.
        critical_section::with(|_| {
            let allowed = !released || (!self.estop.is_tripped() && !board::estop_asserted_raw());
            if allowed {
                for b in self.motors.brakes.iter_mut() {
                    b.set_level(level);
                }
            }
        });
    }
}

impl PowerStage<f32> for Hardware {
    fn supply_voltage(&mut self) -> f32 {
        let s = &mut self.sensors;
        f32::from(s.adc.blocking_read(&mut s.supply, SampleTime::CYCLES15))
            * board::SUPPLY_V_PER_COUNT
    }
    fn driver_fault(&mut self) -> bool {
        self.sensors.driver_fault.is_low()
    }
}

impl SafetyChain for Hardware {
    fn estop_pressed(&mut self) -> bool {
        self.estop_input.is_high() == board::ESTOP_ACTIVE_HIGH
    }
    fn relay_open(&mut self) -> bool {
        self.sensors.relay_feedback.is_high()
    }
}

/// The board around the control tick.
pub struct Control {
    /// Encoders, bridges, brakes, switches, currents, power stage, safety chain.
    pub hw: Hardware,
    /// The status LED.
    pub led: Output<'static>,
    /// The independent watchdog (started).
    pub iwdg: IndependentWatchdog<'static, IWDG>,
    /// Ticks since the last timing log.
    pub ticks: u32,
    /// The flash, for the calibrated geometry's sector and the event log's.
    pub flash: embassy_stm32::flash::Flash<'static, embassy_stm32::flash::Blocking>,
    /// The event log's writer (None: its flash could not be read at boot).
    pub events: Option<control::event_log::EventStore>,
}

impl ControlBoard<f32> for Control {
    type Hardware = Hardware;
    fn hardware(&mut self) -> &mut Hardware {
        &mut self.hw
    }
    fn cycles(&mut self) -> u32 {
        DWT::cycle_count()
    }
    fn feed_watchdog(&mut self) {
        self.iwdg.pet();
    }
    fn persist_fault_log(&mut self, log: &control::faults::FaultLog) {
        crate::safe_halt::persist(log);
    }
    fn persist_events(&mut self, log: &control::event_log::EventLog) {
        crate::safe_halt::persist_events(log);
    }
    fn store_events(
        &mut self,
        log: &mut control::event_log::EventLog,
        now_ms: u32,
        words: usize,
        may_erase: bool,
    ) -> control::event_log::Step {
        let Some(store) = self.events.as_mut() else {
            return control::event_log::Step::Idle;
        };
        let mut sectors = crate::event_flash::EventSectors(&mut self.flash);
        let step = store.step(&mut sectors, log, now_ms, words, may_erase);
        match step {
            control::event_log::Step::Erased { sector } => {
                self.iwdg.pet();
                info!("event log: sector {} erased", sector);
            }
            control::event_log::Step::Failed(_) => warn!("event log: a flash operation failed"),
            control::event_log::Step::GaveUp => warn!("event log: flash given up"),
            _ => {}
        }
        step
    }
    fn program_window_us(&self) -> u32 {
        crate::event_flash::PROGRAM_WINDOW_US
    }
    fn store_geometry(
        &mut self,
        record: &master_link::GeometryRecord,
    ) -> Result<(), master_link::GeometryRefusal> {
        let r = crate::geometry_flash::store(&mut self.flash, record);
        self.iwdg.pet();
        match r {
            Ok(()) => info!("calibrated geometry version {} stored", record.version),
            Err(e) => warn!("calibrated geometry not stored: {}", e),
        }
        r
    }
    fn after_tick<M: Mechanism<f32> + Clone>(
        &mut self,
        service: &TickService<f32, M>,
        outcome: &TickOutcome,
    ) {
        if let Some((from, to)) = outcome.state_change {
            info!(
                "state {} -> {} (faults {:x})",
                from,
                to,
                outcome.status.faults.bits()
            );
        }
        self.ticks = self.ticks.wrapping_add(1);
        match Indicator::of(outcome.state) {
            Indicator::Solid => self.led.set_high(),
            Indicator::Blink(n) if self.ticks.is_multiple_of(n) => self.led.toggle(),
            Indicator::Blink(_) => {}
        }
        if self.ticks.is_multiple_of(1000) {
            let t = service.timing();
            info!(
                "tick: worst jitter {} us, worst exec {} us, last exec {} us, missed periods {}",
                t.worst_jitter_us,
                control::watchdog::TickTiming::cycles_to_us(t.worst_cycles, board::CPU_HZ),
                outcome.exec_us,
                service.missed_periods()
            );
        }
    }
}

/// The master link's receiving side: USART3 with circular DMA.
pub struct LinkRx(pub RingBufferedUartRx<'static>);

impl ByteRx for LinkRx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, ()> {
        self.0.read(buf).await.map_err(|e| warn!("uart rx: {}", e))
    }
}

/// The master link's sending side: USART3 with DMA.
pub struct LinkTx(pub UartTx<'static, Async>);

impl ByteTx for LinkTx {
    async fn write_all(&mut self, frame: &[u8]) {
        if let Err(e) = self.0.write(frame).await {
            warn!("uart tx: {}", e);
        }
    }
}
