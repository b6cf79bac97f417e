//! The emergency stop in software: the e-stop interrupt turns the PWM and the driver
//! enable off at once through [`SafeOutputs`] (no allocation, no lock: register writes) and
//! trips an [`EStopLatch`] (an atomic) that the control tick turns into
//! [`crate::state_machine::Event::EmergencyStop`]. In every state but `Homing` and
//! `Enabled`, and on any fault, every output is off ([`outputs_allowed`]; the runtime
//! disables the bridges every tick).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use hal::SafeOutputs;

use crate::state_machine::{State, StateMachine};

/// Set by the e-stop interrupt, taken by the control tick. Lock-free (atomics), so it can
/// live in a `static` shared by the interrupt and the tasks.
#[derive(Debug, Default)]
pub struct EStopLatch {
    tripped: AtomicBool,
    count: AtomicU32,
}

impl EStopLatch {
    /// Not tripped.
    pub const fn new() -> Self {
        EStopLatch {
            tripped: AtomicBool::new(false),
            count: AtomicU32::new(0),
        }
    }
    /// Trips the latch (from the interrupt).
    pub fn trip(&self) {
        self.tripped.store(true, Ordering::Release);
        self.count.fetch_add(1, Ordering::Relaxed);
    }
    /// Takes the trip: `true` once per trip (from the control tick).
    pub fn take(&self) -> bool {
        self.tripped.swap(false, Ordering::AcqRel)
    }
    /// Tripped and not yet taken.
    pub fn is_tripped(&self) -> bool {
        self.tripped.load(Ordering::Acquire)
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

/// Whether the state lets the outputs drive (homing or enabled, no fault); every other
/// state keeps them in the safe state.
pub fn outputs_allowed(sm: &StateMachine) -> bool {
    sm.drives_on() && sm.faults().is_empty() && sm.state() != State::Fault
}
