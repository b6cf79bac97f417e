//! The tick's outputs: what the mode asks of the drives and the brakes, and the output
//! stage that writes it (the bridges' enable, the duties within the current limit, the
//! brakes) and remembers what it wrote.

use hal::Hardware;
use servo::NUM_JOINTS;

use crate::current::CurrentMonitor;
use crate::stops::Outputs;

/// What was last written to the outputs: the monitors read it (the back-EMF check needs the
/// duty that drove the last period), and the next write depends on it (the bridges are
/// enabled on the first tick with torque; the brake check waits for the brakes' engage
/// time since they were applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputStage<S> {
    /// The drives produced torque over the last tick.
    torque_on: bool,
    /// The bridges are enabled (`hal::MotorOutputs::enable` written since the last disable
    /// or forced-safe).
    bridges_on: bool,
    /// The brakes are released (their coils powered).
    brakes_released: bool,
    /// When the brakes were last applied, µs.
    brakes_applied_at_us: Option<u64>,
    /// The duties applied over the last tick.
    last_duty: [S; NUM_JOINTS],
}

impl<S: crate::scalar::Scalar> OutputStage<S> {
    /// Everything off, brakes applied.
    pub fn new() -> Self {
        OutputStage {
            torque_on: false,
            bridges_on: false,
            brakes_released: false,
            brakes_applied_at_us: None,
            last_duty: [S::zero(); NUM_JOINTS],
        }
    }
    /// The drives produced torque over the last tick.
    pub fn torque_on(&self) -> bool {
        self.torque_on
    }
    /// The brakes are released.
    pub fn brakes_released(&self) -> bool {
        self.brakes_released
    }
    /// When the brakes were last applied, µs.
    pub fn brakes_applied_at_us(&self) -> Option<u64> {
        self.brakes_applied_at_us
    }
    /// The duties of the last tick.
    pub fn last_duty(&self) -> [S; NUM_JOINTS] {
        self.last_duty
    }
    /// Writes the tick's outputs `out`: the duties within the current limit (`current`,
    /// with the joint speeds `qdot` and the supply `supply_v`), the brakes, torque.
    #[allow(clippy::too_many_arguments)]
    pub fn write<H: Hardware<S>>(
        &mut self,
        hw: &mut H,
        out: Outputs,
        duty: &mut [S; NUM_JOINTS],
        current: &mut CurrentMonitor<S>,
        qdot: &[S; NUM_JOINTS],
        supply_v: S,
        now_us: u64,
    ) {
        if out.torque {
            if !self.bridges_on {
                hw.enable();
                self.bridges_on = true;
            }
            current.limit(duty, qdot, supply_v);
            hw.set_duties(duty);
            self.last_duty = *duty;
        } else {
            hw.disable();
            self.bridges_on = false;
            self.last_duty = [S::zero(); NUM_JOINTS];
            current.reset_overload();
        }
        let released = out.brakes_released && out.torque;
        if self.brakes_released && !released {
            self.brakes_applied_at_us = Some(now_us);
        }
        self.brakes_released = released;
        hw.set_brakes_released(released);
        self.torque_on = out.torque;
    }

    /// The e-stop path forced the outputs safe: the bridges are off, the brakes applied
    /// (at `now_us` at the latest).
    pub fn forced_safe(&mut self, now_us: u64) {
        self.bridges_on = false;
        if self.brakes_released {
            self.brakes_applied_at_us = Some(now_us);
        }
        self.brakes_released = false;
    }
}

impl<S: crate::scalar::Scalar> Default for OutputStage<S> {
    fn default() -> Self {
        Self::new()
    }
}
