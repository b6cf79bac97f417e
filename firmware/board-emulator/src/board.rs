//! The RSPR board around the MCU: the 8 MHz crystal, the 3.3 V rail, the master link on
//! USART3 as a host wire, and the board's edge: what the firmware drives (PWM, direction,
//! enable, brakes) read off the pins, and what the world does to the inputs (encoders,
//! current sense, switches, e-stop, relay feedback, driver fault, supply sense).

use std::collections::VecDeque;
use std::num::{NonZeroU32, NonZeroU64};

use rigless::chip::uart::Peer;
use rigless::chip::Timeline;
use rigless::device::Level;
use rigless::emulator::CoreSpec;
use rigless::machine::armv7m;
use rigless::machine::{Board, Crystal, HostWire, Supply, Target};
use rigless::mcu::{Mcu, Operate};
use rigless::snapshot::Store;
use rigless::time::VirtualNanos;

use crate::mcu::{BoardMcu, McuError};
use crate::pins::{BoardTarget, PinMap, CURRENT_SENSE_ZERO_V, REFERENCE, SUPPLY_DIVIDER, VREF_V};

/// The high-speed crystal on PH0/PH1.
pub const HSE_HZ: u64 = 8_000_000;
/// The core clock the firmware sets (8 MHz HSE, PLL to 168 MHz).
pub const CORE_HZ: u64 = board_profile::BoardProfile::REFERENCE.cpu_hz as u64;
/// Instructions per second of virtual time: one per core cycle (no flash wait states or
/// pipeline stalls are modelled, so cycle figures are approximate).
pub const INSTRUCTIONS_PER_SECOND: u64 = CORE_HZ;
/// The board's 3.3 V rail, mV.
pub const RAIL_MV: u32 = 3300;
/// The master link's wire (USART3), as `Board::hosts` names it.
pub const MASTER_WIRE: HostWire = HostWire {
    name: "master",
    port: 5770,
};
/// USART3's index in rigless's `Stm32f427::usart` (USART1, USART2, USART3, ...).
const USART3: usize = 2;

/// Why the board could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// The MCU.
    #[error(transparent)]
    Mcu(#[from] McuError),
}

/// The master's end of the link: bytes queued to send (taken by USART3's receiver at its baud
/// from the stop they were queued at) and every byte the board sent, with its instant.
#[derive(Debug, Default)]
pub struct MasterWire {
    outgoing: VecDeque<u8>,
    heard: Vec<u16>,
    unread: Vec<(VirtualNanos, u8)>,
}

impl MasterWire {
    /// Queues bytes for the board.
    pub fn send(&mut self, bytes: &[u8]) {
        self.outgoing.extend(bytes.iter().copied());
    }

    /// Bytes queued and not yet on the wire.
    pub fn queued(&self) -> usize {
        self.outgoing.len()
    }

    /// The bytes the board sent since the last call, with the instant each stop bit ended.
    pub fn take_received(&mut self) -> Vec<(VirtualNanos, u8)> {
        std::mem::take(&mut self.unread)
    }
}

impl Store for MasterWire {}

impl Peer for MasterWire {
    fn receive(&mut self, word: u16, context: &mut Timeline<'_, '_>) {
        self.heard.push(word);
        self.unread
            .push((context.now(), u8::try_from(word & 0xFF).unwrap_or_default()));
    }

    fn transmit(&mut self, _now: VirtualNanos) -> Option<u16> {
        self.outgoing.pop_front().map(u16::from)
    }

    fn received(&self) -> &[u16] {
        &self.heard
    }
}

/// What the world does to the board's inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signals {
    /// Each encoder's count (x4 quadrature, wrapping 16 bits), joint order.
    pub encoder_counts: [u16; 6],
    /// Each motor's armature current, A (+ towards +q), joint order.
    pub currents_a: [f64; 6],
    /// Each home / limit switch actuated (its NC contact open), joint order.
    pub switches_actuated: [bool; 6],
    /// The e-stop chain open (pressed or broken).
    pub estop_pressed: bool,
    /// The safety relay open (its feedback contact open).
    pub relay_open: bool,
    /// A motor driver pulls nFAULT low.
    pub driver_fault: bool,
    /// The bridges' supply, V.
    pub supply_v: f64,
}

impl Signals {
    /// At rest: nothing moving, no switch actuated, e-stop released, relay closed, 24 V.
    pub const REST: Signals = Signals {
        encoder_counts: [0; 6],
        currents_a: [0.0; 6],
        switches_actuated: [false; 6],
        estop_pressed: false,
        relay_open: false,
        driver_fault: false,
        supply_v: 24.0,
    };
}

/// What the firmware drives, read off the pins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outputs {
    /// Each bridge's PWM duty, 0..=1 (magnitude).
    pub duty: [f64; 6],
    /// Each bridge's direction pin high (towards +q).
    pub dir_positive: [bool; 6],
    /// The driver enable pin high.
    pub driver_enable: bool,
    /// The brake outputs high (released): legs, links.
    pub brakes_released: [bool; 2],
    /// The status LED on.
    pub led: bool,
}

impl Outputs {
    /// Everything low: what a board out of reset drives (pins floating read low with the
    /// board's pull-downs).
    pub const OFF: Outputs = Outputs {
        duty: [0.0; 6],
        dir_positive: [false; 6],
        driver_enable: false,
        brakes_released: [false; 2],
        led: false,
    };

    /// The signed duty each bridge is commanded (sign-magnitude drive): the PWM duty towards
    /// the direction pin's side.
    pub fn signed_duty(&self) -> [f64; 6] {
        std::array::from_fn(|j| {
            let d = self.duty.get(j).copied().unwrap_or_default();
            if self.dir_positive.get(j).copied().unwrap_or(true) {
                d
            } else {
                -d
            }
        })
    }

    /// The outputs as bits, for the trace digest and the edge log: enable, LED, brakes, DIR.
    pub fn bits(&self) -> u16 {
        let mut b = u16::from(self.driver_enable) | u16::from(self.led) << 1;
        for (i, r) in self.brakes_released.iter().enumerate() {
            b |= u16::from(*r) << (2 + i);
        }
        for (i, d) in self.dir_positive.iter().enumerate() {
            b |= u16::from(*d) << (4 + i);
        }
        b
    }
}

/// The board: the MCU and what is around it.
#[derive(Debug)]
pub struct RsprBoard {
    /// The MCU.
    pub mcu: BoardMcu,
    /// The pin map.
    pub map: PinMap,
    /// Current sense: amps per volt away from its zero.
    pub current_a_per_v: f64,
    /// The HSE crystal.
    pub hse: Crystal,
    /// The rail.
    pub rail: Supply,
    sensed: Signals,
}

impl Store for RsprBoard {}

impl RsprBoard {
    /// The reference board out of reset, sensing [`Signals::REST`].
    pub fn new() -> Result<Self, BoardError> {
        Self::for_target(&REFERENCE)
    }

    /// The board `target` (its pins and current sense around the same MCU) out of reset,
    /// sensing [`Signals::REST`].
    pub fn for_target(target: &BoardTarget) -> Result<Self, BoardError> {
        let mut board = RsprBoard {
            mcu: BoardMcu::new()?,
            map: target.map,
            current_a_per_v: target.current_sense_a_per_v,
            hse: Crystal(HSE_HZ),
            rail: Supply(RAIL_MV),
            sensed: Signals::REST,
        };
        board.mcu.part.rcc.attach_crystals(board.hse.0, 0);
        board.mcu.part.set_supply(board.rail.0);
        for adc in &mut board.mcu.part.adc {
            adc.set_reference(board.rail.0);
        }
        board.mcu.part.usart[USART3].attach(MasterWire::default());
        board.sense(&Signals::REST);
        Ok(board)
    }

    /// The master's end of the link.
    pub fn wire(&mut self) -> Option<&mut MasterWire> {
        self.mcu.part.usart[USART3].chip_mut::<MasterWire>()
    }

    /// What the board last sensed.
    pub fn sensed(&self) -> &Signals {
        &self.sensed
    }

    /// Hands the world's signals to the inputs: encoder counts and pins at the next stop, the
    /// analog inputs at once.
    pub fn sense(&mut self, s: &Signals) {
        self.sensed = *s;
        let map = self.map;
        for (wiring, count) in map.encoders.iter().zip(s.encoder_counts) {
            self.mcu.set_encoder(wiring.timer, count);
        }
        for (input, current) in map.current_sense.iter().zip(s.currents_a) {
            let volts = CURRENT_SENSE_ZERO_V + current / self.current_a_per_v;
            self.mcu.set_analog(input.channel, volts.clamp(0.0, VREF_V));
        }
        // Normally-closed contacts to ground: closed drives the pin low; open leaves it to the
        // pull-up (high).
        let contact = |open: bool| if open { None } else { Some(Level::Low) };
        for (pin, actuated) in map.home_switch.iter().zip(s.switches_actuated) {
            self.mcu.set_pin(*pin, contact(actuated));
        }
        self.mcu.set_pin(map.estop, contact(s.estop_pressed));
        // The relay's feedback contact closes to ground while the relay holds.
        self.mcu.set_pin(map.relay_feedback, contact(s.relay_open));
        // Open-drain nFAULT with the board's pull-up: pulled low on a fault.
        let nfault = if s.driver_fault {
            Level::Low
        } else {
            Level::High
        };
        self.mcu.set_pin(map.driver_fault, Some(nfault));
        self.mcu.set_analog(
            map.supply_sense.channel,
            (s.supply_v / SUPPLY_DIVIDER).clamp(0.0, VREF_V),
        );
    }

    /// What the firmware drives now.
    pub fn drive(&mut self) -> Outputs {
        let map = self.map;
        let mut duty = [0.0; 6];
        for (d, wiring) in duty.iter_mut().zip(map.pwm.iter()) {
            *d = self.mcu.pwm_duty(wiring);
        }
        let mut dir_positive = [false; 6];
        for (d, pin) in dir_positive.iter_mut().zip(map.dir) {
            *d = self.mcu.pin_level(pin) == Level::High;
        }
        let [legs, links] = map.brakes;
        let brakes_released = [
            self.mcu.pin_level(legs) == Level::High,
            self.mcu.pin_level(links) == Level::High,
        ];
        Outputs {
            duty,
            dir_positive,
            driver_enable: self.mcu.pin_level(map.driver_enable) == Level::High,
            brakes_released,
            led: self.mcu.pin_level(map.led) == Level::High,
        }
    }

    /// The core's description: a Cortex-M4 with the single-precision FPU and an 8-region MPU
    /// (DS8626 section 2.2), 4 priority bits, SysTick on the 168 MHz core clock, one
    /// instruction per cycle of virtual time, booting from flash (BOOT0 low).
    pub fn core(&self) -> Option<CoreSpec> {
        let core = armv7m::Core {
            variant: armv7m::Variant::M4,
            clock_hz: NonZeroU64::new(CORE_HZ)?,
            interrupt_lines: NonZeroU32::new(u32::from(self.mcu.cpu().interrupt_lines))?,
            priority_bits: 4,
            refclk_divider: NonZeroU32::new(8)?,
            instructions_per_second: NonZeroU64::new(INSTRUCTIONS_PER_SECOND)?,
            boot: "flash",
        };
        let mut config = armv7m::Config::new(core, &rigless::cpu::armv7m::windows(self.mcu.bus()));
        config.fpu = armv7m::Fpu::FpV4Sp;
        config.mpu_regions = armv7m::MpuRegions::Eight;
        Some(config.spec())
    }
}

impl Board for RsprBoard {
    fn name(&self) -> &'static str {
        "rspr-board"
    }

    fn targets(&mut self) -> Vec<Target<'_>> {
        match self.core() {
            Some(core) => vec![Target::new("stm32f405", &mut self.mcu, core)],
            None => Vec::new(),
        }
    }

    fn target_names(&self) -> Vec<&'static str> {
        vec!["stm32f405"]
    }

    fn mcu(&mut self, target: usize) -> Option<&mut dyn Mcu> {
        (target == 0).then_some(&mut self.mcu as &mut dyn Mcu)
    }

    fn hosts(&self) -> Vec<HostWire> {
        vec![MASTER_WIRE]
    }

    fn attach_host(&mut self, name: &str, peer: Box<dyn Peer>) -> bool {
        if name != MASTER_WIRE.name {
            return false;
        }
        self.mcu.part.usart[USART3].attach_boxed(peer);
        true
    }

    fn host_mut(&mut self, name: &str) -> Option<&mut dyn Peer> {
        if name == MASTER_WIRE.name {
            self.mcu.part.usart[USART3].peer_mut()
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pins::BOARD;
    use rigless::mcu::{Mcu, Operate};
    use rigless::soc::Width;

    fn settled(board: &mut RsprBoard, s: &Signals, at: u64) {
        board.sense(s);
        board.mcu.poll(VirtualNanos(at));
    }

    /// The inputs follow the world: the relay feedback reads high (with the firmware's
    /// pull-up) while the relay is open, nFAULT low on a driver fault, a home switch high
    /// while actuated.
    #[test]
    fn inputs_follow_the_relay_the_drivers_and_the_switches() -> Result<(), BoardError> {
        let mut b = RsprBoard::new()?;
        let at = VirtualNanos(0);
        // GPIOC clock on, pull-ups on PC10 (switch l1) and PC14 (relay feedback).
        let pupdr = (0b01 << (2 * 14)) | (0b01 << (2 * 10));
        for (address, value) in [(0x4002_3830, 1 << 2), (0x4002_080C, pupdr)] {
            if let Err(e) = b.mcu.write(at, address, Width::W32, value) {
                panic!("register write refused: {e:?}");
            }
        }
        settled(&mut b, &Signals::REST, 1_000);
        assert_eq!(b.mcu.pin_level(BOARD.relay_feedback), Level::Low);
        assert_eq!(b.mcu.pin_level(BOARD.driver_fault), Level::High);
        assert_eq!(b.mcu.pin_level(BOARD.home_switch[0]), Level::Low);
        let s = Signals {
            relay_open: true,
            driver_fault: true,
            switches_actuated: [true, false, false, false, false, false],
            ..Signals::REST
        };
        settled(&mut b, &s, 2_000);
        assert_eq!(b.mcu.pin_level(BOARD.relay_feedback), Level::High);
        assert_eq!(b.mcu.pin_level(BOARD.driver_fault), Level::Low);
        assert_eq!(b.mcu.pin_level(BOARD.home_switch[0]), Level::High);
        Ok(())
    }

    /// Out of reset every output reads low: the brakes hold, the drivers are off.
    #[test]
    fn out_of_reset_the_brakes_hold_and_the_drivers_are_off() -> Result<(), BoardError> {
        let out = RsprBoard::new()?.drive();
        assert_eq!(out.brakes_released, [false, false]);
        assert!(!out.driver_enable);
        assert_eq!(out.duty, [0.0; 6]);
        Ok(())
    }
}
