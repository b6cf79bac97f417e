//! The emergency stop's software channel. The button's first channel is hard-wired: it
//! opens the safety relay, which removes the drivers' power and the brakes' coil power
//! without the MCU (`firmware/README.md`). The second channel is this: the button's
//! interrupt puts the outputs in their safe state at once through [`SafeOutputs`] (PWM
//! off, driver enable low, brakes applied; no allocation, no lock: register writes) and
//! trips an [`EStopLatch`] (an atomic) that the next control tick turns into the fault
//! `EmergencyStopButton` (its stop: STO with brakes, [`crate::stops`]).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use hal::SafeOutputs;

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
