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

use crate::backlash::Backlash;
use crate::encoder::QuadratureEncoder;
use crate::friction::{implicit_velocity_step, Friction, VelocityStep};
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct JointFaults {
    /// The encoder counter is frozen.
    pub encoder_stuck: bool,
    /// The encoder drops one count in every `n`.
    pub encoder_lose_one_in: Option<u32>,
    /// The motor leads are open: no current flows, no torque, no back-EMF braking.
    pub motor_disconnected: bool,
    /// The load side is jammed (e.g. a mechanical collision): it does not move; the
    /// motor still moves within the backlash.
    pub load_seized: bool,
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

/// State of one joint.
#[derive(Debug, Clone)]
pub struct Joint {
    model: JointModel,
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
}

impl Joint {
    /// A joint at rest at `q = 0`, gap centred, counter 0.
    pub fn new(model: JointModel, counts_per_rev: u32) -> Self {
        let mut j = Joint {
            model,
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

    /// Replaces the set of injected faults.
    pub fn set_faults(&mut self, faults: JointFaults) {
        self.faults = faults;
        self.encoder.stuck = faults.encoder_stuck;
        self.encoder.lose_one_in = faults.encoder_lose_one_in;
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

    /// Force (N) or torque (N m) carried by the transmission at the joint.
    pub fn transmitted_effort(&self) -> f64 {
        self.transmitted
    }

    /// The 16-bit encoder counter.
    pub fn encoder_counter(&self) -> u16 {
        self.encoder.counter()
    }

    /// Advances the joint by `dt` seconds (`dt > 0`, checked by the caller).
    pub fn step(&mut self, dt: f64) {
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
        let free_m = implicit_velocity_step(
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
            implicit_velocity_step(
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
                    sol = implicit_velocity_step(
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

    /// Free flight inside the backlash.
    fn fly(&mut self, free_m: VelocityStep, free_l: VelocityStep, predicted_gap: f64, dt: f64) {
        let h = self.model.backlash.half();
        self.q += dt * free_l.v;
        self.gap = predicted_gap.clamp(-h, h);
        self.v_motor = free_m.v;
        self.v_load = free_l.v;
        self.stuck_motor = free_m.stuck;
        self.stuck_load = free_l.stuck;
        self.transmitted = 0.0;
    }
}
