//! The laparoscope path: figure-eight passes through the task box from the central pose,
//! at the speeds and scales of its settings (`[scenario.laparoscope]` of the simulation's
//! `default.toml`), the path `host-sim sim` follows and `host-sim teleop` streams.

use crate::figure8::Figure8;
use crate::path::{Phase, Piece, Trajectory};
use crate::profile::Profile;
use kinematics_core::Pose;
use nalgebra::Vector3;
use serde::Deserialize;

/// The laparoscope path's settings (`[scenario.laparoscope]`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Laparoscope {
    /// The figure-eight's size: amplitudes in x and y, the dip in z, mm.
    pub loop_size_mm: [f64; 3],
    /// The largest tilt of the platform, deg.
    pub tilt_deg: f64,
    /// One lap per pass at these tip speeds, mm/s ...
    pub pass_speeds_mm_s: Vec<f64>,
    /// ... with the figure scaled by these factors.
    pub pass_scales: Vec<f64>,
    /// Hold at the centre before the first pass, s.
    pub hold_s: f64,
    /// Time after a pass that still belongs to its phase, s (and the least hold after it).
    pub settle_s: f64,
}

/// The laparoscope path from `centre` with the tip acceleration `accel_mm_s2` (mm/s^2): a
/// hold, then per pass one lap of the figure-eight and a hold at the centre. The phases
/// are the passes, each with its settling time.
pub fn laparoscope(
    settings: &Laparoscope,
    accel_mm_s2: f64,
    centre: &Pose<f64>,
) -> (Trajectory, Vec<Phase>) {
    let l = settings;
    let size = Vector3::from(l.loop_size_mm) * 1e-3;
    let mut traj = Trajectory::default();
    traj.push(Piece::Hold {
        pose: *centre,
        duration_s: l.hold_s,
    });
    let mut phases = Vec::new();
    for (i, (speed, scale)) in l.pass_speeds_mm_s.iter().zip(&l.pass_scales).enumerate() {
        let figure = Figure8::new(centre.t, size * *scale, l.tilt_deg.to_radians());
        let length = figure.length();
        let profile = Profile::new(length, speed * 1e-3, accel_mm_s2 * 1e-3);
        let start = traj.push(Piece::Loop { figure, profile });
        phases.push(Phase {
            name: format!(
                "pass {}: {speed} mm/s, figure-eight x{scale} ({:.1} mm, tilt up to {} deg)",
                i + 1,
                length * 1e3,
                l.tilt_deg
            ),
            start_s: start,
            end_s: start + profile.duration() + l.settle_s,
            speed_mm_s: Some(*speed),
        });
        traj.push(Piece::Hold {
            pose: *centre,
            duration_s: l.hold_s.max(l.settle_s),
        });
    }
    (traj, phases)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// Each pass is one lap at its speed: it starts and ends at the centre, and its phase
    /// lasts the lap (length / speed plus the ramps) and the settling time.
    #[test]
    fn each_pass_is_a_lap_from_the_centre_back_to_it() {
        let settings = Laparoscope {
            loop_size_mm: [15.0, 12.0, 5.0],
            tilt_deg: 20.0,
            pass_speeds_mm_s: vec![2.5, 25.0],
            pass_scales: vec![0.25, 1.0],
            hold_s: 0.3,
            settle_s: 0.3,
        };
        let centre = Pose::central(0.16);
        let (traj, phases) = laparoscope(&settings, 100.0, &centre);
        assert_eq!(phases.len(), 2);
        for (p, scale) in phases.iter().zip(&settings.pass_scales) {
            for t in [p.start_s, p.end_s] {
                assert!(
                    (traj.pose(t).unwrap().t - centre.t).norm() < 1e-9,
                    "{}",
                    p.name
                );
            }
            let speed = p.speed_mm_s.unwrap() * 1e-3;
            let size = Vector3::from(settings.loop_size_mm) * (1e-3 * scale);
            let length = Figure8::new(centre.t, size, 0.0).length();
            let lap_s = p.end_s - p.start_s - settings.settle_s;
            // A trapezoid: at least length / speed, at most one ramp time speed / accel more.
            assert!(lap_s >= length / speed - 1e-12, "{}: {lap_s}", p.name);
            assert!(
                lap_s <= length / speed + speed / 0.1 + 1e-12,
                "{}: {lap_s}",
                p.name
            );
            // Halfway through the lap the platform is away from the centre.
            let half = traj.pose(p.start_s + lap_s / 2.0).unwrap();
            assert!((half.t - centre.t).norm() > 1e-3 * scale, "{}", p.name);
        }
        assert!(phases[1]
            .name
            .starts_with("pass 2: 25 mm/s, figure-eight x1 ("));
    }
}
