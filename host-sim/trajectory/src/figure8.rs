//! The laparoscope's closed figure-eight.

use kinematics_core::Pose;
use nalgebra::{Rotation3, Vector3};
use std::f64::consts::PI;

/// The laparoscope's closed figure-eight (see `[scenario.laparoscope]` in the simulation's
/// `default.toml`): from the centre, x = a sin(2 pi u), y = b sin(4 pi u), a dip of c (1 -
/// cos(2 pi u)) below the centre in z, the platform tilting up to `tilt` about a
/// horizontal axis that turns once per lap.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure8 {
    /// Centre, m.
    pub centre: Vector3<f64>,
    /// Size, m: the amplitudes in x and y, the dip below the centre in z.
    pub size: Vector3<f64>,
    /// Largest tilt, rad.
    pub tilt: f64,
    /// Cumulative length at u = i / (n - 1), m.
    table: Vec<f64>,
}

impl Figure8 {
    const SAMPLES: usize = 4001;

    /// The figure with its arc-length table.
    pub fn new(centre: Vector3<f64>, size: Vector3<f64>, tilt: f64) -> Self {
        let mut f = Figure8 {
            centre,
            size,
            tilt,
            table: Vec::with_capacity(Self::SAMPLES),
        };
        let mut acc = 0.0;
        let mut prev = f.position(0.0);
        f.table.push(0.0);
        for i in 1..Self::SAMPLES {
            let p = f.position(i as f64 / (Self::SAMPLES - 1) as f64);
            acc += (p - prev).norm();
            f.table.push(acc);
            prev = p;
        }
        f
    }

    /// Length of the loop, m.
    pub fn length(&self) -> f64 {
        self.table.last().copied().unwrap_or(0.0)
    }

    fn position(&self, u: f64) -> Vector3<f64> {
        let a = 2.0 * PI * u;
        self.centre
            + Vector3::new(
                self.size.x * a.sin(),
                self.size.y * (2.0 * a).sin(),
                self.size.z * (a.cos() - 1.0),
            )
    }

    /// The pose at parameter `u` in [0, 1].
    pub fn pose_at_u(&self, u: f64) -> Pose<f64> {
        let theta = self.tilt * (PI * u).sin().powi(2);
        let axis = Vector3::new((PI * u).cos(), (PI * u).sin(), 0.0);
        Pose {
            t: self.position(u),
            r: Rotation3::from_scaled_axis(axis * theta),
        }
    }

    /// The pose at arc length `s`, m.
    pub fn pose_at_length(&self, s: f64) -> Pose<f64> {
        let n = self.table.len();
        if n < 2 {
            return self.pose_at_u(0.0);
        }
        let s = s.clamp(0.0, self.length());
        let i = self.table.partition_point(|x| *x < s).clamp(1, n - 1);
        let (s0, s1) = (self.table[i - 1], self.table[i]);
        let f = if s1 > s0 { (s - s0) / (s1 - s0) } else { 0.0 };
        self.pose_at_u(((i - 1) as f64 + f) / (n - 1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics_core::pose::rotation_angle;

    #[test]
    fn figure8_starts_and_ends_at_the_centre() {
        let c = Vector3::new(0.0, 0.0, 0.16);
        let f = Figure8::new(c, Vector3::new(0.015, 0.012, 0.007), 0.3);
        for s in [0.0, f.length()] {
            let p = f.pose_at_length(s);
            assert!((p.t - c).norm() < 1e-9);
            assert!(rotation_angle(&p.r) < 1e-9);
        }
    }
}
