//! What every tick reads first, in every mode: the inputs, and the monitors that judge
//! them.

use hal::Hardware;
use servo::NUM_JOINTS;

use super::config::RuntimeConfig;
use crate::absolute::ChannelCheck;
use crate::current::CurrentMonitor;
use crate::monitors::{EncoderCheck, MotorCheck, PowerCheck, SafetyChainCheck};
use crate::scalar::Scalar;

/// The inputs read at the start of a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inputs<S> {
    /// Motor currents, A.
    pub currents: [S; NUM_JOINTS],
    /// Supply voltage, V.
    pub supply_v: S,
    /// A driver reports a fault.
    pub driver_fault: bool,
    /// Limit switches.
    pub switches: [bool; NUM_JOINTS],
    /// The e-stop button is pressed.
    pub estop_pressed: bool,
    /// The safety relay is open.
    pub relay_open: bool,
}

impl<S: num_traits::Float> Inputs<S> {
    /// Nothing read yet.
    pub fn none() -> Self {
        Inputs {
            currents: [S::zero(); NUM_JOINTS],
            supply_v: S::zero(),
            driver_fault: false,
            switches: [false; NUM_JOINTS],
            estop_pressed: false,
            relay_open: false,
        }
    }

    /// Reads them from the hardware.
    pub fn read<H: Hardware<S>>(hw: &mut H) -> Self {
        Inputs {
            currents: hw.currents(),
            supply_v: hw.supply_voltage(),
            driver_fault: hw.driver_fault(),
            switches: hw.switches(),
            estop_pressed: hw.estop_pressed(),
            relay_open: hw.relay_open(),
        }
    }

    /// The safety chain's cause is present: the button pressed, or the relay disagreeing
    /// with it.
    pub fn safety_chain_tripped(&self) -> bool {
        self.estop_pressed || !SafetyChainCheck::agrees(self.estop_pressed, self.relay_open)
    }
}

/// The plausibility monitors every mode runs (the standstill of a safe operating stop is
/// the stop's own).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Monitors<S> {
    /// Currents: limits, I²t, overcurrent and overload trips.
    pub current: CurrentMonitor<S>,
    /// Encoders: jumps, dead encoders (back-EMF).
    pub encoder: EncoderCheck<S>,
    /// Motor circuits: open, shorted.
    pub motor: MotorCheck<S>,
    /// The power stage: supply, driver fault.
    pub power: PowerCheck<S>,
    /// The safety chain: the e-stop button against the relay's feedback.
    pub chain: SafetyChainCheck,
    /// The second position channel against the encoders (where the board has it).
    pub channel: ChannelCheck<S>,
}

impl<S: Scalar> Monitors<S> {
    /// The monitors of `cfg`.
    pub fn new(cfg: &RuntimeConfig<S>) -> Self {
        Monitors {
            current: CurrentMonitor::new(cfg.current),
            encoder: EncoderCheck::new(cfg.encoder_check),
            motor: MotorCheck::new(&cfg.current.motors),
            power: PowerCheck::new(cfg.power),
            chain: SafetyChainCheck::new(cfg.relay_debounce_ticks),
            channel: ChannelCheck::new(cfg.channel),
        }
    }
}
