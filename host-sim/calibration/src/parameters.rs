//! The identified parameters: 14 per chain (42 for the robot) and 6 for each of the two
//! transforms of the measurement (tracker to base, marker to platform), as deviations from
//! a reference (the nominal robot and the transforms' first estimates).
//!
//! Per chain, in this order: the base pivot (3, m), the base axis's tilt about two
//! directions normal to it (2, rad), the link length (m), the platform joint (3, m), the
//! platform axis's tilt (2, rad), the leg's length offset, the leg encoder's zero (m) and
//! the link encoder's zero (rad). The transforms: translation (3, m) and rotation vector
//! (3, rad, applied on the left of the reference rotation).
//!
//! Each parameter has a **scale**, its tolerance (0.5 mm on positions and lengths, 0.5 deg
//! on axes, 20 counts on the encoder zeros; 1 mm and 1 deg on the transforms): the solver
//! and the identifiability analysis work on the parameters divided by their scales, so
//! that a singular value of 1 means "determined to its tolerance".

use crate::rigid::{self, Rigid};
use kinematics_core::{Chain, ChainDimensions, GeometryError, PerChain, PerChainGeometry};
use nalgebra::{Rotation3, Vector3};

/// Parameters per chain.
pub const PER_CHAIN: usize = 14;
/// Parameters of the robot (three chains).
pub const ROBOT: usize = 3 * PER_CHAIN;
/// Index of the first tracker-to-base parameter.
pub const TRACKER: usize = ROBOT;
/// Index of the first marker-to-platform parameter.
pub const MARKER: usize = ROBOT + 6;
/// All parameters.
pub const COUNT: usize = ROBOT + 12;

/// One encoder count of the legs, m (the reference board profile's).
pub fn leg_count_m() -> f64 {
    board_profile::BoardProfile::REFERENCE.joints[0].unit_per_count()
}
/// One encoder count of the rotating links, rad (the reference board profile's).
pub fn link_count_rad() -> f64 {
    board_profile::BoardProfile::REFERENCE.joints[3].unit_per_count()
}

/// A parameter's unit at the edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// Metres, shown in mm.
    Length,
    /// Radians, shown in deg.
    Angle,
}

/// What the parameter at an index is.
#[derive(Clone, Debug, PartialEq)]
pub struct Info {
    /// E.g. `chain1.base_pivot_x`, `tracker.rx`.
    pub name: String,
    /// Its unit.
    pub unit: Unit,
    /// Its scale (tolerance), SI.
    pub scale: f64,
}

/// The manufacturing tolerances the scales are (and the simulation perturbs by).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Positions and lengths, m.
    pub length_m: f64,
    /// Axis directions, rad.
    pub axis_rad: f64,
    /// Encoder zeros, counts.
    pub zero_counts: f64,
}

impl Default for Tolerances {
    /// ±0.5 mm, ±0.5 deg, ±20 counts (issue 19).
    fn default() -> Self {
        Tolerances {
            length_m: 0.5e-3,
            axis_rad: 0.5f64.to_radians(),
            zero_counts: 20.0,
        }
    }
}

const CHAIN_FIELDS: [(&str, Unit); PER_CHAIN] = [
    ("base_pivot_x", Unit::Length),
    ("base_pivot_y", Unit::Length),
    ("base_pivot_z", Unit::Length),
    ("base_axis_tilt_1", Unit::Angle),
    ("base_axis_tilt_2", Unit::Angle),
    ("link_length", Unit::Length),
    ("platform_joint_x", Unit::Length),
    ("platform_joint_y", Unit::Length),
    ("platform_joint_z", Unit::Length),
    ("platform_axis_tilt_1", Unit::Angle),
    ("platform_axis_tilt_2", Unit::Angle),
    ("leg_offset", Unit::Length),
    ("leg_zero", Unit::Length),
    ("link_zero", Unit::Angle),
];

/// Every parameter's name, unit and scale, in index order.
pub fn infos(tol: &Tolerances) -> Vec<Info> {
    let mut v = Vec::with_capacity(COUNT);
    for chain in 1..=3 {
        for (k, (field, unit)) in CHAIN_FIELDS.iter().enumerate() {
            let scale = match (k, unit) {
                (12, _) => tol.zero_counts * leg_count_m(),
                (13, _) => tol.zero_counts * link_count_rad(),
                (_, Unit::Length) => tol.length_m,
                (_, Unit::Angle) => tol.axis_rad,
            };
            v.push(Info {
                name: format!("chain{chain}.{field}"),
                unit: *unit,
                scale,
            });
        }
    }
    for frame in ["tracker", "marker"] {
        for (axis, unit, scale) in [
            ("x", Unit::Length, 1e-3),
            ("y", Unit::Length, 1e-3),
            ("z", Unit::Length, 1e-3),
            ("rx", Unit::Angle, 1f64.to_radians()),
            ("ry", Unit::Angle, 1f64.to_radians()),
            ("rz", Unit::Angle, 1f64.to_radians()),
        ] {
            v.push(Info {
                name: format!("{frame}.{axis}"),
                unit,
                scale,
            });
        }
    }
    v
}

/// Two unit vectors normal to `v` and to each other (the directions of its tilts).
pub fn tilt_basis(v: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    // The world axis least aligned with v, made normal to it.
    let pick = [Vector3::x(), Vector3::y(), Vector3::z()]
        .into_iter()
        .min_by(|a, b| a.dot(v).abs().total_cmp(&b.dot(v).abs()))
        .unwrap_or_else(Vector3::x);
    let e1 = (pick - v * pick.dot(v)).normalize();
    (e1, v.cross(&e1))
}

fn tilted(v: &Vector3<f64>, a: f64, b: f64) -> Vector3<f64> {
    let (e1, e2) = tilt_basis(v);
    (v + e1 * a + e2 * b).normalize()
}

/// The robot of the reference with the deviations `delta` (its first [`ROBOT`] entries).
pub fn geometry(
    reference: &PerChainGeometry<f64>,
    delta: &[f64],
) -> Result<PerChainGeometry<f64>, GeometryError> {
    let chains = PerChain::from_fn(|c: Chain| {
        let d = &reference.chains()[c];
        let x = |k: usize| delta.get(c.index() * PER_CHAIN + k).copied().unwrap_or(0.0);
        ChainDimensions {
            base_pivot: d.base_pivot + Vector3::new(x(0), x(1), x(2)),
            base_axis: tilted(&d.base_axis, x(3), x(4)),
            link_length: d.link_length + x(5),
            platform_joint: d.platform_joint + Vector3::new(x(6), x(7), x(8)),
            platform_axis: tilted(&d.platform_axis, x(9), x(10)),
            leg_offset: d.leg_offset + x(11),
            leg_zero: d.leg_zero + x(12),
            link_zero: d.link_zero + x(13),
        }
    });
    PerChainGeometry::new(*reference.nominal(), chains)
}

/// A transform of the reference moved by the six deviations from `first`.
pub fn transform(reference: &Rigid, delta: &[f64], first: usize) -> Rigid {
    let x = |k: usize| delta.get(first + k).copied().unwrap_or(0.0);
    Rigid {
        t: reference.t + Vector3::new(x(0), x(1), x(2)),
        r: Rotation3::from_scaled_axis(Vector3::new(x(3), x(4), x(5))) * reference.r,
    }
}

/// The deviations that turn `reference` into `target` for one chain's tilt pair
/// (first-order: the components of the new axis along the tilt basis).
pub fn tilt_of(reference: &Vector3<f64>, target: &Vector3<f64>) -> (f64, f64) {
    let (e1, e2) = tilt_basis(reference);
    let s = target.dot(reference);
    (target.dot(&e1) / s, target.dot(&e2) / s)
}

/// The deviations (robot part) that turn `reference` into `target`: exact, since the tilt
/// parameterisation is v + a e1 + b e2 normalised.
pub fn robot_delta(reference: &PerChainGeometry<f64>, target: &PerChainGeometry<f64>) -> Vec<f64> {
    let mut v = vec![0.0; ROBOT];
    for c in Chain::ALL {
        let (r, t) = (&reference.chains()[c], &target.chains()[c]);
        let (a1, a2) = tilt_of(&r.base_axis, &t.base_axis);
        let (p1, p2) = tilt_of(&r.platform_axis, &t.platform_axis);
        let dc = t.base_pivot - r.base_pivot;
        let dp = t.platform_joint - r.platform_joint;
        let vals = [
            dc.x,
            dc.y,
            dc.z,
            a1,
            a2,
            t.link_length - r.link_length,
            dp.x,
            dp.y,
            dp.z,
            p1,
            p2,
            t.leg_offset - r.leg_offset,
            t.leg_zero - r.leg_zero,
            t.link_zero - r.link_zero,
        ];
        for (k, x) in vals.into_iter().enumerate() {
            if let Some(slot) = v.get_mut(c.index() * PER_CHAIN + k) {
                *slot = x;
            }
        }
    }
    v
}

/// The deviations of a transform from its reference (translation, rotation vector).
pub fn transform_delta(reference: &Rigid, target: &Rigid) -> [f64; 6] {
    let dt = target.t - reference.t;
    let dr = rigid::rotation_vector(&(target.r * reference.r.inverse()));
    [dt.x, dt.y, dt.z, dr.x, dr.y, dr.z]
}
