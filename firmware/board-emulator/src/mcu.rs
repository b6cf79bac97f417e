//! The MCU the image runs on: rigless's STM32F427 with what the image needs and the F427
//! model lacks, TIM9..TIM14 ([`crate::timers`]), the EXTI and SYSCFG ([`crate::exti`]),
//! answered in the slots the F427's bus already decodes (their addresses and interrupt lines
//! are the F405's too), plus the board's inputs applied at the instant of a stop.

use std::collections::BTreeMap;

use rigless::device::{Device, ErasedDevice, Level, ResetCause};
use rigless::mcu::{Mcu, Operate};
use rigless::soc::st::tim::Channel;
use rigless::soc::stm32f427::generated::rcc::{apb1enr, apb2enr, Register as RccRegister};
use rigless::soc::stm32f427::peripherals::gpio::{Gpio, Pin};
use rigless::soc::stm32f427::peripherals::rcc::Apb;
use rigless::soc::stm32f427::Stm32f427;
use rigless::soc::{Bus, Error as SocError, FieldSpec, Width};
use rigless::time::VirtualNanos;

use crate::exti::{Exti, Syscfg};
use crate::pins::{EncoderTimer, PinId, PwmWiring, SmallTimer};
use crate::timers::{Clocked, OneChannel, OneChannelOr, TwoChannel};

/// Offset of `TIMx_CNT` and `TIMx_ARR` (RM0090 rev 19 sections 17.4, 18.4, 19.4).
const CNT: u64 = 0x24;
const ARR: u64 = 0x2C;

/// Why the MCU could not be built.
#[derive(Debug, thiserror::Error)]
pub enum McuError {
    /// The F427's own description or a slot this crate answers for was refused.
    #[error("building the STM32F427 model: {0}")]
    Part(#[from] SocError),
}

/// The slots this wrapper answers for.
#[derive(Debug, Clone, Copy)]
struct Slots {
    tim: [usize; 6],
    exti: usize,
    syscfg: usize,
}

/// What the board puts on the MCU's pins, applied at the next stop's instant.
#[derive(Debug, Default)]
struct Inputs {
    /// The drive wanted on each input pin (`None` = nothing drives it: open contact).
    wanted_pins: BTreeMap<PinId, Option<Level>>,
    /// What was applied, so only changes reach the port.
    applied_pins: BTreeMap<PinId, Option<Level>>,
    /// Encoder counts the world has reached (wrapping), by timer.
    wanted_counts: BTreeMap<u64, u16>,
    /// The counts already added to each timer's `CNT`.
    applied_counts: BTreeMap<u64, u16>,
    /// Something wanted differs from what was applied (or may: after a reset).
    dirty: bool,
}

/// The STM32F427 model with TIM9..TIM14, EXTI and SYSCFG, standing in for the F405.
#[derive(Debug)]
pub struct BoardMcu {
    /// rigless's STM32F427.
    pub part: Stm32f427,
    /// TIM9.
    pub tim9: Clocked<TwoChannel>,
    /// TIM10.
    pub tim10: Clocked<OneChannel>,
    /// TIM11.
    pub tim11: Clocked<OneChannelOr>,
    /// TIM12 (the firmware's time driver).
    pub tim12: Clocked<TwoChannel>,
    /// TIM13.
    pub tim13: Clocked<OneChannel>,
    /// TIM14.
    pub tim14: Clocked<OneChannel>,
    /// The EXTI.
    pub exti: Exti,
    /// SYSCFG.
    pub syscfg: Syscfg,
    slots: Slots,
    inputs: Inputs,
}

fn enable_bit(timer: SmallTimer) -> &'static FieldSpec {
    match timer {
        SmallTimer::Tim9 => apb2enr::TIM9EN,
        SmallTimer::Tim10 => apb2enr::TIM10EN,
        SmallTimer::Tim11 => apb2enr::TIM11EN,
        SmallTimer::Tim12 => apb1enr::TIM12EN,
        SmallTimer::Tim13 => apb1enr::TIM13EN,
        SmallTimer::Tim14 => apb1enr::TIM14EN,
    }
}

impl BoardMcu {
    /// The part out of reset, nothing on its pins.
    pub fn new() -> Result<Self, McuError> {
        let part = Stm32f427::new()?;
        let bus = part.bus();
        let tim = [
            bus.slot("TIM9")?,
            bus.slot("TIM10")?,
            bus.slot("TIM11")?,
            bus.slot("TIM12")?,
            bus.slot("TIM13")?,
            bus.slot("TIM14")?,
        ];
        let slots = Slots {
            tim,
            exti: bus.slot("EXTI")?,
            syscfg: bus.slot("SYSCFG")?,
        };
        let mut mcu = BoardMcu {
            part,
            tim9: Clocked::new(),
            tim10: Clocked::new(),
            tim11: Clocked::new(),
            tim12: Clocked::new(),
            tim13: Clocked::new(),
            tim14: Clocked::new(),
            exti: Exti::new(),
            syscfg: Syscfg,
            slots,
            inputs: Inputs::default(),
        };
        mcu.check()?;
        Ok(mcu)
    }

    fn small_timer_at(&self, slot: usize) -> Option<SmallTimer> {
        self.slots
            .tim
            .iter()
            .position(|s| *s == slot)
            .and_then(|i| SmallTimer::ALL.get(i).copied())
    }

    /// The slot of a chapter-19 timer.
    pub fn slot_of(&self, timer: SmallTimer) -> usize {
        let i = SmallTimer::ALL
            .iter()
            .position(|t| *t == timer)
            .unwrap_or_default();
        self.slots.tim.get(i).copied().unwrap_or_default()
    }

    /// The slot of the EXTI.
    pub fn exti_slot(&self) -> usize {
        self.slots.exti
    }

    /// The clock the tree gives `timer` now: its bus's timer clock (RM0090 rev 19 section
    /// 6.2: PCLKx, or twice PCLKx when the APB prescaler is not 1), 0 while its enable bit in
    /// `RCC_APBxENR` is clear.
    pub fn timer_clock_hz(&mut self, timer: SmallTimer) -> u64 {
        let (rcc, registers) = self.part.clocks();
        let (enables, apb) = if timer.on_apb2() {
            (registers.get(RccRegister::Apb2enr), Apb::Two)
        } else {
            (registers.get(RccRegister::Apb1enr), Apb::One)
        };
        if enable_bit(timer).is_set(enables) {
            rcc.timer_clock(registers, apb)
        } else {
            0
        }
    }

    /// Stops (or restarts) the time driver's timer clock from outside, as a fault: the
    /// firmware's time stands still until the next reset.
    pub fn stop_time_driver_clock(&mut self, now: VirtualNanos, stopped: bool) {
        self.tim12.stopped = stopped;
        let hz = self.timer_clock_hz(SmallTimer::Tim12);
        self.tim12.set_wanted_hz(hz);
        let slot = self.slot_of(SmallTimer::Tim12);
        let (registers, mut context) = self.part.bus_mut().drive(now, slot);
        Device::poll(&mut self.tim12, registers, &mut context);
    }

    fn small(&mut self, timer: SmallTimer) -> &mut dyn SmallTimerModel {
        match timer {
            SmallTimer::Tim9 => &mut self.tim9,
            SmallTimer::Tim10 => &mut self.tim10,
            SmallTimer::Tim11 => &mut self.tim11,
            SmallTimer::Tim12 => &mut self.tim12,
            SmallTimer::Tim13 => &mut self.tim13,
            SmallTimer::Tim14 => &mut self.tim14,
        }
    }

    /// The level on a pin now, as a wire soldered to it would see it.
    pub fn pin_level(&mut self, pin: PinId) -> Level {
        let (gpio, registers) = self.part.port(pin.port.index());
        match Pin::new(pin.number) {
            Some(p) => gpio.level(p, registers),
            None => Level::Low,
        }
    }

    /// The alternate function a pin is set to carry, when in alternate-function mode.
    pub fn pin_function(&mut self, pin: PinId) -> Option<u8> {
        let (_, registers) = self.part.port(pin.port.index());
        Pin::new(pin.number).and_then(|p| Gpio::function(p, registers))
    }

    /// The duty a PWM output carries to its bridge, 0..=1: the pulse's high time over its
    /// period when the pin is in the timer's alternate function and the channel runs PWM; a
    /// forced level reads 0 or 1; anything else (pin not routed, timer stopped) is 0.
    pub fn pwm_duty(&mut self, wiring: &PwmWiring) -> f64 {
        if self.pin_function(wiring.pin) != Some(wiring.timer.alternate_function()) {
            return 0.0;
        }
        let Some(channel) = Channel::new(wiring.channel) else {
            return 0.0;
        };
        let slot = self.slot_of(wiring.timer);
        let registers = self.part.bus().slots()[slot].registers();
        let model: &dyn SmallTimerModel = match wiring.timer {
            SmallTimer::Tim9 => &self.tim9,
            SmallTimer::Tim10 => &self.tim10,
            SmallTimer::Tim11 => &self.tim11,
            SmallTimer::Tim12 => &self.tim12,
            SmallTimer::Tim13 => &self.tim13,
            SmallTimer::Tim14 => &self.tim14,
        };
        match model.pulse_fraction(channel, registers) {
            Some(d) => d,
            None => match model.output_level(channel, registers) {
                Some(Level::High) => 1.0,
                _ => 0.0,
            },
        }
    }

    /// A chapter-19 timer channel's PWM as (high time, period) in ns of virtual time, when it
    /// runs one (`Tim::pulse`), whatever its pin.
    pub fn pulse_ns(&mut self, timer: SmallTimer, channel: u8) -> Option<(u64, u64)> {
        let channel = Channel::new(channel)?;
        let slot = self.slot_of(timer);
        let registers = self.part.bus().slots()[slot].registers();
        let model: &dyn SmallTimerModel = match timer {
            SmallTimer::Tim9 => &self.tim9,
            SmallTimer::Tim10 => &self.tim10,
            SmallTimer::Tim11 => &self.tim11,
            SmallTimer::Tim12 => &self.tim12,
            SmallTimer::Tim13 => &self.tim13,
            SmallTimer::Tim14 => &self.tim14,
        };
        model.pulse_ns(channel, registers)
    }

    /// What the board wants on an input pin from the next stop on (`None`: nothing drives
    /// it, e.g. an open contact, so the pin's pull decides).
    pub fn set_pin(&mut self, pin: PinId, level: Option<Level>) {
        if self.inputs.wanted_pins.insert(pin, level) != Some(level) {
            self.inputs.dirty = true;
        }
    }

    /// The count an encoder's shaft has reached (wrapping 16 bits), added to its timer's
    /// `CNT` as a difference at the next stop.
    pub fn set_encoder(&mut self, timer: EncoderTimer, count: u16) {
        if self.inputs.wanted_counts.insert(timer.base(), count) != Some(count) {
            self.inputs.dirty = true;
        }
        self.inputs
            .applied_counts
            .entry(timer.base())
            .or_insert(count);
    }

    /// The voltage on an ADC1 pin channel, from now on.
    pub fn set_analog(&mut self, channel: u8, volts: f64) {
        let millivolts = (volts.clamp(0.0, 3.6) * 1000.0).round() as u32;
        if let Some(ch) = rigless::soc::stm32f427::peripherals::adc::Channel::new(channel) {
            if let Some(adc) = self.part.adc.get_mut(0) {
                adc.set_input(ch, millivolts);
            }
        }
    }

    /// Applies the board's inputs at `now`: pins whose wanted drive changed (and the EXTI
    /// edge when the pin's level changes on a line SYSCFG routes to its port), encoder counts.
    pub fn apply_inputs(&mut self, now: VirtualNanos) {
        if !std::mem::take(&mut self.inputs.dirty) {
            return;
        }
        let changed: Vec<(PinId, Option<Level>)> = self
            .inputs
            .wanted_pins
            .iter()
            .filter(|(pin, level)| self.inputs.applied_pins.get(pin) != Some(level))
            .map(|(p, l)| (*p, *l))
            .collect();
        for (pin, level) in changed {
            self.drive_pin(now, pin, level);
            self.inputs.applied_pins.insert(pin, level);
        }
        let counts: Vec<(u64, u16)> = self
            .inputs
            .wanted_counts
            .iter()
            .map(|(b, c)| (*b, *c))
            .collect();
        for (base, wanted) in counts {
            let applied = self
                .inputs
                .applied_counts
                .get(&base)
                .copied()
                .unwrap_or(wanted);
            let delta = i64::from(wanted.wrapping_sub(applied) as i16);
            if delta != 0 {
                self.add_counts(now, base, delta);
                self.inputs.applied_counts.insert(base, wanted);
            }
        }
    }

    fn add_counts(&mut self, now: VirtualNanos, base: u64, delta: i64) {
        let (Ok(count), Ok(arr)) = (
            self.part.peek(now, base + CNT, Width::W32),
            self.part.peek(now, base + ARR, Width::W32),
        ) else {
            return;
        };
        let modulus = i64::try_from(arr).unwrap_or(i64::MAX).saturating_add(1);
        let count = i64::try_from(count).unwrap_or_default();
        let next = (count + delta).rem_euclid(modulus.max(1));
        // A timer whose clock is off refuses the write: it counts nothing, as on the part.
        let _ = self.part.write(
            now,
            base + CNT,
            Width::W32,
            u64::try_from(next).unwrap_or_default(),
        );
    }

    fn drive_pin(&mut self, now: VirtualNanos, pin: PinId, level: Option<Level>) {
        let Some(p) = Pin::new(pin.number) else {
            return;
        };
        let (before, after) = self
            .part
            .drive_port(now, pin.port.index(), |gpio, regs, ctx| {
                let before = gpio.level(p, regs);
                gpio.drive(p, level, regs, ctx);
                (before, gpio.level(p, regs))
            });
        if before == after {
            return;
        }
        let line = u32::from(pin.number);
        let routed = {
            let registers = self.part.bus().slots()[self.slots.syscfg].registers();
            Syscfg::port_of(line, registers) == u8::try_from(pin.port.index()).ok()
        };
        if routed {
            let slot = self.slots.exti;
            let (registers, mut context) = self.part.bus_mut().drive(now, slot);
            self.exti
                .edge(line, after == Level::High, registers, &mut context);
        }
    }
}

/// What the board reads off a chapter-19 timer, whatever its layout.
pub trait SmallTimerModel {
    /// High time over period of the channel's PWM, when it runs one.
    fn pulse_fraction(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<f64>;
    /// The channel's output level, when the pin is driven.
    fn output_level(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<Level>;
    /// Sets the clock the tree gives it.
    fn want_hz(&mut self, hz: u64);
    /// The channel's PWM as (high time, period), ns, when it runs one.
    fn pulse_ns(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<(u64, u64)>;
}

impl<F> SmallTimerModel for Clocked<F>
where
    F: rigless::soc::st::tim::Family<Instance = rigless::soc::st::tim::Counter>,
{
    fn pulse_fraction(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<f64> {
        let pulse = self.tim.pulse(channel, registers)?;
        if pulse.period.0 == 0 {
            return None;
        }
        Some(pulse.width.0 as f64 / pulse.period.0 as f64)
    }

    fn output_level(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<Level> {
        self.tim.output(channel, registers)
    }

    fn want_hz(&mut self, hz: u64) {
        self.set_wanted_hz(hz);
    }

    fn pulse_ns(
        &self,
        channel: Channel,
        registers: &rigless::device::RegisterFile,
    ) -> Option<(u64, u64)> {
        self.tim
            .pulse(channel, registers)
            .map(|p| (p.width.0, p.period.0))
    }
}

impl Mcu for BoardMcu {
    fn bus(&self) -> &Bus {
        self.part.bus()
    }

    fn bus_mut(&mut self) -> &mut Bus {
        self.part.bus_mut()
    }

    /// The F427's reset (a fresh part, its reset flags in `RCC_CSR`), then this wrapper's
    /// models back to their reset state; the board's inputs are driven again at the next stop
    /// (the fresh part's ports have nothing on their pins).
    fn reset(&mut self, at: VirtualNanos, cause: ResetCause) {
        self.part.reset(at, cause);
        Device::reset(&mut self.tim9);
        Device::reset(&mut self.tim10);
        Device::reset(&mut self.tim11);
        Device::reset(&mut self.tim12);
        Device::reset(&mut self.tim13);
        Device::reset(&mut self.tim14);
        Device::reset(&mut self.exti);
        self.inputs.applied_pins.clear();
        self.inputs.applied_counts = self.inputs.wanted_counts.clone();
        self.inputs.dirty = true;
    }

    fn poll(&mut self, now: VirtualNanos) {
        self.part.poll(now);
        self.apply_inputs(now);
    }

    fn split(&mut self, slot: usize) -> (&mut Bus, Option<&mut dyn ErasedDevice>) {
        if let Some(timer) = self.small_timer_at(slot) {
            let hz = self.timer_clock_hz(timer);
            self.small(timer).want_hz(hz);
            let model: &mut dyn ErasedDevice = match timer {
                SmallTimer::Tim9 => &mut self.tim9,
                SmallTimer::Tim10 => &mut self.tim10,
                SmallTimer::Tim11 => &mut self.tim11,
                SmallTimer::Tim12 => &mut self.tim12,
                SmallTimer::Tim13 => &mut self.tim13,
                SmallTimer::Tim14 => &mut self.tim14,
            };
            return (self.part.bus_mut(), Some(model));
        }
        if slot == self.slots.exti {
            return (self.part.bus_mut(), Some(&mut self.exti));
        }
        if slot == self.slots.syscfg {
            return (self.part.bus_mut(), Some(&mut self.syscfg));
        }
        self.part.split(slot)
    }
}
