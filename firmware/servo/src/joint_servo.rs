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

impl<S: Float> Channel<S> {
    /// A sample (`[setpoint, velocity, acceleration, measured]`, motor side) whose
    /// setpoint or velocity is not finite: the PID rejects it (duty 0, its state kept),
    /// which latches a [`FaultKind::NonFiniteInput`] fault (into `fault` unless one is
    /// latched already), and the monitor sees it. Out of line: it never runs with sane
    /// inputs.
    #[cold]
    #[inline(never)]
    fn reject(
        &mut self,
        [setpoint, setpoint_velocity, setpoint_acceleration, measured]: [S; 4],
        joint: usize,
        dt: S,
        time_us: u64,
        fault: &mut Option<TrackingFault<S>>,
    ) {
        let input = PidInput {
            setpoint,
            setpoint_velocity,
            setpoint_acceleration,
            measured,
        };
        let p = self.pid.update(&input, dt);
        if p.error.is_some() && fault.is_none() {
            *fault = Some(self.tracking.latch(TrackingFault {
                kind: FaultKind::NonFiniteInput,
                joint: Some(joint),
                error: S::zero(),
                duration: S::zero(),
                time_us,
            }));
        }
        let sample = TrackingSample {
            setpoint: input.setpoint,
            setpoint_velocity: input.setpoint_velocity,
            measured: input.measured,
            duty: p.duty,
        };
        let f = self.tracking.update(&sample, dt, time_us);
        if fault.is_none() {
            *fault = f;
        }
    }
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
    // Cold (at enable, a stop, the park move; never in a tick): compiled for size.
    #[cold]
    pub fn new(config: &ServoConfig<S>) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut channels = [Channel {
            backlash: BacklashCompensator::new(BacklashParams::off()),
            pid: Pid::new(PidGains::proportional(S::zero())),
            tracking: TrackingMonitor::new(0, TrackingLimits::leg()),
        }; NUM_JOINTS];
        for ((j, ch), t) in channels.iter_mut().enumerate().zip(&config.tracking.joints) {
            new_tracking(ch, j, t);
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
            configure(ch, p, b, t);
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
        if !all_finite(setpoint_q, setpoint_qdot, setpoint_qddot, measured_q) {
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
            // Backlash: motor-side setpoint and velocity (`r` and `dt` are checked).
            let b = ch.backlash.update_checked(*r, dt);
            let r_m = *r + b.offset;
            let v_m = *v + b.offset_rate;
            if !(r_m.is_finite() && v_m.is_finite()) {
                // The offset took a huge finite input beyond the range (cannot happen
                // with sane inputs; kept as a safety net).
                ch.reject([r_m, v_m, *a, *y], j, dt, time_us, &mut self.fault);
                continue;
            }
            // Position loop.
            let input = PidInput {
                setpoint: r_m,
                setpoint_velocity: v_m,
                setpoint_acceleration: *a,
                measured: *y,
            };
            // Every value of `input` and `dt` is checked, the duty is finite.
            let p = ch.pid.update_checked(&input, dt);
            *duty = p.duty;
            *sat = p.saturated;
            // Monitor, on what the loop actually tracks.
            let sample = TrackingSample {
                setpoint: r_m,
                setpoint_velocity: v_m,
                measured: *y,
                duty: p.duty,
            };
            if ch.tracking.update_checked(&sample, dt, time_us) && self.fault.is_none() {
                self.fault = ch.tracking.fault();
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

    /// One joint's measurement moved by a new reference while nothing moved (the setpoint
    /// moves with it): its loop goes on with its integral (what holds its load), `measured`
    /// taken as the previous measurement (no derivative kick). False outside `0..6`.
    pub fn rereference_joint(&mut self, joint: usize, measured: S) -> bool {
        match self.channels.get_mut(joint) {
            Some(ch) => {
                let integral = ch.pid.integral();
                ch.pid.reset_with_integral(measured, integral);
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

/// Every value of the four arrays is finite. One multiply-add per value: `x * 0` is 0
/// for a finite `x` and NaN for an infinite or NaN one, and a NaN stays in the sum.
#[inline(always)]
fn all_finite<S: Float>(
    a: &[S; NUM_JOINTS],
    b: &[S; NUM_JOINTS],
    c: &[S; NUM_JOINTS],
    d: &[S; NUM_JOINTS],
) -> bool {
    let zero = S::zero();
    let sum = |x: &[S; NUM_JOINTS]| x.iter().fold(zero, |acc, v| acc + *v * zero);
    sum(a) + sum(b) + sum(c) + sum(d) == zero
}

// Construction and reconfiguration are cold: one call per channel, not the body unrolled
// six times over (the board image's text; the control tick never calls them).
#[inline(never)]
fn new_tracking<S: Float>(ch: &mut Channel<S>, j: usize, t: &TrackingLimits<S>) {
    ch.tracking = TrackingMonitor::new(j, *t);
}

#[inline(never)]
fn configure<S: Float>(
    ch: &mut Channel<S>,
    p: &PidGains<S>,
    b: &BacklashParams<S>,
    t: &TrackingLimits<S>,
) {
    ch.pid.set_gains(*p);
    ch.backlash.set_params(*b);
    ch.tracking.set_limits(*t);
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    /// Finite inputs that the backlash offset carries beyond the range (a huge offset
    /// a previous servo left ramps out at once: a rate of -f32::MAX, added to a huge
    /// negative desired velocity) latch a non-finite-input fault on that joint, zero
    /// every duty and leave that joint's PID untouched.
    #[test]
    fn a_motor_velocity_beyond_the_range_latches_a_non_finite_input_fault() {
        let mut servo = JointServo::<f32>::new(&ServoConfig::default()).unwrap();
        let q = [0.17, 0.17, 0.17, 0.0, 0.0, 0.0];
        servo.reset(&q);
        let mut offsets = [0.0; NUM_JOINTS];
        offsets[2] = 3e38;
        servo.resume_backlash(&q, &offsets);
        let mut qdot = [0.0; NUM_JOINTS];
        qdot[2] = -3e38;
        let pid_before = *servo.pid(2).unwrap();
        let out = servo.update(&q, &qdot, &q, 1e-3);
        let fault = out.fault.unwrap();
        assert_eq!(fault.kind, FaultKind::NonFiniteInput);
        assert_eq!(fault.joint, Some(2));
        assert_eq!(out.duty, [0.0; NUM_JOINTS]);
        assert_eq!(servo.tracking(2).unwrap().fault(), Some(fault));
        assert_eq!(*servo.pid(2).unwrap(), pid_before);
    }
}
