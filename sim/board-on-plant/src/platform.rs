//! The platform on the joints: its true pose, and what the tool and a wall load the joints
//! with through it.

use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::{forward, inverse, jacobian, Branch, FkConfig, Pose, RsprGeometry, Wrench};
use nalgebra::{Vector3, Vector6};
use plant::{Plant, PlantError, NUM_JOINTS};

/// Gravity, m/s² (along -z0).
pub const GRAVITY_M_S2: f64 = 9.81;

/// Why the platform's pose could not be found.
#[derive(Debug, thiserror::Error)]
pub enum PlatformError {
    /// The forward kinematics of the load-side joints did not converge.
    #[error("the true pose (forward kinematics of the plant's joints) failed: {0:?}")]
    TruePose(kinematics_core::FkError),
    /// The plant refused the loads.
    #[error("plant: {0}")]
    Plant(#[from] PlantError),
}

/// A tool the platform carries: its weight on a lever fixed to the platform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass from o_p in {p}, m.
    pub com_p_m: [f64; 3],
    /// Gravity, m/s² (along -z0).
    pub gravity_m_s2: f64,
}

impl Tool {
    /// The thesis's tool: 1.2 kg on a 0.1 m lever along x_p.
    pub const THESIS: Tool = Tool {
        mass_kg: 1.2,
        com_p_m: [0.100, 0.0, 0.0],
        gravity_m_s2: GRAVITY_M_S2,
    };

    /// The wrench the platform exerts on the tool at `pose` (CONVENTIONS.md, "Forces"):
    /// s_e = [0, 0, m g; c × f] with c = R com_p, so c × f = [c_y f_z, -c_x f_z, 0].
    pub fn wrench(&self, pose: &Pose<f64>) -> Wrench<f64> {
        let fz = self.mass_kg * self.gravity_m_s2;
        let r = pose.r.matrix();
        let [x, y, z] = self.com_p_m;
        let cx = r.m11 * x + r.m12 * y + r.m13 * z;
        let cy = r.m21 * x + r.m22 * y + r.m23 * z;
        Wrench::new(0.0, 0.0, fz, cy * fz, -(cx * fz), 0.0)
    }
}

/// A stiff wall in the task space: a half-space the platform centre `o_p` cannot enter
/// without the wall pushing back, `f = k δ + c max(0, -v_n)` along the wall's normal while
/// the penetration `δ > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// A point of the wall's surface, m, {0}.
    pub point: Vector3<f64>,
    /// The unit normal out of the wall (towards the free side).
    pub normal: Vector3<f64>,
    /// Stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Damping while pressing in, N s/m.
    pub damping_n_s_per_m: f64,
}

impl Wall {
    /// The force the wall exerts on the platform with `o_p` at `p`, moving at `v`.
    pub fn force(&self, p: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        let depth = (self.point - p).dot(&self.normal);
        if depth <= 0.0 {
            return Vector3::zeros();
        }
        let into = (-v.dot(&self.normal)).max(0.0);
        self.normal * (self.stiffness_n_per_m * depth + self.damping_n_s_per_m * into)
    }
}

/// The moving platform on the plant's load-side joints: its true pose (forward kinematics,
/// warm-started from the last), its velocity, and the loads on the joints of what it
/// carries and touches.
///
/// Not modelled: the platform's own inertia and the friction in the passive joints; the
/// joints are coupled through the platform by the static loads alone.
#[derive(Clone, Debug)]
pub struct Platform {
    robot: RsprGeometry<f64>,
    fk: FkConfig<f64>,
    /// The tool, if carried.
    pub tool: Option<Tool>,
    /// A wall in the task space, if any.
    pub wall: Option<Wall>,
    pose: Pose<f64>,
    velocity: Vector3<f64>,
    q: [f64; NUM_JOINTS],
    t_s: f64,
    wall_force: Vector3<f64>,
    loads: [f64; NUM_JOINTS],
}

impl Platform {
    /// The reference robot's platform on the joints `q` at time `t_s` (pose by forward
    /// kinematics from the central pose), at rest, carrying nothing.
    pub fn new(q: [f64; NUM_JOINTS], t_s: f64) -> Result<Self, PlatformError> {
        let robot = RsprGeometry::<f64>::reference();
        let fk = FkConfig::default();
        let pose = forward(
            &robot,
            &Vector6::from_row_slice(&q),
            Branch::OUTER,
            &Pose::central(robot.hc),
            &fk,
        )
        .map_err(PlatformError::TruePose)?
        .pose;
        Ok(Platform {
            robot,
            fk,
            tool: None,
            wall: None,
            pose,
            velocity: Vector3::zeros(),
            q,
            t_s,
            wall_force: Vector3::zeros(),
            loads: [0.0; NUM_JOINTS],
        })
    }

    /// The true pose at the last update.
    pub fn pose(&self) -> &Pose<f64> {
        &self.pose
    }
    /// The velocity of o_p between the last two updates, m/s.
    pub fn velocity(&self) -> Vector3<f64> {
        self.velocity
    }
    /// The load-side joints at the last update.
    pub fn q(&self) -> [f64; NUM_JOINTS] {
        self.q
    }
    /// The force the wall exerted on the platform at the last loads, N.
    pub fn wall_force(&self) -> Vector3<f64> {
        self.wall_force
    }
    /// The joint loads at the last [`Platform::apply_loads`], N and N m (+q).
    pub fn loads(&self) -> [f64; NUM_JOINTS] {
        self.loads
    }

    /// The true pose of the joints `q` at `t_s` (forward kinematics warm-started from the
    /// last pose) and the velocity since the last update; joints that have not moved keep
    /// the pose, at rest.
    pub fn update(&mut self, q: [f64; NUM_JOINTS], t_s: f64) -> Result<(), PlatformError> {
        let dt = t_s - self.t_s;
        if dt <= 0.0 {
            return Ok(());
        }
        self.t_s = t_s;
        if q == self.q {
            self.velocity = Vector3::zeros();
            return Ok(());
        }
        let fk = forward(
            &self.robot,
            &Vector6::from_row_slice(&q),
            Branch::OUTER,
            &self.pose,
            &self.fk,
        )
        .map_err(PlatformError::TruePose)?;
        self.velocity = (fk.pose.t - self.pose.t) / dt;
        self.pose = fk.pose;
        self.q = q;
        Ok(())
    }

    /// The tool's and the wall's loads on the joints at the pose of the last update: -τ,
    /// τ = J^-T s_e (Eq. 7.10; J = Js^-1 J̃, Eq. 7.18) for the wrench s_e the platform
    /// exerts on them (the wall's force acts at o_p: no moment); `None` where the pose has
    /// no Jacobian.
    pub fn joint_loads(&mut self) -> Option<[f64; NUM_JOINTS]> {
        let mut se = Wrench::<f64>::zeros();
        if let Some(tool) = &self.tool {
            se += tool.wrench(&self.pose);
        }
        let mut wall_force = Vector3::zeros();
        if let Some(w) = &self.wall {
            wall_force = w.force(&self.pose.t, &self.velocity);
            se[0] -= wall_force.x;
            se[1] -= wall_force.y;
            se[2] -= wall_force.z;
        }
        self.wall_force = wall_force;
        if se.iter().all(|x| *x == 0.0) {
            return Some([0.0; NUM_JOINTS]);
        }
        let sol = inverse(&self.robot, &self.pose, Branch::OUTER).ok()?;
        let jac = jacobian(&self.robot, &sol).ok()?;
        let st = forces_with_inv_cond(&jac, &se, 1.0, 0.0).ok()?;
        Some(std::array::from_fn(|j| -st.tau[j]))
    }

    /// [`Platform::joint_loads`] set on `plant`; where the pose has no Jacobian the loads
    /// stay as they were.
    pub fn apply_loads(&mut self, plant: &mut Plant) -> Result<(), PlantError> {
        if let Some(loads) = self.joint_loads() {
            self.loads = loads;
            plant.set_external_load(loads)?;
        }
        Ok(())
    }
}
