//! The small hardware traits the control code runs behind, so that the same code runs
//! on the STM32 board, on the host against the plant model, and in the emulators.
//!
//! ## Sign conventions (all implementations must follow them)
//! * Joint order `[l1, l2, l3, theta1, theta2, theta3]` in every array.
//! * A positive duty drives the joint towards `+q` (leg lengthens, link angle grows).
//! * Motion towards `+q` makes the joint's counter count **up**. An implementation whose
//!   motor or encoder is wired the other way round inverts it here (negate the duty,
//!   count `0u16.wrapping_sub(raw)`), so the layers above never see an inverted joint.
//! * Currents are positive when they produce positive torque (towards `+q`).

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

use num_traits::Float;

/// Number of actuated joints: `[l1, l2, l3, theta1, theta2, theta3]`.
pub const NUM_JOINTS: usize = 6;

/// The six quadrature encoder counters (e.g. STM32 timers in encoder mode): raw 16-bit
/// values that wrap; `servo::encoder` extends them to 64-bit counts.
pub trait QuadratureCounter {
    /// The raw counters of the six axes, in joint order, latched as close together in
    /// time as the hardware allows.
    fn counts(&mut self) -> [u16; NUM_JOINTS];

    /// The raw counter of one axis (`None` outside `0..6`). The default reads all six.
    fn count(&mut self, axis: usize) -> Option<u16> {
        self.counts().get(axis).copied()
    }
}

/// The six H-bridges.
pub trait MotorOutputs<S: Float> {
    /// Sets the six duties, each in `[-1, 1]` (positive drives towards `+q`); an
    /// implementation clamps out-of-range values and treats NaN as 0.
    fn set_duties(&mut self, duty: &[S; NUM_JOINTS]);
    /// Turns every bridge off (outputs high-impedance or braking: the board's safe state).
    fn disable(&mut self);
    /// Turns the bridges on; the duties start at 0 until the next `set_duties`.
    fn enable(&mut self);
}

/// A monotonic microsecond clock (wraps only after 584 000 years).
pub trait Clock {
    /// Microseconds since an arbitrary epoch (boot).
    fn now_us(&self) -> u64;
}

/// Optional motor current sensing.
pub trait CurrentSense<S: Float> {
    /// Motor currents of the six joints, A, positive for torque towards `+q`.
    fn currents(&mut self) -> [S; NUM_JOINTS];
}

/// Lets a `&mut` to a counter be passed where a counter is expected.
impl<T: QuadratureCounter + ?Sized> QuadratureCounter for &mut T {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        (**self).counts()
    }
}

/// Lets a `&mut` to the motor outputs be passed where motor outputs are expected.
impl<S: Float, T: MotorOutputs<S> + ?Sized> MotorOutputs<S> for &mut T {
    fn set_duties(&mut self, duty: &[S; NUM_JOINTS]) {
        (**self).set_duties(duty)
    }
    fn disable(&mut self) {
        (**self).disable()
    }
    fn enable(&mut self) {
        (**self).enable()
    }
}

/// The home/limit switches, one per joint (e.g. GPIO inputs).
pub trait LimitSwitches {
    /// Each joint's switch, `true` when actuated, joint order.
    fn switches(&mut self) -> [bool; NUM_JOINTS];
}

impl<T: LimitSwitches + ?Sized> LimitSwitches for &mut T {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        (**self).switches()
    }
}

/// The outputs' safe state, reachable from an interrupt or a fault handler: every PWM
/// output off and the driver enable de-asserted. Implementations must not allocate, block
/// or take locks (plain register writes).
pub trait SafeOutputs {
    /// Every PWM output off and the driver enable de-asserted, now.
    fn force_safe(&mut self);
}

impl<T: SafeOutputs + ?Sized> SafeOutputs for &mut T {
    fn force_safe(&mut self) {
        (**self).force_safe()
    }
}
