//! Plants that differ from the drawing: every physical parameter of every joint drawn
//! within `+-spread` of its nominal value, from a seed (the robot a lab actually built).
//!
//! Drawn, independently per joint, uniform in `[1 - spread, 1 + spread]` times nominal:
//! the winding resistance and inductance, the torque constant (the back-EMF constant with
//! it: they are one constant in SI), the rotor and transmission inertias, the motor-side
//! Coulomb and viscous friction, the load's mass or inertia, its Coulomb and viscous
//! friction, and the backlash. Kept: the gearing and lead (the drawing's, which
//! commissioning checks), the efficiencies, the breakaway ratio, the driver's current
//! regulation and protection (board settings), the supply, the encoders.

use plant::config::DriveConfig;
use plant::PlantConfig;

use crate::error::IdentifyError;

/// SplitMix64: a seeded, well-mixed sequence (the same as the plant's sensor noise).
#[derive(Debug, Clone)]
pub struct SplitMix(u64);

impl SplitMix {
    /// A sequence from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix(seed)
    }

    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [-1, 1).
    pub fn symmetric(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// `base` with every drawn parameter (see the module documentation) multiplied by a
/// factor in `[1 - spread, 1 + spread]` from `seed`; `spread` in [0, 0.5].
pub fn perturbed(base: &PlantConfig, seed: u64, spread: f64) -> Result<PlantConfig, IdentifyError> {
    if !(spread.is_finite() && (0.0..=0.5).contains(&spread)) {
        return Err(IdentifyError::Setting {
            name: "spread",
            value: spread,
            expected: "0 .. 0.5",
        });
    }
    let mut rng = SplitMix::new(seed);
    let mut f = move || 1.0 + spread * rng.symmetric();
    let mut cfg = base.clone();
    for p in cfg.prismatic.iter_mut() {
        perturb_drive(&mut p.drive, &mut f);
        p.load_mass_kg *= f();
        p.load_coulomb_friction_n *= f();
        p.load_viscous_friction_n_s_per_m *= f();
        p.backlash_mm *= f();
    }
    for r in cfg.rotary.iter_mut() {
        perturb_drive(&mut r.drive, &mut f);
        r.load_inertia_kg_m2 *= f();
        r.load_coulomb_friction_nm *= f();
        r.load_viscous_friction_nm_s_per_rad *= f();
        r.backlash_arcsec *= f();
    }
    cfg.validate()
        .map_err(|e| IdentifyError::Plant(format!("the perturbed plant: {e}")))?;
    Ok(cfg)
}

/// A joint's motor and transmission, each factor drawn in turn from `f` (the torque
/// constant and the back-EMF constant are one constant in SI units: one factor for both).
fn perturb_drive(d: &mut DriveConfig, f: &mut impl FnMut() -> f64) {
    d.resistance_ohm *= f();
    d.inductance_h *= f();
    let kt = f();
    d.torque_constant_nm_per_a *= kt;
    d.back_emf_v_s_per_rad *= kt;
    d.rotor_inertia_kg_m2 *= f();
    d.transmission_inertia_kg_m2 *= f();
    d.coulomb_friction_motor_side_nm *= f();
    d.viscous_friction_motor_side_nm_s_per_rad *= f();
}
