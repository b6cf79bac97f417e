//! The excitation: a staircase of duty steps, designed on the joint's prior (its drawing
//! and data sheets) to stay within a stated travel and motor effort on every plant within
//! the stated uncertainty of the prior.
//!
//! ## Model (joint units; `u` duty, `V` supply, `k = n Kt` the torque constant times the
//! gear, `R` the circuit resistance)
//! ```text
//! M dv/dt = k i - b v - Fc sgn v ,      L di/dt = V u - R i - k v
//! ```
//! With the current quasi-static (`L / R` is 0.1 .. 0.3 ms against a 1 ms period) the
//! duty drives the joint as `M dv/dt = K_u u - B v - Fc sgn v`, `K_u = k V / R` and
//! `B = b + k^2 / R` (the back-EMF is most of the damping), time constant `tau = M / B`.
//!
//! ## The staircase
//! Per direction `s = +1, -1`: duties `s u1, s u2, s u3, s u2, s u1, 0`, each held one
//! segment, where `u_i` gives the steady speed `i v_top / 3` on the prior,
//! `u = u_f + B v / K_u`, `u_f` the duty that holds the friction: the breakaway duty
//! measured in that direction (else the prior's `Fc / K_u`, which a plant with more
//! friction or less effort per duty than the prior may not overcome at the low levels). A segment lasts `settle` time constants of the slowest plant the
//! uncertainty allows (`tau (1 + e) / (1 - e)`, `e` the uncertainty): its first half
//! holds the acceleration (the inertia), its second half the steady motion (the friction
//! at three speeds, both directions). The zero-duty segment brakes the joint (the bridge
//! shorts the motor) to rest before the other direction, so the joint returns to its
//! start. `cycles` repeats the whole.
//!
//! ## Bounds
//! One staircase travels `(1 + 2 + 3 + 2 + 1) / 3 v_top T_seg = 3 v_top T_seg` plus the
//! braking `v_top tau / 3`; a plant within the uncertainty runs up to `(1 + e) / (1 - e)`
//! faster for the same duty (a smaller `k`), so `v_top` is chosen for that factor times
//! the travel to stay within the part of the limit the encoder sees (the limit less the
//! backlash, [`Excitation::unseen`]). The motor effort `k |i|` (quasi-static
//! `|K_u u - k^2 v / R|`) is simulated on the prior over the whole sequence and `v_top`
//! lowered until the same factor times its peak is within the effort limit.
//!
//! The plan cannot bound the travel alone: each level holds the breakaway duty, the
//! static friction, while the joint slides on its Coulomb friction, lower by the
//! breakaway ratio (1.2 on the reference robot); the surplus drives every level faster
//! than planned, by `(u_break - u_coulomb) V / k`, a speed the factor above does not
//! cover (on a link of the +-30 % plants, 0.0012 of duty: +0.05 rad/s on levels of 0.034,
//! 0.067 and 0.101 rad/s). So the run watches its travel with the stopping distance at the
//! measured speed ([`crate::rig::JointRig::record`]): a step that would leave the joint,
//! braked, beyond the limit is braked instead, and the plan's steps that way end there.
//! The current is watched against the effort limit likewise (the run stops beyond it).

use plant::joint::{JointKind, JointModel};

use crate::error::IdentifyError;

/// What is known of a joint before identification (drawing and data sheets), joint units:
/// m and N on a leg, rad and N m on a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prior {
    /// Leg or link.
    pub kind: JointKind,
    /// Reflected mass or inertia, both sides of the transmission, kg or kg m^2.
    pub mass: f64,
    /// Torque constant times the gear, `k = n Kt`, N/A or N m/A.
    pub force_per_amp: f64,
    /// Circuit resistance (winding and bridge), ohm.
    pub resistance: f64,
    /// Coulomb friction seen at the joint, N or N m.
    pub coulomb: f64,
    /// Mechanical viscous friction, N s/m or N m s/rad.
    pub viscous: f64,
    /// Bridge supply, V.
    pub supply_v: f64,
    /// Backlash between the motor (the encoder) and the load, m or rad (0 without).
    pub backlash: f64,
}

impl Prior {
    /// The joint as its motor sees it while it drives the load, from the joint's
    /// parameters (the data sheets' values for a prior; the plant's true ones to judge an
    /// identification). The transmission's friction is proportional to the force it
    /// carries (`plant::gearing`, `mu = 1 / eta - 1`), and the force it carries to the load
    /// is `m_load a + b_load v + Fc_load sgn v`, so the motor feels the load side's
    /// inertia and friction times `1 + mu`: mass `M_m + (1 + mu) m_load`, Coulomb
    /// friction `n Tc + (1 + mu) Fc_load`, viscous `n^2 b_m + (1 + mu) b_load` (the motor
    /// side's `M_m = (J_rotor + J_trans) n^2`, `Tc`, `b_m`).
    pub fn from_model(m: &JointModel) -> Prior {
        let n = m.transmission.ratio;
        let mu1 = 1.0 + m.transmission.mesh_friction_coefficient();
        Prior {
            kind: m.kind,
            mass: m.reflected_motor_inertia() + mu1 * m.load_inertia,
            force_per_amp: n * m.motor.torque_constant,
            resistance: m.circuit_resistance(),
            coulomb: n * m.motor_friction.coulomb + mu1 * m.load_friction.coulomb,
            viscous: n * n * m.motor_friction.viscous + mu1 * m.load_friction.viscous,
            supply_v: m.bridge.supply,
            backlash: m.backlash.width,
        }
    }

    /// Checks that every value is finite and positive (the viscous term and the backlash
    /// may be 0).
    pub fn validate(&self) -> Result<(), IdentifyError> {
        for (name, value, allow_zero) in [
            ("mass", self.mass, false),
            ("force_per_amp_n_per_a", self.force_per_amp, false),
            ("resistance_ohm", self.resistance, false),
            ("coulomb", self.coulomb, true),
            ("viscous", self.viscous, true),
            ("supply_v", self.supply_v, false),
            ("backlash", self.backlash, true),
        ] {
            let ok = value.is_finite() && (value > 0.0 || (allow_zero && value == 0.0));
            if !ok {
                return Err(IdentifyError::Prior { name, value });
            }
        }
        Ok(())
    }

    /// Effort per unit duty at rest, `K_u = k V / R`.
    pub fn force_per_duty(&self) -> f64 {
        self.force_per_amp * self.supply_v / self.resistance
    }

    /// Total damping seen from the duty, `B = b + k^2 / R`.
    pub fn damping(&self) -> f64 {
        self.viscous + self.force_per_amp * self.force_per_amp / self.resistance
    }

    /// Mechanical time constant `M / B`, s.
    pub fn time_constant(&self) -> f64 {
        self.mass / self.damping()
    }

    /// The duty of the steady speed `v` (>= 0).
    pub fn duty_for_speed(&self, v: f64) -> f64 {
        (self.damping() * v + self.coulomb) / self.force_per_duty()
    }
}

/// The bounds of the test: how far the joint may move from its start and how much effort
/// its motor may exert.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationLimits {
    /// Largest excursion from the start, m or rad.
    pub travel: f64,
    /// Largest motor effort `k |i|` at the joint, N or N m.
    pub effort: f64,
}

impl ExcitationLimits {
    /// The defaults: 3 mm and 110 N on a leg (half the rated 220 N), 5 deg and 0.25 N m
    /// on a link (half the rated 0.5 N m).
    pub fn for_kind(kind: JointKind) -> Self {
        match kind {
            JointKind::Prismatic => ExcitationLimits {
                travel: 3e-3,
                effort: 110.0,
            },
            JointKind::Rotary => ExcitationLimits {
                travel: 5f64.to_radians(),
                effort: 0.25,
            },
        }
    }

    /// Checks both are finite and positive.
    pub fn validate(&self) -> Result<(), IdentifyError> {
        for (name, value) in [("travel", self.travel), ("effort", self.effort)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(IdentifyError::Setting {
                    name,
                    value,
                    expected: "finite and positive",
                });
            }
        }
        Ok(())
    }
}

/// How the staircase is laid out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationDesign {
    /// Relative uncertainty of every prior parameter the bounds must hold for, in
    /// [0, 0.6]. Default 0.3.
    pub uncertainty: f64,
    /// Segment length in time constants of the slowest plant, >= 2. Default 5.
    pub settle: f64,
    /// Repetitions of the two staircases, >= 1. Default 2.
    pub cycles: usize,
    /// Ticks at rest before the first step. Default 20.
    pub lead_in_ticks: usize,
}

impl Default for ExcitationDesign {
    fn default() -> Self {
        ExcitationDesign {
            uncertainty: 0.3,
            settle: 5.0,
            cycles: 2,
            lead_in_ticks: 20,
        }
    }
}

/// A designed excitation: the duty of each control period and what the prior predicts.
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// One duty per control period.
    pub duties: Vec<f64>,
    /// Ticks per segment.
    pub segment_ticks: usize,
    /// The three steady speeds on the prior, m/s or rad/s.
    pub speeds: [f64; 3],
    /// The three duties towards +q and (magnitudes) towards -q.
    pub levels: [[f64; 3]; 2],
    /// The largest excursion from the start the prior predicts, m or rad.
    pub predicted_travel: f64,
    /// The largest motor effort the prior predicts, N or N m.
    pub predicted_effort: f64,
    /// The current the run stops at: the effort limit over the prior's `k`, A.
    pub current_limit_a: f64,
    /// The travel the joint must stay within, m or rad (the stated test travel).
    pub travel_limit: f64,
    /// The longest time constant of the braked joint within the uncertainty,
    /// `tau (1 + e)^2 / (1 - e)^2`, s: a joint braked at the speed `v` comes to rest
    /// within `v` times it (see [`crate::rig::Watch`]).
    pub stop_time_s: f64,
    /// The joint's motion the encoder cannot see: the largest backlash within the
    /// uncertainty, `(1 + e)` times the prior's, m or rad.
    pub unseen: f64,
}

impl Excitation {
    /// What the run watches: the travel and the current it must stay within, and how far
    /// a braked joint may coast.
    pub fn watch(&self) -> crate::rig::Watch {
        crate::rig::Watch {
            travel: self.travel_limit,
            current_limit_a: self.current_limit_a,
            stop_time_s: self.stop_time_s,
            unseen: self.unseen,
        }
    }
}

/// Simulates the prior's quasi-static model over `duties` (period `period_s`): the
/// largest excursion and the largest effort `|K_u u - k^2 v / R|`.
fn simulate_prior(prior: &Prior, duties: &[f64], period_s: f64) -> (f64, f64) {
    let ku = prior.force_per_duty();
    let b = prior.damping();
    let emf = prior.force_per_amp * prior.force_per_amp / prior.resistance;
    let m = prior.mass;
    let sub = 20;
    let dt = period_s / f64::from(sub);
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let (mut travel, mut effort) = (0.0f64, 0.0f64);
    for u in duties {
        for _ in 0..sub {
            let drive = ku * u - emf * v;
            effort = effort.max(drive.abs());
            // Backward Euler with Coulomb friction (plant::friction): sticks when the
            // momentum cannot overcome it.
            let p = m * v + dt * (drive + emf * v);
            let dc = dt * prior.coulomb;
            v = if p.abs() <= dc {
                0.0
            } else {
                (p - dc.copysign(p)) / (m + dt * b)
            };
            x += dt * v;
            travel = travel.max(x.abs());
        }
    }
    (travel, effort)
}

/// The staircase's duties for a top speed `v_top`: per direction, the duty that holds
/// the friction (`friction[0]` towards +q, `friction[1]` towards -q) plus the prior's
/// damping times the speed.
fn staircase(
    prior: &Prior,
    design: &ExcitationDesign,
    v_top: f64,
    seg: usize,
    friction: [f64; 2],
) -> (Vec<f64>, [f64; 3], [[f64; 3]; 2]) {
    let speeds = [v_top / 3.0, 2.0 * v_top / 3.0, v_top];
    let per_speed = prior.damping() / prior.force_per_duty();
    let levels = friction.map(|f| speeds.map(|v| f + per_speed * v));
    let mut duties = vec![0.0; design.lead_in_ticks];
    for _ in 0..design.cycles {
        for (s, l) in [(1.0, levels[0]), (-1.0, levels[1])] {
            for u in [l[0], l[1], l[2], l[1], l[0], 0.0] {
                duties.extend(std::iter::repeat_n(s * u, seg));
            }
        }
    }
    (duties, speeds, levels)
}

/// Designs the staircase for `prior` within `limits` at the control period `period_s`.
/// `breakaway`: the duties at which the joint was seen to start moving towards +q and -q
/// ([`crate::rig::JointRig::breakaway`]), the friction part of every level; without it
/// the prior's friction `Fc / K_u` (which a plant with more friction or less effort per
/// duty than the prior may not overcome at the lowest levels).
pub fn design(
    prior: &Prior,
    limits: &ExcitationLimits,
    design: &ExcitationDesign,
    period_s: f64,
    breakaway: Option<[f64; 2]>,
) -> Result<Excitation, IdentifyError> {
    prior.validate()?;
    if let Some(b) = breakaway {
        for v in b {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(IdentifyError::Setting {
                    name: "breakaway duty",
                    value: v,
                    expected: "0 .. 1",
                });
            }
        }
    }
    limits.validate()?;
    if !(design.uncertainty.is_finite() && (0.0..=0.6).contains(&design.uncertainty)) {
        return Err(IdentifyError::Setting {
            name: "uncertainty",
            value: design.uncertainty,
            expected: "0 .. 0.6",
        });
    }
    if !(design.settle.is_finite() && design.settle >= 2.0) {
        return Err(IdentifyError::Setting {
            name: "settle",
            value: design.settle,
            expected: ">= 2 time constants",
        });
    }
    if design.cycles == 0 {
        return Err(IdentifyError::Setting {
            name: "cycles",
            value: 0.0,
            expected: ">= 1",
        });
    }
    if !(period_s.is_finite() && period_s > 0.0) {
        return Err(IdentifyError::Setting {
            name: "period_s",
            value: period_s,
            expected: "finite and positive",
        });
    }
    let factor = (1.0 + design.uncertainty) / (1.0 - design.uncertainty);
    let tau_slow = prior.time_constant() * factor;
    let seg = (design.settle * tau_slow / period_s).ceil().max(16.0) as usize;
    let t_seg = seg as f64 * period_s;
    let friction_duty = prior.coulomb / prior.force_per_duty();
    let friction = breakaway.unwrap_or([friction_duty; 2]);
    // The prior with the friction the levels hold (the smaller side: the faster plant).
    let simulated = Prior {
        coulomb: friction[0].min(friction[1]) * prior.force_per_duty(),
        ..*prior
    };
    // The encoder (motor side) reads the travel less what the backlash hides: the plan
    // keeps to what it can see.
    let unseen = (1.0 + design.uncertainty) * prior.backlash;
    let travel = limits.travel - unseen;
    if travel <= 0.0 {
        return Err(IdentifyError::NoExcitation(format!(
            "the test travel {} is within the joint's backlash {unseen}",
            limits.travel
        )));
    }
    let stop_time_s = prior.time_constant() * factor * factor;
    let mut v_top = travel / (factor * (3.0 * t_seg + tau_slow / 3.0));
    for _ in 0..8 {
        let (duties, speeds, levels) = staircase(prior, design, v_top, seg, friction);
        let (predicted, effort) = simulate_prior(&simulated, &duties, period_s);
        let over = (factor * predicted / travel).max(factor * effort / limits.effort);
        if over <= 1.0 {
            let top = levels[0][2].max(levels[1][2]);
            if top >= 1.0 {
                return Err(IdentifyError::NoExcitation(format!(
                    "the top speed {v_top:.4} needs a duty of {top:.3} on the prior"
                )));
            }
            return Ok(Excitation {
                duties,
                segment_ticks: seg,
                speeds,
                levels,
                predicted_travel: predicted,
                predicted_effort: effort,
                current_limit_a: limits.effort / prior.force_per_amp,
                travel_limit: limits.travel,
                stop_time_s,
                unseen,
            });
        }
        // The excursion and (roughly) the effort grow with the speed: shrink and retry.
        v_top /= over * 1.05;
    }
    Err(IdentifyError::NoExcitation(format!(
        "the effort limit {} is too small for the joint's friction {:.4} (no speed fits)",
        limits.effort, prior.coulomb
    )))
}
