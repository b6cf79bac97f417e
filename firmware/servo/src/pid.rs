//! Per-joint PID position controller with feed-forward, producing an H-bridge duty.
//!
//! ## The law (sample `k`, sample time `dt`; units: joint units m or rad, duty)
//! ```text
//! e      = r - y                                      position error
//! e_db   = sign(e) * max(|e| - deadband, 0)           deadband, continuous at the edge
//! P      = kp * e_db
//! v_raw  = (y - y_prev) / dt                          measured velocity (backward difference)
//! a      = 1 - exp(-2 pi fc dt)                       exact first-order low-pass coefficient
//! v_f   += a * (v_raw - v_f)                          filtered measured velocity
//! D      = kd * (r_dot - v_f)    (or -kd * v_f)       derivative on the measurement
//! FF     = kv r_dot + ka r_ddot + f_c clamp(r_dot / v_band, -1, 1)
//! u_raw  = P + I + D + FF ;  u = clamp(u_raw, -limit, limit) ; saturated = u != u_raw
//! I     += ki e_db dt       (anti-windup: see [`AntiWindup`]) ; |I| <= integral_limit
//! ```
//! * The derivative acts on the measured velocity, never on the difference of the
//!   position error, so a position setpoint step causes no derivative kick. `r_dot` is
//!   the desired velocity the caller passes (from the Jacobian), not a differenced
//!   setpoint; with [`PidGains::derivative_uses_setpoint_velocity`] the D term damps the
//!   velocity *error*, so tracking at constant speed is not dragged by the damping.
//! * The integral stores duty (ki already applied), so changing `ki` does not bump the
//!   output, and it is used one sample later (forward Euler), as in Astrom & Hagglund.
//! * Inside the deadband P and I see zero error; the deadband shrinks the error by its
//!   width instead of cutting it, so entering or leaving it causes no step in the output.
//! * Every term is bounded and every state is kept finite, so for any finite input the
//!   duty is finite and within the limit; a non-finite input or time step gives duty 0 and
//!   an [`InputError`] and leaves the state untouched.

use num_traits::Float;

use crate::checks::{is_leg, Check, ConfigError};
use crate::num::{bound, bound_below, clamp, clamp_sym, lit, sane_limit, sign, valid_dt};
use crate::NUM_JOINTS;

/// Bound on each term of the law, duty. Far above any useful value (the output is
/// limited to <= 1), it only keeps the sum finite for absurd inputs.
const TERM_BOUND: f64 = 1e9;

/// How the integral is kept from winding up while the output is saturated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AntiWindup<S> {
    /// No anti-windup beyond [`PidGains::integral_limit`]. For analysis and tests only.
    None,
    /// Conditional integration (clamping): while the output is saturated the integral is
    /// not updated with an error that would drive it further into saturation.
    Clamp,
    /// Back-calculation: `I += ki e_db dt + (1 - exp(-kt dt)) (u - u_raw)`, i.e. the
    /// integral is pulled back towards the value that just saturates the output with time
    /// constant `1 / kt` (exact discretisation, stable for every `dt`).
    BackCalculation {
        /// `kt`, 1/s, finite and >= 0. Rules of thumb: `ki / kp` (1/Ti) or, with D,
        /// `sqrt(ki / kd)` (Astrom: Tt = sqrt(Ti Td)).
        tracking_gain: S,
    },
}

/// PID gains and feed-forward of one joint. Units: `u` = m for the legs, rad for the
/// links; duty is dimensionless in `[-1, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidGains<S> {
    /// Proportional gain, duty/u. Default legs 500 duty/m (0.1 mm of error -> 0.05 duty),
    /// links 12 duty/rad: a ~30 Hz / ~25 Hz position loop, damping ~0.8 with `kd`, on
    /// the plant's mechanical time constants (5.6 ms legs, 15 ms links).
    pub kp: S,
    /// Integral gain, duty/(u s). Default legs 10 000, links 240 (`ki = kp * 20 /s`:
    /// the integral acts below ~3 Hz; it only has to cancel friction and gravity).
    pub ki: S,
    /// Derivative gain, duty/(u/s). Default legs 1.5, links 0.08 (damping ~0.8).
    pub kd: S,
    /// Cutoff of the low-pass filter on the measured velocity, Hz, finite and > 0.
    /// Default 200 Hz: attenuates the 1-count quantisation steps (1.5 mm/s on a leg at
    /// 1 kHz) while adding only ~8 deg of phase at the 30 Hz loop crossover.
    pub derivative_cutoff_hz: S,
    /// `true` (default): `D = kd (r_dot - v_f)` (damps the velocity error, no drag when
    /// tracking); `false`: `D = -kd v_f` (classic derivative on measurement only).
    pub derivative_uses_setpoint_velocity: bool,
    /// Velocity feed-forward, duty/(u/s). Default `1 / no-load speed`: legs 1/0.378 =
    /// 2.65 duty/(m/s), links 1/28.5 = 0.0351 duty/(rad/s) (24 V, 317 rpm/V and 3 mm/rev;
    /// 408 rpm/V and 36:1).
    pub kv: S,
    /// Acceleration feed-forward, duty/(u/s^2). Default: reflected inertia over stall
    /// torque at full duty: legs 0.0147, links 5.3e-4. Only used through
    /// [`JointServo::update_with_acceleration`](crate::JointServo::update_with_acceleration).
    pub ka: S,
    /// Coulomb friction feed-forward, duty, applied as `friction_ff * clamp(r_dot /
    /// friction_band, -1, 1)`. Default legs 0.003, links 0.004 (motor + gear friction over
    /// stall torque).
    pub friction_ff: S,
    /// Desired speed at which the friction feed-forward reaches full value, u/s, finite
    /// and > 0 (a linear ramp avoids chattering at zero speed). Default legs 1e-3 m/s,
    /// links 0.01 rad/s.
    pub friction_band: S,
    /// Output saturation, duty, in (0, 1]. Default 1.
    pub output_limit: S,
    /// Bound on the integral term, duty, finite and >= 0. Default 0.25: the steady loads
    /// (nominal current at stall) need < 0.11 duty on either joint type.
    pub integral_limit: S,
    /// Error deadband, u, finite and >= 0. Default 0 (off). Inside `|e| <= deadband` P
    /// and I see zero error (the integral holds).
    pub deadband: S,
    /// Anti-windup strategy. Default [`AntiWindup::Clamp`].
    pub anti_windup: AntiWindup<S>,
}

impl<S: Float> PidGains<S> {
    /// The default gains of a prismatic leg (see the field docs).
    pub fn leg() -> Self {
        PidGains {
            kp: lit(500.0),
            ki: lit(10_000.0),
            kd: lit(1.5),
            derivative_cutoff_hz: lit(200.0),
            derivative_uses_setpoint_velocity: true,
            kv: lit(1.0 / 0.378),
            ka: lit(0.0147),
            friction_ff: lit(0.003),
            friction_band: lit(1e-3),
            output_limit: S::one(),
            integral_limit: lit(0.25),
            deadband: S::zero(),
            anti_windup: AntiWindup::Clamp,
        }
    }

    /// The default gains of a rotating link (see the field docs).
    pub fn link() -> Self {
        PidGains {
            kp: lit(12.0),
            ki: lit(240.0),
            kd: lit(0.08),
            derivative_cutoff_hz: lit(200.0),
            derivative_uses_setpoint_velocity: true,
            kv: lit(1.0 / 28.5),
            ka: lit(5.3e-4),
            friction_ff: lit(0.004),
            friction_band: lit(0.01),
            output_limit: S::one(),
            integral_limit: lit(0.25),
            deadband: S::zero(),
            anti_windup: AntiWindup::Clamp,
        }
    }

    /// Proportional-only gains (everything else zero or off), limit 1.
    pub fn proportional(kp: S) -> Self {
        PidGains {
            kp,
            ki: S::zero(),
            kd: S::zero(),
            derivative_cutoff_hz: lit(200.0),
            derivative_uses_setpoint_velocity: true,
            kv: S::zero(),
            ka: S::zero(),
            friction_ff: S::zero(),
            friction_band: S::one(),
            output_limit: S::one(),
            integral_limit: S::one(),
            deadband: S::zero(),
            anti_windup: AntiWindup::Clamp,
        }
    }

    /// Checks every field of joint `joint`; the error names the first bad one.
    pub fn validate(&self, joint: usize) -> Result<(), ConfigError> {
        let c = Check {
            section: "pid",
            joint,
        };
        c.non_negative("kp", self.kp)?;
        c.non_negative("ki", self.ki)?;
        c.non_negative("kd", self.kd)?;
        c.positive("derivative_cutoff_hz", self.derivative_cutoff_hz)?;
        c.non_negative("kv", self.kv)?;
        c.non_negative("ka", self.ka)?;
        c.non_negative("friction_ff", self.friction_ff)?;
        c.positive("friction_band", self.friction_band)?;
        c.unit_fraction("output_limit", self.output_limit)?;
        c.non_negative("integral_limit", self.integral_limit)?;
        c.non_negative("deadband", self.deadband)?;
        if let AntiWindup::BackCalculation { tracking_gain } = self.anti_windup {
            c.non_negative("anti_windup.tracking_gain", tracking_gain)?;
        }
        Ok(())
    }
}

/// PID gains of the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidConfig<S> {
    /// Per-joint gains, joint order. Default: [`PidGains::leg`] x3, [`PidGains::link`] x3.
    pub joints: [PidGains<S>; NUM_JOINTS],
}

impl<S: Float> Default for PidConfig<S> {
    fn default() -> Self {
        let mut joints = [PidGains::leg(); NUM_JOINTS];
        for (j, g) in joints.iter_mut().enumerate() {
            if !is_leg(j) {
                *g = PidGains::link();
            }
        }
        PidConfig { joints }
    }
}

impl<S: Float> PidConfig<S> {
    /// Checks every joint; the error names the first bad field and its joint.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (j, g) in self.joints.iter().enumerate() {
            g.validate(j)?;
        }
        Ok(())
    }
}

/// One sample's input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidInput<S> {
    /// Position setpoint `r`, u.
    pub setpoint: S,
    /// Desired velocity `r_dot`, u/s (feed-forward and D term).
    pub setpoint_velocity: S,
    /// Desired acceleration `r_ddot`, u/s^2 (feed-forward only).
    pub setpoint_acceleration: S,
    /// Measured position `y`, u.
    pub measured: S,
}

impl<S: Float> PidInput<S> {
    /// A position-only input (zero desired velocity and acceleration).
    pub fn new(setpoint: S, measured: S) -> Self {
        PidInput {
            setpoint,
            setpoint_velocity: S::zero(),
            setpoint_acceleration: S::zero(),
            measured,
        }
    }

    /// The same input with desired velocity `v`.
    pub fn with_velocity(mut self, v: S) -> Self {
        self.setpoint_velocity = v;
        self
    }

    /// The same input with desired acceleration `a`.
    pub fn with_acceleration(mut self, a: S) -> Self {
        self.setpoint_acceleration = a;
        self
    }
}

/// Why a sample was rejected (duty 0, state untouched).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputError {
    /// The position setpoint is NaN or infinite.
    NonFiniteSetpoint,
    /// The desired velocity is NaN or infinite.
    NonFiniteVelocity,
    /// The desired acceleration is NaN or infinite.
    NonFiniteAcceleration,
    /// The measured position is NaN or infinite.
    NonFiniteMeasurement,
    /// The sample time is not finite and > 0.
    InvalidTimeStep,
}

impl<S: Float> PidInput<S> {
    /// The first problem of this input and `dt`, if any.
    pub fn check(&self, dt: S) -> Option<InputError> {
        if !self.setpoint.is_finite() {
            Some(InputError::NonFiniteSetpoint)
        } else if !self.setpoint_velocity.is_finite() {
            Some(InputError::NonFiniteVelocity)
        } else if !self.setpoint_acceleration.is_finite() {
            Some(InputError::NonFiniteAcceleration)
        } else if !self.measured.is_finite() {
            Some(InputError::NonFiniteMeasurement)
        } else if !valid_dt(dt) {
            Some(InputError::InvalidTimeStep)
        } else {
            None
        }
    }
}

/// The terms that made up a sample's output (before saturation), duty.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PidTerms<S> {
    /// Proportional term.
    pub p: S,
    /// Integral term (the value used in this sample).
    pub i: S,
    /// Derivative term.
    pub d: S,
    /// Feed-forward (velocity + acceleration + friction).
    pub ff: S,
}

/// One sample's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidOutput<S> {
    /// Duty, within `[-output_limit, output_limit]`, always finite; 0 on an input error.
    pub duty: S,
    /// The unsaturated sum was beyond the output limit.
    pub saturated: bool,
    /// The input was rejected (then `duty` is 0).
    pub error: Option<InputError>,
    /// The terms, for logging and tuning.
    pub terms: PidTerms<S>,
}

impl<S: Float> PidOutput<S> {
    fn rejected(error: InputError) -> Self {
        PidOutput {
            duty: S::zero(),
            saturated: false,
            error: Some(error),
            terms: PidTerms {
                p: S::zero(),
                i: S::zero(),
                d: S::zero(),
                ff: S::zero(),
            },
        }
    }
}

/// PID controller state of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pid<S> {
    gains: PidGains<S>,
    /// Integral term, duty.
    integral: S,
    /// Measured position of the previous sample, u.
    prev_measured: S,
    /// Low-pass filtered measured velocity, u/s.
    velocity: S,
    /// `prev_measured` holds a measurement.
    primed: bool,
    /// The exponential coefficients for the last sample time (the control rate is
    /// fixed, and `exp` is ~60 instructions per call on the Cortex-M4); unprepared
    /// ([`Coefficients::unprepared`]) until the first sample after new gains.
    coefficients: Coefficients<S>,
}

/// What one sample needs of the gains and the sample time, prepared once per gains and
/// `dt` (the control rate is fixed): `a = 1 - exp(-2π fc dt)`, `b = 1 - exp(-kt dt)`,
/// `1 / dt`, and the sanitized limits (a NaN, negative or infinite limit taken as the
/// per-field rule of [`sane_limit`]), so that a sample only multiplies, adds and compares.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Coefficients<S> {
    /// The sample time they are for; 0 (never a valid one) while unprepared.
    dt: S,
    a: S,
    b: S,
    /// `1 / dt`.
    inv_dt: S,
    /// The output limit, in `[0, 1]`.
    limit: S,
    /// The deadband, `>= 0`.
    deadband: S,
    /// The integral limit, `>= 0`.
    integral_limit: S,
    /// `1 / friction_band` (1 when the band is not positive).
    inv_band: S,
}

impl<S: Float> Coefficients<S> {
    /// Coefficients of no sample time (`dt` 0): the next sample prepares them.
    fn unprepared() -> Self {
        let zero = S::zero();
        Coefficients {
            dt: zero,
            a: zero,
            b: zero,
            inv_dt: zero,
            limit: zero,
            deadband: zero,
            integral_limit: zero,
            inv_band: zero,
        }
    }
}

impl<S: Float> Pid<S> {
    /// A controller with `gains` (use [`PidGains::validate`] first; invalid gains never
    /// produce an invalid duty, but their behaviour is unspecified). The first update
    /// primes the derivative with its measurement (no kick).
    pub fn new(gains: PidGains<S>) -> Self {
        Pid {
            gains,
            integral: S::zero(),
            prev_measured: S::zero(),
            velocity: S::zero(),
            primed: false,
            coefficients: Coefficients::unprepared(),
        }
    }

    /// The gains.
    pub fn gains(&self) -> &PidGains<S> {
        &self.gains
    }

    /// Replaces the gains, keeping the state (bumpless: the integral is stored as duty).
    pub fn set_gains(&mut self, gains: PidGains<S>) {
        self.gains = gains;
        self.coefficients = Coefficients::unprepared();
        let limit = sane_limit(gains.integral_limit, S::max_value());
        self.integral = clamp_sym(self.integral, limit);
    }

    /// Bumpless reset: integral 0, filtered velocity 0, and `measured` taken as the
    /// previous measurement so the next update has no derivative kick. A non-finite
    /// `measured` makes the next update prime itself instead.
    pub fn reset(&mut self, measured: S) {
        self.reset_with_integral(measured, S::zero());
    }

    /// Like [`reset`](Self::reset) but preloads the integral with `integral` (duty,
    /// bounded by the integral limit), e.g. the duty that was holding the joint, for a
    /// bumpless transfer from another controller.
    pub fn reset_with_integral(&mut self, measured: S, integral: S) {
        let limit = sane_limit(self.gains.integral_limit, S::max_value());
        self.integral = clamp_sym(integral, limit);
        self.velocity = S::zero();
        self.prev_measured = measured;
        self.primed = measured.is_finite();
    }

    /// The integral term, duty.
    pub fn integral(&self) -> S {
        self.integral
    }

    /// The low-pass filtered measured velocity, u/s.
    pub fn filtered_velocity(&self) -> S {
        self.velocity
    }

    /// Makes the kept coefficients those of `dt` (computed once per gains and sample
    /// time: a valid `dt` is never 0, the `dt` of the unprepared coefficients).
    #[inline(always)]
    fn prepare_for(&mut self, dt: S) {
        if self.coefficients.dt != dt {
            self.prepare(dt);
        }
    }

    /// Computes and keeps the coefficients of `dt` (out of line: it runs once per gains
    /// and sample time, and its two `exp` need not be inlined in every caller).
    #[inline(never)]
    fn prepare(&mut self, dt: S) {
        let g = &self.gains;
        let kt = match g.anti_windup {
            AntiWindup::BackCalculation { tracking_gain } => {
                sane_limit(tracking_gain, S::max_value())
            }
            _ => S::zero(),
        };
        let max = S::max_value();
        let band = if g.friction_band > S::zero() {
            g.friction_band
        } else {
            S::one()
        };
        self.coefficients = Coefficients {
            dt,
            // a = 1 - exp(-2 pi fc dt), in [0, 1] for every dt > 0 (stable at any rate).
            a: clamp(
                S::one() - (-lit::<S>(core::f64::consts::TAU) * g.derivative_cutoff_hz * dt).exp(),
                S::zero(),
                S::one(),
            ),
            b: clamp(S::one() - (-kt * dt).exp(), S::zero(), S::one()),
            inv_dt: sane_limit(S::one() / dt, max),
            limit: sane_limit(g.output_limit, S::one()),
            deadband: sane_limit(g.deadband, max),
            integral_limit: sane_limit(g.integral_limit, max),
            inv_band: sane_limit(S::one() / band, max),
        };
    }

    /// One sample: computes the duty from `input` with sample time `dt` (s).
    ///
    /// With finite inputs, a valid `dt` and valid gains no intermediate value can be NaN
    /// (the coefficients are sanitized, each product is of two finite factors), so the
    /// intermediate bounds are plain comparisons ([`bound`]); the one NaN that invalid
    /// gains could make is caught on the sum, which then gives duty 0 and keeps the state.
    /// (The bounds only act for absurd values: a sample is first computed without them,
    /// and again with them when one of them could act; the result is the same.)
    pub fn update(&mut self, input: &PidInput<S>, dt: S) -> PidOutput<S> {
        if let Some(error) = input.check(dt) {
            return PidOutput::rejected(error);
        }
        self.update_checked(input, dt)
    }

    /// [`update`](Self::update) of an input that passed [`PidInput::check`] with `dt`
    /// (finite values, valid `dt`); for [`JointServo`](crate::JointServo), which checks
    /// its inputs once for the whole chain. Inlined there, so that the terms it does not
    /// use are never stored.
    ///
    /// The law's bounds on the terms and on the intermediate values only act for absurd
    /// values (beyond `1e9` duty or the scalar's range), so the sample is first computed
    /// without them ([`Pid::terms_unbounded`]) and one test on the sum of the terms'
    /// magnitudes shows that none of them could have acted; otherwise (never for a sane
    /// configuration and sane inputs) it is computed again with every bound
    /// ([`Pid::terms_bounded`]). Both give the same values, to the bit.
    #[inline(always)]
    pub(crate) fn update_checked(&mut self, input: &PidInput<S>, dt: S) -> PidOutput<S> {
        self.sample::<true>(input, dt)
    }

    /// One sample of a checked input; `UNBOUNDED_FIRST`: try the terms without their
    /// bounds first (`false` only in the tests, which compare the two ways).
    #[inline(always)]
    fn sample<const UNBOUNDED_FIRST: bool>(&mut self, input: &PidInput<S>, dt: S) -> PidOutput<S> {
        self.prepare_for(dt);
        if !self.primed {
            // First sample: no previous measurement, so no velocity yet (no kick).
            self.prev_measured = input.measured;
            self.velocity = S::zero();
            self.primed = true;
        }
        let unbounded = if UNBOUNDED_FIRST {
            self.terms_unbounded(input, dt)
        } else {
            None
        };
        let t = match unbounded {
            Some(t) => t,
            None => match self.terms_bounded(input, dt) {
                Some(t) => t,
                // Only invalid (non-finite) gains get here: the safe output, state kept.
                None => {
                    return PidOutput {
                        duty: S::zero(),
                        saturated: false,
                        error: None,
                        terms: PidTerms {
                            p: S::zero(),
                            i: S::zero(),
                            d: S::zero(),
                            ff: S::zero(),
                        },
                    }
                }
            },
        };
        let coef = &self.coefficients;
        let limit = coef.limit;
        let i = self.integral;
        let u_raw = t.p + i + t.d + t.ff;
        self.prev_measured = input.measured;
        self.velocity = t.velocity;
        // (`u_raw` is not NaN: one test on its magnitude for both the bound and the flag.)
        let saturated = u_raw.abs() > limit;
        let u = if !saturated {
            u_raw
        } else if u_raw > S::zero() {
            limit
        } else {
            -limit
        };

        // Integral update (forward Euler) with the chosen anti-windup.
        let next = match self.gains.anti_windup {
            AntiWindup::None => i + t.step,
            // Conditional integration: skip an update that pushes further into saturation.
            AntiWindup::Clamp => {
                if saturated && sign(t.e_db) == sign(u_raw) {
                    i
                } else {
                    i + t.step
                }
            }
            // Back-calculation: I += ki e dt + (1 - exp(-kt dt)) (u - u_raw).
            AntiWindup::BackCalculation { .. } => i + t.step + coef.b * (u - u_raw),
        };
        // Within the limit (the usual case) at one test; else bounded (NaN, which invalid
        // gains can make of the step, gives 0).
        self.integral = if next.abs() <= coef.integral_limit {
            next
        } else {
            clamp_sym(next, coef.integral_limit)
        };

        PidOutput {
            duty: u,
            saturated,
            error: None,
            terms: PidTerms {
                p: t.p,
                i,
                d: t.d,
                ff: t.ff,
            },
        }
    }

    /// The terms of the law without its bounds, when none of the bounds would act: every
    /// term within `TERM_BOUND` (tested on the sum of their magnitudes, which is at least
    /// each of them) implies that every intermediate value was finite (an infinite one
    /// makes a term infinite or NaN: each is a product with a finite factor, and a NaN
    /// fails the test), so that [`Pid::terms_bounded`] would give the same values.
    #[inline(always)]
    fn terms_unbounded(&self, input: &PidInput<S>, dt: S) -> Option<Terms<S>> {
        let g = &self.gains;
        let coef = &self.coefficients;
        let y = input.measured;
        let r_dot = input.setpoint_velocity;
        let e = input.setpoint - y;
        let e_db = if coef.deadband > S::zero() {
            sign(e) * bound_below(e.abs() - coef.deadband, S::zero())
        } else {
            e
        };
        let p = g.kp * e_db;
        let v_raw = (y - self.prev_measured) * coef.inv_dt;
        let velocity = self.velocity + coef.a * (v_raw - self.velocity);
        let v_ref = if g.derivative_uses_setpoint_velocity {
            r_dot
        } else {
            S::zero()
        };
        let d = g.kd * (v_ref - velocity);
        let ff_v = g.kv * r_dot;
        let ff_a = g.ka * input.setpoint_acceleration;
        let ff_f = g.friction_ff * bound(r_dot * coef.inv_band, S::one());
        let step = g.ki * e_db * dt;
        let size = p.abs() + d.abs() + ff_v.abs() + ff_a.abs() + ff_f.abs() + step.abs();
        if size <= lit(TERM_BOUND) {
            Some(Terms {
                e_db,
                p,
                velocity,
                d,
                ff: ff_v + ff_a + ff_f,
                step,
            })
        } else {
            None
        }
    }

    /// The terms of the law with every bound; `None` when the sum of the terms is NaN
    /// (only invalid gains can make it so).
    #[inline(never)]
    fn terms_bounded(&self, input: &PidInput<S>, dt: S) -> Option<Terms<S>> {
        let g = &self.gains;
        let coef = &self.coefficients;
        let big = lit::<S>(TERM_BOUND);
        let max = S::max_value();
        let y = input.measured;
        let r_dot = input.setpoint_velocity;

        // Position error, kept finite for finite inputs of opposite huge values.
        let e = bound(input.setpoint - y, max);
        // Deadband: shrink |e| by the width (continuous, so no bump at the edge).
        let e_db = if coef.deadband > S::zero() {
            sign(e) * bound_below(e.abs() - coef.deadband, S::zero())
        } else {
            e
        };
        // Proportional term.
        let p = bound(g.kp * e_db, big);

        // Measured velocity by backward difference.
        let v_raw = bound((y - self.prev_measured) * coef.inv_dt, max);
        // First-order low-pass, exact for a constant input over the sample.
        let velocity = bound(self.velocity + coef.a * (v_raw - self.velocity), max);
        // Derivative on the measurement: damps the measured velocity (or the velocity
        // error against the desired velocity), never the change of the position error.
        let v_ref = if g.derivative_uses_setpoint_velocity {
            r_dot
        } else {
            S::zero()
        };
        let d = bound(g.kd * bound(v_ref - velocity, max), big);

        // Feed-forward: velocity, acceleration, and Coulomb friction ramped in over
        // `friction_band` around zero desired speed.
        let ff = bound(g.kv * r_dot, big)
            + bound(g.ka * input.setpoint_acceleration, big)
            + bound(g.friction_ff * bound(r_dot * coef.inv_band, S::one()), big);

        // The integral step (forward Euler).
        let step = bound(g.ki * e_db * dt, big);

        if (p + self.integral + d + ff).is_nan() {
            return None;
        }
        Some(Terms {
            e_db,
            p,
            velocity,
            d,
            ff,
            step,
        })
    }
}

/// What one sample computes before the output and the integral: the error after the
/// deadband, the P, D and feed-forward terms, the new filtered velocity and the integral
/// step (duty; velocity in u/s).
#[derive(Clone, Copy)]
struct Terms<S> {
    e_db: S,
    p: S,
    velocity: S,
    d: S,
    ff: S,
    step: S,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use proptest::prelude::*;

    /// [`Pid::update`] with every bound applied (the law as written), for comparison.
    fn update_bounded<S: Float>(pid: &mut Pid<S>, input: &PidInput<S>, dt: S) -> PidOutput<S> {
        match input.check(dt) {
            Some(error) => PidOutput::rejected(error),
            None => pid.sample::<false>(input, dt),
        }
    }

    /// The output and the state, bit for bit (so that `-0.0 != 0.0` and NaN == NaN); an
    /// f32 through f64, which is exact.
    fn bits<S: Float>(out: &PidOutput<S>, pid: &Pid<S>) -> [u64; 9] {
        let b = |x: S| x.to_f64().map_or(u64::MAX, f64::to_bits);
        [
            b(out.duty),
            u64::from(out.saturated),
            u64::from(out.error.is_some()),
            b(out.terms.p),
            b(out.terms.i),
            b(out.terms.d),
            b(out.terms.ff),
            b(pid.integral()),
            b(pid.filtered_velocity()),
        ]
    }

    /// Moderate values most of the time, any finite one (huge, tiny) sometimes: both the
    /// unbounded and the bounded way are taken.
    fn value() -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => -1.0f64..1.0,
            2 => -1e4f64..1e4,
            1 => prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO,
        ]
    }

    /// A gain: 0, moderate, or any positive finite value.
    fn gain() -> impl Strategy<Value = f64> {
        prop_oneof![
            1 => Just(0.0),
            4 => 0.0f64..1e4,
            1 => prop::num::f64::POSITIVE.prop_filter("finite", |x| x.is_finite()),
        ]
    }

    fn gains() -> impl Strategy<Value = PidGains<f64>> {
        (
            (gain(), gain(), gain(), 1e-3f64..1e6, gain(), gain(), gain()),
            (
                1e-9f64..10.0,
                0.01f64..=1.0,
                gain(),
                0.0f64..1e-3,
                0u8..3,
                gain(),
            ),
            any::<bool>(),
        )
            .prop_map(
                |((kp, ki, kd, fc, kv, ka, ff), (band, limit, ilimit, db, aw, kt), dusv)| {
                    PidGains {
                        kp,
                        ki,
                        kd,
                        derivative_cutoff_hz: fc,
                        derivative_uses_setpoint_velocity: dusv,
                        kv,
                        ka,
                        friction_ff: ff,
                        friction_band: band,
                        output_limit: limit,
                        integral_limit: ilimit,
                        deadband: db,
                        anti_windup: match aw {
                            0 => AntiWindup::None,
                            1 => AntiWindup::Clamp,
                            _ => AntiWindup::BackCalculation { tracking_gain: kt },
                        },
                    }
                },
            )
    }

    fn gains32(g: &PidGains<f64>) -> PidGains<f32> {
        PidGains {
            kp: g.kp as f32,
            ki: g.ki as f32,
            kd: g.kd as f32,
            derivative_cutoff_hz: g.derivative_cutoff_hz as f32,
            derivative_uses_setpoint_velocity: g.derivative_uses_setpoint_velocity,
            kv: g.kv as f32,
            ka: g.ka as f32,
            friction_ff: g.friction_ff as f32,
            friction_band: g.friction_band as f32,
            output_limit: g.output_limit as f32,
            integral_limit: g.integral_limit as f32,
            deadband: g.deadband as f32,
            anti_windup: match g.anti_windup {
                AntiWindup::None => AntiWindup::None,
                AntiWindup::Clamp => AntiWindup::Clamp,
                AntiWindup::BackCalculation { tracking_gain } => AntiWindup::BackCalculation {
                    tracking_gain: tracking_gain as f32,
                },
            },
        }
    }

    proptest! {
        #![proptest_config(proptest_config::cases(512))]

        /// Property: computing the terms without their bounds when none of them would
        /// act gives the law with every bound, to the bit: output, terms and state, for
        /// any valid gains and any finite inputs and time steps (f64 and f32, where the
        /// values overflow much sooner).
        #[test]
        fn the_unbounded_terms_give_the_bounded_law_to_the_bit(
            g in gains(),
            samples in prop::collection::vec(
                (value(), value(), value(), value(), prop_oneof![
                    4 => Just(1e-3),
                    1 => 1e-5f64..1.0,
                    1 => prop::num::f64::POSITIVE.prop_filter("finite", |x| x.is_finite()),
                ]),
                1..40,
            ),
        ) {
            prop_assert!(g.validate(0).is_ok());
            let (mut fast, mut law) = (Pid::new(g), Pid::new(g));
            let g32 = gains32(&g);
            let (mut fast32, mut law32) = (Pid::new(g32), Pid::new(g32));
            for (r, v, a, y, dt) in samples {
                let input = PidInput { setpoint: r, setpoint_velocity: v, setpoint_acceleration: a, measured: y };
                let out = fast.update(&input, dt);
                let expected = update_bounded(&mut law, &input, dt);
                prop_assert_eq!(bits(&out, &fast), bits(&expected, &law));
                prop_assert_eq!(fast, law);

                let input = PidInput {
                    setpoint: r as f32,
                    setpoint_velocity: v as f32,
                    setpoint_acceleration: a as f32,
                    measured: y as f32,
                };
                let out = fast32.update(&input, dt as f32);
                let expected = update_bounded(&mut law32, &input, dt as f32);
                prop_assert_eq!(bits(&out, &fast32), bits(&expected, &law32));
                prop_assert_eq!(fast32, law32);
            }
        }
    }

    /// Inputs for the refresh tests: a moving setpoint and measurement.
    fn input(k: usize) -> PidInput<f64> {
        let t = k as f64;
        PidInput::new(2e-3 * (0.3 * t).sin(), 1.6e-3 * (0.3 * t - 0.4).sin())
            .with_velocity(2e-3 * (0.3 * t).cos())
            .with_acceleration(0.5 * (0.2 * t).sin())
    }

    /// The coefficients kept per gains and sample time are those of the current gains
    /// and `dt`: after new gains, or a new `dt`, a controller that ran before gives what
    /// a new one in the same state gives.
    #[test]
    fn new_gains_and_a_new_time_step_take_effect_at_once() {
        let first = PidGains::<f64>::leg();
        let mut second = PidGains::link();
        second.derivative_cutoff_hz = 35.0;
        second.output_limit = 0.004;
        second.integral_limit = 0.01;
        second.deadband = 2e-4;
        second.friction_band = 3e-3;
        second.anti_windup = AntiWindup::BackCalculation {
            tracking_gain: 40.0,
        };
        for (gains_then, dt_then, dt_now) in [
            (first, 1e-3, 1e-3),    // new gains, same dt
            (second, 1e-3, 2.5e-4), // same gains, new dt
            (first, 1e-4, 3e-3),    // new gains and new dt
        ] {
            let mut pid = Pid::new(gains_then);
            for k in 0..30 {
                pid.update(&input(k), dt_then);
            }
            // The same state as a new controller's (the kept coefficients aside).
            if gains_then != second {
                pid.set_gains(second);
            }
            pid.reset(input(30).measured);
            let mut fresh = Pid::new(second);
            fresh.reset(input(30).measured);
            for k in 31..200 {
                let (out, expected) = (
                    pid.update(&input(k), dt_now),
                    fresh.update(&input(k), dt_now),
                );
                assert_eq!(out, expected, "sample {k}");
            }
            assert_eq!(pid.integral(), fresh.integral());
        }
    }
}
