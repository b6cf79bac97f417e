//! One actuated joint: H-bridge, DC motor, transmission with backlash, load, friction and
//! encoder, and its time step.
//!
//! ## Model (joint units: m for prismatic joints, rad for rotary joints)
//! * Motor side: position `x_m = theta_motor / n`, mass `M = (J_rotor + J_trans) n^2`,
//!   driven by `n Kt i`, with Coulomb/viscous friction `n T_c`, `n^2 b` and the back-EMF.
//! * Load side: position `q` (the true joint position used by the robot's pose), mass or
//!   inertia `m`, external load `F_ext` (the force the environment applies in `+q`),
//!   load-side Coulomb/viscous friction.
//! * Backlash: the gap `x_m - q` is free in `[-b/2, b/2]`; at a limit the flanks touch
//!   rigidly and the two sides move as one body (see [`crate::backlash`]). The force in
//!   the transmission feels the load-proportional mesh friction of
//!   [`crate::gearing`].
//!
//! ## Time step
//! 1. Electrical: mean motor torque over the step, affine in the end speed
//!    ([`crate::motor`]).
//! 2. Each side takes an implicit velocity step on its own ([`crate::friction`]). If the
//!    predicted gap stays within the backlash, those are the new velocities (free flight).
//! 3. Otherwise the flanks are in contact: one implicit step of the combined body from
//!    the momentum-conserving (inelastic) common velocity, with the mesh friction from the
//!    transmitted force (a short fixed-point iteration), and the gap set on the flank.
//! 4. Positions advance with the new velocities (semi-implicit Euler), the current with
//!    the exact exponential at the new speed, the encoder with the new motor angle.
//!
//! Every part is implicit or exact, so the step is stable for any `dt` (tested up to
//! 10 ms); accuracy, not stability, limits it: at 100 us results agree with 10 us to a
//! fraction of a percent (see the tests).
//!
//! What depends only on the parameters and `dt` (the exponentials of step 1 and 4, the
//! denominators of the implicit steps) is computed once per `dt`; the contact force of
//! step 3 is the exact fixed point of its affine branch once the passes settle on one
//! (see `Contact`), which the four passes of the first version approached.

use crate::backlash::Backlash;
use crate::encoder::QuadratureEncoder;
use crate::friction::{velocity_step_from_momentum, Friction, VelocityStep};
use crate::gearing::Transmission;
use crate::hbridge::{Duty, HBridge};
use crate::motor::DcMotor;

/// Kind of joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Lead-screw leg, joint unit m, effort unit N.
    Prismatic,
    /// Rotating link, joint unit rad, effort unit N m.
    Rotary,
}

/// Faults currently injected into one joint (all off by default).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointFaults {
    /// The encoder counter is frozen.
    pub encoder_stuck: bool,
    /// The encoder drops one count in every `n`.
    pub encoder_lose_one_in: Option<u32>,
    /// The encoder keeps only one count in every `n` (a failing sensor).
    pub encoder_keep_one_in: Option<u32>,
    /// The motor leads are open: no current flows, no torque, no back-EMF braking.
    pub motor_disconnected: bool,
    /// The load side is jammed (e.g. a mechanical collision): it does not move; the
    /// motor still moves within the backlash.
    pub load_seized: bool,
    /// The motor's terminals are shorted: the driver's short-circuit protection latches
    /// its fault as soon as it drives the motor, and the shorted winding brakes the shaft.
    pub motor_shorted: bool,
    /// The driver's current regulation no longer limits the current (a failed sense
    /// resistor or comparator).
    pub current_regulation_lost: bool,
    /// Part of the winding is shorted: its resistance is this fraction of the nominal
    /// (None: healthy).
    pub winding_resistance_ratio: Option<f64>,
    /// The driver reports a fault of its own (over-temperature, under-voltage lockout)
    /// and turns its bridge off whenever it is enabled.
    pub driver_failed: bool,
    /// The brake holds this fraction of its rated torque (None: healthy).
    pub brake_holding_ratio: Option<f64>,
    /// A bridge transistor is stuck on: full supply towards +q while enabled, no current
    /// regulation.
    pub bridge_stuck_on: bool,
}

/// Physical parameters of one joint, SI, joint units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointModel {
    /// Prismatic or rotary.
    pub kind: JointKind,
    /// The motor.
    pub motor: DcMotor,
    /// The H-bridge that drives it.
    pub bridge: HBridge,
    /// Motor-to-joint transmission.
    pub transmission: Transmission,
    /// Backlash at the joint.
    pub backlash: Backlash,
    /// Friction at the motor shaft (N m, N m s/rad); its breakaway ratio applies to the
    /// whole joint.
    pub motor_friction: Friction,
    /// Mass (kg) or inertia (kg m^2) of the load side.
    pub load_inertia: f64,
    /// Friction on the load side (N or N m, per m/s or rad/s).
    pub load_friction: Friction,
    /// The driver's current regulation: the largest |current|, A (infinite: none).
    pub current_limit: f64,
    /// The driver's overcurrent protection: above this |current| it latches its fault and
    /// turns the bridge off, A (infinite: none).
    pub driver_ocp: f64,
    /// The holding brake on the motor shaft: holding torque (N m), engage and release
    /// times (s).
    pub brake: BrakeModel,
}

/// A spring-applied holding brake on the motor shaft.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrakeModel {
    /// Holding torque at the motor shaft, N m (0: no brake).
    pub holding_torque: f64,
    /// From the coil's power removed to holding, s.
    pub engage_s: f64,
    /// From the coil powered to free, s.
    pub release_s: f64,
}

impl BrakeModel {
    /// No brake.
    pub const NONE: BrakeModel = BrakeModel {
        holding_torque: 0.0,
        engage_s: 0.0,
        release_s: 0.0,
    };
}

/// The brake's state: what the coil is told and what the brake does.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BrakeState {
    /// The coil is powered (release commanded).
    released_cmd: bool,
    /// The brake holds now.
    holding: bool,
    /// Time left until the brake follows the command, s.
    timer: f64,
}

impl JointModel {
    /// Winding plus bridge resistance, ohm.
    pub fn circuit_resistance(&self) -> f64 {
        self.motor.resistance + self.bridge.on_resistance
    }

    /// Motor-side mass or inertia seen at the joint, `(J_rotor + J_trans) n^2`.
    pub fn reflected_motor_inertia(&self) -> f64 {
        let n = self.transmission.ratio;
        (self.motor.rotor_inertia + self.transmission.inertia_at_motor) * n * n
    }

    /// Encoder counts per joint unit (counts/m or counts/rad) for `counts_per_rev`.
    pub fn counts_per_joint_unit(&self, counts_per_rev: u32) -> f64 {
        f64::from(counts_per_rev) * self.transmission.ratio / std::f64::consts::TAU
    }

    /// Continuous effort the joint delivers to its environment at the motor's nominal
    /// current while driving (N or N m): `n eta (Kt I_nom - T_c) - F_c,load`.
    pub fn rated_effort(&self) -> f64 {
        let n = self.transmission.ratio;
        let tm =
            self.motor.torque_constant * self.motor.nominal_current - self.motor_friction.coulomb;
        n * self.transmission.efficiency * tm - self.load_friction.coulomb
    }

    /// Steady joint speed with no external load at `duty` in [-1, 1] (m/s or rad/s).
    pub fn no_load_speed(&self, duty: f64) -> f64 {
        let n = self.transmission.ratio;
        let r = self.circuit_resistance();
        let kt = self.motor.torque_constant;
        let mu1 = 1.0 + self.transmission.mesh_friction_coefficient();
        let drive = n * kt * self.bridge.supply * duty.abs() / r;
        let coulomb = n * self.motor_friction.coulomb + mu1 * self.load_friction.coulomb;
        let damping = n * n * (kt * self.motor.back_emf_constant / r + self.motor_friction.viscous)
            + mu1 * self.load_friction.viscous;
        duty.signum() * (drive - coulomb).max(0.0) / damping
    }
}

/// The parts of a joint's step that depend only on its parameters and the step length
/// `dt`, computed once per `dt` rather than in every step (the simulator steps with one
/// `dt` throughout): the exponentials of the exact electrical solution (motor.rs) and the
/// denominators `1 / (M + dt c)` of the backward-Euler friction steps (friction.rs).
/// Index `[0]` of the pairs: motor connected; `[1]`: motor leads open (no back-EMF).
#[derive(Debug, Clone, Copy, PartialEq)]
struct StepConstants {
    /// The step length these are for (NaN before the first step: never equal).
    dt: f64,
    /// `exp(-dt R / L)`: the decay of the current over one step.
    decay: f64,
    /// `1 / R`, R the winding plus bridge resistance.
    inv_r: f64,
    /// Back-EMF per joint velocity, `Ke n`.
    emf_per_v: f64,
    /// Mean drive force `n Kt (phi i0 + (1 - phi) u / R)` (motor.rs) =
    /// `drive_i i0 + drive_u u`, `phi = (1 - exp(-x)) / x`, `x = dt R / L`.
    drive_i: f64,
    drive_u: f64,
    /// Reflected motor mass `(J_rotor + J_trans) n^2`, load mass and their sum.
    mass_m: f64,
    mass_l: f64,
    mass: f64,
    /// `1 / (M_m + dt (n^2 b + n^2 Kt Ke (1 - phi) / R))`: the motor side's implicit step,
    /// viscous friction plus the back-EMF's implicit damping (motor.rs).
    inv_den_m: [f64; 2],
    /// `1 / (M_l + dt c_l)`: the load side's.
    inv_den_l: f64,
    /// `1 / (M_m + M_l + dt (c_m + c_l))`: both sides as one body (flanks in contact).
    inv_den_both: [f64; 2],
    /// `dt` times the Coulomb and the breakaway friction: motor side (`n T_c`), load side,
    /// and both sides together.
    dt_coulomb_m: f64,
    dt_static_m: f64,
    dt_coulomb_l: f64,
    dt_static_l: f64,
    dt_coulomb_both: f64,
    dt_static_both: f64,
    /// Load-side Coulomb friction.
    coulomb_l: f64,
    /// `dt` times the mesh friction coefficient `1 / eta - 1` (gearing.rs).
    dt_mu: f64,
    /// The shares `M_m / (M_m + M_l)` and `M_l / (M_m + M_l)` (common velocity, closure).
    share_m: f64,
    share_l: f64,
    /// Half the backlash: the gap's limit (backlash.rs).
    half_backlash: f64,
    /// `M_l / dt`, and `alpha = M_l / dt + c_l` of the transmitted force (`Contact`).
    mass_l_per_dt: f64,
    alpha: f64,
    /// Force at the joint per ampere, `n Kt`.
    force_per_amp: f64,
    /// `dt` times the brake's holding force at the joint, `dt n T_b`.
    dt_brake: f64,
}

impl StepConstants {
    fn new(m: &JointModel, dt: f64) -> Self {
        let n = m.transmission.ratio;
        let r = m.circuit_resistance();
        let kt = m.motor.torque_constant;
        let ke = m.motor.back_emf_constant;
        let x = dt * r / m.motor.inductance;
        let phi = crate::motor::phi(x);
        let mass_m = m.reflected_motor_inertia();
        let mass_l = m.load_inertia;
        let mass = mass_m + mass_l;
        let viscous_m = n * n * m.motor_friction.viscous;
        let emf_damping = n * n * kt * ke * (1.0 - phi) / r;
        let damping_m = [viscous_m + emf_damping, viscous_m];
        let fl = m.load_friction;
        let coulomb_m = n * m.motor_friction.coulomb;
        let static_m = m.motor_friction.breakaway_ratio * coulomb_m;
        StepConstants {
            dt,
            decay: (-x).exp(),
            inv_r: 1.0 / r,
            emf_per_v: ke * n,
            drive_i: n * kt * phi,
            drive_u: n * kt * (1.0 - phi) / r,
            mass_m,
            mass_l,
            mass,
            inv_den_m: damping_m.map(|c| 1.0 / (mass_m + dt * c)),
            inv_den_l: 1.0 / (mass_l + dt * fl.viscous),
            inv_den_both: damping_m.map(|c| 1.0 / (mass + dt * (c + fl.viscous))),
            dt_coulomb_m: dt * coulomb_m,
            dt_static_m: dt * static_m,
            dt_coulomb_l: dt * fl.coulomb,
            dt_static_l: dt * fl.static_limit(),
            dt_coulomb_both: dt * (coulomb_m + fl.coulomb),
            dt_static_both: dt * (static_m + fl.static_limit()),
            coulomb_l: fl.coulomb,
            dt_mu: dt * m.transmission.mesh_friction_coefficient(),
            half_backlash: m.backlash.half(),
            share_m: mass_m / mass,
            share_l: mass_l / mass,
            mass_l_per_dt: mass_l / dt,
            alpha: mass_l / dt + fl.viscous,
            force_per_amp: n * kt,
            dt_brake: dt * n * m.brake.holding_torque,
        }
    }
}

/// The flanks in contact: both sides move as one body (momentum `p = M v0 + dt F` with
/// `F` the drive and the external load) whose backward-Euler step with Coulomb friction
/// (friction.rs) also feels the mesh friction `mu |F_t|` of the transmitted force
/// (gearing.rs), while `F_t` follows from the load side's own balance over the step,
///
/// ```text
/// F_t = M_l (v - v_c) / dt - F_ext + c_l v + F_c,l sgn(v)        (v_c: common velocity)
/// ```
///
/// `F_t = g(F_t)` is a fixed point. While the body slides (`|p| > dt (hold + mu |F_t|)`,
/// `s = sgn p`), `v = (p - s dt (C + mu |F_t|)) / D` and `g` is affine on each sign
/// `sigma` of `F_t`:
///
/// ```text
/// g(F) = A - s sigma B F,   A = alpha (p - s dt C) / D + F_rest + s F_c,l,
/// B = alpha dt mu / D,      alpha = M_l / dt + c_l,   F_rest = -M_l v_c / dt - F_ext,
/// ```
///
/// with the fixed point `F* = A / (1 + s sigma B)`. `B` is about `mu M_l / (M_m + M_l)`
/// (0.003 on the legs, 0.08 on the links), the rate at which plain passes converge. So:
/// at most four passes `F <- g(F)` from the last step's force; as soon as a pass slides
/// with `F` keeping its sign, the exact fixed point of that branch is taken if it lies on
/// the branch (same sign, still sliding, `sgn v = s`); a pass that reproduces its `F`
/// exactly (held by friction) ends the passes too.
#[derive(Debug, Clone, Copy)]
struct Contact {
    /// Momentum of the combined body at the start, with the step's impulse.
    p: f64,
    /// `dt` times the load-independent Coulomb friction of both sides.
    dt_coulomb: f64,
    /// `dt` times the load-independent friction held at rest (breakaway if both sides
    /// were at rest, else Coulomb).
    dt_hold: f64,
    /// `1 / D`, `D = M_m + M_l + dt (c_m + c_l)`.
    inv_den: f64,
    /// `dt mu`.
    dt_mu: f64,
    /// `M_l / dt + c_l`.
    alpha: f64,
    /// `F_t` at rest: `-M_l v_c / dt - F_ext`.
    f_at_rest: f64,
    /// Load-side Coulomb friction `F_c,l`.
    coulomb_l: f64,
}

impl Contact {
    /// One pass: the body's step with the mesh friction of `f`, and the transmitted force
    /// it implies.
    fn pass(&self, f: f64) -> (VelocityStep, f64) {
        let mesh = self.dt_mu * f.abs();
        let sol = velocity_step_from_momentum(
            self.p,
            self.dt_coulomb + mesh,
            self.dt_hold + mesh,
            self.inv_den,
        );
        let f_new = if sol.stuck {
            self.f_at_rest
        } else {
            // sgn v: v is not zero while sliding.
            self.alpha * sol.v + self.f_at_rest + self.coulomb_l.copysign(sol.v)
        };
        (sol, f_new)
    }

    /// The sliding branch's fixed point for `sigma = sgn F_t` (+-1), if it lies on that
    /// branch.
    fn branch_fixed_point(&self, sigma: f64) -> Option<(VelocityStep, f64)> {
        let s = 1.0f64.copysign(self.p);
        let b = self.alpha * self.dt_mu * self.inv_den;
        let den = 1.0 + s * sigma * b;
        // (A NaN falls through to the checks below, which it fails.)
        if den <= 0.0 {
            return None;
        }
        let a = self.alpha * (self.p - s * self.dt_coulomb) * self.inv_den
            + self.f_at_rest
            + s * self.coulomb_l;
        let f = a / den;
        let mesh = self.dt_mu * f.abs();
        // On the branch: F* has the sign sigma, the body slides, and v has the sign of p
        // (false for NaN).
        let v = (self.p - s * (self.dt_coulomb + mesh)) * self.inv_den;
        (f * sigma > 0.0 && self.p.abs() > self.dt_hold + mesh && v * s > 0.0)
            .then_some((VelocityStep { v, stuck: false }, f))
    }

    /// The body's step and the transmitted force, from the start force `f`.
    fn solve(&self, mut f: f64) -> (VelocityStep, f64) {
        let mut out = (
            VelocityStep {
                v: 0.0,
                stuck: true,
            },
            f,
        );
        for _ in 0..4 {
            out = self.pass(f);
            let (sol, f_new) = out;
            if f_new == f {
                break;
            }
            if !sol.stuck && f_new * f > 0.0 {
                if let Some(fixed) = self.branch_fixed_point(1.0f64.copysign(f_new)) {
                    return fixed;
                }
            }
            f = f_new;
        }
        out
    }
}

/// State of one joint.
#[derive(Debug, Clone)]
pub struct Joint {
    model: JointModel,
    /// The model without the injected faults (a winding short changes `model`).
    nominal: JointModel,
    /// Load-side position (true joint position), m or rad.
    q: f64,
    /// Load-side velocity.
    v_load: f64,
    /// Gap `x_m - q` within the backlash.
    gap: f64,
    /// Motor-side velocity in joint units.
    v_motor: f64,
    /// Armature current, A.
    current: f64,
    stuck_motor: bool,
    stuck_load: bool,
    /// Force in the transmission at the joint, + when the motor side pushes the load
    /// towards +q; 0 inside the backlash.
    transmitted: f64,
    duty: Duty,
    external: f64,
    faults: JointFaults,
    encoder: QuadratureEncoder,
    /// The step's constants for the last step length.
    consts: StepConstants,
    /// The H-bridge is enabled (else high-impedance: the motor coasts).
    bridge_enabled: bool,
    /// The driver latched a fault (short circuit): its bridge is off until it is
    /// re-enabled.
    driver_fault: bool,
    /// The current regulation limited the current in the last step.
    current_limited: bool,
    brake: BrakeState,
}

impl Joint {
    /// A joint at rest at `q = 0`, gap centred, counter 0.
    pub fn new(model: JointModel, counts_per_rev: u32) -> Self {
        let mut j = Joint {
            model,
            nominal: model,
            q: 0.0,
            v_load: 0.0,
            gap: 0.0,
            v_motor: 0.0,
            current: 0.0,
            stuck_motor: true,
            stuck_load: true,
            transmitted: 0.0,
            duty: Duty {
                applied: 0.0,
                saturated: false,
            },
            external: 0.0,
            faults: JointFaults::default(),
            encoder: QuadratureEncoder::new(counts_per_rev),
            consts: StepConstants::new(&model, f64::NAN),
            bridge_enabled: true,
            driver_fault: false,
            current_limited: false,
            brake: BrakeState {
                released_cmd: true,
                holding: false,
                timer: 0.0,
            },
        };
        j.set_position(0.0);
        j
    }

    /// The parameters.
    pub fn model(&self) -> &JointModel {
        &self.model
    }

    /// Puts both sides at rest at `q`, the gap centred, no current; the encoder counter
    /// reads 0 here.
    pub fn set_position(&mut self, q: f64) {
        self.q = q;
        self.gap = 0.0;
        self.v_load = 0.0;
        self.v_motor = 0.0;
        self.current = 0.0;
        self.stuck_motor = true;
        self.stuck_load = true;
        self.transmitted = 0.0;
        self.encoder.reset(self.motor_angle());
    }

    /// Holds a (saturated) duty until changed.
    pub fn set_duty(&mut self, duty: Duty) {
        self.duty = duty;
    }

    /// The duty being applied.
    pub fn duty(&self) -> Duty {
        self.duty
    }

    /// Sets the external load (force or torque on the joint towards +q).
    pub fn set_external_load(&mut self, load: f64) {
        self.external = load;
    }

    /// The external load (force or torque on the joint towards +q).
    pub fn external_load(&self) -> f64 {
        self.external
    }

    /// Enables the H-bridge or turns it off (high-impedance: no current, the motor
    /// coasts). Enabling clears a latched driver fault (the cause may trip it again).
    pub fn set_bridge_enabled(&mut self, enabled: bool) {
        if enabled && !self.bridge_enabled {
            self.driver_fault = false;
        }
        self.bridge_enabled = enabled;
    }

    /// The bridge is enabled and its driver not latched off.
    pub fn bridge_on(&self) -> bool {
        self.bridge_enabled && !self.driver_fault
    }

    /// The driver latched a fault.
    pub fn driver_fault(&self) -> bool {
        self.driver_fault
    }

    /// The current regulation limited the current in the last step.
    pub fn current_limited(&self) -> bool {
        self.current_limited
    }

    /// Powers the brake's coil (`true`: release) or removes its power (apply); the brake
    /// follows after its release or engage time.
    pub fn set_brake_released(&mut self, released: bool) {
        if released != self.brake.released_cmd {
            self.brake.released_cmd = released;
            self.brake.timer = if released {
                self.model.brake.release_s
            } else {
                self.model.brake.engage_s
            };
        }
    }

    /// The brake holds now.
    pub fn brake_holding(&self) -> bool {
        self.brake.holding
    }

    /// Sets the supply voltage of the joint's bridge, V.
    pub fn set_supply(&mut self, volts: f64) {
        self.model.bridge.supply = volts;
        self.nominal.bridge.supply = volts;
    }

    /// Replaces the set of injected faults.
    pub fn set_faults(&mut self, faults: JointFaults) {
        self.faults = faults;
        let ratio = faults.winding_resistance_ratio.unwrap_or(1.0);
        self.model.motor.resistance = self.nominal.motor.resistance * ratio;
        // The step's constants depend on the resistance.
        self.consts.dt = f64::NAN;
        self.encoder.stuck = faults.encoder_stuck;
        self.encoder.lose_one_in = faults.encoder_lose_one_in;
        self.encoder.keep_one_in = faults.encoder_keep_one_in;
        if faults.motor_disconnected {
            self.current = 0.0;
        }
        if faults.load_seized {
            self.v_load = 0.0;
            self.stuck_load = true;
        }
    }

    /// The injected faults.
    pub fn faults(&self) -> JointFaults {
        self.faults
    }

    /// Load-side (true) position.
    pub fn position(&self) -> f64 {
        self.q
    }

    /// Load-side velocity.
    pub fn velocity(&self) -> f64 {
        self.v_load
    }

    /// Motor angle mapped to joint units.
    pub fn motor_side_position(&self) -> f64 {
        self.q + self.gap
    }

    /// Motor velocity mapped to joint units.
    pub fn motor_side_velocity(&self) -> f64 {
        self.v_motor
    }

    /// Motor shaft angle, rad.
    pub fn motor_angle(&self) -> f64 {
        self.model.transmission.ratio * (self.q + self.gap)
    }

    /// Armature current, A.
    pub fn current(&self) -> f64 {
        self.current
    }

    /// Gap inside the backlash, `x_m - q`.
    pub fn gap(&self) -> f64 {
        self.gap
    }

    /// The motor's effort at the joint, `n Kt i` (N or N m, before the transmission's
    /// losses).
    pub fn motor_effort(&self) -> f64 {
        self.model.transmission.ratio * self.model.motor.torque_constant * self.current
    }

    /// Force (N) or torque (N m) carried by the transmission at the joint.
    pub fn transmitted_effort(&self) -> f64 {
        self.transmitted
    }

    /// The 16-bit encoder counter.
    pub fn encoder_counter(&self) -> u16 {
        self.encoder.counter()
    }

    /// Advances the joint by `dt` seconds (`dt > 0`, checked by the caller).
    ///
    /// The parts of the step that depend only on the parameters and `dt` (the electrical
    /// exponentials, the implicit steps' denominators) are computed on the first step of a
    /// given `dt` and reused while `dt` stays the same ([`StepConstants`]).
    pub fn step(&mut self, dt: f64) {
        if self.consts.dt != dt {
            self.refresh_constants(dt);
        }
        self.step_brake(dt);
        // A shorted motor trips the driver's short-circuit protection as soon as the
        // bridge drives it.
        if (self.faults.motor_shorted && self.bridge_on() && self.duty.applied != 0.0)
            || (self.faults.driver_failed && self.bridge_enabled)
        {
            self.driver_fault = true;
        }
        let bridge_on = self.bridge_on();
        // Borrowed, not copied: the step reads a few of the constants on each path.
        let k = &self.consts;
        let (decay, inv_r, emf_per_v) = (k.decay, k.inv_r, k.emf_per_v);
        let shorted = self.faults.motor_shorted;
        // No current path: open leads, or a bridge off (high-impedance) on a sound winding.
        let open = self.faults.motor_disconnected || (!bridge_on && !shorted);
        let u = if bridge_on && self.faults.bridge_stuck_on {
            self.model.bridge.supply
        } else if bridge_on && !shorted {
            self.model.bridge.voltage(self.duty)
        } else {
            0.0
        };
        let mut off = usize::from(open);
        let brake = if self.brake.holding {
            k.dt_brake * self.faults.brake_holding_ratio.unwrap_or(1.0)
        } else {
            0.0
        };

        // 1. Electrical: mean drive force at the joint over the step, affine in the end
        //    velocity (motor.rs: n Kt (phi i0 + (1 - phi) u / R) - damping v).
        let mut drive = if open {
            0.0
        } else {
            k.drive_i * self.current + k.drive_u * u
        };
        // The driver's current regulation: where the mean current at the present speed
        // would exceed the limit, the driver chops and holds the current at the limit
        // (a current source: constant force, no back-EMF damping).
        let limit =
            if bridge_on && !self.faults.current_regulation_lost && !self.faults.bridge_stuck_on {
                self.model.current_limit
            } else {
                f64::INFINITY
            };
        let at_speed = drive - k.drive_u * emf_per_v * self.v_motor;
        let chopping = !open && at_speed.abs() > k.force_per_amp * limit;
        if chopping {
            drive = (k.force_per_amp * limit).copysign(at_speed);
            off = 1;
        }
        self.current_limited = chopping;
        let ext = self.external;

        // 2. Each side on its own: the backward-Euler step with Coulomb friction of
        //    friction.rs, from the momentum p = M v0 + dt F.
        let free_m = {
            let (v0, hold) = if self.stuck_motor {
                (0.0, k.dt_static_m)
            } else {
                (self.v_motor, k.dt_coulomb_m)
            };
            let p = k.mass_m * v0 + dt * drive;
            velocity_step_from_momentum(p, k.dt_coulomb_m + brake, hold + brake, k.inv_den_m[off])
        };
        let free_l = if self.faults.load_seized {
            VelocityStep {
                v: 0.0,
                stuck: true,
            }
        } else {
            let (v0, hold) = if self.stuck_load {
                (0.0, k.dt_static_l)
            } else {
                (self.v_load, k.dt_coulomb_l)
            };
            let p = k.mass_l * v0 + dt * ext;
            velocity_step_from_momentum(p, k.dt_coulomb_l, hold, k.inv_den_l)
        };
        let predicted_gap = self.gap + dt * (free_m.v - free_l.v);
        // The flanks a predicted gap beyond the backlash presses together (backlash.rs):
        // +1 at g = +b/2, -1 at g = -b/2, 0 inside (free flight).
        let h = k.half_backlash;
        let flank = if predicted_gap > h {
            1.0
        } else if predicted_gap < -h {
            -1.0
        } else {
            0.0
        };

        if flank == 0.0 {
            self.fly(free_m, free_l, predicted_gap, dt);
        } else if self.faults.load_seized {
            // The motor side runs onto the jammed load and stops there.
            self.gap = flank * h;
            self.v_motor = 0.0;
            self.stuck_motor = true;
            self.v_load = 0.0;
            self.stuck_load = true;
            self.transmitted = drive;
        } else {
            // 3. Flanks in contact: one body, from the momentum-conserving common
            //    velocity.
            let v_common = k.share_m * self.v_motor + k.share_l * self.v_load;
            let stuck = self.stuck_motor && self.stuck_load;
            // Transmitted force: start from the last one on this flank, else from the
            // quasi-static balance of the load.
            let f_start = if self.transmitted * flank > 0.0 {
                self.transmitted
            } else {
                -ext + self.model.load_friction.sliding(v_common)
            };
            let (v_start, dt_hold) = if stuck {
                (0.0, k.dt_static_both)
            } else {
                (v_common, k.dt_coulomb_both)
            };
            let contact = Contact {
                p: k.mass * v_start + dt * (drive + ext),
                dt_coulomb: k.dt_coulomb_both + brake,
                dt_hold: dt_hold + brake,
                inv_den: k.inv_den_both[off],
                dt_mu: k.dt_mu,
                // F_t = M_l (v - v_c) / dt - F_ext + c_l v + F_c,l sgn v
                alpha: k.alpha,
                f_at_rest: -k.mass_l_per_dt * v_common - ext,
                coulomb_l: k.coulomb_l,
            };
            let (sol, f_t) = contact.solve(f_start);
            if f_t * flank < 0.0 && h > 0.0 {
                // The flanks would have to pull: they separate after all.
                self.fly(free_m, free_l, predicted_gap, dt);
            } else {
                let target = flank * h;
                // The closure splits so that the centre of mass stays
                // (Backlash::split_closure): the load moves by -dg M_m / (M_m + M_l).
                let d_load = -(target - self.gap) * k.share_m;
                self.q += sol.v * dt + d_load;
                self.gap = target;
                self.v_motor = sol.v;
                self.v_load = sol.v;
                self.stuck_motor = sol.stuck;
                self.stuck_load = sol.stuck;
                self.transmitted = f_t;
            }
        }

        // 4. Current at the new speed, exact exponential (motor.rs):
        //    i = i_ss + (i0 - i_ss) exp(-dt R / L), i_ss = (u - Ke n v) / R.
        self.current = if open {
            0.0
        } else if chopping {
            limit.copysign(at_speed)
        } else {
            let i_ss = (u - emf_per_v * self.v_motor) * inv_r;
            let i = i_ss + (self.current - i_ss) * decay;
            // Flush a decayed current to zero rather than crawl through subnormals.
            if i.abs() < 1e-15 {
                0.0
            } else {
                i.clamp(-limit, limit)
            }
        };
        self.encoder.update(self.motor_angle());
        // The driver's overcurrent protection trips within the step.
        if bridge_on && self.current.abs() > self.model.driver_ocp {
            self.driver_fault = true;
        }
    }

    /// The brake follows its coil after the engage or release time.
    fn step_brake(&mut self, dt: f64) {
        let b = &mut self.brake;
        let holding = !b.released_cmd;
        if b.holding != holding {
            b.timer -= dt;
            if b.timer <= 0.0 {
                b.holding = holding;
                b.timer = 0.0;
            }
        }
    }

    /// Moves the encoder's counter by `counts` at once (an electrical glitch).
    pub fn glitch_encoder(&mut self, counts: i64) {
        self.encoder.glitch(counts);
    }

    /// The step as first written (every constant recomputed, the contact force by four
    /// fixed-point passes): the reference the cached step is tested against.
    #[cfg(test)]
    fn step_reference(&mut self, dt: f64) {
        let m = self.model;
        let n = m.transmission.ratio;
        let r = m.circuit_resistance();
        let u = m.bridge.voltage(self.duty);
        let mass_m = m.reflected_motor_inertia();
        let mass_l = m.load_inertia;
        let ratio = m.motor_friction.breakaway_ratio;

        // 1. Electrical: mean drive force at the joint, affine in the end velocity.
        let (drive, emf_damping) = if self.faults.motor_disconnected {
            (0.0, 0.0)
        } else {
            let t = m.motor.mean_torque(self.current, u, r, dt);
            (n * t.constant, n * n * t.damping)
        };
        let damping_m = n * n * m.motor_friction.viscous + emf_damping;
        let coulomb_m = n * m.motor_friction.coulomb;
        let fl = m.load_friction;
        let ext = self.external;

        // 2. Each side on its own.
        let free_m = crate::friction::implicit_velocity_step(
            mass_m,
            self.v_motor,
            drive,
            damping_m,
            coulomb_m,
            ratio * coulomb_m,
            self.stuck_motor,
            dt,
        );
        let free_l = if self.faults.load_seized {
            VelocityStep {
                v: 0.0,
                stuck: true,
            }
        } else {
            crate::friction::implicit_velocity_step(
                mass_l,
                self.v_load,
                ext,
                fl.viscous,
                fl.coulomb,
                fl.static_limit(),
                self.stuck_load,
                dt,
            )
        };
        let predicted_gap = self.gap + dt * (free_m.v - free_l.v);

        match m.backlash.contact(predicted_gap) {
            None => self.fly(free_m, free_l, predicted_gap, dt),
            Some(flank) if self.faults.load_seized => {
                // The motor side runs onto the jammed load and stops there.
                self.gap = m.backlash.gap_at(flank);
                self.v_motor = 0.0;
                self.stuck_motor = true;
                self.v_load = 0.0;
                self.stuck_load = true;
                self.transmitted = drive;
            }
            Some(flank) => {
                // 3. Flanks in contact: one body.
                let mass = mass_m + mass_l;
                let v_common = (mass_m * self.v_motor + mass_l * self.v_load) / mass;
                let mu = m.transmission.mesh_friction_coefficient();
                let stuck = self.stuck_motor && self.stuck_load;
                // Transmitted force: start from the last one on this flank, else from the
                // quasi-static balance of the load.
                let mut f_t = if self.transmitted * flank.sign() > 0.0 {
                    self.transmitted
                } else {
                    -ext + fl.sliding(v_common)
                };
                let mut sol = VelocityStep {
                    v: v_common,
                    stuck: false,
                };
                for _ in 0..4 {
                    // Stiction raises the load-independent friction only; the mesh
                    // friction keeps its running value (catalogue efficiency).
                    let mesh = mu * f_t.abs();
                    sol = crate::friction::implicit_velocity_step(
                        mass,
                        v_common,
                        drive + ext,
                        damping_m + fl.viscous,
                        coulomb_m + fl.coulomb + mesh,
                        ratio * coulomb_m + fl.static_limit() + mesh,
                        stuck,
                        dt,
                    );
                    let load_friction = if sol.stuck {
                        0.0
                    } else {
                        fl.coulomb * sol.v.signum()
                    };
                    f_t =
                        mass_l * (sol.v - v_common) / dt - ext + fl.viscous * sol.v + load_friction;
                }
                if f_t * flank.sign() < 0.0 && m.backlash.width > 0.0 {
                    // The flanks would have to pull: they separate after all.
                    self.fly(free_m, free_l, predicted_gap, dt);
                } else {
                    let target = m.backlash.gap_at(flank);
                    let (_, d_load) = Backlash::split_closure(target - self.gap, mass_m, mass_l);
                    self.q += sol.v * dt + d_load;
                    self.gap = target;
                    self.v_motor = sol.v;
                    self.v_load = sol.v;
                    self.stuck_motor = sol.stuck;
                    self.stuck_load = sol.stuck;
                    self.transmitted = f_t;
                }
            }
        }

        // 4. Current at the new speed (exact exponential), encoder at the new angle.
        self.current = if self.faults.motor_disconnected {
            0.0
        } else {
            let i = m
                .motor
                .current_after(self.current, u, n * self.v_motor, r, dt);
            // Flush a decayed current to zero rather than crawl through subnormals.
            if i.abs() < 1e-15 {
                0.0
            } else {
                i
            }
        };
        self.encoder.update(self.motor_angle());
    }

    /// Computes the step's constants for a new step length (out of the step's hot path).
    #[cold]
    #[inline(never)]
    fn refresh_constants(&mut self, dt: f64) {
        self.consts = StepConstants::new(&self.model, dt);
    }

    /// Free flight inside the backlash. A motor side whose free step would carry it past
    /// a flank (the contact's solution had the flanks pull: the load side held by its
    /// stiction against a push it cannot transmit) stops on the flank: it moves by what
    /// the gap's change and the load side's step leave it, and its velocity is that
    /// motion's (the velocity the back-EMF and the encoder both read), not the free step's.
    fn fly(&mut self, free_m: VelocityStep, free_l: VelocityStep, predicted_gap: f64, dt: f64) {
        let h = self.model.backlash.half();
        let gap = predicted_gap.clamp(-h, h);
        let on_flank = gap != predicted_gap;
        self.v_motor = if on_flank {
            free_l.v + (gap - self.gap) / dt
        } else {
            free_m.v
        };
        self.q += dt * free_l.v;
        self.gap = gap;
        self.v_load = free_l.v;
        self.stuck_motor = free_m.stuck && !on_flank;
        self.stuck_load = free_l.stuck;
        self.transmitted = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Plant, PlantConfig};

    /// The cached step against the step as first written, on every joint of the shipped
    /// plant: a duty that reverses (free flight through the backlash, both flanks), an
    /// external load that presses, lifts and reverses, stick and slip. The two differ only
    /// by rounding and by the contact force's fixed point, which the reference approaches
    /// in four passes (0.08^4 relative on the links).
    #[test]
    fn the_cached_step_follows_the_reference_step() -> Result<(), Box<dyn std::error::Error>> {
        let plant = Plant::new(&PlantConfig::default())?;
        let cpr = plant.config().encoder.counts_per_rev();
        let dt = 1e-4;
        for j in 0..6 {
            // The reference step predates the driver's current regulation: both run
            // without it here (tests/drive.rs tests the regulation).
            let mut model = *plant.joint(j)?.model();
            model.current_limit = f64::INFINITY;
            model.driver_ocp = f64::INFINITY;
            let effort = model.rated_effort();
            let mut a = Joint::new(model, cpr);
            let mut b = Joint::new(model, cpr);
            let (mut worst_q, mut worst_v, mut worst_i, mut worst_f) =
                (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            let (mut pushing, mut pulling, mut free) = (0, 0, 0);
            for k in 0..20_000 {
                let t = f64::from(k) * dt;
                let duty = 0.3 * (2.0 * std::f64::consts::PI * 1.5 * t).sin()
                    + 0.02 * (2.0 * std::f64::consts::PI * 13.0 * t).sin();
                let d = Duty {
                    applied: duty,
                    saturated: false,
                };
                let load = effort * 0.3 * (2.0 * std::f64::consts::PI * 0.7 * t).cos();
                for joint in [&mut a, &mut b] {
                    joint.set_duty(d);
                    joint.set_external_load(load);
                }
                a.step(dt);
                b.step_reference(dt);
                let f = a.transmitted_effort();
                if f > 0.0 {
                    pushing += 1;
                } else if f < 0.0 {
                    pulling += 1;
                } else {
                    free += 1;
                }
                worst_q = worst_q.max((a.position() - b.position()).abs());
                worst_v = worst_v.max((a.velocity() - b.velocity()).abs());
                worst_i = worst_i.max((a.current() - b.current()).abs());
                worst_f = worst_f.max((a.transmitted_effort() - b.transmitted_effort()).abs());
            }
            let v_max = model.no_load_speed(1.0);
            let i_stall = model.bridge.supply / model.circuit_resistance();
            assert!(
                pushing > 1000 && pulling > 1000 && free > 20,
                "joint {j}: flanks +{pushing} -{pulling}, free {free}"
            );
            // m or rad: 20 nm on a leg, 2 nm at the 90 mm of a link.
            assert!(worst_q <= 2e-8, "joint {j}: position {worst_q:e}");
            assert!(worst_v <= 1e-7 * v_max, "joint {j}: velocity {worst_v:e}");
            assert!(worst_i <= 1e-7 * i_stall, "joint {j}: current {worst_i:e}");
            assert!(
                worst_f <= 1e-5 * effort,
                "joint {j}: transmitted {worst_f:e}"
            );
        }
        Ok(())
    }
}
