//! Commissioning: the first power-up of a robot just built. One joint at a time, with the
//! others unpowered and their brakes applied, a bounded open-loop test checks the wiring
//! the rest of the firmware takes for granted (`CONVENTIONS.md`, "Hardware signs") and
//! reports what it found as a [`CommissionRecord`], each finding implying its fix.
//!
//! The test of joint `j`, at the control period (the runtime's `Commissioning` mode runs
//! it; no loop is closed on any sensor, so a reversed or swapped one cannot run away):
//!
//! 1. **Driver** (drives off): the drivers' fault line must read no fault; if it reads one
//!    the test ends without driving (`DRIVER_FAULT_LINE`).
//! 2. **Offset** (drives on, zero duty, brakes applied, [`CommissionConfig::offset_us`]):
//!    the mean current of the joint is the current sense's offset (`CURRENT_OFFSET` beyond
//!    [`CommissionConfig::offset_tolerance_a`]).
//! 3. **Applied** (brakes applied, [`CommissionConfig::applied_us`]): the brake check's
//!    duty (30 % of the continuous rating at stall) towards +q; a sensor that sees more
//!    than the brake check's slip says the brake did not hold.
//! 4. **Released** (brakes released, a release time at zero duty, then a duty ramp
//!    towards +q up to [`CommissionConfig::max_duty`], 90 % of the continuous rating at
//!    stall): the push ends when any sensor has seen [`CommissionConfig::target`] of
//!    motion, or at the ramp's end. The encoder that moved most (each in its own joint's
//!    units over its target), the sign of its motion, the second position channel's motion
//!    (the reference, where fitted), the scale of the two on the same flank of the
//!    backlash (the least-squares slope of the channel against the encoder over every tick
//!    from [`SCALE_FROM`] of the target to the end), the current's sign and the duty at
//!    which it moved.
//! 5. **Settle** (zero duty, brakes applied for their engage time).
//! 6. **Return** (where the push moved the joint and did not go beyond the limit): brakes
//!    released, the duty ramped as in the push but towards -q, open loop, until the sensor
//!    that measured the push (the joint's second channel where fitted, else the encoder
//!    that moved) is back where the test began, less the distance the joint coasted after
//!    the push (the return's coast, at about the push's speed, covers it), or at the
//!    ramp's end. The reversed duty moves the joint back whatever the wiring: the push
//!    showed which way that sensor runs. Then settle again, and torque off: done. The
//!    joint rests where it stood before the test (within the channel's resolution and the
//!    two coasts' difference; without the channel, within the backlash too), so the
//!    encoders' counts since boot still say where each joint is.
//!
//! Every tick, in every phase, every encoder and every channel reading is watched against
//! [`CommissionConfig::limit`] from where the test began: beyond it the test ends at once
//! (torque off, brakes applied) with `TRAVEL_EXCEEDED`. The board's monitors keep running
//! around it (overcurrent, overload, I²t, the power stage, the safety chain, encoder
//! jumps, the heartbeat); those that assume the wiring under test (the motor and encoder
//! models, the limit switches) are left to this test while it runs.

use master_link::{CommissionFindings as F, CommissionRecord};
use num_traits::Float;
use servo::NUM_JOINTS;

use crate::scalar::lit;

/// The fraction of the target travel from which the scale is measured: the backlash gap
/// (at most 0.2 mm on the legs, 20 arc-seconds on the links) is taken up well before.
pub const SCALE_FROM: f64 = 0.3;

/// The settings of a joint's test (SI: m on the legs, rad on the links; joint order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommissionConfig<S> {
    /// The push ends once any sensor has seen this much motion (default 1.5 mm, 1.5 deg).
    pub target: [S; NUM_JOINTS],
    /// The travel limit: any sensor beyond it ends the test at once (default 3 mm, 3 deg).
    pub limit: [S; NUM_JOINTS],
    /// The duty against the applied brake (the brake check's: 30 % of the continuous
    /// rating at stall).
    pub applied_duty: [S; NUM_JOINTS],
    /// The ramp's last duty with the brake released (three times the brake check's: 90 %
    /// of the continuous rating at stall, below the overload monitor's 90 % of the peak).
    pub max_duty: [S; NUM_JOINTS],
    /// Motion beyond which a brake did not hold (the brake check's 4 counts).
    pub slip: [S; NUM_JOINTS],
    /// Motion below which nothing moved (2 counts).
    pub still: [S; NUM_JOINTS],
    /// The current sense's tolerance at zero current, A (5 steps of the converter: 20 mA
    /// with the INA240's gain of 20 on 10 mΩ and a 12-bit converter on 3.3 V).
    pub offset_tolerance_a: S,
    /// Where each home switch is actuated at and below (None: the joint has none), and how
    /// far from it a joint may rest and still find it actuated (homing's switch travel).
    pub home_switch: [Option<(S, S)>; NUM_JOINTS],
    /// Tolerance of the counts per unit against the profile (default 5 %: half the 10 %
    /// of a wrong gear ratio, ten times the reference's resolution over the target).
    pub scale_tolerance: S,
    /// The offset measurement, µs.
    pub offset_us: u64,
    /// The push against the applied brake, µs.
    pub applied_us: u64,
    /// The brakes' release (and engage) time, µs.
    pub release_us: u64,
    /// The released push's ramp from 0 to `max_duty`, µs.
    pub ramp_us: u64,
}

impl<S: Float> CommissionConfig<S> {
    /// The reference robot's test: `applied_duty` the brake check's, `home_switch` the
    /// homing's, `counts_per_unit` the profile's.
    pub fn reference(
        applied_duty: [S; NUM_JOINTS],
        home_switch: [Option<(S, S)>; NUM_JOINTS],
        counts_per_unit: [S; NUM_JOINTS],
    ) -> Self {
        let deg = lit::<S>(core::f64::consts::PI / 180.0);
        let per = |leg: S, link: S| core::array::from_fn(|j| if j < 3 { leg } else { link });
        let counts = |n: f64| core::array::from_fn(|j| lit::<S>(n) / at(&counts_per_unit, j));
        CommissionConfig {
            target: per(lit(0.0015), lit::<S>(1.5) * deg),
            limit: per(lit(0.003), lit::<S>(3.0) * deg),
            applied_duty,
            max_duty: applied_duty.map(|d| d * lit(3.0)),
            slip: counts(4.0),
            still: counts(2.0),
            offset_tolerance_a: lit(0.02),
            home_switch,
            scale_tolerance: lit(0.05),
            offset_us: 50_000,
            applied_us: 40_000,
            release_us: 60_000,
            ramp_us: 600_000,
        }
    }
}

/// What the test reads each tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Readings<S> {
    /// The motors' positions by their encoders (joint units, the profile's scale).
    pub motor: [S; NUM_JOINTS],
    /// The second channel's positions, where fitted and read.
    pub absolute: Option<[S; NUM_JOINTS]>,
    /// Motor currents, A.
    pub current: [S; NUM_JOINTS],
    /// Home switches (actuated).
    pub switches: [bool; NUM_JOINTS],
    /// The drivers' fault line reads a fault.
    pub driver_fault: bool,
}

// `Settle`'s `back`: the return follows it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Driver,
    Offset { until_us: u64 },
    Applied { until_us: u64 },
    Releasing { until_us: u64 },
    Ramp { since_us: u64 },
    Settle { until_us: u64, back: bool },
    Return { since_us: u64 },
    Done,
}

/// One joint's test (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTest<S> {
    cfg: CommissionConfig<S>,
    joint: usize,
    phase: Phase,
    start_motor: [S; NUM_JOINTS],
    start_abs: Option<[S; NUM_JOINTS]>,
    /// Sum and number of current samples (offset, then while moving).
    offset_sum: S,
    offset_n: u32,
    moving_sum: S,
    moving_n: u32,
    /// The scale's first point (encoder, channel), once the channel saw `SCALE_FROM`.
    scale_from: Option<(S, S)>,
    /// The encoder the scale is measured on (the one that moved most at the first point).
    scale_k: usize,
    /// The least-squares sums of the channel (y) against that encoder (x) from the first
    /// point, each from it: n, Σx, Σy, Σx², Σxy.
    fit: [S; 5],
    applied_motion: S,
    peak: S,
    breakaway: S,
    switch_start: bool,
    switch_position: S,
    findings: F,
    record: CommissionRecord,
    /// The encoders and the channel where the test began (the return's goal).
    origin_motor: [S; NUM_JOINTS],
    origin_abs: Option<[S; NUM_JOINTS]>,
    /// The return's sensor (0..5 an encoder, 6 the joint's channel), the sign of the push's
    /// motion on it, and where it read at the push's end.
    back: Option<(usize, S, S)>,
    /// The distance the joint coasted after the push, on the return's sensor.
    coast: S,
}

impl<S: Float> JointTest<S> {
    /// The test of `joint` starting from the readings `r`.
    // Once per joint's test: cold, compiled for size (the board image's text).
    #[cold]
    pub fn start(cfg: CommissionConfig<S>, joint: usize, r: &Readings<S>) -> Self {
        let j = joint.min(NUM_JOINTS - 1);
        JointTest {
            cfg,
            joint: j,
            phase: Phase::Driver,
            start_motor: r.motor,
            start_abs: r.absolute,
            offset_sum: S::zero(),
            offset_n: 0,
            moving_sum: S::zero(),
            moving_n: 0,
            scale_from: None,
            scale_k: j,
            fit: [S::zero(); 5],
            applied_motion: S::zero(),
            peak: S::zero(),
            breakaway: S::zero(),
            switch_start: r.switches.get(j).copied().unwrap_or(false),
            switch_position: S::nan(),
            findings: F::NONE,
            origin_motor: r.motor,
            origin_abs: r.absolute,
            back: None,
            coast: S::zero(),
            record: CommissionRecord {
                joint: j as u8,
                moved_encoder: 255,
                encoder_motion: f32::NAN,
                reference_motion: f32::NAN,
                scale: f32::NAN,
                current_offset_a: f32::NAN,
                current_a: f32::NAN,
                applied_motion: f32::NAN,
                switch_position: f32::NAN,
                ..CommissionRecord::default()
            },
        }
    }

    /// The joint tested.
    pub fn joint(&self) -> usize {
        self.joint
    }

    /// The test has ended.
    pub fn done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// The record so far (final once [`JointTest::done`]).
    pub fn record(&self) -> CommissionRecord {
        self.record
    }

    /// Torque on, and the brakes released, in the current phase.
    pub fn outputs(&self) -> (bool, bool) {
        match self.phase {
            Phase::Driver | Phase::Done => (false, false),
            Phase::Offset { .. } | Phase::Settle { .. } | Phase::Applied { .. } => (true, false),
            Phase::Releasing { .. } | Phase::Ramp { .. } | Phase::Return { .. } => (true, true),
        }
    }

    /// The duties the current phase asks for at `now_us` (open loop: the tested joint's
    /// only, towards +q).
    pub fn duty(&self, now_us: u64) -> [S; NUM_JOINTS] {
        let mut duty = [S::zero(); NUM_JOINTS];
        let d = match self.phase {
            Phase::Applied { .. } => at(&self.cfg.applied_duty, self.joint),
            Phase::Ramp { since_us } => self.ramp_duty(since_us, now_us),
            Phase::Return { since_us } => -self.ramp_duty(since_us, now_us),
            _ => S::zero(),
        };
        if let Some(x) = duty.get_mut(self.joint) {
            *x = d;
        }
        duty
    }

    fn ramp_duty(&self, since_us: u64, now_us: u64) -> S {
        let t = S::from(now_us.saturating_sub(since_us)).unwrap_or_else(S::zero);
        let ramp = S::from(self.cfg.ramp_us.max(1)).unwrap_or_else(S::one);
        at(&self.cfg.max_duty, self.joint) * (t / ramp).min(S::one())
    }

    /// Each sensor's motion since the start over its joint's `scale` (encoders, then the
    /// channel's): the largest, and the encoder that moved most by that measure.
    fn motions(&self, r: &Readings<S>, scale: &[S; NUM_JOINTS]) -> (S, usize, S) {
        let mut enc = (S::zero(), 255usize);
        for k in 0..NUM_JOINTS {
            let m = ((at(&r.motor, k) - at(&self.start_motor, k)) / at(scale, k)).abs();
            if !(m <= enc.0) {
                enc = (m, k);
            }
        }
        let mut abs = S::zero();
        if let (Some(a), Some(a0)) = (r.absolute, self.start_abs) {
            for k in 0..NUM_JOINTS {
                let m = ((at(&a, k) - at(&a0, k)) / at(scale, k)).abs();
                if !(m <= abs) {
                    abs = m;
                }
            }
        }
        (enc.0.max(abs), enc.1, enc.0)
    }

    /// One tick with the readings `r` at `now_us`: advances the phases.
    pub fn step(&mut self, r: &Readings<S>, now_us: u64) {
        if self.done() {
            return;
        }
        let j = self.joint;
        let (travel, _, _) = self.motions(r, &self.cfg.limit);
        self.peak = self.peak.max(travel);
        self.record.peak_travel = f32_of(self.peak);
        if !(travel <= S::one()) {
            // Beyond the travel limit (or a reading not a number): stop at once.
            self.findings.insert(F::TRAVEL_EXCEEDED);
            self.finish(r, now_us);
            return;
        }
        let sw = r.switches.get(j).copied().unwrap_or(false);
        if sw != self.switch_start && self.switch_position.is_nan() {
            if let Some(a) = r.absolute {
                self.switch_position = at(&a, j);
            }
        }
        let current = at(&r.current, j);
        match self.phase {
            Phase::Driver => {
                if r.driver_fault {
                    self.findings.insert(F::DRIVER_FAULT_LINE);
                    self.finish(r, now_us);
                } else {
                    self.phase = Phase::Offset {
                        until_us: now_us + self.cfg.offset_us,
                    };
                }
            }
            Phase::Offset { until_us } => {
                self.offset_sum = self.offset_sum + current;
                self.offset_n += 1;
                if now_us >= until_us {
                    self.phase = Phase::Applied {
                        until_us: now_us + self.cfg.applied_us,
                    };
                }
            }
            Phase::Applied { until_us } => {
                // The encoders only: the channel's noise is of the order of the slip.
                let (_, _, m) = self.motions(r, &self.cfg.slip);
                self.applied_motion = self.applied_motion.max(m);
                if m > S::one() || now_us >= until_us {
                    self.phase = Phase::Releasing {
                        until_us: now_us + self.cfg.release_us,
                    };
                }
            }
            Phase::Releasing { until_us } => {
                if now_us >= until_us {
                    // The released push measures from here: the applied push may have
                    // moved a free joint a little.
                    self.start_motor = r.motor;
                    self.start_abs = r.absolute;
                    self.phase = Phase::Ramp { since_us: now_us };
                }
            }
            Phase::Ramp { since_us } => {
                let (m, _, _) = self.motions(r, &self.cfg.target);
                let (_, _, still) = self.motions(r, &self.cfg.still);
                if still > S::one() {
                    if self.breakaway == S::zero() {
                        self.breakaway = self.ramp_duty(since_us, now_us);
                    }
                    self.moving_sum = self.moving_sum + current;
                    self.moving_n += 1;
                }
                if let (None, Some(a), Some(a0)) = (self.scale_from, r.absolute, self.start_abs) {
                    if (at(&a, j) - at(&a0, j)).abs()
                        >= lit::<S>(SCALE_FROM) * at(&self.cfg.target, j)
                    {
                        let (_, k, _) = self.motions(r, &self.cfg.target);
                        self.scale_k = k.min(NUM_JOINTS - 1);
                        self.scale_from = Some((at(&r.motor, self.scale_k), at(&a, j)));
                    }
                }
                if let (Some((m1, p1)), Some(a)) = (self.scale_from, r.absolute) {
                    let (x, y) = (at(&r.motor, self.scale_k) - m1, at(&a, j) - p1);
                    let f = &mut self.fit;
                    *f = [
                        f[0] + S::one(),
                        f[1] + x,
                        f[2] + y,
                        f[3] + x * x,
                        f[4] + x * y,
                    ];
                }
                let ramp_end = now_us.saturating_sub(since_us) >= self.cfg.ramp_us;
                if m >= S::one() || ramp_end {
                    self.finish(r, now_us);
                }
            }
            Phase::Settle { until_us, back } => {
                if now_us >= until_us {
                    match (back, self.back) {
                        (true, Some((k, sign, end))) => {
                            self.coast = (self.sensor(r, k) - end) * sign;
                            self.phase = Phase::Return { since_us: now_us };
                        }
                        _ => {
                            self.phase = Phase::Done;
                            self.record.done = true;
                        }
                    }
                }
            }
            Phase::Return { since_us } => {
                // Back where the test began, less the coast to come (or the ramp's end).
                let left = self.back.map_or(S::zero(), |(k, sign, _)| {
                    (self.sensor(r, k) - self.origin(k)) * sign
                });
                // A reading not a number ends it too.
                if !(left > self.coast.max(S::zero()))
                    || now_us.saturating_sub(since_us) >= self.cfg.ramp_us
                {
                    self.phase = Phase::Settle {
                        until_us: now_us + self.cfg.release_us,
                        back: false,
                    };
                }
            }
            Phase::Done => {}
        }
    }

    /// Ends the push: the findings from what was measured, then the brakes engage.
    #[cold]
    fn finish(&mut self, r: &Readings<S>, now_us: u64) {
        let j = self.joint;
        let cfg = self.cfg;
        let rec = &mut self.record;
        let offset = if self.offset_n > 0 {
            self.offset_sum / S::from(self.offset_n).unwrap_or_else(S::one)
        } else {
            S::nan()
        };
        rec.current_offset_a = f32_of(offset);
        if offset.abs() > cfg.offset_tolerance_a {
            self.findings.insert(F::CURRENT_OFFSET);
        }
        let pushed = matches!(self.phase, Phase::Ramp { .. });
        if self.offset_n > 0 {
            rec.applied_motion = f32_of(self.applied_motion * at(&cfg.slip, j));
        }
        rec.reference = self.start_abs.is_some() && r.absolute.is_some();
        // The switch: actuated at rest where the reference puts the joint away from it.
        let sw_end = r.switches.get(j).copied().unwrap_or(false);
        rec.switch = u8::from(self.switch_start) | (u8::from(sw_end) << 1);
        rec.switch_position = f32_of(self.switch_position);
        if self.switch_start {
            match (self.start_abs, cfg.home_switch.get(j).copied().flatten()) {
                (Some(a0), Some((home, travel))) if at(&a0, j) > home + travel => {
                    self.findings.insert(F::SWITCH_INVERTED)
                }
                (Some(_), None) => self.findings.insert(F::SWITCH_INVERTED),
                (Some(_), Some(_)) => {}
                (None, _) => self.findings.insert(F::SWITCH_ACTUATED),
            }
        }
        if pushed {
            self.judge_motion(r);
        }
        self.record.findings = self.findings;
        // Beyond the travel limit, or before anything was pushed: torque off now. After
        // the push: zero duty while the brakes engage, then the return (where the push
        // moved the joint), then torque off.
        self.phase = if self.findings.contains(F::TRAVEL_EXCEEDED) || !pushed {
            self.record.done = true;
            Phase::Done
        } else {
            Phase::Settle {
                until_us: now_us + cfg.release_us,
                back: self.back.is_some(),
            }
        };
    }

    /// The reading of the return's sensor `k` (0..5 an encoder, 6 the joint's channel).
    fn sensor(&self, r: &Readings<S>, k: usize) -> S {
        match r.absolute {
            Some(a) if k == NUM_JOINTS => at(&a, self.joint),
            _ => at(&r.motor, k),
        }
    }

    /// Where the return's sensor `k` read when the test began.
    fn origin(&self, k: usize) -> S {
        match self.origin_abs {
            Some(a) if k == NUM_JOINTS => at(&a, self.joint),
            _ => at(&self.origin_motor, k),
        }
    }

    /// The released push's findings: what moved, which way, by how much.
    #[cold]
    fn judge_motion(&mut self, r: &Readings<S>) {
        let j = self.joint;
        let cfg = self.cfg;
        let (_, k, enc) = self.motions(r, &cfg.target);
        let (_, _, still) = self.motions(r, &cfg.still);
        let applied_moved = self.applied_motion > S::one();
        let moved = still > S::one();
        self.record.breakaway_duty = f32_of(self.breakaway);
        // A brake that let the joint move at the applied push's duty and needed more than
        // that duty to move once released held harder released than applied.
        let harder_released = !moved || self.breakaway > at(&cfg.applied_duty, j);
        match (applied_moved, moved) {
            (true, _) if harder_released => self.findings.insert(F::BRAKE_INVERTED),
            (true, _) => self.findings.insert(F::BRAKE_NOT_HOLDING),
            (false, false) => self.findings.insert(F::NO_MOTION),
            (false, true) => {}
        }
        if !moved || k >= NUM_JOINTS || enc * at(&cfg.target, k) / at(&cfg.still, k) <= S::one() {
            return;
        }
        self.record.moved_encoder = k as u8;
        // The return's sensor: the joint's channel where both ends read it, else the
        // encoder that moved; the push's sign on it from where the test began.
        let b = if self.origin_abs.is_some() && r.absolute.is_some() {
            NUM_JOINTS
        } else {
            k
        };
        let (x, x0) = (self.sensor(r, b), self.origin(b));
        self.back = Some((b, if x < x0 { -S::one() } else { S::one() }, x));
        let dm = at(&r.motor, k) - at(&self.start_motor, k);
        self.record.encoder_motion = f32_of(dm);
        if k != j {
            self.findings.insert(F::ENCODER_SWAPPED);
        }
        if self.moving_n > 0 {
            let mean = self.moving_sum / S::from(self.moving_n).unwrap_or_else(S::one);
            let i = mean - self.record_offset();
            self.record.current_a = f32_of(i);
            if i < -cfg.offset_tolerance_a {
                self.findings.insert(F::CURRENT_SIGN);
            }
        }
        match (r.absolute, self.start_abs) {
            (Some(a), Some(a0)) => {
                let dp = at(&a, j) - at(&a0, j);
                self.record.reference_motion = f32_of(dp);
                if dp < S::zero() {
                    self.findings.insert(F::MOTOR_REVERSED);
                }
                if (dm < S::zero()) != (dp < S::zero()) {
                    self.findings.insert(F::ENCODER_REVERSED);
                }
                // The scale of this joint's own encoder (another's is checked once the
                // cables are put right).
                if let (Some((_, p1)), true) = (self.scale_from, k == j && self.scale_k == j) {
                    let ep = at(&a, j) - p1;
                    // Over half the target at least, the slope of the channel against the
                    // encoder by least squares over every tick of it: the channel's
                    // quantisation and noise average out over the steps it crosses (a
                    // 12-bit converter's step is 5.5 % of a link's half target), where
                    // the ratio of two readings carries a step's error whole.
                    if ep.abs() >= lit::<S>(0.5) * at(&cfg.target, j) {
                        let [n, sx, sy, sxx, sxy] = self.fit;
                        // Counts per unit over the profile's: dx/dy, the inverse slope.
                        let scale = ((n * sxx - sx * sx) / (n * sxy - sx * sy)).abs();
                        self.record.scale = f32_of(scale);
                        if !((scale - S::one()).abs() <= cfg.scale_tolerance) {
                            self.findings.insert(F::SCALE);
                        }
                    }
                }
            }
            _ => {
                if dm < S::zero() {
                    self.findings.insert(F::DIRECTION_MISMATCH);
                }
            }
        }
    }

    fn record_offset(&self) -> S {
        let o = S::from(self.record.current_offset_a).unwrap_or_else(S::zero);
        if o.is_nan() {
            S::zero()
        } else {
            o
        }
    }
}

fn f32_of<S: Float>(x: S) -> f32 {
    x.to_f32().unwrap_or(f32::NAN)
}

/// Joint `j` of `x` (NaN beyond the joints: every comparison with it fails, so a wrong
/// index can only end a test, never move a joint).
fn at<S: Float>(x: &[S; NUM_JOINTS], j: usize) -> S {
    x.get(j).copied().unwrap_or_else(S::nan)
}
