//! The software plant on the MCU: six independent joints, each a DC motor driven by an
//! H-bridge (averaged: duty x supply), geared to the thesis's encoder resolutions and read
//! by a 500-line encoder decoded x4 on the motor shaft (2000 counts per motor revolution),
//! with viscous and Coulomb friction; home switches on the legs and hard stops on the
//! links, as the homing procedure expects. f32 throughout.
//!
//! Per joint (motor side, ω in rad/s, the inductance neglected: L/R <= 0.24 ms):
//!
//! ```text
//! i = (u V - Ke ω) / R            u = duty in [-1, 1], 0 while the bridges are off (braking)
//! J ω' = Kt i - b ω - Tc sign(ω)   (stuck while |Kt u V / R| <= 1.2 Tc)
//! ```
//!
//! i.e. `ω' = (ω∞ - ω) / τ` with `τ = J / (Kt Ke / R + b)`, integrated exactly over fixed
//! steps of [`STEP_US`] with the friction sign of the step's start. Positions are kept in
//! encoder counts (an integer and a fraction), so nothing drifts in f32.
//!
//! The brakes are ideal: while applied (and once the bridges' power and the brakes'
//! coils are what the firmware commands) a joint does not move. The supply reads 24 V,
//! the drivers never report a fault, and the safety chain is closed (no e-stop button on
//! this board): the emulator exercises the control path, the fault paths are tested on
//! the host and in the STM32 emulator.
//!
//! Parameters: those of `host-sim/plant/plant.toml` (40 mm motor and 3 mm per motor
//! revolution on the legs: 0.0015 mm/count; 25 mm motor and 36:1 on the links: 0.005
//! deg/count), the load-side masses, inertias and frictions referred to the motor. Not
//! modelled here: backlash, gravity and the tool's weight, the closed chains' coupling.

use core::sync::atomic::{AtomicBool, Ordering};

use hal::{
    Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage, QuadratureCounter, SafeOutputs,
    SafetyChain,
};

/// Integration step, µs.
pub const STEP_US: u64 = 250;
/// Encoder counts per motor revolution (500 lines, x4).
const COUNTS_PER_REV: f32 = 2000.0;
/// Supply of the bridges, V.
const SUPPLY_V: f32 = 24.0;
/// On-resistance of the bridge in series with the motor, Ω.
const BRIDGE_OHM: f32 = 0.03;

/// The bridges are off (e-stop or disable): every duty reads 0.
static KILLED: AtomicBool = AtomicBool::new(true);

/// The interrupt-safe kill: one atomic store.
pub struct RawKill;

impl SafeOutputs for RawKill {
    fn force_safe(&mut self) {
        KILLED.store(true, Ordering::SeqCst);
    }
}

/// Physical parameters of one joint (SI, motor side unless named otherwise).
#[derive(Clone, Copy, Debug)]
pub struct MotorParams {
    /// Terminal resistance, Ω.
    pub resistance_ohm: f32,
    /// Torque constant = back-EMF constant, N m/A.
    pub kt: f32,
    /// Rotor + transmission + load inertia referred to the motor, kg m².
    pub inertia: f32,
    /// Viscous friction referred to the motor, N m s/rad.
    pub viscous: f32,
    /// Coulomb friction referred to the motor, N m.
    pub coulomb: f32,
    /// Joint travel per motor revolution, m (legs) or rad (links).
    pub travel_per_rev: f32,
}

impl MotorParams {
    /// A leg: 40 mm motor (0.317 Ω, 30.2 mN m/A, 142 g cm²), 2:1 spur pair and a 6 mm lead
    /// screw (3 mm per motor revolution), 0.4 kg moving, 2 N + 5 N s/m on the load side.
    pub fn leg() -> Self {
        let r = 0.003 / core::f32::consts::TAU; // m per motor rad
        let to_motor = r / 0.7 / 0.95; // N on the load -> N m at the motor (efficiencies)
        MotorParams {
            resistance_ohm: 0.317,
            kt: 0.0302,
            inertia: 142e-7 + 3.0e-7 + 0.4 * r * r,
            viscous: 1.0e-6 + 5.0 * r * r,
            coulomb: 5.1e-3 + 2.0 * to_motor,
            travel_per_rev: 0.003,
        }
    }

    /// A rotating link: 25 mm motor (2.14 Ω, 23.4 mN m/A, 10.8 g cm²), 36:1 gears,
    /// 3.5e-3 kg m² link, 0.01 N m + 1e-3 N m s/rad on the load side.
    pub fn link() -> Self {
        let g = 36.0;
        MotorParams {
            resistance_ohm: 2.14,
            kt: 0.0234,
            inertia: 10.8e-7 + 0.5e-7 + 3.5e-3 / (g * g),
            viscous: 1.0e-7 + 1.0e-3 / (g * g),
            coulomb: 0.9e-3 + 0.01 / (g * 0.9),
            travel_per_rev: core::f32::consts::TAU / g,
        }
    }
}

/// One joint's model in encoder counts.
#[derive(Clone, Copy, Debug)]
struct Joint {
    /// Counts per joint unit (m or rad).
    counts_per_unit: f32,
    /// No-load speed per unit duty, counts/s.
    speed_per_duty: f32,
    /// Speed offset of the Coulomb friction, counts/s.
    coulomb_speed: f32,
    /// exp(-STEP / τ) and τ, s.
    decay: f32,
    tau_s: f32,
    /// Current per unit duty at rest, A; current per count/s of speed, A s.
    amps_per_duty: f32,
    amps_per_speed: f32,
    /// Position: whole counts and the fraction in [0, 1).
    counts: i64,
    frac: f32,
    /// Speed, counts/s.
    speed: f32,
    /// Joint position at `counts == 0`.
    q_at_zero: f32,
    /// Home switch closed at or below this joint position.
    switch_below: Option<f32>,
    /// Hard stop at this joint position (the joint cannot go below it).
    stop_at: Option<f32>,
}

impl Joint {
    fn new(p: &MotorParams, q0: f32) -> Self {
        let r_total = p.resistance_ohm + BRIDGE_OHM;
        let damping = p.kt * p.kt / r_total + p.viscous;
        let counts_per_motor_rad = COUNTS_PER_REV / core::f32::consts::TAU;
        let tau_s = p.inertia / damping;
        Joint {
            counts_per_unit: COUNTS_PER_REV / p.travel_per_rev,
            speed_per_duty: counts_per_motor_rad * p.kt * SUPPLY_V / r_total / damping,
            coulomb_speed: counts_per_motor_rad * p.coulomb / damping,
            decay: libm::expf(-(STEP_US as f32) * 1e-6 / tau_s),
            tau_s,
            amps_per_duty: SUPPLY_V / r_total,
            amps_per_speed: p.kt / r_total / counts_per_motor_rad,
            counts: 0,
            frac: 0.0,
            speed: 0.0,
            q_at_zero: q0,
            switch_below: None,
            stop_at: None,
        }
    }

    fn q(&self) -> f32 {
        self.q_at_zero + (self.counts as f32 + self.frac) / self.counts_per_unit
    }

    fn step(&mut self, duty: f32) {
        let h = STEP_US as f32 * 1e-6;
        let drive = duty * self.speed_per_duty;
        let sign = if self.speed > 0.0 {
            1.0
        } else if self.speed < 0.0 {
            -1.0
        } else if drive.abs() <= 1.2 * self.coulomb_speed {
            // Stuck: static friction holds.
            return;
        } else {
            drive.signum()
        };
        let v_inf = drive - sign * self.coulomb_speed;
        let v0 = self.speed;
        let mut v1 = v_inf + (v0 - v_inf) * self.decay;
        let mut dx = v_inf * h + (v0 - v_inf) * self.tau_s * (1.0 - self.decay);
        if v1 * sign < 0.0 {
            // Friction stopped it within the step.
            v1 = 0.0;
            if dx * sign < 0.0 {
                dx = 0.0;
            }
        }
        self.speed = v1;
        let x = self.frac + dx;
        let whole = libm::floorf(x);
        self.counts += whole as i64;
        self.frac = x - whole;
        if let Some(stop) = self.stop_at {
            if self.q() < stop {
                // Against the stop: the position is held there, the motion ends.
                let c = (stop - self.q_at_zero) * self.counts_per_unit;
                let whole = libm::floorf(c);
                self.counts = whole as i64;
                self.frac = c - whole;
                if self.speed < 0.0 {
                    self.speed = 0.0;
                }
            }
        }
    }

    fn current(&self, duty: f32) -> f32 {
        duty * self.amps_per_duty - self.speed * self.amps_per_speed
    }
}

/// The six joints behind the controller's hardware traits.
pub struct Plant {
    joints: [Joint; 6],
    /// The counters' raw value at `counts == 0`.
    raw0: [u16; 6],
    duty: [f32; 6],
    /// Time simulated up to, µs.
    t_us: u64,
    /// At most this much time is simulated per call, µs.
    max_catch_up_us: u64,
    /// Time not simulated because the emulator stalled, µs.
    pub frozen_us: u64,
    /// The brakes' coils are powered (released).
    brakes_released: bool,
    /// Steps computed.
    pub steps: u64,
}

impl Plant {
    /// The plant at rest at joint positions `q0` (m, rad) at time `now_us`, its counters
    /// reading `raw0` there; home switches on the legs at `switch_m`, hard stops on the
    /// links at `stops_rad`. A call of [`Plant::advance_to`] simulates at most
    /// `max_catch_up_us`: when the emulator stalls (its host is busy), the plant's time
    /// stands still rather than running open-loop on stale duties.
    pub fn new(
        q0: [f32; 6],
        raw0: [u16; 6],
        switch_m: f32,
        stops_rad: [f32; 3],
        now_us: u64,
        max_catch_up_us: u64,
    ) -> Self {
        let leg = MotorParams::leg();
        let link = MotorParams::link();
        let mut joints = [Joint::new(&leg, 0.0); 6];
        for (j, (joint, q)) in joints.iter_mut().zip(q0).enumerate() {
            *joint = Joint::new(if j < 3 { &leg } else { &link }, q);
            if j < 3 {
                joint.switch_below = Some(switch_m);
            } else {
                joint.stop_at = stops_rad.get(j - 3).copied();
            }
        }
        Plant {
            joints,
            raw0,
            duty: [0.0; 6],
            t_us: now_us,
            max_catch_up_us,
            frozen_us: 0,
            brakes_released: false,
            steps: 0,
        }
    }

    /// The joint positions now (m, rad).
    pub fn positions(&self) -> [f32; 6] {
        let mut out = [0.0; 6];
        for (o, j) in out.iter_mut().zip(self.joints.iter()) {
            *o = j.q();
        }
        out
    }

    /// Simulates up to `now_us` in steps of [`STEP_US`] with the duties held.
    pub fn advance_to(&mut self, now_us: u64) {
        let behind = now_us.saturating_sub(self.t_us);
        if behind > self.max_catch_up_us {
            self.frozen_us += behind - self.max_catch_up_us;
            self.t_us = now_us - self.max_catch_up_us;
        }
        let killed = KILLED.load(Ordering::Relaxed);
        // The brakes hold unless released, and the kill cuts their coils too.
        let held = killed || !self.brakes_released;
        while self.t_us + STEP_US <= now_us {
            for (joint, d) in self.joints.iter_mut().zip(self.duty) {
                if held {
                    joint.speed = 0.0;
                } else {
                    joint.step(if killed { 0.0 } else { d });
                }
            }
            self.t_us += STEP_US;
            self.steps += 1;
        }
    }
}

impl QuadratureCounter for Plant {
    fn counts(&mut self) -> [u16; 6] {
        let mut out = [0u16; 6];
        for ((o, j), r0) in out.iter_mut().zip(self.joints.iter()).zip(self.raw0) {
            // A 16-bit timer in encoder mode: the count wraps.
            *o = r0.wrapping_add(j.counts as u16);
        }
        out
    }
}

impl MotorOutputs<f32> for Plant {
    fn set_duties(&mut self, duty: &[f32; 6]) {
        for (o, d) in self.duty.iter_mut().zip(duty) {
            *o = if d.is_finite() {
                d.clamp(-1.0, 1.0)
            } else {
                0.0
            };
        }
    }

    fn disable(&mut self) {
        KILLED.store(true, Ordering::SeqCst);
        self.duty = [0.0; 6];
    }

    fn enable(&mut self) {
        self.duty = [0.0; 6];
        // Never over a pending emergency stop.
        critical_section::with(|_| {
            if !crate::SHARED.estop.is_tripped() {
                KILLED.store(false, Ordering::SeqCst);
            }
        });
    }
}

impl LimitSwitches for Plant {
    fn switches(&mut self) -> [bool; 6] {
        let mut out = [false; 6];
        for (o, j) in out.iter_mut().zip(self.joints.iter()) {
            *o = j.switch_below.is_some_and(|s| j.q() <= s);
        }
        out
    }
}

impl CurrentSense<f32> for Plant {
    fn currents(&mut self) -> [f32; 6] {
        let killed = KILLED.load(Ordering::Relaxed);
        let mut out = [0.0; 6];
        for ((o, j), d) in out.iter_mut().zip(self.joints.iter()).zip(self.duty) {
            *o = j.current(if killed { 0.0 } else { d });
        }
        out
    }
}

impl Brakes for Plant {
    fn set_brakes_released(&mut self, released: bool) {
        self.brakes_released = released;
    }
}

impl PowerStage<f32> for Plant {
    fn supply_voltage(&mut self) -> f32 {
        SUPPLY_V
    }
    fn driver_fault(&mut self) -> bool {
        false
    }
}

impl SafetyChain for Plant {
    fn estop_pressed(&mut self) -> bool {
        false
    }
    fn relay_open(&mut self) -> bool {
        false
    }
}
