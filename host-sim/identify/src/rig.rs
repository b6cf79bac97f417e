//! One joint of the simulated robot as the board sees it: the plant's own joint model
//! (`plant::joint`, the integrator of the whole plant) stepped at the board-on-plant step
//! (ten plant steps per control period), driven through the board's duty path and read
//! through its sensors:
//!
//! * **duty**: clamped to [-1, 1] and truncated to the PWM's resolution as the board's
//!   `hw` module does (`|d| * max_duty` in whole timer counts; [`PWM_STEPS`]);
//! * **encoder**: the plant's wrapping 16-bit counter, extended by the servo's own
//!   [`CountExtender`] at each control tick;
//! * **current**: the motor current at the tick (the board's current sense);
//! * **second position channel**: the plant's potentiometer model
//!   ([`plant::PositionSensor`]) with its noise, where the board has it fitted.
//!
//! Closed-loop runs use the board's servo, [`servo::JointServo`] (backlash compensation,
//! PID with its feed-forward, tracking monitor), with this joint's channel driven and the
//! five others idle at zero.

use plant::hbridge::{Duty, HBridge};
use plant::joint::{Joint, JointKind, JointModel};
use plant::PositionSensor;
use servo::{BacklashParams, CountExtender, JointServo, PidGains, ServoConfig, NUM_JOINTS};

use crate::error::IdentifyError;
use crate::recording::{Recording, Sample};

/// Plant steps per control period (the board-on-plant step: 100 us at 1 kHz).
pub const PLANT_STEPS_PER_TICK: u32 = 10;

/// PWM resolution: timer counts of a full duty (20 kHz PWM on an 84 MHz timer clock, the
/// coarsest of the board's PWM timers). The board truncates `|d| * PWM_STEPS`.
pub const PWM_STEPS: f64 = 4200.0;

/// The joint names, joint order.
pub const JOINT_NAMES: [&str; NUM_JOINTS] = servo::JOINT_NAMES;

/// A duty as the board's PWM produces it: clamped to [-1, 1], truncated to whole timer
/// counts; a non-finite duty drives nothing.
pub fn pwm_duty(d: f64) -> f64 {
    if !d.is_finite() {
        return 0.0;
    }
    let c = d.clamp(-1.0, 1.0);
    c.signum() * (c.abs() * PWM_STEPS).floor() / PWM_STEPS
}

/// What an excitation run watches, every control period (see [`JointRig::record`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Watch {
    /// The stated test travel: the joint (its load side) stays within it of its start,
    /// m or rad.
    pub travel: f64,
    /// The current the run stops at, A.
    pub current_limit_a: f64,
    /// The longest time constant of the braked joint, s: braked (duty 0, the bridge
    /// shorts the motor) at the speed `v`, `M dv/dt = -B v - Fc sgn v` brings it to rest
    /// within `v M / B` (the friction only shortens it).
    pub stop_time_s: f64,
    /// The joint's motion the encoder cannot see (the backlash: the load moves up to it
    /// more than the motor side from one flank to the other), m or rad.
    pub unseen: f64,
}

/// One sample of a closed-loop run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracePoint {
    /// Time since the start of the run, s.
    pub t: f64,
    /// The setpoint, m or rad (relative to the start).
    pub setpoint: f64,
    /// The position the encoder reads (motor side), relative to the start.
    pub measured: f64,
    /// The true load-side position, relative to the start.
    pub load: f64,
    /// The duty the servo commanded.
    pub duty: f64,
}

/// One joint on the bench: the plant's joint model behind the board's duty and sensor
/// path.
#[derive(Debug, Clone)]
pub struct JointRig {
    joint: Joint,
    index: usize,
    period_s: f64,
    counts_per_rev: u32,
    counts_per_unit: f64,
    sensor: Option<PositionSensor>,
    extender: CountExtender,
    time_s: f64,
    start_q: f64,
    start_count: i64,
    excursion: f64,
}

impl JointRig {
    /// Joint `index` (0..6) with the parameters `model`, an encoder of `counts_per_rev`
    /// counts per motor revolution read at `period_s` (counts per joint unit
    /// `counts_per_unit`), at rest at `start_q`; `sensor`: the second position channel,
    /// where fitted.
    pub fn new(
        index: usize,
        model: JointModel,
        counts_per_rev: u32,
        counts_per_unit: f64,
        period_s: f64,
        start_q: f64,
        sensor: Option<PositionSensor>,
    ) -> Result<Self, IdentifyError> {
        if index >= NUM_JOINTS {
            return Err(IdentifyError::NoSuchJoint(index));
        }
        if !(period_s.is_finite() && (1e-4..=1e-2).contains(&period_s)) {
            return Err(IdentifyError::Setting {
                name: "period_s",
                value: period_s,
                expected: "0.0001 .. 0.01 s",
            });
        }
        if !(counts_per_unit.is_finite() && counts_per_unit > 0.0) {
            return Err(IdentifyError::Setting {
                name: "counts_per_unit",
                value: counts_per_unit,
                expected: "finite and positive",
            });
        }
        let mut joint = Joint::new(model, counts_per_rev);
        joint.set_position(start_q);
        let mut extender = CountExtender::new();
        let start_count = extender.update(joint.encoder_counter());
        Ok(JointRig {
            joint,
            index,
            period_s,
            counts_per_rev,
            counts_per_unit,
            sensor,
            extender,
            time_s: 0.0,
            start_q,
            start_count,
            excursion: 0.0,
        })
    }

    /// The joint's name.
    pub fn name(&self) -> &'static str {
        JOINT_NAMES[self.index]
    }

    /// The joint's index.
    pub fn index(&self) -> usize {
        self.index
    }

    /// The joint's parameters.
    pub fn model(&self) -> &JointModel {
        self.joint.model()
    }

    /// Prismatic or rotary.
    pub fn kind(&self) -> JointKind {
        self.joint.model().kind
    }

    /// The control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Encoder counts per motor revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev
    }

    /// Encoder counts per joint unit.
    pub fn counts_per_unit(&self) -> f64 {
        self.counts_per_unit
    }

    /// The supply the bridge applies at full duty, V (the board measures it).
    pub fn supply_v(&self) -> f64 {
        self.joint.model().bridge.supply
    }

    /// Reads the sensors at a tick: the extended count, the current and the second
    /// channel.
    fn read(&mut self) -> (i64, f64, Option<u16>) {
        let count = self.extender.update(self.joint.encoder_counter());
        let abs = self
            .sensor
            .as_ref()
            .map(|s| s.reading(self.joint.position(), self.time_s));
        (count, self.joint.current(), abs)
    }

    /// Applies a duty (through the PWM) and advances one control period.
    fn drive(&mut self, duty: f64) -> f64 {
        let applied = pwm_duty(duty);
        // A finite duty in [-1, 1]: the bridge takes it as is.
        let d = HBridge::saturate(applied).unwrap_or(Duty {
            applied: 0.0,
            saturated: false,
        });
        self.joint.set_duty(d);
        let dt = self.period_s / f64::from(PLANT_STEPS_PER_TICK);
        for _ in 0..PLANT_STEPS_PER_TICK {
            self.joint.step(dt);
            self.excursion = self
                .excursion
                .max((self.joint.position() - self.start_q).abs());
        }
        self.time_s += self.period_s;
        applied
    }

    /// Stops the motor (duty 0: the bridge brakes it) and lets it come to rest.
    fn stop(&mut self) {
        for _ in 0..((0.2 / self.period_s) as usize) {
            self.drive(0.0);
        }
    }

    /// Encoder position relative to the start, joint units.
    fn measured_of(&self, count: i64) -> f64 {
        (count - self.start_count) as f64 / self.counts_per_unit
    }

    /// Applies `duties`, one per control period, recording at each tick (before the
    /// tick's duty is applied) the count, the current and the second channel, within what
    /// `watch` states:
    ///
    /// * **the travel**: the encoder sees the joint's motion less what the backlash hides
    ///   (`watch.unseen`) and within a count, so it keeps the joint within `travel` by
    ///   keeping its own reading within `travel - unseen - 1 count`. Each tick, from the
    ///   position `x` and the speed `v` over the last period (a period behind: the speed
    ///   at the tick is up to a period's acceleration beyond it), the joint braked now
    ///   comes to rest within `x + v (T + stop_time_s)`. Where that is beyond the reading's
    ///   share of the travel and the tick's duty pushes that way, the run brakes instead
    ///   (duty 0, recorded as applied), and keeps braking while the plan pushes that way:
    ///   the excitation's steps in that direction end early, the plan's next steps the
    ///   other way run as planned. A reading beyond its share all the same stops the run
    ///   with an error (the bound on the braked coast did not hold: a prior far from the
    ///   joint).
    /// * **the current**: beyond `current_limit_a` the run stops with an error.
    pub fn record(&mut self, duties: &[f64], watch: &Watch) -> Result<Recording, IdentifyError> {
        let seen = watch.travel - watch.unseen - 1.0 / self.counts_per_unit;
        let mut samples = Vec::with_capacity(duties.len() + 1);
        let mut last: Option<f64> = None;
        // The direction the run brakes in instead of pushing (0: none).
        let mut braking = 0.0f64;
        for (tick, u) in duties.iter().enumerate() {
            let (count, current, abs) = self.read();
            let x = self.measured_of(count);
            if x.abs() > seen {
                self.stop();
                return Err(IdentifyError::TravelExceeded {
                    joint: self.name(),
                    moved: x.abs(),
                    limit: seen,
                    tick,
                });
            }
            if current.abs() > watch.current_limit_a {
                self.stop();
                return Err(IdentifyError::CurrentExceeded {
                    joint: self.name(),
                    current,
                    limit: watch.current_limit_a,
                    tick,
                });
            }
            let v = last.map_or(0.0, |p| (x - p) / self.period_s);
            last = Some(x);
            let rest = x + v * (self.period_s + watch.stop_time_s);
            if braking * u < 0.0 {
                // The plan turned: its steps the other way run.
                braking = 0.0;
            }
            if braking == 0.0 && rest.abs() > seen && rest * u > 0.0 {
                braking = u.signum();
            }
            let planned = if braking * u > 0.0 { 0.0 } else { *u };
            let applied = self.drive(planned);
            samples.push(Sample {
                duty: applied,
                current_a: current,
                count,
                abs_count: abs,
            });
        }
        // The last reading closes the last period (no duty after it).
        let (count, current, abs) = self.read();
        samples.push(Sample {
            duty: 0.0,
            current_a: current,
            count,
            abs_count: abs,
        });
        self.stop();
        Ok(Recording {
            period_s: self.period_s,
            supply_v: self.supply_v(),
            counts_per_unit: self.counts_per_unit,
            abs_counts_per_unit: self.sensor.as_ref().map(|s| s.counts_per_unit),
            samples,
        })
    }

    /// The breakaway duties: from rest, the duty ramps at `rate` (duty per s) until the
    /// encoder has moved `counts` counts (then the motor brakes to rest), towards +q and
    /// then towards -q. Returns the two duties' magnitudes; an error when the joint has not
    /// moved by `max_duty` (a brake that holds, a seized joint) or leaves `travel`.
    pub fn breakaway(
        &mut self,
        rate: f64,
        max_duty: f64,
        counts: i64,
        travel: f64,
    ) -> Result<[f64; 2], IdentifyError> {
        let mut out = [0.0; 2];
        for (slot, dir) in out.iter_mut().zip([1.0, -1.0]) {
            let (c0, _, _) = self.read();
            let mut tick = 0usize;
            loop {
                let (c, _, _) = self.read();
                if (c - c0).abs() >= counts {
                    break;
                }
                let moved = self.measured_of(c).abs();
                if moved > travel {
                    self.stop();
                    return Err(IdentifyError::TravelExceeded {
                        joint: self.name(),
                        moved,
                        limit: travel,
                        tick,
                    });
                }
                let u = rate * tick as f64 * self.period_s;
                if u > max_duty {
                    self.stop();
                    return Err(IdentifyError::NoExcitation(format!(
                        "joint {} does not move up to a duty of {max_duty:.4} (a brake \
                         that holds, a seized joint)",
                        self.name()
                    )));
                }
                *slot = self.drive(dir * u).abs();
                tick += 1;
            }
            self.stop();
        }
        Ok(out)
    }

    /// Runs the board's servo on this joint for `ticks` periods with `gains` and the
    /// backlash compensation `backlash`, following `reference(t) = (r, r_dot)` (relative
    /// to the position at the start of the run). Stops with an error when the servo
    /// latches a fault or the joint leaves `travel` of its start.
    pub fn servo_run(
        &mut self,
        gains: &PidGains<f64>,
        backlash: BacklashParams<f64>,
        ticks: usize,
        travel: f64,
        reference: impl Fn(f64) -> (f64, f64),
    ) -> Result<Vec<TracePoint>, IdentifyError> {
        let mut cfg = ServoConfig::<f64>::default();
        cfg.pid.joints[self.index] = *gains;
        cfg.backlash.joints[self.index] = backlash;
        let mut servo = JointServo::new(&cfg).map_err(|e| IdentifyError::Servo(e.to_string()))?;
        let (count0, _, _) = self.read();
        let y0 = self.measured_of(count0);
        let q0 = self.joint.position();
        let mut start = [0.0; NUM_JOINTS];
        start[self.index] = y0;
        servo.reset(&start);
        servo.reset_backlash(&start, &[servo::Direction::Unknown; NUM_JOINTS]);
        let mut trace = Vec::with_capacity(ticks);
        for tick in 0..ticks {
            let t = tick as f64 * self.period_s;
            let (count, _, _) = self.read();
            let y = self.measured_of(count);
            if (y - y0).abs() > travel {
                self.stop();
                return Err(IdentifyError::TravelExceeded {
                    joint: self.name(),
                    moved: (y - y0).abs(),
                    limit: travel,
                    tick,
                });
            }
            let (r, v) = reference(t);
            let mut sp = [0.0; NUM_JOINTS];
            let mut spd = [0.0; NUM_JOINTS];
            let mut meas = [0.0; NUM_JOINTS];
            sp[self.index] = y0 + r;
            spd[self.index] = v;
            meas[self.index] = y;
            let out = servo.update(&sp, &spd, &meas, self.period_s);
            if let Some(f) = out.fault {
                self.stop();
                return Err(IdentifyError::Servo(format!(
                    "joint {}: the servo latched {:?} at tick {tick}",
                    self.name(),
                    f.kind
                )));
            }
            let duty = out.duty[self.index];
            trace.push(TracePoint {
                t,
                setpoint: r,
                measured: y - y0,
                load: self.joint.position() - q0,
                duty,
            });
            self.drive(duty);
        }
        Ok(trace)
    }

    /// The largest distance the joint (its load side, the plant's true position) has been
    /// from where it started, over every plant step since: what the person at the robot
    /// sees move, which no sensor of the board reads exactly (the simulation's truth).
    pub fn joint_excursion(&self) -> f64 {
        self.excursion
    }

    /// The position where the joint started, joint units (load side).
    pub fn start_q(&self) -> f64 {
        self.start_q
    }
}
