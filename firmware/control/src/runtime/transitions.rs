//! The changes of mode: each asks [`crate::modes::next`] first, then moves the data the
//! new mode owns out of the old one.

use kinematics_core::guards::Subject;
use kinematics_core::{Mechanism, Pose};
use master_link::{EventKind, FaultCause, StopReason, Warnings};
use num_traits::Float;
use servo::NUM_JOINTS;

use super::mode::{Held, Latched, Mode, Stop, StopDrive, StopSequence};
use super::Runtime;
use crate::brakes::BrakeCheck;
use crate::controller::{Controller, ControllerError};
use crate::drive::to_array;
use crate::homing::{Homing, HomingError};
use crate::modes::{next, Event, ModeKind, Refusal, LOSE_HOMING};
use crate::monitors::Finding;
use crate::park::{ParkMove, ParkRefusal};
use crate::scalar::Scalar;
use crate::stops::{StopEvent, StopPhase};

/// Encoder counts a holding servo may stand off its setpoint on each joint: a count
/// either side (see `Runtime::held_start`).
const HOLD_COUNTS: f64 = 2.0;

/// The event of the hold that begins (the clutch before the dead-man before the heartbeat).
fn hold_event(hold: crate::modes::Hold) -> StopEvent {
    if hold.clutch {
        StopEvent::ClutchEngaged
    } else if hold.operator_absent {
        StopEvent::OperatorAbsent
    } else {
        StopEvent::HeartbeatLate
    }
}

/// The joint a guard reading names, if any.
pub(super) fn subject_joint(subject: Subject) -> Option<usize> {
    match subject {
        Subject::Joint(j) => Some(usize::from(j).saturating_sub(1)),
        Subject::Chain(c) => Some(c.index()),
        _ => None,
    }
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// Carries `event` out: the table's next mode, or why it is refused (nothing changes
    /// then). Faults go through [`Runtime::fault`].
    pub(super) fn apply(&mut self, event: Event, now_us: u64) -> Result<ModeKind, Refusal> {
        let from = self.mode.kind();
        if let Event::Fault(cause) = event {
            self.fault(Finding::board::<S>(cause, S::zero()), now_us);
            return Ok(self.mode.kind());
        }
        // The master's conditions change whatever the mode (a pedal pressed while ready
        // holds once enabled).
        self.session.note(
            event,
            matches!(from, ModeKind::Following | ModeKind::Holding),
        );
        let to = match next(from, event, self.context(now_us)) {
            Ok(to) => to,
            Err(r) => {
                self.refusals = self.refusals.wrapping_add(1);
                return Err(r);
            }
        };
        if to != from || event == Event::StopComplete {
            self.enter(to, event, now_us)?;
        }
        self.after_transition(from, event);
        Ok(self.mode.kind())
    }

    /// Bookkeeping after any event: counts, the session's late heartbeat, the reference.
    fn after_transition(&mut self, from: ModeKind, event: Event) {
        let to = self.mode.kind();
        if !matches!(to, ModeKind::Following | ModeKind::Holding) {
            self.session.note(event, false);
        }
        if from == ModeKind::Fault && to != ModeKind::Fault && event == Event::ClearFault {
            self.warnings.remove(Warnings::HEARTBEAT_LATE);
            // A cleared disagreement starts over from where the channels stand now.
            self.monitors.channel.restart();
        }
    }

    /// Moves into `to` (the table allowed it); `Enable`'s own checks may still refuse.
    fn enter(&mut self, to: ModeKind, event: Event, now_us: u64) -> Result<(), Refusal> {
        match to {
            ModeKind::Homing => self.enter_homing(now_us),
            ModeKind::Parking => {
                self.start_park(now_us);
                Ok(())
            }
            ModeKind::Enabling => self.enter_enabling(now_us),
            ModeKind::Following | ModeKind::Holding => {
                self.enter_enabled(now_us);
                Ok(())
            }
            ModeKind::Stopping => {
                self.enter_stopping(event, now_us);
                Ok(())
            }
            ModeKind::Ready | ModeKind::Disabled => {
                self.enter_idle(to);
                Ok(())
            }
            ModeKind::Fault => {
                self.stop_complete_in_fault();
                Ok(())
            }
            // The `Commission` command starts the joint's test (`commission.rs`).
            ModeKind::Commissioning => Ok(()),
            ModeKind::Boot => Err(Refusal::NotAllowed),
        }
    }

    /// Where the joints are: a homed robot's measured joints; before any reference, the
    /// configured rest positions (where the brakes held them when the board started, its
    /// encoders' counts 0) moved by what each encoder counted since (a commissioning test,
    /// a homing that failed or was stopped on the way).
    pub fn known_joints(&self) -> [S; NUM_JOINTS] {
        if self.mode.homed() {
            return self.sensing.measured().q;
        }
        let enc = self.sensing.encoders();
        core::array::from_fn(|j| {
            let rest = self
                .cfg
                .homing
                .joints
                .get(j)
                .map_or(S::zero(), |h| h.rest_position);
            enc.joint(j).map_or(rest, |e| {
                rest + S::from(e.count()).unwrap_or_else(S::zero) / e.counts_per_unit()
            })
        })
    }

    /// The switches as the limit-switch check reads them (`monitors::check_ranges`): once
    /// homed, every actuated switch is the end of travel (the supervisor keeps every
    /// setpoint inside the switches: a leg's 1 mm, a link's degrees). Before the
    /// references, a switch that reads actuated where the board knows its joint to be at
    /// it ([`Runtime::known_joints`] within the switch's travel of the joint's home
    /// position: a leg's home switch, a link's switch beside the hard stop it homes
    /// against) is where a stopped or failed homing left the joint: nothing but a homing
    /// or a commissioning test moves an unhomed joint, and the homing leaves such a
    /// switch first (`HomingPhase::LeaveSwitch`; a link's sweep ignores it). Latched,
    /// that reading would refuse every `ClearFault` for as long as the joint rests there
    /// (no `Home` from `Fault`): the robot locked out. A switch actuated where its joint
    /// cannot be is a fault as before.
    pub(super) fn limit_switches(&self, switches: &[bool; NUM_JOINTS]) -> [bool; NUM_JOINTS] {
        if self.mode.homed() || self.mode.kind() == ModeKind::Parking {
            return *switches;
        }
        let known = self.known_joints();
        core::array::from_fn(|j| {
            let closed = switches.get(j).copied().unwrap_or(false);
            let at_home = self.cfg.homing.joints.get(j).is_some_and(|h| {
                known
                    .get(j)
                    .is_some_and(|q| Float::abs(*q - h.home_position) <= h.switch_travel_max)
            });
            closed && !at_home
        })
    }

    /// `Home`: the homing starts from where the joints are (a homed robot's known joints
    /// start the travel windows); the master just spoke, so the heartbeat restarts. Where
    /// the board has the second position channel and it reads, the references are restored
    /// from it and verified (`Homing::start_restore`: no sweep to the switches, so no load
    /// check of a sweep); otherwise every joint sweeps to its switch or stop.
    fn enter_homing(&mut self, now_us: u64) -> Result<(), Refusal> {
        let Ok(mut homing) = Homing::new(&self.cfg.homing, &self.cfg.controller.servo) else {
            return Err(Refusal::NotAllowed);
        };
        let known = self.known_joints();
        self.session.rearm(now_us);
        self.sensing.lose_reference();
        let m = *self.sensing.measured();
        let counts = self.sensing.encoders().counts();
        let restore = match m.absolute {
            Some(p) if self.sensing.channel_fitted() => {
                homing.start_restore(&m.q, &m.motor, &counts, &p, now_us);
                true
            }
            _ => {
                homing.start(&m.q, &m.motor, &counts, Some(&known), now_us);
                false
            }
        };
        // Before any motion: a switch that cannot read what it reads, or a declared tool
        // the homing's sweep cannot carry, fails it.
        let checked = homing.check_switches(&self.inputs.switches).and_then(|()| {
            if restore {
                Ok(())
            } else {
                self.check_homing_load(&known)
            }
        });
        self.mode = Mode::Homing(homing);
        if let Err(e) = checked {
            let finding = Finding {
                cause: FaultCause::HomingFailed,
                joint: e.joint(),
                value: e.code(),
            };
            self.fault(finding, now_us);
        }
        Ok(())
    }

    /// With a declared tool, its loads along the homing's path (`homing_load`): a homing
    /// they do not allow is refused before it moves anything.
    fn check_homing_load(&self, rest: &[S; NUM_JOINTS]) -> Result<(), HomingError> {
        let Some(tool) = self.cfg.controller.tool else {
            return Ok(());
        };
        // The push's effort at the supply measured now, or at the lowest it may be.
        let [lo, _] = self.cfg.power.supply_v;
        let supply = if self.monitors.power.supply_in_range(self.inputs.supply_v) {
            self.inputs.supply_v
        } else {
            lo
        };
        crate::homing_load::check(
            &self.robot,
            self.cfg.controller.branch,
            &self.cfg.controller.fk,
            &self.cfg.homing,
            rest,
            &tool,
            &self.cfg.current.motors,
            &self.cfg.current.limits,
            supply,
        )
        .map_err(|r| HomingError::LoadTooHeavy { joint: r.joint() })
    }

    /// `Enable` from `Ready`: the reset acknowledged, the safety chain sound, the
    /// controller at the measured pose (or where the last one held), the brake check
    /// started; the heartbeat and the target clock restart.
    fn enter_enabling(&mut self, now_us: u64) -> Result<(), Refusal> {
        if self.inputs.estop_pressed {
            return Err(Refusal::FaultStillActive);
        }
        if self.inputs.safety_chain_tripped() {
            return Err(Refusal::SafetyRelayMismatch);
        }
        let held = match &self.mode {
            Mode::Ready { held } => *held,
            _ => None,
        };
        let measured = *self.sensing.measured();
        let mut built = Controller::new(self.robot.clone(), self.cfg.controller, &measured);
        if matches!(built, Err(ControllerError::Supervisor(_))) {
            if let Some(pose) = self.held_start(held.as_ref(), &measured.q) {
                built = Controller::starting_at(
                    self.robot.clone(),
                    self.cfg.controller,
                    &measured,
                    &pose,
                );
            }
        }
        let ctl = match built {
            Ok(c) => c,
            Err(ControllerError::NoPose | ControllerError::Supervisor(_)) => {
                return Err(Refusal::UnsafeStart)
            }
            Err(_) => return Err(Refusal::NotAllowed),
        };
        self.monitors.current.reset_overload();
        let check = BrakeCheck::start(
            self.cfg.brakes,
            &measured.q,
            now_us,
            self.outputs.brakes_applied_at_us(),
        );
        self.session.restart(now_us);
        self.mode = Mode::Enabling { check, ctl };
        Ok(())
    }

    /// Where an enable whose measured pose the supervisor refuses may start instead: the
    /// setpoint the last controller held, when the measured joints stand within
    /// `HOLD_COUNTS` encoder counts of its joints. A robot stopped at a limit (the
    /// workspace edge) holds there to within the servo's counts, and its measured pose may
    /// stand a count beyond the limit its setpoint keeps to: it is where the supervisor
    /// left it, not a robot moved out of its workspace, and it must be possible to enable
    /// it again (or it is stuck until re-homed). Further off, the start is refused.
    fn held_start(&self, held: Option<&Held<S>>, q: &[S; NUM_JOINTS]) -> Option<Pose<S>> {
        let held = held?;
        let cpu = &self.cfg.controller.encoders.counts_per_unit;
        let band: S = kinematics_core::scalar::lit(HOLD_COUNTS);
        let near = (0..NUM_JOINTS).all(|j| match (q.get(j), held.q.get(j), cpu.get(j)) {
            (Some(a), Some(b), Some(c)) if *c > S::zero() => Float::abs(*a - *b) <= band / *c,
            _ => false,
        });
        near.then_some(held.pose)
    }

    /// Into `Following` or `Holding` (from `Enabling`, or between the two): a hold that
    /// begins decelerates under the supervisor and holds (SS2); a hold that ends follows
    /// again from where the robot stands.
    fn enter_enabled(&mut self, now_us: u64) {
        let hold = self.session.hold();
        let torque_on = self.outputs.torque_on();
        let cfg = self.cfg.stops;
        let mut began = None;
        self.mode = match core::mem::replace(&mut self.mode, Mode::Boot) {
            Mode::Enabling { ctl, .. } | Mode::Following { ctl, .. } if hold.any() => {
                let mut ctl = ctl;
                ctl.hold();
                let sequence = StopSequence::start(cfg, hold_event(hold), now_us, torque_on);
                began = Some((hold_event(hold), sequence.stopper.status()));
                Mode::Holding { ctl, sequence }
            }
            Mode::Enabling { ctl, .. } | Mode::Holding { ctl, .. } => {
                self.last_target_us = now_us;
                Mode::Following { ctl, jog: None }
            }
            other => other,
        };
        if let Some((event, stop)) = began {
            self.record_stop(event, stop, now_us);
        }
    }

    /// A stop that is not a fault began: an entry of the event log.
    fn record_stop(&mut self, event: StopEvent, stop: master_link::StopStatus, now_us: u64) {
        let reason = match event {
            StopEvent::Disable => StopReason::Disable,
            StopEvent::HeartbeatLate => StopReason::HeartbeatLate,
            StopEvent::ClutchEngaged => StopReason::ClutchEngaged,
            StopEvent::OperatorAbsent => StopReason::OperatorAbsent,
            StopEvent::Fault(_) => return,
        };
        self.record_event(EventKind::Stop { reason, stop }, now_us);
    }

    /// Into `Stopping` (SS1): `Disable` while driving, the end of the park move (the
    /// controller starts at the park pose and stops there), or a cleared fault whose stop
    /// still drives (it continues to rest).
    fn enter_stopping(&mut self, event: Event, now_us: u64) {
        let torque_on = self.outputs.torque_on();
        let cfg = self.cfg.stops;
        let fresh = |drive| Stop {
            sequence: StopSequence::start(cfg, StopEvent::Disable, now_us, torque_on),
            drive,
        };
        // The end of the park move: the controller starts at the measured pose.
        let parked = if event == Event::Parked {
            if self.sensing.track_pose().is_err() {
                return self.park_failed(ParkRefusal::NoPose { sample: u16::MAX }, now_us);
            }
            match Controller::new(
                self.robot.clone(),
                self.cfg.controller,
                self.sensing.measured(),
            ) {
                Ok(ctl) => Some(ctl),
                Err(_) => {
                    let value = HomingError::Park { reason: 5 }.code();
                    let finding = Finding {
                        cause: FaultCause::HomingFailed,
                        joint: None,
                        value,
                    };
                    return self.fault(finding, now_us);
                }
            }
        } else {
            None
        };
        let (mut stop, homed) = match core::mem::replace(&mut self.mode, Mode::Boot) {
            Mode::Homing(_) | Mode::Parking { .. } if parked.is_some() => match parked {
                Some(ctl) => (fresh(StopDrive::Controller(ctl)), true),
                None => (fresh(StopDrive::ZeroDuty), false),
            },
            Mode::Homing(_) | Mode::Parking { .. } | Mode::Commissioning(_) => {
                (fresh(StopDrive::ZeroDuty), false)
            }
            Mode::Enabling { ctl, .. } | Mode::Following { ctl, .. } => {
                (fresh(StopDrive::Controller(ctl)), true)
            }
            Mode::Holding { ctl, mut sequence } => {
                sequence
                    .stopper
                    .request(StopEvent::Disable, now_us, torque_on);
                (
                    Stop {
                        sequence,
                        drive: StopDrive::Controller(ctl),
                    },
                    true,
                )
            }
            Mode::Fault {
                mut stop, homed, ..
            } => {
                stop.sequence
                    .stopper
                    .request(StopEvent::Disable, now_us, torque_on);
                (stop, homed)
            }
            other => {
                self.mode = other;
                return;
            }
        };
        if stop.sequence.stopper.outputs(false).decelerate {
            if let StopDrive::Controller(ctl) = &mut stop.drive {
                ctl.hold();
            }
        }
        let status = stop.sequence.stopper.status();
        self.mode = Mode::Stopping { stop, homed };
        if event == Event::Disable {
            self.record_stop(StopEvent::Disable, status, now_us);
        }
        self.settle_stop(now_us);
    }

    /// A stop that reached torque off: `Stopping` ends in `Ready` (with where the
    /// controller held) or `Disabled`; a fault's stop keeps only where it held.
    pub(super) fn settle_stop(&mut self, now_us: u64) {
        let off = matches!(self.mode.stop_phase(), StopPhase::TorqueOff { .. });
        match self.mode.kind() {
            ModeKind::Stopping | ModeKind::Fault if off => {
                let from = self.mode.kind();
                if next(from, Event::StopComplete, self.context(now_us)).is_ok() {
                    let to = match (from, self.mode.homed()) {
                        (ModeKind::Fault, _) => ModeKind::Fault,
                        (_, true) => ModeKind::Ready,
                        (_, false) => ModeKind::Disabled,
                    };
                    if to == ModeKind::Fault {
                        self.stop_complete_in_fault();
                    } else {
                        self.enter_idle(to);
                    }
                    self.after_transition(from, Event::StopComplete);
                }
            }
            _ => {}
        }
    }

    /// The controller's setpoint as where it held, if the reference stands.
    fn held_of(ctl: &Controller<S, M>) -> Held<S> {
        let sup = ctl.supervisor();
        Held {
            pose: *sup.setpoint(),
            q: to_array(sup.setpoint_joints()),
        }
    }

    /// Into `Ready` or `Disabled`: from a completed stop (the controller's setpoint kept
    /// in `Ready`), from a cleared fault whose stop is over, or at boot.
    fn enter_idle(&mut self, to: ModeKind) {
        let held = match &self.mode {
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => match &stop.drive {
                StopDrive::Controller(c) => Some(Self::held_of(c)),
                StopDrive::Off(h) => *h,
                StopDrive::ZeroDuty => None,
            },
            _ => None,
        };
        self.mode = match to {
            ModeKind::Ready => Mode::Ready { held },
            _ => Mode::Disabled,
        };
    }

    /// A fault's stop reached torque off: the controller is gone, where it held is kept
    /// while the reference stands.
    fn stop_complete_in_fault(&mut self) {
        if let Mode::Fault { stop, homed, .. } = &mut self.mode {
            if let StopDrive::Controller(c) = &stop.drive {
                let held = homed.then(|| Self::held_of(c));
                stop.drive = StopDrive::Off(held);
            } else if matches!(stop.drive, StopDrive::ZeroDuty) {
                stop.drive = StopDrive::Off(None);
            }
        }
    }

    /// Latches a fault (the first since the last clear is the one reported), logs it, and
    /// starts the stop the table names for it (a stop in force is only ever replaced by a
    /// stronger one). A fault whose cause makes the encoders' reference doubtful loses the
    /// homing.
    pub fn fault(&mut self, finding: Finding, now_us: u64) {
        let finding = self.attributed(finding);
        let record = finding.record(now_us);
        let cause = finding.cause;
        if let Mode::Fault { latched, .. } = &self.mode {
            // The same fault twice in one tick (an `EmergencyStop` message both latched
            // and queued) is one.
            if latched.last == (cause, record.joint, now_us) {
                return;
            }
        }
        let from = self.mode.kind();
        // (A heartbeat loss while nothing drives is no fault.)
        if next(from, Event::Fault(cause), self.context(now_us)) != Ok(ModeKind::Fault) {
            return;
        }
        let loses = Event::Fault(cause)
            .fault_bits()
            .is_some_and(|b| b.intersects(LOSE_HOMING));
        let torque_on = self.outputs.torque_on();
        let cfg = self.cfg.stops;
        let event = StopEvent::Fault(cause);
        let (latched, mut stop, homed) = match core::mem::replace(&mut self.mode, Mode::Boot) {
            Mode::Fault {
                latched,
                mut stop,
                homed,
            } => {
                stop.sequence.stopper.request(event, now_us, torque_on);
                (latched.with(cause, record, now_us), stop, homed && !loses)
            }
            other => {
                let homed = other.homed() && !loses;
                let stop = self.stop_of(other, event, now_us, torque_on, cfg);
                (Latched::new(cause, record, now_us), stop, homed)
            }
        };
        if !homed {
            if let StopDrive::Off(h) = &mut stop.drive {
                *h = None;
            }
        }
        if stop.sequence.stopper.outputs(false).decelerate {
            if let StopDrive::Controller(ctl) = &mut stop.drive {
                ctl.hold();
            }
        }
        let status = stop.sequence.stopper.status();
        self.mode = Mode::Fault {
            latched,
            stop,
            homed,
        };
        self.unreported = true;
        if !homed {
            self.sensing.lose_reference();
        }
        self.log.record(record, status);
        // The relay test's latch first: a safety-chain fault is written with it pending.
        self.sync_relay_test(now_us);
        self.record_event(
            EventKind::Fault {
                cause,
                joint: record.joint,
                value: record.value,
                stop: status,
            },
            now_us,
        );
        if from != ModeKind::Fault {
            self.session.note(Event::Fault(cause), false);
        }
        self.settle_stop(now_us);
    }

    /// A finding a failing encoder explains (the motor model's current or back-EMF, the
    /// servo's tracking, the standstill), on a joint whose encoder saw less motion than
    /// the second channel (where fitted) by more than the channel's check allows, is named
    /// as the encoder (`EncoderDisagree`): the monitors that judge the encoder through the
    /// motor model would otherwise name it by its symptom.
    fn attributed(&self, f: Finding) -> Finding {
        const EXPLAINED: [FaultCause; 6] = [
            FaultCause::EncoderDead,
            FaultCause::MotorOpen,
            FaultCause::CurrentImplausible,
            FaultCause::NoMotion,
            FaultCause::FollowingError,
            FaultCause::StandstillLost,
        ];
        let explained = match f.joint {
            Some(j) if self.sensing.channel_fitted() && EXPLAINED.contains(&f.cause) => {
                self.monitors.channel.explains(j).map(|e| (j, e))
            }
            _ => None,
        };
        match explained {
            Some((j, e)) => Finding::joint(FaultCause::EncoderDisagree, j, e),
            None => f,
        }
    }

    /// The stop of `event` in a mode that had none, or the one in force made stronger.
    fn stop_of(
        &self,
        mode: Mode<S, M>,
        event: StopEvent,
        now_us: u64,
        torque_on: bool,
        cfg: crate::stops::StopConfig,
    ) -> Stop<S, M> {
        let fresh = |drive| Stop {
            sequence: StopSequence::start(cfg, event, now_us, torque_on),
            drive,
        };
        match mode {
            Mode::Boot | Mode::Disabled => fresh(StopDrive::Off(None)),
            Mode::Ready { held } => fresh(StopDrive::Off(held)),
            Mode::Homing(_) | Mode::Parking { .. } | Mode::Commissioning(_) => {
                fresh(StopDrive::ZeroDuty)
            }
            Mode::Enabling { ctl, .. } | Mode::Following { ctl, .. } => {
                fresh(StopDrive::Controller(ctl))
            }
            Mode::Holding { ctl, mut sequence } => {
                sequence.stopper.request(event, now_us, torque_on);
                Stop {
                    sequence,
                    drive: StopDrive::Controller(ctl),
                }
            }
            Mode::Stopping { mut stop, .. } | Mode::Fault { mut stop, .. } => {
                stop.sequence.stopper.request(event, now_us, torque_on);
                stop
            }
        }
    }

    /// Every joint referenced: the pose is solved, and the park move starts (its path is
    /// checked against the guards first), or, without a park position or after references
    /// restored from the second channel (the robot stays where it is: its tool may be
    /// inside a patient), the homing is done.
    fn start_park(&mut self, now_us: u64) {
        if self.sensing.track_pose().is_err() {
            return self.park_failed(ParkRefusal::NoPose { sample: 0 }, now_us);
        }
        let m = *self.sensing.measured();
        let restored = self.mode.homing().is_some_and(Homing::restored);
        let park = self.cfg.homing.park.filter(|_| !restored);
        let (Some(park), Some(pose)) = (park, m.pose) else {
            let _ = self.apply(Event::Parked, now_us);
            return;
        };
        let Ok(guards) = kinematics_core::guards::Guards::new(
            self.robot.clone(),
            self.cfg.controller.branch,
            self.cfg.controller.limits,
        ) else {
            return self.park_failed(ParkRefusal::Invalid, now_us);
        };
        let park = ParkMove::new(
            guards,
            self.cfg.controller.fk,
            self.cfg.park,
            m.q,
            pose,
            park,
        );
        self.mode = match core::mem::replace(&mut self.mode, Mode::Boot) {
            Mode::Homing(homing) => Mode::Parking { homing, park },
            other => other,
        };
    }

    /// A homing failure of the park move.
    pub(super) fn park_failed(&mut self, reason: ParkRefusal<S>, now_us: u64) {
        let (joint, code) = match reason {
            ParkRefusal::Guard { reading, .. } => (
                subject_joint(reading.subject),
                HomingError::Park { reason: 1 },
            ),
            ParkRefusal::NoPose { .. } => (None, HomingError::Park { reason: 2 }),
            ParkRefusal::Invalid => (None, HomingError::Park { reason: 3 }),
            ParkRefusal::NotSettled { joint, .. } => (Some(joint), HomingError::Park { reason: 4 }),
        };
        let f = Finding {
            cause: FaultCause::HomingFailed,
            joint,
            value: code.code(),
        };
        self.fault(f, now_us);
    }
}
