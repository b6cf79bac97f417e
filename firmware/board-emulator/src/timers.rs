//! TIM9..TIM14 of RM0090 rev 19 chapter 19, from rigless's own timer model ([`Tim`]) with
//! [`Family`] types for ST's `tim9`, `tim10` and `tim11` register layouts, and a wrapper that
//! runs each on the timer clock of its bus as the clock tree sets it.
//!
//! | RM0090 rev 19 | what it says | here |
//! |---|---|---|
//! | 19.1, 19.2 | TIM9/TIM12: 16-bit up counter, 2 channels, slave mode controller (reset, gated, trigger, external clock), TRGO; TIM10/11/13/14: 16-bit up counter, 1 channel, no slave controller; none has DMA | [`Kind::TwoChannelSlave`] and [`Kind::OneChannel`]: up counting only, `dma()` false, channels 2 / 1 |
//! | 19.4.4, 19.5.3 | `TIMx_SR` flags are `rc_w0` | rigless's part description types every timer's `SR` zero-to-clear (its `EVERY_TIMER`) |
//! | 19.3.9, 19.5.x | PWM mode 1/2, `CCRx` preload, `ARR` preload under `ARPE` | the shared model's output stage |
//! | 6.2 | the timer clock of APB1/APB2: PCLKx, or 2 x PCLKx when the APB prescaler is not 1 | [`Clocked`] reads `Rcc::timer_clock` and the timer's enable bit before every call and re-bases the counter (rigless wires these six to no clock of the tree) |
//!
//! Not modelled: the input-capture remaps of `TIM11_OR` (the register stores, nothing reads it),
//! the debug freeze bits (`DBGMCU_APBx_FZ`), and the clock change is heard at the timer's next
//! access or event rather than at the instant `RCC_CFGR` is written (the firmware sets the tree
//! up before it starts a timer).

use rigless::device::{Device, DeviceContext, RegisterFile, RequestChange};
use rigless::soc::st::tim::{Counter, Family, Kind, Tim};
use rigless::soc::stm32f427::generated::{tim10, tim11, tim9};
use rigless::soc::stm32f427::peripherals::tim::PART;
use rigless::soc::RegisterSpec;
use rigless::time::{EventId, VirtualNanos};

/// The `tim9` layout: TIM9 and TIM12.
#[derive(Debug, Clone, Copy)]
pub struct TwoChannel;

impl Family for TwoChannel {
    type Register = tim9::Register;
    type Instance = Counter;
    const PART: &'static rigless::soc::st::tim::Part = &PART;
    const KINDS: &'static [Kind] = &[Kind::TwoChannelSlave];
}

/// The `tim10` layout: TIM10, TIM13 and TIM14 (ST's file gives TIM13 and TIM14 TIM10's table).
#[derive(Debug, Clone, Copy)]
pub struct OneChannel;

impl Family for OneChannel {
    type Register = tim10::Register;
    type Instance = Counter;
    const PART: &'static rigless::soc::st::tim::Part = &PART;
    const KINDS: &'static [Kind] = &[Kind::OneChannel];
}

/// The `tim11` layout: TIM11 (TIM10's with the option register `TIM11_OR` at 0x50).
#[derive(Debug, Clone, Copy)]
pub struct OneChannelOr;

impl Family for OneChannelOr {
    type Register = tim11::Register;
    type Instance = Counter;
    const PART: &'static rigless::soc::st::tim::Part = &PART;
    const KINDS: &'static [Kind] = &[Kind::OneChannel];
}

/// The rate every bus runs at out of reset (the 16 MHz HSI), RM0090 rev 19 section 6.2.
pub const RESET_CLOCK_HZ: u64 = 16_000_000;

/// A chapter-19 timer on the clock the tree gives it.
///
/// The MCU sets [`Clocked::set_wanted_hz`] from `RCC` before every call into the model; the
/// wrapper hands the change to the timer (`Device::on_clock`, which keeps what was counted and
/// places its next wake-up at the new rate) at the instant of that call.
#[derive(Debug)]
pub struct Clocked<F: Family<Instance = Counter>> {
    /// The timer.
    pub tim: Tim<F>,
    /// The rate the timer counts at now.
    hz: u64,
    /// The rate the tree gives it.
    wanted: u64,
    /// A test's or a fault's stop of the clock: the timer hears 0 Hz while set.
    pub stopped: bool,
}

impl<F: Family<Instance = Counter>> Clocked<F> {
    /// A timer out of reset, on the reset clock.
    pub fn new() -> Self {
        Clocked {
            tim: Tim::with_clock(RESET_CLOCK_HZ, Counter::Narrow),
            hz: RESET_CLOCK_HZ,
            wanted: RESET_CLOCK_HZ,
            stopped: false,
        }
    }

    /// The rate the tree gives the timer from now (0 while its enable bit is clear).
    pub fn set_wanted_hz(&mut self, hz: u64) {
        self.wanted = if self.stopped { 0 } else { hz };
    }

    /// The rate the timer counts at.
    pub fn hz(&self) -> u64 {
        self.hz
    }

    fn rebase(&mut self, registers: &mut RegisterFile, context: &mut DeviceContext<'_>) {
        if self.wanted != self.hz {
            self.hz = self.wanted;
            self.tim.on_clock(self.wanted, registers, context);
        }
    }
}

impl<F: Family<Instance = Counter>> Default for Clocked<F> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: Family<Instance = Counter>> Device for Clocked<F> {
    type Register = F::Register;

    fn layout(&self) -> &'static [RegisterSpec] {
        Device::layout(&self.tim)
    }

    fn read(
        &mut self,
        register: F::Register,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) -> Option<u64> {
        self.rebase(registers, context);
        self.tim.read(register, registers, context)
    }

    fn peek(
        &self,
        register: F::Register,
        registers: &RegisterFile,
        now: VirtualNanos,
    ) -> Option<u64> {
        self.tim.peek(register, registers, now)
    }

    fn write(
        &mut self,
        register: F::Register,
        value: u64,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) {
        self.rebase(registers, context);
        self.tim.write(register, value, registers, context);
    }

    fn on_event(
        &mut self,
        event: EventId,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) {
        self.rebase(registers, context);
        self.tim.on_event(event, registers, context);
    }

    fn on_request(
        &mut self,
        request: RequestChange,
        registers: &mut RegisterFile,
        context: &mut DeviceContext<'_>,
    ) {
        self.rebase(registers, context);
        self.tim.on_request(request, registers, context);
    }

    fn poll(&mut self, registers: &mut RegisterFile, context: &mut DeviceContext<'_>) {
        self.rebase(registers, context);
    }

    fn reset(&mut self) {
        self.tim.reset();
        self.stopped = false;
    }
}
