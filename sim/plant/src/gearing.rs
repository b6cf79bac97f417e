//! Transmission between motor shaft and joint: ratio, efficiency and reflected inertia.
//!
//! The ratio `n` is the motor angle per unit of joint motion (rad/m for a lead-screw
//! joint, rad/rad for a geared rotary joint). Seen from the joint, the motor side is a
//! body of mass (or inertia) `J_motor n^2` driven by the force `n T_motor`.
//!
//! ## Efficiency
//! Friction in a gear mesh or a screw thread is proportional to the force that the
//! transmission carries. It is modelled as a Coulomb friction of magnitude `mu |F|`
//! (`F` the transmitted force at the joint) that opposes the transmission's motion, with
//! `mu = 1/eta - 1`. Driving the load this gives exactly the catalogue efficiency `eta`
//! (`F = eta n T`); back-driven by the load it gives `eta_back = 1 - mu = 2 - 1/eta`
//! (0.50 for the lead-screw joints, 0.89 for the rotary joints), and a transmission with
//! `eta <= 0.5` is self-locking, as a real lead screw is. At standstill the same
//! friction holds the load within that band (see [`crate::friction`]).

use crate::leadscrew::LeadScrew;
use std::f64::consts::TAU;

/// A transmission from motor shaft to joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transmission {
    /// Motor angle per unit of joint motion (rad/m or rad/rad).
    pub ratio: f64,
    /// Overall efficiency when the motor drives the load, 0..1.
    pub efficiency: f64,
    /// Inertia of gears and screw referred to the motor shaft, kg m^2.
    pub inertia_at_motor: f64,
}

impl Transmission {
    /// A gear train of reduction `gear_ratio` (motor turns per output turn) on a rotary
    /// joint.
    pub fn gearhead(gear_ratio: f64, efficiency: f64, inertia_at_motor: f64) -> Self {
        Transmission {
            ratio: gear_ratio,
            efficiency,
            inertia_at_motor,
        }
    }

    /// A gear stage of reduction `gear_ratio` followed by a lead screw, on a prismatic
    /// joint.
    pub fn gear_and_screw(
        gear_ratio: f64,
        gear_efficiency: f64,
        screw: LeadScrew,
        inertia_at_motor: f64,
    ) -> Self {
        Transmission {
            ratio: gear_ratio * screw.rad_per_metre(),
            efficiency: gear_efficiency * screw.efficiency,
            inertia_at_motor,
        }
    }

    /// Coefficient of the load-proportional transmission friction, `1/eta - 1`.
    pub fn mesh_friction_coefficient(&self) -> f64 {
        1.0 / self.efficiency - 1.0
    }

    /// Efficiency when the load back-drives the motor, `max(0, 2 - 1/eta)` (0 means
    /// self-locking).
    pub fn backdrive_efficiency(&self) -> f64 {
        (1.0 - self.mesh_friction_coefficient()).max(0.0)
    }

    /// Joint motion per motor revolution (m or rad).
    pub fn joint_travel_per_motor_rev(&self) -> f64 {
        TAU / self.ratio
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_mm_lead_behind_two_to_one_gives_three_mm_per_motor_turn() {
        let t = Transmission::gear_and_screw(
            2.0,
            0.95,
            LeadScrew {
                lead: 6e-3,
                efficiency: 0.7,
            },
            0.0,
        );
        assert!((t.joint_travel_per_motor_rev() - 3e-3).abs() < 1e-15);
        assert!((t.efficiency - 0.665).abs() < 1e-12);
        let r = Transmission::gearhead(36.0, 0.9, 0.0);
        assert!((r.joint_travel_per_motor_rev().to_degrees() - 10.0).abs() < 1e-12);
    }
}
