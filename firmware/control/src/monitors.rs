//! The plausibility monitors that run on every tick, in every state, on what the tick
//! measured: the encoders (a jump beyond the joint's top speed; a dead encoder while the
//! motor's back-EMF says it turns), the joint ranges and the limit switches, the power stage
//! (supply voltage, driver fault output), the safety chain (the e-stop button against the
//! safety relay's feedback) and the standstill of a safe operating stop. Each finding names
//! its cause, the joint and the value ([`Finding`]).

use master_link::{FaultCause, FaultRecord, NO_JOINT};
use num_traits::Float;
use servo::NUM_JOINTS;

use crate::current::MotorModel;
use crate::scalar::lit;

/// A fault a monitor found: cause, joint (None: not a joint's) and value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Finding {
    /// The cause.
    pub cause: FaultCause,
    /// The joint.
    pub joint: Option<usize>,
    /// The value (units: see [`FaultCause`]).
    pub value: f32,
}

impl Finding {
    /// A finding about joint `joint`.
    pub fn joint<S: Float>(cause: FaultCause, joint: usize, value: S) -> Self {
        Finding {
            cause,
            joint: Some(joint),
            value: value.to_f32().unwrap_or(f32::NAN),
        }
    }
    /// A finding about the board.
    pub fn board<S: Float>(cause: FaultCause, value: S) -> Self {
        Finding {
            cause,
            joint: None,
            value: value.to_f32().unwrap_or(f32::NAN),
        }
    }
    /// The record for the status and the log, at `now_us`.
    pub fn record(&self, now_us: u64) -> FaultRecord {
        FaultRecord {
            cause: self.cause,
            joint: self
                .joint
                .and_then(|j| u8::try_from(j).ok())
                .unwrap_or(NO_JOINT),
            value: self.value,
            time_ms: u32::try_from(now_us / 1000).unwrap_or(u32::MAX),
        }
    }
}

/// Encoder plausibility settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderCheckConfig<S> {
    /// Counts per joint unit (m or rad), joint order.
    pub counts_per_unit: [S; NUM_JOINTS],
    /// Top speed of each joint (its motor's no-load speed at the supply), m/s or rad/s.
    pub top_speed: [S; NUM_JOINTS],
    /// Margin on the top speed for the jump check (default 1.5).
    pub jump_margin: S,
    /// Motor speed below which the back-EMF estimate is never trusted, rad/s of the motor
    /// (default 3 rad/s).
    pub emf_floor_rad_s: S,
    /// The winding's resistance may differ from the model by this fraction (a warm
    /// winding, the brushes; default 0.3): the back-EMF estimate `V·d − R·i` is trusted
    /// only above `(this·R·|i| + emf_noise_v) / Ke`, so that a current the model's
    /// resistance gets wrong cannot fake motion.
    pub resistance_uncertainty: S,
    /// Voltage error of the estimate besides the resistance (the duty's resolution, the
    /// supply's sensing, the current's; default 0.05 V).
    pub emf_noise_v: S,
    /// Consecutive ticks the back-EMF and the encoder must disagree (default 5).
    pub dead_ticks: u16,
    /// Current below which a motor counts as drawing none, A (default 0.05 A, ten ADC
    /// counts): with no current flowing, `V·d` across the terminals reads as back-EMF
    /// whether the motor spins or its circuit is open. A motor that drew current within
    /// `current_memory_ticks` has a closed circuit, so its back-EMF is believed; one that
    /// has drawn none for longer is the motor check's to judge (`MotorCheck`: open).
    pub current_floor_a: S,
    /// See `current_floor_a` (default 100 ticks).
    pub current_memory_ticks: u16,
}

impl<S: Float> EncoderCheckConfig<S> {
    /// The reference robot's: the motors of [`MotorModel::leg`] / [`MotorModel::link`] at
    /// 24 V, the encoders of `servo::encoder`.
    pub fn reference(counts_per_unit: [S; NUM_JOINTS]) -> Self {
        let (leg, link) = (MotorModel::<S>::leg(), MotorModel::<S>::link());
        let top =
            |m: &MotorModel<S>| lit::<S>(24.0) / m.back_emf_v_s_per_rad / m.motor_rad_per_unit;
        EncoderCheckConfig {
            counts_per_unit,
            top_speed: [
                top(&leg),
                top(&leg),
                top(&leg),
                top(&link),
                top(&link),
                top(&link),
            ],
            jump_margin: lit(1.5),
            emf_floor_rad_s: lit(3.0),
            resistance_uncertainty: lit(0.3),
            emf_noise_v: lit(0.05),
            dead_ticks: 5,
            current_floor_a: lit(0.05),
            current_memory_ticks: 100,
        }
    }
}

/// What drove the motors over the last tick, for the back-EMF check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSample<S> {
    /// The duties applied over the tick.
    pub duty: [S; NUM_JOINTS],
    /// The currents measured at its end, A.
    pub current: [S; NUM_JOINTS],
    /// The supply, V.
    pub supply_v: S,
    /// The drives produced torque.
    pub torque: bool,
}

/// The encoder plausibility monitor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderCheck<S> {
    cfg: EncoderCheckConfig<S>,
    last_counts: Option<[i64; NUM_JOINTS]>,
    disagree: [u16; NUM_JOINTS],
    /// Ticks since each motor last drew current above the floor.
    no_current: [u16; NUM_JOINTS],
    /// Joint speeds from the last two readings, m/s or rad/s.
    qdot: [S; NUM_JOINTS],
    /// One count over the last tick, m/s or rad/s.
    qdot_step: [S; NUM_JOINTS],
}

impl<S: Float> EncoderCheck<S> {
    /// No reading yet.
    pub fn new(cfg: EncoderCheckConfig<S>) -> Self {
        EncoderCheck {
            cfg,
            last_counts: None,
            disagree: [0; NUM_JOINTS],
            no_current: [u16::MAX; NUM_JOINTS],
            qdot: [S::zero(); NUM_JOINTS],
            qdot_step: [S::zero(); NUM_JOINTS],
        }
    }

    /// The joint speeds of the last two readings (m/s, rad/s).
    pub fn qdot(&self) -> &[S; NUM_JOINTS] {
        &self.qdot
    }

    /// The resolution of [`EncoderCheck::qdot`]: one count over the last tick, m/s or
    /// rad/s per joint (a joint creeping at less than that reads 0 or one count a tick:
    /// its speed is known to within this, no better).
    pub fn qdot_resolution(&self) -> &[S; NUM_JOINTS] {
        &self.qdot_step
    }

    /// Checks this tick's extended counts `counts`, `dt` s after the last ones, against
    /// the motor model: a jump (more counts than the top speed allows, with margin), and,
    /// while the drives produce torque, a dead or failing encoder: the back-EMF
    /// `Ke·ω = V·d − R·i` of the last tick's duty and the measured current says the motor
    /// turns faster than the estimate's own uncertainty at that current
    /// (`(k_R·R·|i| + e_V)/Ke`, at least the floor), and the encoder says it turns at less
    /// than half of that, or the other way, for `dead_ticks` ticks.
    pub fn check(
        &mut self,
        counts: &[i64; NUM_JOINTS],
        dt: S,
        motors: &[MotorModel<S>; NUM_JOINTS],
        drive: &DriveSample<S>,
    ) -> Option<Finding> {
        let last = self.last_counts.replace(*counts)?;
        let (duty, current, supply_v, torque) =
            (&drive.duty, &drive.current, drive.supply_v, drive.torque);
        let mut found = None;
        for j in 0..NUM_JOINTS {
            let (Some(c), Some(l), Some(cpu), Some(top), Some(m)) = (
                counts.get(j),
                last.get(j),
                self.cfg.counts_per_unit.get(j),
                self.cfg.top_speed.get(j),
                motors.get(j),
            ) else {
                continue;
            };
            let delta = c.wrapping_sub(*l);
            let dq = S::from(delta).unwrap_or_else(S::zero) / *cpu;
            let speed = if dt > S::zero() { dq / dt } else { S::zero() };
            if let Some(q) = self.qdot.get_mut(j) {
                *q = speed;
            }
            if let Some(r) = self.qdot_step.get_mut(j) {
                *r = if dt > S::zero() && *cpu > S::zero() {
                    S::one() / (*cpu * dt)
                } else {
                    S::zero()
                };
            }
            // Jump: more counts in one tick than the top speed allows.
            let max_counts = *top * self.cfg.jump_margin * dt * *cpu + lit(2.0);
            let counts_abs = S::from(delta.unsigned_abs()).unwrap_or_else(S::infinity);
            if counts_abs > max_counts && found.is_none() {
                found = Some(Finding::joint(FaultCause::EncoderJump, j, counts_abs));
            }
            // Dead: the back-EMF says the motor turns, the encoder does not.
            let n = self.disagree.get_mut(j);
            let (Some(n), Some(d), Some(i), Some(quiet)) =
                (n, duty.get(j), current.get(j), self.no_current.get_mut(j))
            else {
                continue;
            };
            *quiet = if i.abs() >= self.cfg.current_floor_a {
                0
            } else {
                quiet.saturating_add(1)
            };
            let circuit_closed = *quiet <= self.cfg.current_memory_ticks;
            let emf_speed = (supply_v * *d - m.resistance_ohm * *i) / m.back_emf_v_s_per_rad;
            let enc_speed = speed * m.motor_rad_per_unit;
            let trusted = ((self.cfg.resistance_uncertainty * m.resistance_ohm * i.abs()
                + self.cfg.emf_noise_v)
                / m.back_emf_v_s_per_rad)
                .max(self.cfg.emf_floor_rad_s);
            // The model must explain the current: three times what the duty drives at the
            // encoder's speed is a winding short or a failed stage (the motor check's), and
            // then `V·d − R·i` says nothing about the speed.
            let explained = (*i
                - (supply_v * *d - m.back_emf_v_s_per_rad * enc_speed) / m.resistance_ohm)
                .abs()
                <= lit::<S>(2.0)
                    * ((supply_v * *d - m.back_emf_v_s_per_rad * enc_speed) / m.resistance_ohm)
                        .abs()
                        .max(self.cfg.current_floor_a);
            let disagrees = torque
                && emf_speed.is_finite()
                && circuit_closed
                && explained
                && emf_speed.abs() > trusted
                && (enc_speed.abs() < emf_speed.abs() * lit(0.5)
                    || enc_speed.signum() != emf_speed.signum());
            *n = if disagrees { n.saturating_add(1) } else { 0 };
            if *n >= self.cfg.dead_ticks && found.is_none() {
                // The motion the model expects over the window, counts.
                let expected = emf_speed / m.motor_rad_per_unit
                    * dt
                    * *cpu
                    * S::from(self.cfg.dead_ticks).unwrap_or_else(S::one);
                found = Some(Finding::joint(FaultCause::EncoderDead, j, expected));
            }
        }
        found
    }

    /// Forgets the last reading (a new reference after homing keeps the counts, so this is
    /// only for a restart of the counters).
    pub fn restart(&mut self) {
        self.last_counts = None;
        self.disagree = [0; NUM_JOINTS];
    }
}

/// Weight of a new sample in the motor check's filters (time constant about 1.4 ticks).
const MOTOR_FILTER: f64 = 0.5;

/// The motor circuits' plausibility: with the drives on, the current the motor model
/// expects for the last tick's duty at the measured speed, `i = (V·d − Ke·ω)/R` (capped at
/// the drivers' regulation limit), must flow.
/// * **Open circuit** (a broken lead or connector: the joint is held by nothing but its
///   brake): the current is below a fifth of the model's, while that is above the floor,
///   and below the floor itself: a current of the floor or more flows through a closed
///   circuit (a motor turning faster than a dead encoder says draws less than the model's
///   current, not nothing: the back-EMF check names that).
///   The model is judged on the drive filtered over a few ticks
///   (`MOTOR_FILTER`, weight `a`), the current sample by sample (an open circuit shows
///   at once, before the back-EMF check takes the missing current for motion:
///   `EncoderCheck`). The speed is one tick's count difference, off by less than one
///   count a tick (`δω`, [`EncoderCheck::qdot_resolution`]); filtered, the count errors
///   telescope to less than `a` counts a tick: the filtered model's current is off by at
///   most `Ke·a·δω/R` (0.135 A on a leg, 0.017 A on a link), and the judgement starts
///   above 1.25 times that (the floor is above it). Judged on one tick's speed instead,
///   a healthy motor creeping at a count or two a tick with little load reads as open
///   whenever a tick's count falls the wrong way (one count is 0.27 A of model current
///   on a leg).
/// * **Short** (a shorted winding or a failed driver stage): a current above three times
///   the model's. The model's resistance may be 30 % off (a warm winding); a short takes
///   most of it away. Judged on one sample above a fifth of the regulation limit, or on
///   the currents filtered over about two ticks above a twentieth of it (a servo hunting
///   through zero on a short swings through small currents sample by sample; the filter
///   also averages the speed's count errors).
///
/// Each is counted per joint, two up on a sample that shows it and one down on one that
/// does not; `2 × open_ticks` counts are a fault (`open_ticks` samples in a row, or a third
/// of the samples for longer). A sample whose current is too small to show a short (under
/// a fifth of the regulation limit) leaves the short's count as it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorCheck<S> {
    /// Expected currents below this are not judged, A per joint (default 3 % of each
    /// motor's continuous current, at least 0.05 A: ten times the current sensing's
    /// resolution of 4 mA per ADC count).
    pub floor_a: [S; NUM_JOINTS],
    /// Consecutive ticks (default 5).
    pub open_ticks: u16,
    joints: [MotorFilters<S>; NUM_JOINTS],
}

/// One joint's state in the motor check.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MotorFilters<S> {
    /// The open and short counts.
    low: u16,
    high: u16,
    /// Filtered `V·d` (V) and speed (joint units/s), for the open check.
    vd: S,
    w: S,
    /// Filtered `|i|` and expected current (A), for the short check.
    short_i: S,
    short_e: S,
}

impl<S: Float> MotorFilters<S> {
    fn new() -> Self {
        MotorFilters {
            low: 0,
            high: 0,
            vd: S::zero(),
            w: S::zero(),
            short_i: S::zero(),
            short_e: S::zero(),
        }
    }
}

impl<S: Float> MotorCheck<S> {
    /// Floors of 3 % of each motor's continuous current (at least 0.05 A), 5 ticks.
    pub fn new(motors: &[MotorModel<S>; NUM_JOINTS]) -> Self {
        MotorCheck {
            floor_a: motors.map(|m| (m.continuous_a * lit(0.03)).max(lit(0.05))),
            open_ticks: 5,
            joints: [MotorFilters::new(); NUM_JOINTS],
        }
    }

    /// Checks the last tick's drive `drive` against the joint speeds `qdot` (m/s, rad/s),
    /// each off by less than `qdot_resolution` (m/s, rad/s: one count a tick), and each
    /// joint's regulation limit `limit_a` (A).
    pub fn check(
        &mut self,
        drive: &DriveSample<S>,
        qdot: &[S; NUM_JOINTS],
        qdot_resolution: &[S; NUM_JOINTS],
        motors: &[MotorModel<S>; NUM_JOINTS],
        limit_a: &[S; NUM_JOINTS],
    ) -> Option<Finding> {
        let mut found = None;
        let k: S = lit(MOTOR_FILTER);
        for j in 0..NUM_JOINTS {
            let (Some(f), Some(d), Some(i), Some(w), Some(dw), Some(m), Some(lim), Some(floor)) = (
                self.joints.get_mut(j),
                drive.duty.get(j),
                drive.current.get(j),
                qdot.get(j),
                qdot_resolution.get(j),
                motors.get(j),
                limit_a.get(j),
                self.floor_a.get(j),
            ) else {
                continue;
            };
            let omega = *w * m.motor_rad_per_unit;
            let vd = drive.supply_v * *d;
            let expected = ((vd - m.back_emf_v_s_per_rad * omega) / m.resistance_ohm)
                .abs()
                .min(*lim);
            let usable = drive.torque && vd.is_finite() && w.is_finite() && i.is_finite();
            let open = if usable {
                f.vd = f.vd + (vd - f.vd) * k;
                f.w = f.w + (*w - f.w) * k;
                // The filtered model's current, and its error from the speed's counts.
                let filtered = ((f.vd - m.back_emf_v_s_per_rad * f.w * m.motor_rad_per_unit)
                    / m.resistance_ohm)
                    .abs()
                    .min(*lim);
                let allowance =
                    m.back_emf_v_s_per_rad * k * dw.abs() * m.motor_rad_per_unit / m.resistance_ohm;
                // A sample is open when `|i| < 0.2·filtered`. A healthy motor's steady
                // current is at least `filtered − allowance`, which is at least a fifth of
                // `filtered` wherever `filtered ≥ allowance / 0.8`: judging starts there
                // or at the floor, whichever is higher (the defaults' floors are: 0.173 A
                // against 0.169 A on a leg, 0.05 A against 0.021 A on a link).
                // And a current of the floor or more (ten ADC counts) flows through a
                // closed circuit, whatever the model expects: a motor turning faster than
                // its encoder says (a dead encoder) draws less than the model's current,
                // but not nothing (the back-EMF check names that).
                let judged_from = floor.max(allowance * lit(1.25));
                filtered > judged_from && i.abs() < (filtered * lit(0.2)).min(*floor)
            } else {
                // Without torque there is nothing to judge: the filters start over.
                f.vd = S::zero();
                f.w = S::zero();
                // A drive that cannot be modelled (a non-finite current or supply) is
                // not a healthy one.
                drive.torque && !i.is_finite()
            };
            // Leaky counts: two up for a sample that shows it, one down for one that does
            // not (a servo hunting through zero on a shorted winding must not reset the
            // count each time): `open_ticks` samples in a row, or a third of the samples
            // for longer.
            f.low = if open {
                f.low.saturating_add(2)
            } else {
                f.low.saturating_sub(1)
            };
            if f.low >= self.open_ticks * 2 && found.is_none() {
                found = Some(Finding::joint(FaultCause::MotorOpen, j, *d));
            }
            // A short is judged on the currents filtered over a few ticks (measured and
            // expected): a servo hunting through zero on a shorted winding swings the
            // current through small values and back, sample by sample, where one sample
            // says little; over a few it draws several times what the model expects.
            // Judged where the filtered current is a twentieth of the regulation limit
            // or more (about 0.26 A on a leg: 65 ADC counts); below that a sample leaves
            // the count as it is. Without torque there is nothing to judge and it starts
            // over.
            let (short, judged) = if drive.torque && i.is_finite() && expected.is_finite() {
                f.short_i = f.short_i + (i.abs() - f.short_i) * k;
                f.short_e = f.short_e + (expected - f.short_e) * k;
                // One sample that shows it on its own (a large current, three times what
                // the model expects, or the floor), or the filtered currents.
                let sample = i.abs() > *lim * lit(0.2) && i.abs() > expected.max(*floor) * lit(3.0);
                let filtered = f.short_i > *lim * lit(0.05);
                (
                    sample || (filtered && f.short_i > f.short_e * lit(3.0)),
                    filtered || i.abs() > *lim * lit(0.2),
                )
            } else {
                f.short_i = S::zero();
                f.short_e = S::zero();
                (drive.torque, drive.torque)
            };
            f.high = if short {
                f.high.saturating_add(2)
            } else if !drive.torque {
                0
            } else if judged {
                f.high.saturating_sub(1)
            } else {
                f.high
            };
            if f.high >= self.open_ticks * 2 && found.is_none() {
                found = Some(Finding::joint(FaultCause::CurrentImplausible, j, i.abs()));
            }
        }
        found
    }
}

/// The measured joints against their ranges (homed only) and the limit switches outside
/// homing.
pub fn check_ranges<S: Float>(
    q: &[S; NUM_JOINTS],
    range: &[[S; 2]; NUM_JOINTS],
    switches: &[bool; NUM_JOINTS],
    homed: bool,
    homing: bool,
) -> Option<Finding> {
    if !homing {
        if let Some(j) = switches.iter().position(|s| *s) {
            let v = q.get(j).copied().unwrap_or_else(S::zero);
            return Some(Finding::joint(FaultCause::LimitSwitch, j, v));
        }
    }
    if homed {
        for (j, (x, [lo, hi])) in q.iter().zip(range.iter()).enumerate() {
            if !(*x >= *lo && *x <= *hi) {
                return Some(Finding::joint(FaultCause::JointLimit, j, *x));
            }
        }
    }
    None
}

/// Power-stage settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerConfig<S> {
    /// Supply range, V (default 20 .. 28 V for the 24 V bridges).
    pub supply_v: [S; 2],
    /// Consecutive ticks out of range that fault (default 3: rides through a sample's
    /// noise, not a sag).
    pub supply_ticks: u16,
}

impl<S: Float> Default for PowerConfig<S> {
    fn default() -> Self {
        PowerConfig {
            supply_v: [lit(20.0), lit(28.0)],
            supply_ticks: 3,
        }
    }
}

/// The supply voltage and the drivers' fault output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerCheck<S> {
    cfg: PowerConfig<S>,
    out_of_range: u16,
}

impl<S: Float> PowerCheck<S> {
    /// Nothing seen yet.
    pub fn new(cfg: PowerConfig<S>) -> Self {
        PowerCheck {
            cfg,
            out_of_range: 0,
        }
    }
    /// The supply `supply_v` is within its range.
    pub fn supply_in_range(&self, supply_v: S) -> bool {
        let [lo, hi] = self.cfg.supply_v;
        supply_v >= lo && supply_v <= hi
    }
    /// Checks the supply `supply_v` and the driver fault output `driver_fault` (only while
    /// the drivers are powered: `powered`).
    pub fn check(&mut self, supply_v: S, driver_fault: bool, powered: bool) -> Option<Finding> {
        let [lo, hi] = self.cfg.supply_v;
        let bad = !(supply_v >= lo && supply_v <= hi);
        self.out_of_range = if bad && powered {
            self.out_of_range.saturating_add(1)
        } else {
            0
        };
        if powered && driver_fault {
            return Some(Finding::board(FaultCause::DriverFault, S::one()));
        }
        if self.out_of_range >= self.cfg.supply_ticks {
            return Some(Finding::board(FaultCause::SupplyVoltage, supply_v));
        }
        None
    }
}

/// The relay test a safety-chain fault calls for: once the button and the relay have
/// disagreed, the chain is not trusted until, after a power cycle, the button is pressed
/// and the relay seen open, then released and the relay seen closed again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelayTest {
    /// The chain is trusted.
    Passed,
    /// A disagreement was latched in this power cycle: only a power cycle ends it.
    Latched,
    /// After a power cycle: press the button.
    Required,
    /// The button pressed and the relay seen open: release it.
    SeenOpen,
}

/// The safety chain: the e-stop button and the relay's feedback must agree (pressed =
/// relay open) within `debounce_ticks` (the relay's switching time); a disagreement that
/// lasts is a fault, and latches the relay test ([`RelayTest`]): the board refuses to home
/// or enable until the relay has passed it after a power cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SafetyChainCheck {
    debounce_ticks: u16,
    disagree: u16,
    test: RelayTest,
}

impl SafetyChainCheck {
    /// A relay that switches within `debounce_ticks` control periods (default 20 ms).
    pub const fn new(debounce_ticks: u16) -> Self {
        SafetyChainCheck {
            debounce_ticks,
            disagree: 0,
            test: RelayTest::Passed,
        }
    }
    /// The button and the relay agree now.
    pub fn agrees(pressed: bool, relay_open: bool) -> bool {
        pressed == relay_open
    }
    /// Checks the chain (and advances the relay test).
    pub fn check(&mut self, pressed: bool, relay_open: bool) -> Option<Finding> {
        self.test = match self.test {
            RelayTest::Required if pressed && relay_open => RelayTest::SeenOpen,
            RelayTest::SeenOpen if !pressed && !relay_open => RelayTest::Passed,
            t => t,
        };
        if Self::agrees(pressed, relay_open) {
            self.disagree = 0;
            return None;
        }
        self.disagree = self.disagree.saturating_add(1);
        (self.disagree > self.debounce_ticks).then(|| {
            self.test = RelayTest::Latched;
            let v = if pressed { 1.0f32 } else { 2.0 };
            Finding::board(FaultCause::SafetyRelayMismatch, v)
        })
    }
    /// Where the relay test stands.
    pub fn relay_test(&self) -> RelayTest {
        self.test
    }
    /// The chain is trusted (no relay test pending).
    pub fn trusted(&self) -> bool {
        self.test == RelayTest::Passed
    }
    /// At boot: the previous power cycle latched a safety-chain fault (the board kept it
    /// in its non-volatile store), so the relay must pass its test first.
    pub fn require_test(&mut self) {
        self.test = RelayTest::Required;
    }
}

/// Standstill monitoring of a hold: every measured joint within its window of where the
/// hold began.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Standstill<S> {
    window: [S; NUM_JOINTS],
    hold: Option<[S; NUM_JOINTS]>,
}

impl<S: Float> Standstill<S> {
    /// Windows per joint (m, rad).
    pub fn new(window: [S; NUM_JOINTS]) -> Self {
        Standstill { window, hold: None }
    }
    /// The reference robot's windows: 0.25 mm on the legs, 0.005 rad on the links (about
    /// twice the backlash and the encoder's resolution; a quarter of the following-error
    /// windows).
    pub fn reference() -> Self {
        let (l, r) = (lit::<S>(0.25e-3), lit::<S>(0.005));
        Self::new([l, l, l, r, r, r])
    }
    /// The windows per joint (m, rad).
    pub fn windows(&self) -> [S; NUM_JOINTS] {
        self.window
    }
    /// Starts monitoring at the joints `q`.
    pub fn start(&mut self, q: &[S; NUM_JOINTS]) {
        self.hold = Some(*q);
    }
    /// Stops monitoring.
    pub fn stop(&mut self) {
        self.hold = None;
    }
    /// Whether it monitors.
    pub fn active(&self) -> bool {
        self.hold.is_some()
    }
    /// Checks the joints `q`.
    pub fn check(&self, q: &[S; NUM_JOINTS]) -> Option<Finding> {
        let hold = self.hold?;
        for (j, ((x, h), w)) in q
            .iter()
            .zip(hold.iter())
            .zip(self.window.iter())
            .enumerate()
        {
            let d = (*x - *h).abs();
            if !(d <= *w) {
                return Some(Finding::joint(FaultCause::StandstillLost, j, *x - *h));
            }
        }
        None
    }
}
