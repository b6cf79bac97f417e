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
/// output off, the driver enable de-asserted and the brakes applied (their coils
/// unpowered). Implementations must not allocate, block or take locks (plain register
/// writes).
pub trait SafeOutputs {
    /// Every PWM output off, the driver enable de-asserted, the brakes applied, now.
    fn force_safe(&mut self);
}

impl<T: SafeOutputs + ?Sized> SafeOutputs for &mut T {
    fn force_safe(&mut self) {
        (**self).force_safe()
    }
}

/// The holding brakes (spring-applied: unpowered = holding), e.g. two GPIO outputs driving
/// the brake coils of the legs and of the links.
pub trait Brakes {
    /// Releases (`true`: coils powered) or applies (`false`) every brake.
    fn set_brakes_released(&mut self, released: bool);
}

impl<T: Brakes + ?Sized> Brakes for &mut T {
    fn set_brakes_released(&mut self, released: bool) {
        (**self).set_brakes_released(released)
    }
}

/// The power stage's health: the supply voltage and the motor drivers' fault output.
pub trait PowerStage<S: Float> {
    /// The supply voltage of the H-bridges, V.
    fn supply_voltage(&mut self) -> S;
    /// A motor driver reports a fault (over-temperature, short, under-voltage lockout).
    fn driver_fault(&mut self) -> bool;
}

impl<S: Float, T: PowerStage<S> + ?Sized> PowerStage<S> for &mut T {
    fn supply_voltage(&mut self) -> S {
        (**self).supply_voltage()
    }
    fn driver_fault(&mut self) -> bool {
        (**self).driver_fault()
    }
}

/// The hard-wired safety chain as the MCU reads it: the e-stop button (a normally closed
/// contact: open when pressed or broken) and the safety relay's feedback contact (open
/// while the relay has removed the drivers' power).
pub trait SafetyChain {
    /// The e-stop button is pressed (or its wire is broken).
    fn estop_pressed(&mut self) -> bool;
    /// The safety relay is open: the drivers' power is removed (STO by hardware).
    fn relay_open(&mut self) -> bool;
}

impl<T: SafetyChain + ?Sized> SafetyChain for &mut T {
    fn estop_pressed(&mut self) -> bool {
        (**self).estop_pressed()
    }
    fn relay_open(&mut self) -> bool {
        (**self).relay_open()
    }
}

/// The second position channel: an absolute position sensor per joint on the load side
/// (after the backlash), beside the incremental encoders on the motors, e.g. a
/// potentiometer per joint read by a converter. A board without it implements the trait
/// with its defaults: not fitted, no readings.
///
/// The readings are the converter's raw counts, `0 ..= 65535` over each sensor's
/// electrical travel, counting up with motion towards `+q` (a sensor wired the other way
/// round is inverted in the board's `hw` module, `65535 - raw`, as the encoders are); the
/// calibration to joint units is the application's.
pub trait AbsolutePositions {
    /// The board has the channel fitted (the default: it has none).
    fn absolute_fitted(&self) -> bool {
        false
    }
    /// The six readings, joint order, converted as close together in time as the hardware
    /// allows; `None` without the channel or when the read failed (a bus error: a fitted
    /// channel that answers `None` has failed).
    fn absolute_counts(&mut self) -> Option<[u16; NUM_JOINTS]> {
        None
    }
}

impl<T: AbsolutePositions + ?Sized> AbsolutePositions for &mut T {
    fn absolute_fitted(&self) -> bool {
        (**self).absolute_fitted()
    }
    fn absolute_counts(&mut self) -> Option<[u16; NUM_JOINTS]> {
        (**self).absolute_counts()
    }
}

/// Everything the board application drives and reads, in one bound.
pub trait Hardware<S: Float>:
    QuadratureCounter
    + AbsolutePositions
    + MotorOutputs<S>
    + CurrentSense<S>
    + LimitSwitches
    + Brakes
    + PowerStage<S>
    + SafetyChain
{
}

impl<S: Float, T> Hardware<S> for T where
    T: QuadratureCounter
        + AbsolutePositions
        + MotorOutputs<S>
        + CurrentSense<S>
        + LimitSwitches
        + Brakes
        + PowerStage<S>
        + SafetyChain
{
}
