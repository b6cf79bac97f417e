//! The tick's frame, in every mode: the inputs and the monitors on them first, the
//! outputs last (what the mode asks of the drives and the brakes).

use hal::Hardware;
use kinematics_core::Mechanism;
use master_link::FaultCause;
use servo::NUM_JOINTS;

use super::mode::{cause_bit, Mode};
use super::monitoring::Inputs;
use super::Runtime;
use crate::absolute::ChannelInputs;
use crate::current::CurrentFault;
use crate::modes::{Event, ModeKind};
use crate::monitors::{check_ranges, DriveSample, Finding};
use crate::scalar::Scalar;
use crate::stops::{Outputs, StopPhase};

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// Reads the inputs and runs the monitors: every new finding becomes a fault.
    pub(super) fn sense_and_monitor<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) {
        self.sensing.read(hw);
        self.sensing.read_absolute(hw);
        self.inputs = Inputs::read(hw);
        match self.session.poll(now_us) {
            // The heartbeat lost: the fault's value is the silence, in ms (the log and the
            // operator's words show it).
            Some(Event::Fault(FaultCause::HeartbeatTimeout)) => {
                // In 32 bits (a hardware division on the MCU; a silence of 71 minutes
                // saturates).
                let silence_us =
                    u32::try_from(self.session.heartbeat().silence_us(now_us)).unwrap_or(u32::MAX);
                let finding =
                    Finding::board::<f32>(FaultCause::HeartbeatTimeout, (silence_us / 1000) as f32);
                self.fault(finding, now_us);
            }
            Some(ev) => {
                let _ = self.apply(ev, now_us);
            }
            None => {}
        }
        let findings = self.findings(now_us);
        // Every finding is acted on, not only the first: a later one may call for a
        // stronger stop than one already latched (an SS1 over-temperature must not mask an
        // STO encoder jump).
        for f in findings.into_iter().flatten() {
            self.report(f, now_us);
        }
    }

    /// A monitor's finding: a fault, unless its cause was already raised since the fault
    /// was latched (a monitor reports a lasting condition every tick: a repeat is neither
    /// logged nor acted on again).
    fn report(&mut self, f: Finding, now_us: u64) {
        let raised = self
            .mode
            .latched()
            .is_some_and(|l| l.raised & cause_bit(f.cause) != 0);
        if !raised {
            self.fault(f, now_us);
        }
    }

    /// The second position channel against the encoders (`crate::absolute`), on a board
    /// that has it. It runs once the tick's outputs are written (it feeds none of them): a
    /// finding latches its fault now, and its stop drives the outputs from the next tick.
    /// The robot holds while a safe operating stop holds, and while the brakes hold with
    /// torque off (their engage time past).
    pub(super) fn check_channel(&mut self, now_us: u64) {
        if !self.sensing.channel_fitted() || matches!(self.mode, Mode::Commissioning(_)) {
            return;
        }
        let engaged = self
            .outputs
            .brakes_applied_at_us()
            .is_none_or(|t| now_us.saturating_sub(t) >= self.cfg.stops.brake_engage_us);
        let braked = !self.outputs.torque_on() && !self.outputs.brakes_released() && engaged;
        let holding = braked || self.mode.stop_phase() == StopPhase::Holding;
        let m = self.sensing.measured();
        let p = m.absolute.unwrap_or([S::zero(); NUM_JOINTS]);
        let inputs = ChannelInputs {
            raw: m.absolute_raw.as_ref(),
            p: &p,
            motor: &m.motor,
            current: &self.inputs.currents,
            holding,
            epoch: self.sensing.reference_epoch(),
        };
        if let Some(f) = self.monitors.channel.check(&inputs) {
            self.report(f, now_us);
        }
    }

    /// This tick's findings, in order: the button, the safety chain, the power stage, the
    /// currents, the motors, the encoders, the ranges, the standstill, the pose. The motor
    /// check comes before the encoder check: an open circuit also looks like a dead
    /// encoder to the back-EMF (both count from the fault's first tick; the motor check
    /// names it right).
    fn findings(&mut self, now_us: u64) -> [Option<Finding>; 9] {
        let i = self.inputs;
        // An open safety relay has taken the drivers' supply away: whatever the outputs
        // ask, no motor is driven, and a missing current says nothing about the motor or
        // the encoder (the relay's own check names the fault).
        let torque_on = self.outputs.torque_on() && !i.relay_open;
        let button = i
            .estop_pressed
            .then(|| Finding::board::<S>(FaultCause::EmergencyStopButton, S::one()));
        let mon = &mut self.monitors;
        let chain = mon.chain.check(i.estop_pressed, i.relay_open);
        let power = mon.power.check(i.supply_v, i.driver_fault, torque_on);
        let current = mon
            .current
            .monitor(&i.currents, self.dt, torque_on, now_us)
            .map(|f| match f {
                CurrentFault::Overcurrent { joint, current_a } => {
                    Finding::joint(FaultCause::Overcurrent, joint, current_a)
                }
                CurrentFault::Overload { joint, current_a } => {
                    Finding::joint(FaultCause::Overload, joint, current_a)
                }
                CurrentFault::OverTemperature { joint, heat } => {
                    Finding::joint(FaultCause::OverTemperature, joint, heat)
                }
            });
        let counts = self.sensing.encoders().counts();
        let drive = DriveSample {
            duty: self.outputs.last_duty(),
            current: i.currents,
            supply_v: i.supply_v,
            torque: torque_on,
        };
        let motors = &self.cfg.current.motors;
        let encoder = mon.encoder.check(&counts, self.dt, motors, &drive);
        let limits: [S; servo::NUM_JOINTS] = core::array::from_fn(|j| mon.current.peak_current(j));
        let motor = mon.motor.check(
            &drive,
            mon.encoder.qdot(),
            mon.encoder.qdot_resolution(),
            motors,
            &limits,
        );
        // Commissioning tests the wiring these monitors take for granted (the motor and
        // encoder models, the switches): its own travel watch stands in for them.
        let commissioning = matches!(self.mode, Mode::Commissioning(_));
        let encoder = encoder.filter(|f| !commissioning || f.cause == FaultCause::EncoderJump);
        let motor = motor.filter(|_| !commissioning);
        let q = self.sensing.measured().q;
        // Homing watches its own joints (estimated before their references); the park move
        // after it has every reference.
        let kind = self.mode.kind();
        let homing = matches!(kind, ModeKind::Homing | ModeKind::Parking);
        let referenced = self.mode.homed() || kind == ModeKind::Parking;
        let switches = self.limit_switches(&i.switches);
        let ranges = check_ranges(
            &q,
            &self.cfg.mechanics.range,
            &switches,
            referenced,
            homing || commissioning,
        );
        let standstill = self
            .mode
            .stop_sequence()
            .filter(|s| s.stopper.phase() == StopPhase::Holding)
            .and_then(|s| s.standstill.check(&q));
        let failures = self.sensing.counters().fk_failures_in_row;
        let fk = (failures >= self.cfg.fk_failures_to_fault).then(|| {
            Finding::board(
                FaultCause::ForwardKinematics,
                S::from(failures).unwrap_or_else(S::zero),
            )
        });
        [
            button, chain, power, current, motor, encoder, ranges, standstill, fk,
        ]
    }
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// What the mode asks of the outputs now: the stop modes as their stop says, the
    /// driving modes torque with the brakes released (the brake check keeps them applied
    /// until it passes), the others nothing.
    pub(super) fn output_request(&self) -> Outputs {
        let off = Outputs {
            torque: false,
            brakes_released: false,
            decelerate: false,
        };
        let drive = Outputs {
            torque: true,
            brakes_released: true,
            decelerate: false,
        };
        match &self.mode {
            Mode::Boot | Mode::Disabled | Mode::Ready { .. } => off,
            Mode::Commissioning(test) => {
                let (torque, brakes_released) = test.outputs();
                Outputs {
                    torque,
                    brakes_released,
                    decelerate: false,
                }
            }
            Mode::Homing(_) | Mode::Parking { .. } | Mode::Following { .. } => drive,
            Mode::Enabling { check, .. } => Outputs {
                brakes_released: check.brakes_released(),
                ..drive
            },
            Mode::Holding { sequence, .. } => sequence.stopper.outputs(true),
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => {
                stop.sequence.stopper.outputs(false)
            }
        }
    }

    /// The outputs of the tick: the duties within the current limit, the brakes, torque.
    pub(super) fn write_outputs<H: Hardware<S>>(
        &mut self,
        hw: &mut H,
        duty: &mut [S; NUM_JOINTS],
        now_us: u64,
    ) {
        let out = self.output_request();
        let mon = &mut self.monitors;
        let qdot = *mon.encoder.qdot();
        self.outputs.write(
            hw,
            out,
            duty,
            &mut mon.current,
            &qdot,
            self.inputs.supply_v,
            now_us,
        );
    }
}
