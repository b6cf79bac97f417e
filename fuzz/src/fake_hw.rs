//! A cheap fake of the board's hardware behind the `hal` traits: what the runtime writes is
//! recorded (and the duties checked), what it reads comes from the fuzz input.
//!
//! The encoders follow a first-order model unless the input says otherwise: with the
//! bridges on, powered (safety relay closed) and the brakes released, each joint moves at
//! `duty x` its no-load speed at the supply voltage; the motor current of the model is
//! then `(V d - Ke w) / R = 0` (no load). The input may instead hold the encoders still,
//! let them drift by a number of counts per tick, jump once, scale the motion, and give
//! the currents, the supply, the driver fault, the switches, the e-stop button and the
//! relay's feedback directly (including NaN and infinities).

use arbitrary::Arbitrary;
use control::current::MotorModel;
use hal::{
    AbsolutePositions, Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage,
    QuadratureCounter, SafeOutputs, SafetyChain, NUM_JOINTS,
};

/// The nominal supply of the bridges, V.
pub const NOMINAL_SUPPLY_V: f64 = 24.0;

/// How the encoders move from tick to tick.
#[derive(Clone, Copy, Debug, PartialEq, Arbitrary)]
pub enum Motion {
    /// The first-order model: `duty x` no-load speed while driven with the brakes released.
    Follow,
    /// The model's motion times `gain / 16` (negative: the wrong way round).
    Scaled(i8),
    /// Still.
    Still,
    /// Counts per control period on each joint, whatever the drive.
    Drift([i16; NUM_JOINTS]),
}

/// How the current sensors read.
#[derive(Clone, Copy, Debug, PartialEq, Arbitrary)]
pub enum Currents {
    /// The motor model's current (zero at no load).
    Model,
    /// `duty x` the stall current `V / R`, times `k / 16`: a joint pushing on something.
    Stall(i8),
    /// These values, A.
    Raw([f32; NUM_JOINTS]),
}

/// The inputs the fuzz input sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HwInputs {
    /// Limit switches.
    pub switches: [bool; NUM_JOINTS],
    /// The e-stop button is pressed.
    pub estop: bool,
    /// The safety relay's feedback says open.
    pub relay_open: bool,
    /// The drivers' fault output.
    pub driver_fault: bool,
    /// The supply voltage read, V.
    pub supply_v: f64,
    /// The current sensors.
    pub currents: Currents,
    /// The encoders.
    pub motion: Motion,
}

impl Default for HwInputs {
    fn default() -> Self {
        HwInputs {
            switches: [false; NUM_JOINTS],
            estop: false,
            relay_open: false,
            driver_fault: false,
            supply_v: NOMINAL_SUPPLY_V,
            currents: Currents::Model,
            motion: Motion::Follow,
        }
    }
}

/// The fake hardware.
#[derive(Clone, Debug)]
pub struct FakeHw {
    /// The bridges are on (`enable` without a later `disable` or `force_safe`).
    pub enabled: bool,
    /// The duties last set (0 after `enable`, `disable`, `force_safe`).
    pub duty: [f64; NUM_JOINTS],
    /// The brakes' coils are powered (released).
    pub brakes_released: bool,
    /// The inputs.
    pub inputs: HwInputs,
    /// The counters at the start, and the motion since, in counts.
    base: [u16; NUM_JOINTS],
    travel: [f64; NUM_JOINTS],
    counts_per_unit: [f64; NUM_JOINTS],
    motors: [MotorModel<f64>; NUM_JOINTS],
    /// Calls of `set_duties` (for the tests).
    pub duty_writes: u32,
    /// Assert every duty within [-1, 1] where it is written (else only finite, and the
    /// joints written outside are recorded in `over_range` for the caller to judge).
    pub strict_duty: bool,
    /// Joints given a finite duty outside [-1, 1] since the caller last cleared this.
    pub over_range: [bool; NUM_JOINTS],
    /// The counters at the last read, and their change from the read before (as a 16-bit
    /// counter's extension sees it: the nearest wrap).
    last_read: [u16; NUM_JOINTS],
    /// The change of each counter between the last two reads, counts.
    pub read_delta: [i16; NUM_JOINTS],
    /// `force_safe` switched the bridges off, and neither `enable` nor `disable` was called
    /// since.
    pub forced_safe: bool,
}

impl FakeHw {
    /// Counters reading `counts`, the encoders' resolutions `counts_per_unit`, the motors
    /// `motors`; bridges off, brakes applied, default inputs.
    pub fn new(
        counts: [u16; NUM_JOINTS],
        counts_per_unit: [f64; NUM_JOINTS],
        motors: [MotorModel<f64>; NUM_JOINTS],
    ) -> Self {
        FakeHw {
            enabled: false,
            duty: [0.0; NUM_JOINTS],
            brakes_released: false,
            inputs: HwInputs::default(),
            base: counts,
            travel: [0.0; NUM_JOINTS],
            counts_per_unit,
            motors,
            duty_writes: 0,
            strict_duty: true,
            over_range: [false; NUM_JOINTS],
            last_read: counts,
            read_delta: [0; NUM_JOINTS],
            forced_safe: false,
        }
    }

    /// The supply the model uses: the one read if it is a plausible voltage, else the
    /// nominal one.
    fn model_supply(&self) -> f64 {
        let v = self.inputs.supply_v;
        if v.is_finite() && (0.0..=100.0).contains(&v) {
            v
        } else {
            NOMINAL_SUPPLY_V
        }
    }

    /// The bridges drive the motors (on, and the relay powers them).
    fn powered(&self) -> bool {
        self.enabled && !self.inputs.relay_open
    }

    /// The joints' speed of the model, joint units per second.
    fn model_speed(&self) -> [f64; NUM_JOINTS] {
        let v = self.model_supply();
        std::array::from_fn(|j| {
            let (Some(d), Some(m)) = (self.duty.get(j), self.motors.get(j)) else {
                return 0.0;
            };
            if self.powered() && self.brakes_released {
                d * v / m.back_emf_v_s_per_rad / m.motor_rad_per_unit
            } else {
                0.0
            }
        })
    }

    /// Moves the encoders over `dt_s` seconds of which `period_s` is one control period.
    pub fn advance(&mut self, dt_s: f64, period_s: f64) {
        let speed = self.model_speed();
        for j in 0..NUM_JOINTS {
            let (Some(t), Some(s), Some(c)) = (
                self.travel.get_mut(j),
                speed.get(j),
                self.counts_per_unit.get(j),
            ) else {
                continue;
            };
            let counts = match self.inputs.motion {
                Motion::Follow => s * c * dt_s,
                Motion::Scaled(k) => s * c * dt_s * f64::from(k) / 16.0,
                Motion::Still => 0.0,
                Motion::Drift(d) => {
                    let per_period = d.get(j).copied().map_or(0.0, f64::from);
                    per_period * (dt_s / period_s).round()
                }
            };
            *t += counts;
        }
    }

    /// Moves the encoders by `counts` at once.
    pub fn jump(&mut self, counts: &[i16; NUM_JOINTS]) {
        for (t, c) in self.travel.iter_mut().zip(counts) {
            *t += f64::from(*c);
        }
    }
}

/// The fuzzed board has no second position channel (the prototype's board).
impl AbsolutePositions for FakeHw {}

impl QuadratureCounter for FakeHw {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        let now: [u16; NUM_JOINTS] = std::array::from_fn(|j| {
            let base = self.base.get(j).copied().unwrap_or(0);
            let travel = self.travel.get(j).copied().unwrap_or(0.0).round();
            // Wraps like a 16-bit timer (the travel stays far below i64's range).
            base.wrapping_add(travel as i64 as u16)
        });
        for ((d, last), n) in self
            .read_delta
            .iter_mut()
            .zip(self.last_read.iter())
            .zip(now)
        {
            *d = n.wrapping_sub(*last) as i16;
        }
        self.last_read = now;
        now
    }
}

impl MotorOutputs<f64> for FakeHw {
    fn set_duties(&mut self, duty: &[f64; NUM_JOINTS]) {
        for (j, d) in duty.iter().enumerate() {
            assert!(
                d.is_finite() && (!self.strict_duty || (-1.0..=1.0).contains(d)),
                "duty {d} written to joint {j} (all: {duty:?}; inputs {:?})",
                self.inputs
            );
            if let Some(o) = self.over_range.get_mut(j) {
                *o |= !(-1.0..=1.0).contains(d);
            }
        }
        self.duty = *duty;
        self.duty_writes += 1;
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.duty = [0.0; NUM_JOINTS];
        self.forced_safe = false;
    }
    fn enable(&mut self) {
        self.enabled = true;
        self.duty = [0.0; NUM_JOINTS];
        self.forced_safe = false;
    }
}

impl SafeOutputs for FakeHw {
    fn force_safe(&mut self) {
        self.forced_safe = true;
        self.enabled = false;
        self.duty = [0.0; NUM_JOINTS];
        self.brakes_released = false;
    }
}

impl Brakes for FakeHw {
    fn set_brakes_released(&mut self, released: bool) {
        self.brakes_released = released;
    }
}

impl CurrentSense<f64> for FakeHw {
    fn currents(&mut self) -> [f64; NUM_JOINTS] {
        let v = self.model_supply();
        let powered = self.powered();
        match self.inputs.currents {
            // (V d - Ke w) / R with w the model's own speed: zero while it follows.
            Currents::Model => {
                let speed = self.model_speed();
                std::array::from_fn(|j| {
                    let (Some(d), Some(m), Some(s)) =
                        (self.duty.get(j), self.motors.get(j), speed.get(j))
                    else {
                        return 0.0;
                    };
                    if powered {
                        (v * d - m.back_emf_v_s_per_rad * m.motor_rad_per_unit * s)
                            / m.resistance_ohm
                    } else {
                        0.0
                    }
                })
            }
            Currents::Stall(k) => std::array::from_fn(|j| {
                let (Some(d), Some(m)) = (self.duty.get(j), self.motors.get(j)) else {
                    return 0.0;
                };
                if powered {
                    v * d / m.resistance_ohm * f64::from(k) / 16.0
                } else {
                    0.0
                }
            }),
            Currents::Raw(i) => i.map(f64::from),
        }
    }
}

impl LimitSwitches for FakeHw {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        self.inputs.switches
    }
}

impl PowerStage<f64> for FakeHw {
    fn supply_voltage(&mut self) -> f64 {
        self.inputs.supply_v
    }
    fn driver_fault(&mut self) -> bool {
        self.inputs.driver_fault
    }
}

impl SafetyChain for FakeHw {
    fn estop_pressed(&mut self) -> bool {
        self.inputs.estop
    }
    fn relay_open(&mut self) -> bool {
        self.inputs.relay_open
    }
}
