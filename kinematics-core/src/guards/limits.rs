//! Every limit of the guards, in SI, with the reference robot's values and where they come
//! from.

use crate::scalar::{lit, Real};
use crate::vectors::Wrench;
use core::fmt;
use nalgebra::Vector3;

/// A warn level and a stop level for one guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Levels<T: Real> {
    pub warn: T,
    pub stop: T,
}

/// Every limit, in SI. See [`Limits::reference`] for the defaults and where they come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits<T: Real> {
    /// Prismatic stroke (RSPR), m: [min, max].
    pub stroke: [T; 2],
    /// Largest deviation of θ_i (RSPR) or α_i (USR) from its central value, rad.
    pub link_angle_max: T,
    /// Largest deviation of β_i (USR) from its central value, rad.
    pub pitch_max: T,
    /// Largest spherical-joint tilt, rad.
    pub tilt_max: T,
    /// Height of the plane of the central motors' tops above the base plane, m (11.4).
    pub collision_plane_height: T,
    /// Safety-circle radius in that plane, m; 0 disables the collision guard.
    pub collision_radius: T,
    /// Half-extents of the task box centred at [0, 0, hc], m.
    pub box_half: Vector3<T>,
    /// Margin around the task box, m.
    pub box_margin: T,
    /// Largest platform tilt (angle between n and z0), rad.
    pub tilt_cone: T,
    /// Serial measure (dimensionless, lower bound): warn and stop levels.
    pub serial: Levels<T>,
    /// Parallel inverse condition number (lower bound): warn and stop levels.
    pub parallel: Levels<T>,
    /// Largest speed of o_p, m/s.
    pub tip_speed: T,
    /// Largest angular speed, rad/s.
    pub angular_speed: T,
    /// Largest acceleration of o_p, m/s².
    pub tip_accel: T,
    /// Largest angular acceleration, rad/s².
    pub angular_accel: T,
    /// Largest joint speed: [prismatic m/s, revolute rad/s].
    pub joint_speed: [T; 2],
    /// Largest joint acceleration: [prismatic m/s², revolute rad/s²].
    pub joint_accel: [T; 2],
    /// The declared payload: the wrench the platform exerts on its environment when its
    /// force part acts through the platform point `payload_lever` (see
    /// [`Limits::payload_at`]); moment about o_p, in {0}.
    pub payload: Wrench<T>,
    /// The point of {p} through which the payload's force acts, m (a tool's centre of
    /// mass; zero: a constant wrench, such as the thesis's design wrench).
    pub payload_lever: Vector3<T>,
    /// Prismatic force (upper bound, N): warn = continuous rating, stop = peak.
    pub force: Levels<T>,
    /// Revolute torque (upper bound, N m): warn = continuous rating, stop = peak.
    pub torque: Levels<T>,
}

/// A limit that makes no sense.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitsError {
    /// The field (as in the TOML form).
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: &'static str,
}

impl fmt::Display for LimitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl<T: Real> Limits<T> {
    /// The reference robot's limits (CONVENTIONS.md, thesis chapter 4 and Table 11.2):
    /// - stroke 144 .. 210 mm, spherical-joint tilt 30 deg, tip speed 25 mm/s, the attached
    ///   tool as the declared payload (thesis chapter 4: 1.2 kg on a 0.1 m lever along x_p,
    ///   its weight 11.77 N; the thesis's design wrench [7, 7, 7 N, 0.7, 0.7, 0.7 N m]
    ///   stays an input of the design tools, [`Limits::thesis_design_wrench`]),
    ///   continuous ratings 220 N and 0.5 N m as warn levels (thesis Table 11.2);
    /// - estimates to be measured on the robot: link angle ±80 deg about the central value
    ///   (the task needs -73 .. +42 deg); collision plane 60 mm, safety circle 40 mm (the
    ///   thesis found its radius experimentally; the task keeps the legs ≥ 71 mm out);
    ///   peak force and torque 2× the continuous ratings (typical of small gearmotors;
    ///   1.0 N m is also the thesis's synthesis bound); box margin 5 mm; tilt cone 25 deg;
    ///   singularity levels with the task's worst values (serial 0.265, parallel 0.059)
    ///   above warn; angular speed 30 deg/s; accelerations 0.25 m/s² and 300 deg/s²;
    ///   joint speeds 60 mm/s and 3 rad/s; joint accelerations 2 m/s² and 60 rad/s².
    pub fn reference() -> Self {
        let deg = |d: f64| lit::<T>(d.to_radians());
        Limits {
            stroke: [lit(0.144), lit(0.210)],
            link_angle_max: deg(80.0),
            pitch_max: deg(80.0),
            tilt_max: deg(30.0),
            collision_plane_height: lit(0.060),
            collision_radius: lit(0.040),
            box_half: Vector3::new(lit(0.020), lit(0.020), lit(0.010)),
            box_margin: lit(0.005),
            tilt_cone: deg(25.0),
            serial: Levels {
                warn: lit(0.15),
                stop: lit(0.05),
            },
            parallel: Levels {
                warn: lit(0.03),
                stop: lit(0.01),
            },
            tip_speed: lit(0.025),
            angular_speed: deg(30.0),
            tip_accel: lit(0.25),
            angular_accel: deg(300.0),
            joint_speed: [lit(0.060), lit(3.0)],
            joint_accel: [lit(2.0), lit(60.0)],
            payload: Wrench::new(
                T::zero(),
                T::zero(),
                lit(1.2 * 9.81),
                T::zero(),
                T::zero(),
                T::zero(),
            ),
            payload_lever: Vector3::new(lit(0.1), T::zero(), T::zero()),
            force: Levels {
                warn: lit(220.0),
                stop: lit(440.0),
            },
            torque: Levels {
                warn: lit(0.5),
                stop: lit(1.0),
            },
        }
    }

    /// The thesis's design wrench [7, 7, 7 N, 0.7, 0.7, 0.7 N m] (synthesis and force
    /// tables) as the declared payload, a constant wrench (no lever).
    pub fn with_thesis_design_wrench(self) -> Self {
        Limits {
            payload: Self::thesis_design_wrench(),
            payload_lever: Vector3::zeros(),
            ..self
        }
    }

    /// The thesis's design wrench [7, 7, 7 N, 0.7, 0.7, 0.7 N m].
    pub fn thesis_design_wrench() -> Wrench<T> {
        Wrench::new(lit(7.0), lit(7.0), lit(7.0), lit(0.7), lit(0.7), lit(0.7))
    }

    /// The declared payload at the platform orientation `r`: [f; m + (R c) × f], f and m
    /// the force and moment of `payload`, c = `payload_lever` (CONVENTIONS.md forces: a
    /// tool of mass m_t hanging at c gives f = [0, 0, m_t g], m = 0).
    pub fn payload_at(&self, r: &nalgebra::Rotation3<T>) -> Wrench<T> {
        let p = &self.payload;
        let c = r * self.payload_lever;
        let f = Vector3::new(p.x, p.y, p.z);
        let m = c.cross(&f);
        Wrench::new(p.x, p.y, p.z, p.w + m.x, p.a + m.y, p.b + m.z)
    }

    /// Checks that every limit is finite and consistent.
    pub fn validate(&self) -> Result<(), LimitsError> {
        let err = |field, reason| Err(LimitsError { field, reason });
        let scalars: [(&'static str, T); 15] = [
            ("stroke_min_mm", self.stroke[0]),
            ("stroke_max_mm", self.stroke[1]),
            ("link_angle_max_deg", self.link_angle_max),
            ("pitch_max_deg", self.pitch_max),
            ("tilt_max_deg", self.tilt_max),
            ("collision_plane_height_mm", self.collision_plane_height),
            ("collision_radius_mm", self.collision_radius),
            ("box_margin_mm", self.box_margin),
            ("tilt_cone_deg", self.tilt_cone),
            ("tip_speed_mm_s", self.tip_speed),
            ("angular_speed_deg_s", self.angular_speed),
            ("tip_accel_mm_s2", self.tip_accel),
            ("angular_accel_deg_s2", self.angular_accel),
            ("joint_speed_linear_mm_s", self.joint_speed[0]),
            ("joint_speed_angular_deg_s", self.joint_speed[1]),
        ];
        for (field, v) in scalars {
            if !v.is_finite() {
                return err(field, "is not finite");
            }
            if v < T::zero() {
                return err(field, "is negative");
            }
        }
        let positive: [(&'static str, T); 8] = [
            ("tip_speed_mm_s", self.tip_speed),
            ("angular_speed_deg_s", self.angular_speed),
            ("tip_accel_mm_s2", self.tip_accel),
            ("angular_accel_deg_s2", self.angular_accel),
            ("joint_speed_linear_mm_s", self.joint_speed[0]),
            ("joint_speed_angular_deg_s", self.joint_speed[1]),
            ("joint_accel_linear_mm_s2", self.joint_accel[0]),
            ("joint_accel_angular_deg_s2", self.joint_accel[1]),
        ];
        for (field, v) in positive {
            if !(v > T::zero() && v.is_finite()) {
                return err(field, "must be positive and finite");
            }
        }
        let angles: [(&'static str, T); 4] = [
            ("link_angle_max_deg", self.link_angle_max),
            ("pitch_max_deg", self.pitch_max),
            ("tilt_max_deg", self.tilt_max),
            ("tilt_cone_deg", self.tilt_cone),
        ];
        for (field, v) in angles {
            if v > T::pi() {
                return err(field, "exceeds 180 deg");
            }
        }
        if !(self.stroke[0] < self.stroke[1]) {
            return err("stroke_min_mm", "must be below stroke_max_mm");
        }
        if !self
            .box_half
            .iter()
            .all(|h| *h >= T::zero() && h.is_finite())
        {
            return err("box_half_mm", "must be non-negative and finite");
        }
        if !self.payload.iter().all(|x| x.is_finite())
            || !self.payload_lever.iter().all(|x| x.is_finite())
        {
            return err("payload", "is not finite");
        }
        for (field, l) in [("serial", self.serial), ("parallel", self.parallel)] {
            if !(l.stop >= T::zero() && l.warn >= l.stop && l.warn <= T::one()) {
                return err(field, "needs 0 <= stop <= warn <= 1");
            }
        }
        for (field, l) in [("force", self.force), ("torque", self.torque)] {
            if !(l.warn > T::zero() && l.stop >= l.warn && l.stop.is_finite()) {
                return err(field, "needs 0 < warn <= stop (finite)");
            }
        }
        Ok(())
    }
}
