//! The emergency stop's software channel. The button's first channel is hard-wired: it
//! opens the safety relay, which removes the drivers' power and the brakes' coil power
//! without the MCU (`firmware/README.md`). The second channel is this: the button's
//! interrupt puts the outputs in their safe state at once through [`SafeOutputs`] (PWM
//! off, driver enable low, brakes applied; no allocation, no lock: register writes) and
//! trips an [`EStopLatch`] (an atomic) that the next control tick turns into the fault
//! `EmergencyStopButton` (its stop: STO with brakes, [`crate::stops`]).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use hal::SafeOutputs;

/// Set by the e-stop interrupt (the button) or by the link's receive task (an
/// `EmergencyStop` message), taken by the control tick, which latches the fault of the one
/// that tripped it. Lock-free (atomics), so it can live in a `static` shared by the
/// interrupt and the tasks. While it is tripped the outputs must not be enabled again.
#[derive(Debug, Default)]
pub struct EStopLatch {
    button: AtomicBool,
    message: AtomicBool,
    count: AtomicU32,
}

/// What tripped the latch since the last tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EStopTrip {
    /// The button's interrupt.
    pub button: bool,
    /// An `EmergencyStop` message.
    pub message: bool,
}

impl EStopTrip {
    /// Nothing tripped.
    pub const NONE: EStopTrip = EStopTrip {
        button: false,
        message: false,
    };
    /// The button.
    pub const BUTTON: EStopTrip = EStopTrip {
        button: true,
        message: false,
    };
}

impl EStopLatch {
    /// Not tripped.
    pub const fn new() -> Self {
        EStopLatch {
            button: AtomicBool::new(false),
            message: AtomicBool::new(false),
            count: AtomicU32::new(0),
        }
    }
    /// Trips the latch from the button's interrupt.
    pub fn trip(&self) {
        self.button.store(true, Ordering::Release);
        self.count.fetch_add(1, Ordering::Relaxed);
    }
    /// Trips the latch for an `EmergencyStop` message.
    pub fn trip_message(&self) {
        self.message.store(true, Ordering::Release);
        self.count.fetch_add(1, Ordering::Relaxed);
    }
    /// Takes the trips (from the control tick): each once.
    pub fn take(&self) -> EStopTrip {
        EStopTrip {
            button: self.button.swap(false, Ordering::AcqRel),
            message: self.message.swap(false, Ordering::AcqRel),
        }
    }
    /// Tripped and not yet taken.
    pub fn is_tripped(&self) -> bool {
        self.button.load(Ordering::Acquire) || self.message.load(Ordering::Acquire)
    }
    /// Trips since boot.
    pub fn count(&self) -> u32 {
        self.count.load(Ordering::Relaxed)
    }
}

/// What the e-stop interrupt calls: outputs safe first, then the latch. No allocation, no
/// lock, bounded time.
pub fn emergency_stop_isr<O: SafeOutputs + ?Sized>(outputs: &mut O, latch: &EStopLatch) {
    outputs.force_safe();
    latch.trip();
}

/// What the link's receive task calls for an `EmergencyStop` message: outputs safe first,
/// then the latch (the next tick latches `EmergencyStopMessage` even if the request queue
/// was full).
pub fn emergency_stop_message<O: SafeOutputs + ?Sized>(outputs: &mut O, latch: &EStopLatch) {
    outputs.force_safe();
    latch.trip_message();
}
