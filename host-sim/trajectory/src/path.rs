//! A master's path: pieces (holds, straight moves, loops) one after the other.

use crate::figure8::Figure8;
use crate::profile::Profile;
use kinematics_core::pose::rotation_angle;
use kinematics_core::Pose;

/// One piece of a master path.
#[derive(Clone, Debug, PartialEq)]
pub enum Piece {
    /// Stay at a pose.
    Hold { pose: Pose<f64>, duration_s: f64 },
    /// A straight move (translation linear, rotation about a fixed world axis), the
    /// profile over the fraction 0..1 of the way.
    Line {
        from: Pose<f64>,
        to: Pose<f64>,
        profile: Profile,
    },
    /// One lap of a figure-eight, the profile over its arc length (m).
    Loop { figure: Figure8, profile: Profile },
}

impl Piece {
    /// Duration, s.
    pub fn duration(&self) -> f64 {
        match self {
            Piece::Hold { duration_s, .. } => *duration_s,
            Piece::Line { profile, .. } | Piece::Loop { profile, .. } => profile.duration(),
        }
    }

    /// Pose `t` seconds into the piece.
    pub fn pose(&self, t: f64) -> Pose<f64> {
        match self {
            Piece::Hold { pose, .. } => *pose,
            Piece::Line { from, to, profile } => {
                kinematics_core::supervisor::interpolate(from, to, profile.distance(t))
            }
            Piece::Loop { figure, profile } => figure.pose_at_length(profile.distance(t)),
        }
    }

    /// Pose at the end.
    pub fn end(&self) -> Pose<f64> {
        self.pose(self.duration())
    }
}

/// A master path: pieces one after the other from t = 0.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    pieces: Vec<(f64, Piece)>,
    end_s: f64,
}

impl Trajectory {
    /// Appends a piece; returns its start time, s.
    pub fn push(&mut self, piece: Piece) -> f64 {
        let start = self.end_s;
        self.end_s += piece.duration();
        self.pieces.push((start, piece));
        start
    }

    /// End time, s.
    pub fn end_s(&self) -> f64 {
        self.end_s
    }

    /// Pose at time `t` (the last pose after the end); `None` when empty.
    pub fn pose(&self, t: f64) -> Option<Pose<f64>> {
        let i = self.pieces.partition_point(|(s, _)| *s <= t);
        let (start, piece) = self.pieces.get(i.saturating_sub(1))?;
        Some(piece.pose(t - start))
    }

    /// Pose at the end; `None` when empty.
    pub fn last(&self) -> Option<Pose<f64>> {
        self.pieces.last().map(|(_, p)| p.end())
    }
}

/// A time interval judged on its own (a pass of the laparoscope path, the carrying of the
/// tool, ...).
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    pub name: String,
    pub start_s: f64,
    pub end_s: f64,
    /// The tip speed along the path, mm/s, for passes at a constant speed.
    pub speed_mm_s: Option<f64>,
}

/// The master's limits on a straight move (the simulation's `[master]` settings).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterLimits {
    /// Tip acceleration, mm/s^2.
    pub accel_mm_s2: f64,
    /// Angular speed and acceleration of the platform, deg/s and deg/s^2.
    pub angular_speed_deg_s: f64,
    pub angular_accel_deg_s2: f64,
}

/// A straight move at `speed_mm_s` within the master's `limits` (the rotation at their
/// angular speed and acceleration).
pub fn line(limits: &MasterLimits, from: &Pose<f64>, to: &Pose<f64>, speed_mm_s: f64) -> Piece {
    let m = limits;
    let dist = (to.t - from.t).norm();
    let angle = rotation_angle(&(to.r * from.r.inverse()));
    let mut rate = f64::INFINITY;
    let mut acc = f64::INFINITY;
    if dist > 0.0 {
        rate = rate.min(speed_mm_s * 1e-3 / dist);
        acc = acc.min(m.accel_mm_s2 * 1e-3 / dist);
    }
    if angle > 0.0 {
        rate = rate.min(m.angular_speed_deg_s.to_radians() / angle);
        acc = acc.min(m.angular_accel_deg_s2.to_radians() / angle);
    }
    let profile = if rate.is_finite() {
        Profile::new(1.0, rate, acc)
    } else {
        Profile::new(0.0, 0.0, 0.0)
    };
    Piece::Line {
        from: *from,
        to: *to,
        profile,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use nalgebra::Vector3;

    const LIMITS: MasterLimits = MasterLimits {
        accel_mm_s2: 100.0,
        angular_speed_deg_s: 10.0,
        angular_accel_deg_s2: 60.0,
    };

    /// A line ends at its target; the trajectory holds the last pose after its end.
    #[test]
    fn a_line_reaches_its_end_and_the_path_holds_it() {
        let a = Pose::central(0.16);
        let b = Pose {
            t: a.t + Vector3::new(0.01, 0.0, 0.0),
            r: a.r,
        };
        let mut t = Trajectory::default();
        t.push(line(&LIMITS, &a, &b, 10.0));
        // 10 mm at 10 mm/s with 100 mm/s^2: 1 s plus 0.1 s of ramps.
        assert!((t.end_s() - 1.1).abs() < 1e-12, "{}", t.end_s());
        for time in [t.end_s(), t.end_s() + 5.0] {
            assert!((t.pose(time).unwrap().t - b.t).norm() < 1e-15);
        }
        assert!((t.pose(0.0).unwrap().t - a.t).norm() < 1e-15);
        assert!(Trajectory::default().pose(0.0).is_none());
    }
}
