//! The six joint servos together: backlash compensation -> PID -> tracking monitor.
//!
//! Per joint and sample:
//! ```text
//! (offset, offset_rate) = backlash.update(r, dt)
//! r_m     = r + offset                   motor-side setpoint (the encoders are on the motors)
//! r_dot_m = r_dot + offset_rate          desired motor-side velocity
//! duty    = pid.update(r_m, r_dot_m, r_ddot, y, dt)
//! fault   = tracking.update(r_m, r_dot_m, y, duty, dt)
//! ```
//! Any fault (following error, no motion, non-finite input, invalid `dt`) is latched and
//! sets all six duties to 0 (the safe state) from that sample on, until
//! [`JointServo::reset`]. The work per call is the same whatever the inputs.

use num_traits::Float;

use crate::backlash::{BacklashCompensator, BacklashParams, Direction};
use crate::config::{ConfigError, ServoConfig};
use crate::num::{seconds_to_us, valid_dt};
use crate::pid::{Pid, PidGains, PidInput};
use crate::tracking::{FaultKind, TrackingFault, TrackingLimits, TrackingMonitor, TrackingSample};
use crate::NUM_JOINTS;

/// The result of one [`JointServo::update`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoOutput<S> {
    /// Duties for the H-bridges, joint order, each finite and within its PID's output
    /// limit; all 0 while a fault is latched.
    pub duty: [S; NUM_JOINTS],
    /// Which joints' PID output was saturated (all false while faulted).
    pub saturated: [bool; NUM_JOINTS],
    /// The latched fault, if any (reported on every call until reset).
    pub fault: Option<TrackingFault<S>>,
}

impl<S: Float> ServoOutput<S> {
    fn safe(fault: Option<TrackingFault<S>>) -> Self {
        ServoOutput {
            duty: [S::zero(); NUM_JOINTS],
            saturated: [false; NUM_JOINTS],
            fault,
        }
    }
}

/// One joint's chain.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Channel<S> {
    backlash: BacklashCompensator<S>,
    pid: Pid<S>,
    tracking: TrackingMonitor<S>,
}

/// The position servos of the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointServo<S> {
    config: ServoConfig<S>,
    channels: [Channel<S>; NUM_JOINTS],
    fault: Option<TrackingFault<S>>,
    time_us: u64,
    /// The last valid sample time and its whole microseconds (the rate is fixed; the
    /// conversion is a libm round and a soft 64-bit conversion on the Cortex-M4).
    dt_us: (S, u64),
}

impl<S: Float> JointServo<S> {
    /// Six servos with `config` (validated first).
    pub fn new(config: &ServoConfig<S>) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut channels = [Channel {
            backlash: BacklashCompensator::new(BacklashParams::off()),
            pid: Pid::new(PidGains::proportional(S::zero())),
            tracking: TrackingMonitor::new(0, TrackingLimits::leg()),
        }; NUM_JOINTS];
        for ((j, ch), t) in channels.iter_mut().enumerate().zip(&config.tracking.joints) {
            ch.tracking = TrackingMonitor::new(j, *t);
        }
        let mut servo = JointServo {
            config: *config,
            channels,
            fault: None,
            time_us: 0,
            dt_us: (S::zero(), 0),
        };
        servo.apply_config();
        Ok(servo)
    }

    fn apply_config(&mut self) {
        let c = &self.config;
        for (((ch, p), b), t) in self
            .channels
            .iter_mut()
            .zip(&c.pid.joints)
            .zip(&c.backlash.joints)
            .zip(&c.tracking.joints)
        {
            ch.pid.set_gains(*p);
            ch.backlash.set_params(*b);
            ch.tracking.set_limits(*t);
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ServoConfig<S> {
        &self.config
    }

    /// Replaces the configuration at run time (validated first; on error nothing
    /// changes). Bumpless: the PID integrals are kept (bounded by the new limits) and the
    /// backlash offsets ramp to their new targets.
    pub fn set_config(&mut self, config: &ServoConfig<S>) -> Result<(), ConfigError> {
        config.validate()?;
        self.config = *config;
        self.apply_config();
        Ok(())
    }

    /// Imposes each joint's backlash flank from a steady external load (see
    /// [`BacklashCompensator::set_preload`]); `Direction::Unknown` follows the motion.
    pub fn set_preloads(&mut self, flanks: &[Direction; NUM_JOINTS]) {
        for (ch, d) in self.channels.iter_mut().zip(flanks.iter()) {
            ch.backlash.set_preload(*d);
        }
    }

    /// One control sample: setpoints `setpoint_q` (m, rad), desired velocities
    /// `setpoint_qdot` (m/s, rad/s, from the Jacobian), measured positions `measured_q`
    /// (from the encoders), sample time `dt` (s, finite and > 0).
    pub fn update(
        &mut self,
        setpoint_q: &[S; NUM_JOINTS],
        setpoint_qdot: &[S; NUM_JOINTS],
        measured_q: &[S; NUM_JOINTS],
        dt: S,
    ) -> ServoOutput<S> {
        self.update_with_acceleration(
            setpoint_q,
            setpoint_qdot,
            &[S::zero(); NUM_JOINTS],
            measured_q,
            dt,
        )
    }

    /// [`update`](Self::update) with desired accelerations `setpoint_qddot` (m/s^2,
    /// rad/s^2) for the acceleration feed-forward.
    pub fn update_with_acceleration(
        &mut self,
        setpoint_q: &[S; NUM_JOINTS],
        setpoint_qdot: &[S; NUM_JOINTS],
        setpoint_qddot: &[S; NUM_JOINTS],
        measured_q: &[S; NUM_JOINTS],
        dt: S,
    ) -> ServoOutput<S> {
        if valid_dt(dt) {
            if self.dt_us.0 != dt {
                self.dt_us = (dt, seconds_to_us(dt));
            }
            self.time_us = self.time_us.saturating_add(self.dt_us.1);
        }
        if self.fault.is_some() {
            return ServoOutput::safe(self.fault);
        }
        let time_us = self.time_us;

        // Inputs first: a bad sample must not touch any state.
        if !valid_dt(dt) {
            return self.trip(TrackingFault {
                kind: FaultKind::InvalidTimeStep,
                joint: None,
                error: S::zero(),
                duration: S::zero(),
                time_us,
            });
        }
        let inputs = setpoint_q
            .iter()
            .zip(setpoint_qdot)
            .zip(setpoint_qddot)
            .zip(measured_q);
        for (j, (((r, v), a), y)) in inputs.clone().enumerate() {
            if !(r.is_finite() && v.is_finite() && a.is_finite() && y.is_finite()) {
                let error = *r - *y;
                return self.trip(TrackingFault {
                    kind: FaultKind::NonFiniteInput,
                    joint: Some(j),
                    error: if error.is_finite() { error } else { S::zero() },
                    duration: S::zero(),
                    time_us,
                });
            }
        }

        let mut out = ServoOutput::safe(None);
        let outputs = out.duty.iter_mut().zip(out.saturated.iter_mut());
        for (j, ((ch, (((r, v), a), y)), (duty, sat))) in self
            .channels
            .iter_mut()
            .zip(inputs)
            .zip(outputs)
            .enumerate()
        {
            // Backlash: motor-side setpoint and velocity.
            let b = ch.backlash.update(*r, dt);
            let r_m = *r + b.offset;
            let v_m = *v + b.offset_rate;
            // Position loop.
            let input = PidInput {
                setpoint: r_m,
                setpoint_velocity: v_m,
                setpoint_acceleration: *a,
                measured: *y,
            };
            let p = ch.pid.update(&input, dt);
            if p.error.is_some() && self.fault.is_none() {
                // Cannot happen with the inputs checked above; kept as a safety net.
                self.fault = Some(ch.tracking.latch(TrackingFault {
                    kind: FaultKind::NonFiniteInput,
                    joint: Some(j),
                    error: S::zero(),
                    duration: S::zero(),
                    time_us,
                }));
            }
            *duty = p.duty;
            *sat = p.saturated;
            // Monitor, on what the loop actually tracks.
            let sample = TrackingSample {
                setpoint: r_m,
                setpoint_velocity: v_m,
                measured: *y,
                duty: p.duty,
            };
            let f = ch.tracking.update(&sample, dt, time_us);
            if self.fault.is_none() {
                self.fault = f;
            }
        }
        match self.fault {
            Some(f) => ServoOutput::safe(Some(f)),
            None => out,
        }
    }

    fn trip(&mut self, fault: TrackingFault<S>) -> ServoOutput<S> {
        if let Some(ch) = fault.joint.and_then(|j| self.channels.get_mut(j)) {
            ch.tracking.latch(fault);
        }
        self.fault = Some(fault);
        ServoOutput::safe(self.fault)
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<TrackingFault<S>> {
        self.fault
    }

    /// Clears the latched fault and restarts the loops bumplessly at `measured_q`: PID
    /// integrals and filters cleared with `measured_q` as the previous measurement (no
    /// derivative kick), tracking timers cleared. The backlash direction is kept (the
    /// gap does not change while the motors are off). Call with the current encoder
    /// positions before enabling the outputs again.
    pub fn reset(&mut self, measured_q: &[S; NUM_JOINTS]) {
        self.fault = None;
        for (ch, y) in self.channels.iter_mut().zip(measured_q) {
            ch.pid.reset(*y);
            ch.tracking.reset();
        }
    }

    /// Restarts one joint's loop bumplessly at `measured` (its PID integral and filters,
    /// its tracking timers), e.g. when the joint passes from an open-loop move back to
    /// the servo; the other joints and a latched fault are untouched. False outside `0..6`.
    pub fn reset_joint(&mut self, joint: usize, measured: S) -> bool {
        match self.channels.get_mut(joint) {
            Some(ch) => {
                ch.pid.reset(measured);
                ch.tracking.reset();
                true
            }
            None => false,
        }
    }

    /// Tells the backlash compensators which flank each joint is on (e.g. after homing)
    /// with the setpoints `setpoint_q` at that moment.
    pub fn reset_backlash(
        &mut self,
        setpoint_q: &[S; NUM_JOINTS],
        direction: &[Direction; NUM_JOINTS],
    ) {
        for ((ch, r), d) in self.channels.iter_mut().zip(setpoint_q).zip(direction) {
            ch.backlash.reset(*r, *d);
        }
    }

    /// Restarts the backlash compensators at the setpoints `setpoint_q` with the motor
    /// offsets `offsets` a previous servo left (see [`BacklashCompensator::resume`]): the
    /// motors' setpoints are where they stand.
    pub fn resume_backlash(&mut self, setpoint_q: &[S; NUM_JOINTS], offsets: &[S; NUM_JOINTS]) {
        for ((ch, r), o) in self.channels.iter_mut().zip(setpoint_q).zip(offsets) {
            ch.backlash.resume(*r, *o);
        }
    }

    /// [`JointServo::resume_backlash`] for joint `joint` alone (e.g. when its position
    /// was just referenced: its setpoint moved without a motion); false outside `0..6`.
    pub fn resume_backlash_joint(&mut self, joint: usize, setpoint: S, offset: S) -> bool {
        match self.channels.get_mut(joint) {
            Some(ch) => {
                ch.backlash.resume(setpoint, offset);
                true
            }
            None => false,
        }
    }

    /// Servo time, us: the sum of the valid `dt`s since creation.
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// The backlash offsets currently added to the setpoints, m or rad.
    pub fn backlash_offsets(&self) -> [S; NUM_JOINTS] {
        self.channels.map(|c| c.backlash.offset())
    }

    /// The PID integral terms, duty.
    pub fn integrals(&self) -> [S; NUM_JOINTS] {
        self.channels.map(|c| c.pid.integral())
    }

    /// One joint's PID (for diagnostics).
    pub fn pid(&self, joint: usize) -> Option<&Pid<S>> {
        self.channels.get(joint).map(|c| &c.pid)
    }

    /// One joint's backlash compensator (for diagnostics).
    pub fn backlash(&self, joint: usize) -> Option<&BacklashCompensator<S>> {
        self.channels.get(joint).map(|c| &c.backlash)
    }

    /// One joint's tracking monitor (for diagnostics).
    pub fn tracking(&self, joint: usize) -> Option<&TrackingMonitor<S>> {
        self.channels.get(joint).map(|c| &c.tracking)
    }
}
