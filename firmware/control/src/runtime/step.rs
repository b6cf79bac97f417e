//! What each mode does in a tick, between the monitors and the outputs, and the stop's
//! progress after it.

use hal::Hardware;
use kinematics_core::Mechanism;
use master_link::FaultCause;
use num_traits::Float;
use servo::NUM_JOINTS;

use super::mode::{Mode, StopDrive};
use super::transitions::subject_joint;
use super::Runtime;
use crate::brakes::EnableStep;
use crate::controller::Controller;
use crate::drive::TickReport;
use crate::homing::Homing;
use crate::homing::HomingStatus;
use crate::modes::Event;
use crate::monitors::Finding;
use crate::park::ParkMove;
use crate::park::ParkStep;
use crate::scalar::{lit, Scalar};
use crate::sensing::{Measured, Sensing};
use crate::stops::StopPhase;
use crate::wire;

/// What a mode's step produced.
pub(super) struct Step<S: Scalar> {
    /// The duties (before the current limit).
    pub duty: [S; NUM_JOINTS],
    /// The controller's report, when it ran.
    pub control: Option<TickReport<S>>,
    /// The homing's status, when it ran.
    pub homing: Option<HomingStatus>,
    /// The motion is at rest (ends a stop's deceleration).
    pub standstill: bool,
}

impl<S: Scalar> Step<S> {
    fn idle() -> Self {
        Step {
            duty: [S::zero(); NUM_JOINTS],
            control: None,
            homing: None,
            standstill: true,
        }
    }
}

/// What a step asks of the runtime once the mode's data is no longer borrowed.
enum After<S: Scalar> {
    Nothing,
    Homing(HomingStatus),
    Parked,
    ParkFailed(crate::park::ParkRefusal<S>),
    Fault(Finding),
    BrakeCheckFailed { joint: usize, motion: S },
    BrakesReleased,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// The mode's work of this tick, when the outputs allow torque at its start.
    pub(super) fn step_mode<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) -> Step<S> {
        let mut step = Step::idle();
        // Commissioning's test runs with torque off too (it reads the driver fault line
        // first, and ends with torque off).
        if let Mode::Commissioning(test) = &mut self.mode {
            let m = self.sensing.measured();
            let r = crate::commissioning::Readings {
                motor: m.motor,
                absolute: m.absolute,
                current: self.inputs.currents,
                switches: self.inputs.switches,
                driver_fault: self.inputs.driver_fault,
            };
            test.step(&r, now_us);
            if test.outputs().0 {
                step.duty = test.duty(now_us);
            }
            return step;
        }
        if !self.output_request().torque {
            return step;
        }
        let measured = *self.sensing.measured();
        let sensing = &mut self.sensing;
        let after = match &mut self.mode {
            Mode::Homing(homing) => {
                let (st, duty) = homing.step(hw, sensing, now_us);
                step.duty = duty;
                step.homing = Some(st);
                After::Homing(st)
            }
            Mode::Parking { homing, park } => {
                park_step(homing, park, &measured, sensing, &mut step, now_us)
            }
            Mode::Enabling { check, ctl } => match check.step(&measured.q, now_us) {
                EnableStep::Push(d) => {
                    step.duty = d;
                    After::Nothing
                }
                EnableStep::Failed { joint, motion } => After::BrakeCheckFailed { joint, motion },
                EnableStep::Hold => {
                    control_step(ctl, &measured, sensing, &mut step);
                    step.standstill = true;
                    After::Nothing
                }
                EnableStep::Released => {
                    control_step(ctl, &measured, sensing, &mut step);
                    step.standstill = true;
                    After::BrakesReleased
                }
            },
            Mode::Following { ctl, .. } | Mode::Holding { ctl, .. } => {
                control_step(ctl, &measured, sensing, &mut step);
                After::Nothing
            }
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => {
                // Without a controller (a stop during homing) the drives stop where they
                // are.
                if let StopDrive::Controller(ctl) = &mut stop.drive {
                    control_step(ctl, &measured, sensing, &mut step);
                }
                After::Nothing
            }
            Mode::Boot | Mode::Disabled | Mode::Ready { .. } | Mode::Commissioning(_) => {
                After::Nothing
            }
        };
        if let Some(report) = step.control {
            self.control_faults(&report, now_us);
        }
        self.after_step(step, after, now_us)
    }

    fn after_step(&mut self, step: Step<S>, after: After<S>, now_us: u64) -> Step<S> {
        match after {
            After::Nothing => {}
            After::Homing(HomingStatus::Failed(e)) => {
                let f = Finding {
                    cause: FaultCause::HomingFailed,
                    joint: e.joint(),
                    value: e.code(),
                };
                self.fault(f, now_us);
            }
            After::Homing(HomingStatus::Referenced) => {
                let _ = self.apply(Event::Referenced, now_us);
            }
            After::Homing(HomingStatus::Running(_)) => {}
            After::Parked => {
                let _ = self.apply(Event::Parked, now_us);
            }
            After::ParkFailed(r) => {
                self.park_failed(r, now_us);
                return Step::idle();
            }
            After::Fault(f) => {
                self.fault(f, now_us);
                return Step::idle();
            }
            After::BrakeCheckFailed { joint, motion } => {
                let finding = self.brake_check_finding(joint, motion);
                self.fault(finding, now_us);
            }
            After::BrakesReleased => {
                let _ = self.apply(Event::BrakesReleased, now_us);
            }
        }
        step
    }

    /// What a joint's motion against its closed brake during the brake check says. The
    /// check pushed the joint at a known duty with the motor all but still, so the motor
    /// model says what current that drives: `V·d/R`. A current above three times that
    /// (the short check's factor, `MotorCheck`; a warm winding is 30 % off at most) is a
    /// drive that pushed harder than asked (a shorted winding, a lost current
    /// regulation), and the slip says nothing of the brake: the short is named
    /// (`CurrentImplausible`). Otherwise the brake failed (`BrakeCheck`).
    fn brake_check_finding(&self, joint: usize, motion: S) -> Finding {
        let brake = Finding::joint(FaultCause::BrakeCheck, joint, motion);
        let duty = self.outputs.last_duty();
        let (Some(d), Some(i), Some(m), Some(floor)) = (
            duty.get(joint),
            self.inputs.currents.get(joint),
            self.cfg.current.motors.get(joint),
            self.monitors.motor.floor_a.get(joint),
        ) else {
            return brake;
        };
        let asked = Float::max(
            Float::abs(self.inputs.supply_v * *d / m.resistance_ohm),
            *floor,
        );
        if Float::abs(*i) > asked * lit(3.0) {
            Finding::joint(FaultCause::CurrentImplausible, joint, Float::abs(*i))
        } else {
            brake
        }
    }

    /// The faults the controller's tick reports: the servo's, the supervisor's stop.
    fn control_faults(&mut self, report: &TickReport<S>, now_us: u64) {
        if let Some(f) = report.servo.fault {
            let cause = match f.kind {
                servo::tracking::FaultKind::FollowingError => FaultCause::FollowingError,
                servo::tracking::FaultKind::NoMotion => FaultCause::NoMotion,
                servo::tracking::FaultKind::NonFiniteInput
                | servo::tracking::FaultKind::InvalidTimeStep => FaultCause::NonFiniteInput,
            };
            let finding = match f.joint {
                Some(j) => Finding::joint(cause, j, f.error),
                None => Finding::board(cause, f.error),
            };
            if self.latched_fault().cause != cause {
                self.fault(finding, now_us);
            }
        } else if let Some(stop) = report.stop {
            let cause = match wire::guard_fault(stop.guard) {
                f if f == master_link::Faults::SINGULARITY => FaultCause::Singularity,
                _ => FaultCause::GuardStop,
            };
            if self.mode.latched().is_none() {
                let finding = Finding {
                    cause,
                    joint: subject_joint(stop.subject),
                    value: wire::to_f32(stop.value),
                };
                self.fault(finding, now_us);
            }
        }
    }

    /// The stop's progress at `now_us` (`standstill`: the motion has come to rest): a
    /// deceleration that outlasts its timeout is the fault `StandstillLost`; the safe
    /// operating stop starts monitoring the standstill; a stop at torque off settles.
    pub(super) fn advance_stop(&mut self, now_us: u64, standstill: bool) {
        let q = self.sensing.measured().q;
        let Some(seq) = self.mode.stop_sequence_mut() else {
            return;
        };
        let was = seq.stopper.phase();
        let escalated = seq.stopper.advance(now_us, standstill);
        if was != StopPhase::Holding && seq.stopper.phase() == StopPhase::Holding {
            seq.standstill.start(&q);
        }
        if escalated {
            let f = Finding::board::<S>(FaultCause::StandstillLost, S::zero());
            self.fault(f, now_us);
        }
        self.settle_stop(now_us);
    }
}

/// The controller's tick on the measurements: its duties, its report, whether its
/// setpoint stands; its backlash offsets go back to the sensing.
fn control_step<S: Scalar, M: Mechanism<S> + Clone>(
    ctl: &mut Controller<S, M>,
    measured: &Measured<S>,
    sensing: &mut Sensing<S, M>,
    step: &mut Step<S>,
) {
    let report = ctl.tick(measured);
    sensing.set_backlash(&ctl.drive().backlash_offsets());
    step.duty = report.servo.duty;
    step.standstill = ctl.supervisor().twist().iter().all(|x| *x == S::zero());
    step.control = Some(report);
}

/// One tick of the park move: the path check (holding), then the profile under the
/// homing's servo.
fn park_step<S: Scalar, M: Mechanism<S> + Clone>(
    homing: &mut Homing<S>,
    park: &mut ParkMove<S, M>,
    measured: &Measured<S>,
    sensing: &mut Sensing<S, M>,
    step: &mut Step<S>,
    now_us: u64,
) -> After<S> {
    let (q, motor) = (measured.q, measured.motor);
    let park_step = park.step(&q, now_us);
    let out = match park_step {
        ParkStep::Checking { .. } | ParkStep::Arrived => homing.hold(&motor, now_us),
        ParkStep::Move { q: sp, qdot } => homing.track(&sp, &qdot, &motor, now_us),
        ParkStep::Refused(r) => return After::ParkFailed(r),
    };
    sensing.set_backlash(&homing.backlash_offsets());
    if let Some(f) = out.fault {
        return After::Fault(match f.joint {
            Some(j) => Finding::joint(FaultCause::FollowingError, j, f.error),
            None => Finding::board(FaultCause::FollowingError, f.error),
        });
    }
    step.duty = out.duty;
    if park_step == ParkStep::Arrived {
        After::Parked
    } else {
        After::Nothing
    }
}
