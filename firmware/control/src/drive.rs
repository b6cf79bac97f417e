//! The servo half of a control tick: the six joint servos (`servo::JointServo`: PID,
//! backlash compensation, tracking-error monitor) from the tick's measured joints
//! ([`crate::sensing::Measured`]) towards the planner's setpoint, and the motor outputs.

use hal::MotorOutputs;
use kinematics_core::guards::Reading;
use kinematics_core::supervisor::Mode;
use kinematics_core::{scalar, JointKind, Joints};
use servo::config::ConfigError;
use servo::joint_servo::{JointServo, ServoOutput};
use servo::{ServoConfig, NUM_JOINTS};

use crate::planner::Plan;
use crate::scalar::Scalar;
use crate::sensing::Measured;

/// What one tick did (the setpoint itself is the planner's [`Plan`], and the supervisor's
/// accessors).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickReport<S: Scalar> {
    /// The supervisor's mode.
    pub mode: Mode,
    /// A warn-level guard is violated at the setpoint.
    pub warning: bool,
    /// The supervisor's latched stop, if stopped.
    pub stop: Option<Reading<S>>,
    /// Duties, saturation and the latched tracking fault.
    pub servo: ServoOutput<S>,
}

/// The joint servos and the outputs.
#[derive(Clone, Debug)]
pub struct Drive<S: Scalar> {
    kinds: [JointKind; NUM_JOINTS],
    dt: S,
    servo: JointServo<S>,
}

impl<S: Scalar> Drive<S> {
    /// Servos for joints of `kinds`, ticked every `dt` s, holding the joints where the
    /// tick's measurements put them: the loops start at the motors' positions, and the
    /// backlash compensation resumes with the offsets the sensing holds (the motors'
    /// setpoints are where they stand: nothing moves).
    pub fn new(
        kinds: [JointKind; NUM_JOINTS],
        dt: S,
        cfg: &ServoConfig<S>,
        measured: &Measured<S>,
    ) -> Result<Self, ConfigError> {
        let mut servo = JointServo::new(cfg)?;
        servo.reset(&measured.motor);
        servo.resume_backlash(&measured.q, &measured.backlash);
        Ok(Drive { kinds, dt, servo })
    }

    /// The control period, s.
    pub fn dt(&self) -> S {
        self.dt
    }

    /// The joint servos.
    pub fn servo(&self) -> &JointServo<S> {
        &self.servo
    }

    /// The backlash offsets the last tick added to the joint setpoints (motor less
    /// joint), m or rad.
    pub fn backlash_offsets(&self) -> [S; NUM_JOINTS] {
        self.servo.backlash_offsets()
    }

    /// Resets the servo after a tracking fault, its loops at the motors' positions
    /// `motor`.
    pub fn reset(&mut self, motor: &[S; NUM_JOINTS]) {
        self.servo.reset(motor);
    }

    /// Runs the six joint servos from the measured motors towards the plan (the joint
    /// setpoints plus the backlash offsets): the duties (zero on a tracking fault) in the
    /// report, for the caller to limit and write ([`TickReport::apply`]). The offsets
    /// this tick used are [`Drive::backlash_offsets`], for the sensing.
    pub fn act(&mut self, measured: &Measured<S>, plan: &Plan<S>) -> TickReport<S> {
        let q_meas = &measured.motor;
        // Angles from the supervisor are wrapped to (-π, π]; unwrap them next to the
        // (continuous) encoder readings.
        let mut sp = to_array(&plan.setpoint.q);
        for ((s, m), k) in sp.iter_mut().zip(q_meas.iter()).zip(self.kinds.iter()) {
            if *k == JointKind::Angular {
                *s = *m + scalar::wrap_angle(*s - *m);
            }
        }
        self.servo.set_preloads(&plan.flanks);
        let spd = to_array(&plan.setpoint.qdot);
        let out = self.servo.update(&sp, &spd, q_meas, self.dt);
        TickReport {
            mode: plan.setpoint.mode,
            warning: plan.setpoint.warning,
            stop: plan.setpoint.stop,
            servo: out,
        }
    }
}

impl<S: Scalar> TickReport<S> {
    /// Writes the report's duties to the outputs, or turns them off on a tracking fault.
    pub fn apply<H: MotorOutputs<S> + ?Sized>(&self, hw: &mut H) {
        if self.servo.fault.is_some() {
            hw.disable();
        } else {
            hw.set_duties(&self.servo.duty);
        }
    }
}

/// The six components of a joint vector as an array (q order).
pub fn to_array<S: Scalar>(q: &Joints<S>) -> [S; NUM_JOINTS] {
    [q.x, q.y, q.z, q.w, q.a, q.b]
}
