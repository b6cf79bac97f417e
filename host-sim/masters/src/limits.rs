//! Master-side velocity and acceleration limits on the target stream.
//!
//! The board's supervisor enforces its own limits (tip speed 25 mm/s, angular speed
//! 30 deg/s, tip acceleration 250 mm/s², angular acceleration 300 deg/s²: see
//! `Limits::reference()` in `kinematics-core`) and shapes the motion to them: its profile
//! accelerates and brakes within them, and its lead puts the robot on the master's pose
//! despite the braking curve. The master therefore sends the operator's intent as soon as
//! it has it: by default it only caps the speed, at 20 mm/s and 25 deg/s, below the
//! supervisor's (which a motion under the cap never meets, so the cap delays nothing the
//! operator does within it), and limits no acceleration (an acceleration limit
//! `f64::INFINITY`). An acceleration limit on the master lags every start of a motion at
//! speed `v` by up to `v / (2 a)` (25 ms at 10 mm/s and 200 mm/s²), a delay the
//! supervisor's profile would add again; it stays available
//! ([`MotionLimits::with_acceleration`]: 200 mm/s², 250 deg/s²) for a board without
//! that shaping.
//!
//! # The limiter
//!
//! Position and orientation are each limited as a 3-vector (the orientation through the
//! rotation increment, a rotation vector in {0}). Each tick of length `dt`, with `e` the
//! remaining error to the desired pose and `v` the previous velocity:
//!
//! 1. the desired speed is `min(v_max, |e|/dt, s_brake)`, where `s_brake` is the largest
//!    speed from which the acceleration limit still stops within `|e|` in discrete steps:
//!    `s²/(2a) + s·dt/2 = |e|`;
//! 2. the velocity change is limited to `a_max·dt` (in norm);
//! 3. the velocity is limited to `v_max` (in norm; a projection onto a ball that holds
//!    the previous velocity, so step 2's bound still holds);
//! 4. the pose moves by `v·dt`.
//!
//! Without an acceleration limit (`a_max` infinite) a tick goes to the desired pose, or
//! `v_max·dt` towards it.
//!
//! So every output satisfies `|Δx|/dt ≤ v_max` and `|Δx_k/dt_k − Δx_{k−1}/dt_{k−1}| ≤
//! a_max·dt_k` (up to rounding), and a pose that is already where it is wanted stays
//! exactly there.

use crate::pose::{rotate, rotation_increment, CartesianPose};
use nalgebra::Vector3;
use thiserror::Error;

/// The limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionLimits {
    /// Largest tip speed, m/s.
    pub linear_speed_m_s: f64,
    /// Largest angular speed, rad/s.
    pub angular_speed_rad_s: f64,
    /// Largest tip acceleration, m/s² (`f64::INFINITY`: none on the master).
    pub linear_accel_m_s2: f64,
    /// Largest angular acceleration, rad/s² (`f64::INFINITY`: none on the master).
    pub angular_accel_rad_s2: f64,
}

impl Default for MotionLimits {
    /// 20 mm/s, 25 deg/s, no acceleration limit (the board's supervisor has its own).
    fn default() -> Self {
        MotionLimits {
            linear_speed_m_s: 0.020,
            angular_speed_rad_s: 25f64.to_radians(),
            linear_accel_m_s2: f64::INFINITY,
            angular_accel_rad_s2: f64::INFINITY,
        }
    }
}

impl MotionLimits {
    /// The default speed caps with acceleration limits below the supervisor's: 200 mm/s²,
    /// 250 deg/s².
    pub fn with_acceleration() -> Self {
        MotionLimits {
            linear_accel_m_s2: 0.200,
            angular_accel_rad_s2: 250f64.to_radians(),
            ..MotionLimits::default()
        }
    }
}

/// A limit that is not positive (speeds: and finite).
#[derive(Clone, Copy, Debug, Error, PartialEq)]
#[error("motion limits: {field} = {value} is not positive (and finite, for a speed)")]
pub struct LimitsError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
}

impl MotionLimits {
    /// Checks every limit is positive, the speeds finite (an infinite acceleration limit
    /// is none).
    pub fn validate(&self) -> Result<(), LimitsError> {
        for (field, value, infinite_ok) in [
            ("linear_speed_m_s", self.linear_speed_m_s, false),
            ("angular_speed_rad_s", self.angular_speed_rad_s, false),
            ("linear_accel_m_s2", self.linear_accel_m_s2, true),
            ("angular_accel_rad_s2", self.angular_accel_rad_s2, true),
        ] {
            if !((value.is_finite() || (infinite_ok && value == f64::INFINITY)) && value > 0.0) {
                return Err(LimitsError { field, value });
            }
        }
        Ok(())
    }
}

/// One 3-vector channel of the limiter.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Channel {
    v: Vector3<f64>,
    v_max: f64,
    a_max: f64,
}

impl Channel {
    /// The displacement this tick toward `error` (desired − current); whether a limit
    /// acted.
    fn step(&mut self, error: &Vector3<f64>, dt: f64) -> (Vector3<f64>, bool) {
        let d = error.norm();
        let (desired, mut limited) = if d == 0.0 {
            (Vector3::zeros(), false)
        } else if self.a_max == f64::INFINITY {
            // No acceleration limit: there at once (exactly), or at v_max towards it.
            if d / dt <= self.v_max {
                self.v = error / dt;
                return (*error, false);
            }
            (error * (self.v_max / d), true)
        } else {
            let half = self.a_max * dt / 2.0;
            let s_brake = -half + (half * half + 2.0 * self.a_max * d).sqrt();
            let s = self.v_max.min(d / dt).min(s_brake);
            (error * (s / d), s < d / dt)
        };
        let mut dv = desired - self.v;
        let dv_max = self.a_max * dt;
        let n = dv.norm();
        if n > dv_max && self.a_max.is_finite() {
            dv *= dv_max / n;
            limited = true;
        }
        let mut v = self.v + dv;
        let s = v.norm();
        if s > self.v_max {
            v *= self.v_max / s;
            limited = true;
        }
        self.v = v;
        (v * dt, limited)
    }
}

/// The pose limiter.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseLimiter {
    linear: Channel,
    angular: Channel,
    pose: CartesianPose,
}

impl PoseLimiter {
    /// A limiter at rest at `pose`.
    pub fn new(limits: &MotionLimits, pose: CartesianPose) -> Result<Self, LimitsError> {
        limits.validate()?;
        Ok(PoseLimiter {
            linear: Channel {
                v: Vector3::zeros(),
                v_max: limits.linear_speed_m_s,
                a_max: limits.linear_accel_m_s2,
            },
            angular: Channel {
                v: Vector3::zeros(),
                v_max: limits.angular_speed_rad_s,
                a_max: limits.angular_accel_rad_s2,
            },
            pose,
        })
    }

    /// At rest at `pose`.
    pub fn reset(&mut self, pose: CartesianPose) {
        self.pose = pose;
        self.linear.v = Vector3::zeros();
        self.angular.v = Vector3::zeros();
    }

    /// The current pose.
    pub fn pose(&self) -> &CartesianPose {
        &self.pose
    }

    /// Current linear and angular velocity.
    pub fn velocity(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.linear.v, self.angular.v)
    }

    /// One tick of `dt` seconds toward `desired`; the new pose and whether a limit
    /// acted (the output is not the desired pose).
    pub fn step(&mut self, desired: &CartesianPose, dt: f64) -> (CartesianPose, bool) {
        let e_lin = desired.position_m - self.pose.position_m;
        let e_ang = rotation_increment(&self.pose.orientation, &desired.orientation);
        let (dp, l1) = self.linear.step(&e_lin, dt);
        let (dr, l2) = self.angular.step(&e_ang, dt);
        self.pose = CartesianPose {
            position_m: self.pose.position_m + dp,
            orientation: rotate(&self.pose.orientation, &dr),
        };
        (self.pose, l1 || l2)
    }
}
