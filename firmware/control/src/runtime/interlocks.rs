//! The restart interlocks: a latched fault is cleared only once its cause is gone.
//!
//! `ClearFault` re-tests every cause latched since the fault (the status names the first);
//! a cause whose condition can be read at rest refuses the clear while it persists: the
//! button still pressed, the safety chain (latched until a power cycle and a passed relay
//! test), the heartbeat still late, a joint still beyond its range or a switch still
//! closed, a current still above its trip, a winding still above its derating
//! temperature, the supply out of range, a missed deadline (the watchdog resets the
//! board), and the second position channel without a reading or at a rail (an open wire).
//! The others cannot be re-tested at rest: a following error, an encoder, a homing
//! failure, a guard stop, and the drivers' fault line (a driver keeps its fault latched
//! while it is disabled and releases it when enabled again, so the line says nothing until
//! the next enable, whose brake check runs with the drivers on and the power stage
//! monitored). They are cleared, and those that make the reference doubtful have lost the
//! homing. A stop a person asked for (the emergency-stop button or message) is ended only
//! by `ClearFault`: no command that moves a joint also ends it.

use kinematics_core::Mechanism;
use master_link::FaultCause;

use super::mode::{cause_bit, Mode};
use super::Runtime;
use crate::monitors::check_ranges;
use crate::scalar::{lit, Scalar};

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// The first latched cause whose condition is still present, in `Fault`.
    pub fn cause_still_present(&self, now_us: u64) -> Option<FaultCause> {
        let Mode::Fault { latched, .. } = &self.mode else {
            return None;
        };
        FaultCause::ALL
            .iter()
            .copied()
            .filter(|c| latched.raised & cause_bit(*c) != 0)
            .find(|c| self.present(*c, now_us))
    }

    /// In `Fault`: a person stopped the robot (the emergency-stop button or message is
    /// among the latched causes); the table lets only `ClearFault` end that stop.
    pub fn emergency_stop_latched(&self) -> bool {
        let Mode::Fault { latched, .. } = &self.mode else {
            return false;
        };
        [
            FaultCause::EmergencyStopButton,
            FaultCause::EmergencyStopMessage,
        ]
        .iter()
        .any(|c| latched.raised & cause_bit(*c) != 0)
    }

    /// Whether the condition of `cause` holds now.
    fn present(&self, cause: FaultCause, now_us: u64) -> bool {
        let i = &self.inputs;
        let current = &self.monitors.current;
        let each = |f: &dyn Fn(usize, S) -> bool| {
            i.currents
                .iter()
                .enumerate()
                .any(|(j, a)| f(j, Float::abs(*a)))
        };
        match cause {
            FaultCause::EmergencyStopButton => i.estop_pressed,
            FaultCause::SafetyRelayMismatch => {
                i.safety_chain_tripped() || !self.monitors.chain.trusted()
            }
            FaultCause::HeartbeatTimeout => self.session.heartbeat_is_late(now_us),
            FaultCause::LimitSwitch => self.limit_switches(&i.switches).iter().any(|s| *s),
            FaultCause::JointLimit => {
                let q = self.sensing.measured().q;
                let range = &self.cfg.mechanics.range;
                check_ranges(
                    &q,
                    range,
                    &[false; servo::NUM_JOINTS],
                    self.mode.homed(),
                    true,
                )
                .is_some()
            }
            FaultCause::Overcurrent => each(&|j, a| {
                a > current
                    .config()
                    .limits
                    .get(j)
                    .map_or(S::zero(), |l| l.trip_a)
            }),
            FaultCause::Overload => each(&|j, a| a >= current.peak_current(j) * lit::<S>(0.9)),
            FaultCause::OverTemperature => current
                .heat()
                .iter()
                .any(|h| !(*h <= current.derating_from())),
            FaultCause::SupplyVoltage => !self.monitors.power.supply_in_range(i.supply_v),
            FaultCause::DeadlineMissed => true,
            FaultCause::PositionSensor => {
                let raw = self.sensing.measured().absolute_raw;
                self.sensing.channel_fitted()
                    && self.monitors.channel.failed_reading(raw.as_ref()).is_some()
            }
            _ => false,
        }
    }
}

use num_traits::Float;
