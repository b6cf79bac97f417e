//! A simulated robot for tests and demonstrations: its measured pose moves towards the
//! last accepted target at a limited speed, and it refuses targets outside a box around
//! the central pose or tilted beyond a cone. No kinematics, no dynamics.

use crate::pose::PoseSi;
use crate::robot::{Condition, Refusal, RefusalReason, Robot, RobotState, TargetPose};
use kinematics_core::pose::Pose;
use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use std::time::Duration;

/// Settings of a [`FakeRobot`], SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FakeRobotConfig {
    /// Pose at start.
    pub start: PoseSi,
    /// Centre of the box targets must lie in, m.
    pub box_centre: Vector3<f64>,
    /// Half extents of that box, m.
    pub box_half: Vector3<f64>,
    /// Largest angle between the platform normal and z0, rad.
    pub tilt_cone: f64,
    /// Largest speed of o_p, m/s.
    pub speed: f64,
    /// Largest angular speed, rad/s.
    pub angular_speed: f64,
}

impl Default for FakeRobotConfig {
    /// The reference robot's numbers (`host-sim/limits/reference.toml`): central pose at
    /// hc = 160 mm, the 40 x 40 x 20 mm task box plus its 5 mm margin, a 25 deg tilt cone,
    /// 25 mm/s and 30 deg/s.
    fn default() -> Self {
        let centre = Vector3::new(0.0, 0.0, 0.160);
        FakeRobotConfig {
            start: Pose {
                t: centre,
                r: Rotation3::identity(),
            },
            box_centre: centre,
            box_half: Vector3::new(0.025, 0.025, 0.015),
            tilt_cone: 25f64.to_radians(),
            speed: 0.025,
            angular_speed: 30f64.to_radians(),
        }
    }
}

/// The simulated robot.
#[derive(Clone, Debug)]
pub struct FakeRobot {
    config: FakeRobotConfig,
    pose: PoseSi,
    target: Option<PoseSi>,
}

/// Angle between the platform normal R·z and z0.
fn tilt(r: &Rotation3<f64>) -> f64 {
    r.matrix()[(2, 2)].clamp(-1.0, 1.0).acos()
}

impl FakeRobot {
    /// A robot at `config.start`, without target.
    pub fn new(config: FakeRobotConfig) -> Self {
        FakeRobot {
            config,
            pose: config.start,
            target: None,
        }
    }

    /// The last accepted target.
    pub fn target(&self) -> Option<&PoseSi> {
        self.target.as_ref()
    }

    /// Moves towards the target for `dt` at the speed limits.
    pub fn step(&mut self, dt: Duration) {
        let Some(target) = self.target else { return };
        let dt = dt.as_secs_f64();
        let dp = target.t - self.pose.t;
        let max_step = self.config.speed * dt;
        let dist = dp.norm();
        self.pose.t = if dist <= max_step {
            target.t
        } else {
            self.pose.t + dp * (max_step / dist)
        };
        let q = UnitQuaternion::from_rotation_matrix(&self.pose.r);
        let qt = UnitQuaternion::from_rotation_matrix(&target.r);
        let angle = q.angle_to(&qt);
        let max_turn = self.config.angular_speed * dt;
        self.pose.r = if angle <= max_turn {
            target.r
        } else {
            q.slerp(&qt, max_turn / angle).to_rotation_matrix()
        };
    }

    fn reached(&self) -> bool {
        self.target
            .is_none_or(|t| t.t == self.pose.t && t.r == self.pose.r)
    }
}

impl Robot for FakeRobot {
    fn submit_target(&mut self, target: &TargetPose) -> Result<(), Refusal> {
        let c = &self.config;
        let d = target.t - c.box_centre;
        let outside = (0..3).any(|i| d[i].abs() > c.box_half[i]);
        if outside {
            let mm = target.t * 1000.0;
            let lo = (c.box_centre - c.box_half) * 1000.0;
            let hi = (c.box_centre + c.box_half) * 1000.0;
            return Err(Refusal::new(
                RefusalReason::Unreachable,
                format!(
                    "target x_mm={:.3} y_mm={:.3} z_mm={:.3} outside the box x {:.1}..{:.1}, y {:.1}..{:.1}, z {:.1}..{:.1} mm",
                    mm.x, mm.y, mm.z, lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
                ),
            ));
        }
        let r = target.r.unwrap_or(self.pose.r);
        let tilt = tilt(&r);
        if tilt > c.tilt_cone {
            return Err(Refusal::new(
                RefusalReason::Unreachable,
                format!(
                    "target tilt_deg={:.2} beyond the {:.1} deg cone",
                    tilt.to_degrees(),
                    c.tilt_cone.to_degrees()
                ),
            ));
        }
        self.target = Some(Pose { t: target.t, r });
        Ok(())
    }

    fn measured_pose(&self) -> Option<PoseSi> {
        Some(self.pose)
    }

    fn state(&self) -> RobotState {
        if self.reached() {
            RobotState {
                condition: Condition::Ready,
                detail: "holding".to_owned(),
            }
        } else {
            RobotState {
                condition: Condition::Moving,
                detail: "moving to target".to_owned(),
            }
        }
    }
}
