//! The description of an RSPR or USR robot from its geometry, and the joint-state vector
//! (every joint of the tree) for a platform pose.
//!
//! **The closed chains as a tree.** URDF describes trees; the robot has three closed
//! chains. As dVRK does for its parallelogram, the tree follows every chain from the base
//! up to its platform pin, and the platform hangs off chain 1's pin only; the passive joints
//! of all three chains (the spherical joints, as three revolutes each, and the platform's
//! revolute pins) take the values the kinematics computes, so that chains 2 and 3 end where
//! the platform's joints are. Per chain i (joint names in `code`):
//! - RSPR: the rotating link turns about its axis a_i at the base pivot c_i
//!   (`theta<i>`, the actuated θ_i); at its end, b_i, the spherical joint (`ball<i>_z`,
//!   `ball<i>_y`, `ball<i>_x`: rotations about the socket's z, y and x in turn, all zero at
//!   the central configuration); the leg's cylinder, along the leg; its piston (`l<i>`,
//!   prismatic, the actuated l_i); the revolute pin at p_i about the platform axis
//!   R r_i (`pin<i>`, zero at the central configuration).
//! - USR: the universal joint at e_i (`alpha<i>` about z0, then `beta<i>`, the elevation);
//!   the lower link; the spherical joint at b_i (as above); the upper link of length l2; the
//!   pin at p_i.
//!
//! The leg's frame is z along ŝ1_i (from b_i to p_i) and x along the pin's axis R r_i (the
//! leg lies in the plane normal to that axis: Eq. 6.13 on the RSPR, Eq. 6.25 on the USR).
//! An angle of an actuated revolute joint is given within ±180 deg of its value at the
//! central configuration (the joint's limits are centred there).

use crate::model::{Drive, Joint, JointType, Link, Shape, Tree, Visual};
use crate::{BASE_FRAME, PLATFORM_FRAME};
use kinematics_core::guards::Limits;
use kinematics_core::mechanism::radial;
use kinematics_core::pose::Pose;
use kinematics_core::scalar::wrap_angle;
use kinematics_core::{
    forward, inverse, Branch, Chain, FkConfig, FkError, IkError, PerChainGeometry, Robot,
};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::collections::HashMap;
use thiserror::Error;

/// Why a description or a joint-state vector could not be made.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum DescriptionError {
    /// The central configuration has no inverse kinematics on the branch (the description's
    /// zero positions come from it).
    #[error("the central configuration on branch {branch}: {error}")]
    Central { branch: Branch, error: IkError },
    /// The pose has no inverse kinematics on the description's branch.
    #[error("the pose has no inverse kinematics on branch {branch}: {error}")]
    Ik { branch: Branch, error: IkError },
    /// The joints have no forward kinematics.
    #[error("the joints have no forward kinematics: {0:?}")]
    Fk(FkError),
    /// A joint of the tree got no value (a defect of the description).
    #[error("joint {0} got no value")]
    NoValue(String),
    /// A spherical joint at 90 deg from its central direction about its y axis, where
    /// its three angles are not defined (far outside any tilt limit).
    #[error("chain {chain}: the spherical joint is turned 90 deg about its y axis, where its angles are undefined")]
    BallGimbalLock { chain: u8 },
}

/// The fixed data of one chain the joint-state computation needs.
#[derive(Clone, Debug, PartialEq)]
struct ChainFrames {
    /// The first base joint's frame in {0} (its z the rotating link's axis; on the RSPR
    /// turned by the link encoder's zero, so that the joint value is θ_i).
    base: Isometry3<f64>,
    /// The spherical joint's frame at rest in the lower link's frame (the leg frame at the
    /// central configuration).
    ball_zero: UnitQuaternion<f64>,
    /// The platform's orientation in the pin's frame at rest (the transpose of the leg
    /// frame at the central configuration, where R = I).
    pin_zero: UnitQuaternion<f64>,
    /// Centre of the platform joint pp_i and its axis r_i, {p}.
    platform_joint: Vector3<f64>,
    platform_axis: Vector3<f64>,
    /// Central values of the actuated joints of this chain (rad or m), in chain order
    /// (RSPR: θ_i; USR: α_i, β_i).
    central_angles: [f64; 2],
}

/// The robot's description: the tree and what the joint-state vector needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Description {
    robot: Robot<f64>,
    branch: Branch,
    tree: Tree,
    /// Chains 1, 2, 3.
    chains: Vec<ChainFrames>,
}

/// Every moving joint of the description and its value (rad, m), in the description's
/// joint order: what `/joint_states` publishes.
#[derive(Clone, Debug, PartialEq)]
pub struct JointStates {
    pub names: Vec<String>,
    pub positions: Vec<f64>,
}

impl JointStates {
    /// The values by joint name.
    pub fn as_map(&self) -> HashMap<String, f64> {
        self.names
            .iter()
            .cloned()
            .zip(self.positions.iter().copied())
            .collect()
    }
}

/// The names of chain `i`'s (1-based) actuated joints, in q order within the chain.
fn actuated_names(usr: bool, i: usize) -> [String; 2] {
    if usr {
        [format!("alpha{i}"), format!("beta{i}")]
    } else {
        [format!("l{i}"), format!("theta{i}")]
    }
}

/// The leg frame in {0}: z along ŝ1 (b -> p), x along the pin axis m (made normal to ŝ1).
fn leg_frame(s1: &Vector3<f64>, m: &Vector3<f64>) -> Rotation3<f64> {
    let z = s1.normalize();
    let x = (m - z * m.dot(&z)).normalize();
    let y = z.cross(&x);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))
}

/// Rz(a) Ry(b) Rx(c) = m: (a, b, c), or None at |b| = 90 deg.
fn zyx_angles(m: &Matrix3<f64>) -> Option<[f64; 3]> {
    let cb = m[(0, 0)].hypot(m[(1, 0)]);
    if cb < 1e-9 {
        return None;
    }
    Some([
        m[(1, 0)].atan2(m[(0, 0)]),
        (-m[(2, 0)]).atan2(cb),
        m[(2, 1)].atan2(m[(2, 2)]),
    ])
}

fn iso(t: Vector3<f64>, r: UnitQuaternion<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(t), r)
}

fn rot_z(a: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a)
}

/// Visual sizes (m): the geometry fixes lengths and joint centres; the cross-sections
/// are illustrative.
mod size {
    pub const LINK_WIDTH: f64 = 0.008;
    pub const LINK_THICKNESS: f64 = 0.005;
    pub const BALL_RADIUS: f64 = 0.006;
    pub const CYLINDER_RADIUS: f64 = 0.008;
    pub const ROD_RADIUS: f64 = 0.004;
    pub const PIN_RADIUS: f64 = 0.004;
    pub const PIN_LENGTH: f64 = 0.016;
    pub const PLATE_THICKNESS: f64 = 0.005;
    pub const MOTOR_RADIUS: f64 = 0.008;
    pub const MOTOR_LENGTH: f64 = 0.02;
}

fn visual(origin: Isometry3<f64>, shape: Shape, material: &'static str) -> Visual {
    Visual {
        origin,
        shape,
        material,
    }
}

/// A cylinder along x from `from` to `from + length` (in the link's frame).
fn rod_along_x(length: f64, radius: f64, material: &'static str) -> Visual {
    let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
    visual(
        iso(Vector3::new(length / 2.0, 0.0, 0.0), turn),
        Shape::Cylinder { radius, length },
        material,
    )
}

fn rod_along_z(start: f64, length: f64, radius: f64, material: &'static str) -> Visual {
    visual(
        iso(
            Vector3::new(0.0, 0.0, start + length / 2.0),
            UnitQuaternion::identity(),
        ),
        Shape::Cylinder { radius, length },
        material,
    )
}

impl Description {
    /// The description of `robot` on `branch` (the prototype runs [`Branch::OUTER`]), with
    /// the actuated joints' limits from `limits` (the RSPR's stroke and link angle, the
    /// USR's yaw and elevation, the joint speeds, the peak force and torque).
    pub fn new(
        robot: &Robot<f64>,
        limits: &Limits<f64>,
        branch: Branch,
    ) -> Result<Self, DescriptionError> {
        use kinematics_core::mechanism::Mechanism;
        let central_pose = Pose::central(robot.hc());
        let central = inverse(robot, &central_pose, branch)
            .map_err(|error| DescriptionError::Central { branch, error })?;
        let usr = matches!(robot, Robot::Usr(_));
        let mut links = vec![Link {
            name: BASE_FRAME.into(),
            visuals: Vec::new(),
        }];
        let mut joints = Vec::new();
        let mut frames = Vec::new();
        let mut plate_radius: f64 = 0.0;
        let mut base_radius: f64 = 0.0;
        let mut max_link: f64 = 0.0;
        let min_leg = Chain::ALL
            .iter()
            .map(|c| central.chains[*c].leg)
            .fold(f64::INFINITY, f64::min);
        for chain in Chain::ALL {
            let i = chain.number() as usize;
            let cs = &central.chains[chain];
            let names = actuated_names(usr, i);
            // The first base joint's frame and the lower link's length.
            let (base, link_length, leg_origin, platform_joint, platform_axis) =
                chain_base(robot, chain);
            base_radius = base_radius.max(base.translation.vector.norm());
            max_link = max_link.max(link_length);
            plate_radius = plate_radius.max(platform_joint.xy().norm());
            // The lower link's frame at the central configuration.
            let central_angles = if usr { [cs.qa, cs.qb] } else { [cs.qb, 0.0] };
            let link_rot = if usr {
                base.rotation
                    * rot_z(cs.qa)
                    * UnitQuaternion::from_axis_angle(&-Vector3::y_axis(), cs.qb)
            } else {
                base.rotation * rot_z(cs.qb)
            };
            let leg0 = UnitQuaternion::from_rotation_matrix(&leg_frame(
                &cs.s1,
                &(central_pose.r * platform_axis),
            ));
            let ball_zero = link_rot.inverse() * leg0;
            let pin_zero = leg0.inverse() * UnitQuaternion::from_rotation_matrix(&central_pose.r);
            let lower = if usr {
                format!("lower_link{i}")
            } else {
                format!("rotating_link{i}")
            };
            let lim = |c: f64, half: f64, effort: f64, velocity: f64| JointType::Revolute {
                lower: c - half,
                upper: c + half,
                effort,
                velocity,
            };
            // The base joints.
            if usr {
                let yaw = format!("yaw{i}");
                links.push(Link {
                    name: yaw.clone(),
                    visuals: vec![visual(
                        Isometry3::identity(),
                        Shape::Sphere {
                            radius: size::BALL_RADIUS,
                        },
                        "joint",
                    )],
                });
                joints.push(Joint {
                    name: names[0].clone(),
                    kind: lim(
                        cs.qa,
                        limits.link_angle_max,
                        limits.torque.stop,
                        limits.joint_speed[1],
                    ),
                    drive: Drive::Actuated,
                    parent: BASE_FRAME.into(),
                    child: yaw.clone(),
                    origin: base,
                    axis: Vector3::z(),
                });
                joints.push(Joint {
                    name: names[1].clone(),
                    kind: lim(
                        cs.qb,
                        limits.pitch_max,
                        limits.torque.stop,
                        limits.joint_speed[1],
                    ),
                    drive: Drive::Actuated,
                    parent: yaw,
                    child: lower.clone(),
                    origin: Isometry3::identity(),
                    axis: -Vector3::y(),
                });
            } else {
                joints.push(Joint {
                    name: names[1].clone(),
                    kind: lim(
                        cs.qb,
                        limits.link_angle_max,
                        limits.torque.stop,
                        limits.joint_speed[1],
                    ),
                    drive: Drive::Actuated,
                    parent: BASE_FRAME.into(),
                    child: lower.clone(),
                    origin: base,
                    axis: Vector3::z(),
                });
            }
            links.push(Link {
                name: lower.clone(),
                visuals: vec![
                    if usr {
                        rod_along_x(link_length, size::ROD_RADIUS, "link")
                    } else {
                        visual(
                            iso(
                                Vector3::new(link_length / 2.0, 0.0, 0.0),
                                UnitQuaternion::identity(),
                            ),
                            Shape::Box {
                                size: [link_length, size::LINK_WIDTH, size::LINK_THICKNESS],
                            },
                            "link",
                        )
                    },
                    visual(
                        iso(
                            Vector3::new(link_length, 0.0, 0.0),
                            UnitQuaternion::identity(),
                        ),
                        Shape::Sphere {
                            radius: size::BALL_RADIUS,
                        },
                        "joint",
                    ),
                ],
            });
            // The spherical joint: three revolutes about z, y, x of the socket's frame.
            let leg_link = if usr {
                format!("upper_link{i}")
            } else {
                format!("cylinder{i}")
            };
            let ball_links = [
                lower.clone(),
                format!("ball{i}_yaw"),
                format!("ball{i}_pitch"),
                leg_link.clone(),
            ];
            for (k, (axis_name, axis)) in [
                ("z", Vector3::z()),
                ("y", Vector3::y()),
                ("x", Vector3::x()),
            ]
            .into_iter()
            .enumerate()
            {
                joints.push(Joint {
                    name: format!("ball{i}_{axis_name}"),
                    kind: JointType::Continuous,
                    drive: Drive::Passive,
                    parent: ball_links[k].clone(),
                    child: ball_links[k + 1].clone(),
                    origin: if k == 0 {
                        iso(Vector3::new(link_length, 0.0, 0.0), ball_zero)
                    } else {
                        Isometry3::identity()
                    },
                    axis,
                });
                if k < 2 {
                    links.push(Link {
                        name: ball_links[k + 1].clone(),
                        visuals: Vec::new(),
                    });
                }
            }
            // The leg: the RSPR's cylinder and piston, the USR's upper link.
            let pin_parent = if usr {
                links.push(Link {
                    name: leg_link.clone(),
                    visuals: vec![rod_along_z(0.0, leg_origin, size::ROD_RADIUS, "leg")],
                });
                leg_link.clone()
            } else {
                let body = 0.55 * min_leg;
                links.push(Link {
                    name: leg_link.clone(),
                    visuals: vec![rod_along_z(0.0, body, size::CYLINDER_RADIUS, "leg")],
                });
                let piston = format!("piston{i}");
                links.push(Link {
                    name: piston.clone(),
                    visuals: vec![rod_along_z(-body, body, size::ROD_RADIUS, "leg")],
                });
                joints.push(Joint {
                    name: names[0].clone(),
                    kind: JointType::Prismatic {
                        lower: limits.stroke[0],
                        upper: limits.stroke[1],
                        effort: limits.force.stop,
                        velocity: limits.joint_speed[0],
                    },
                    drive: Drive::Actuated,
                    parent: leg_link.clone(),
                    child: piston.clone(),
                    origin: iso(
                        Vector3::new(0.0, 0.0, leg_origin),
                        UnitQuaternion::identity(),
                    ),
                    axis: Vector3::z(),
                });
                piston
            };
            let pin = format!("pin{i}");
            links.push(Link {
                name: format!("pin{i}_link"),
                visuals: vec![visual(
                    iso(
                        Vector3::zeros(),
                        UnitQuaternion::from_axis_angle(
                            &Vector3::y_axis(),
                            std::f64::consts::FRAC_PI_2,
                        ),
                    ),
                    Shape::Cylinder {
                        radius: size::PIN_RADIUS,
                        length: size::PIN_LENGTH,
                    },
                    "joint",
                )],
            });
            joints.push(Joint {
                name: pin,
                kind: JointType::Continuous,
                drive: Drive::Passive,
                parent: pin_parent,
                child: format!("pin{i}_link"),
                origin: iso(
                    Vector3::new(0.0, 0.0, if usr { leg_origin } else { 0.0 }),
                    UnitQuaternion::identity(),
                ),
                axis: Vector3::x(),
            });
            if chain == Chain::One {
                joints.push(Joint {
                    name: format!("pin{i}_{PLATFORM_FRAME}"),
                    kind: JointType::Fixed,
                    drive: Drive::Fixed,
                    parent: format!("pin{i}_link"),
                    child: PLATFORM_FRAME.into(),
                    origin: iso(-(pin_zero * platform_joint), pin_zero),
                    axis: Vector3::x(),
                });
            }
            frames.push(ChainFrames {
                base,
                ball_zero,
                pin_zero,
                platform_joint,
                platform_axis,
                central_angles,
            });
        }
        // The base plate and the motors, the platform plate.
        let base_visuals = &mut links[0].visuals;
        base_visuals.push(rod_along_z(
            -size::PLATE_THICKNESS,
            size::PLATE_THICKNESS,
            base_radius + max_link + 0.01,
            "base",
        ));
        for f in &frames {
            base_visuals.push(visual(
                f.base
                    * iso(
                        Vector3::new(0.0, 0.0, -size::MOTOR_LENGTH / 2.0),
                        UnitQuaternion::identity(),
                    ),
                Shape::Cylinder {
                    radius: size::MOTOR_RADIUS,
                    length: size::MOTOR_LENGTH,
                },
                "joint",
            ));
        }
        links.push(Link {
            name: PLATFORM_FRAME.into(),
            visuals: vec![rod_along_z(
                -size::PLATE_THICKNESS / 2.0,
                size::PLATE_THICKNESS,
                plate_radius,
                "platform",
            )],
        });
        let name = match robot {
            Robot::Rspr(_) => "rspr",
            Robot::RsprPerChain(_) => "rspr_per_chain",
            Robot::Usr(_) => "usr",
        };
        Ok(Description {
            robot: *robot,
            branch,
            tree: Tree {
                name: name.into(),
                links,
                joints,
            },
            chains: frames,
        })
    }

    /// The tree (links, joints, shapes).
    pub fn tree(&self) -> &Tree {
        &self.tree
    }

    /// The robot described.
    pub fn robot(&self) -> &Robot<f64> {
        &self.robot
    }

    /// The branch the joint states are computed on.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// Every moving joint's value at a platform pose: the actuated joints from the inverse
    /// kinematics on the description's branch, the passive ones from the chain frames
    /// (see the module documentation).
    pub fn joint_states(&self, pose: &Pose<f64>) -> Result<JointStates, DescriptionError> {
        let sol =
            inverse(&self.robot, pose, self.branch).map_err(|error| DescriptionError::Ik {
                branch: self.branch,
                error,
            })?;
        let usr = matches!(self.robot, Robot::Usr(_));
        let mut values: HashMap<String, f64> = HashMap::new();
        for (chain, f) in Chain::ALL.into_iter().zip(&self.chains) {
            let i = chain.number() as usize;
            let cs = &sol.chains[chain];
            let names = actuated_names(usr, i);
            let near = |a: f64, c: f64| c + wrap_angle(a - c);
            let link_rot = if usr {
                let alpha = near(cs.qa, f.central_angles[0]);
                let beta = near(cs.qb, f.central_angles[1]);
                values.insert(names[0].clone(), alpha);
                values.insert(names[1].clone(), beta);
                f.base.rotation
                    * rot_z(alpha)
                    * UnitQuaternion::from_axis_angle(&-Vector3::y_axis(), beta)
            } else {
                let theta = near(cs.qb, f.central_angles[0]);
                values.insert(names[0].clone(), cs.qa);
                values.insert(names[1].clone(), theta);
                f.base.rotation * rot_z(theta)
            };
            let leg = UnitQuaternion::from_rotation_matrix(&leg_frame(
                &cs.s1,
                &(pose.r * f.platform_axis),
            ));
            let ball = (f.ball_zero.inverse() * link_rot.inverse() * leg).to_rotation_matrix();
            let [bz, by, bx] =
                zyx_angles(ball.matrix()).ok_or(DescriptionError::BallGimbalLock {
                    chain: chain.number(),
                })?;
            values.insert(format!("ball{i}_z"), bz);
            values.insert(format!("ball{i}_y"), by);
            values.insert(format!("ball{i}_x"), bx);
            // R = L Rx(γ) G (G the pin's rest orientation): Rx(γ) = Lᵀ R Gᵀ.
            let pin = (leg.inverse()
                * UnitQuaternion::from_rotation_matrix(&pose.r)
                * f.pin_zero.inverse())
            .to_rotation_matrix();
            let m = pin.matrix();
            values.insert(format!("pin{i}"), m[(2, 1)].atan2(m[(1, 1)]));
        }
        let mut out = JointStates {
            names: Vec::new(),
            positions: Vec::new(),
        };
        for j in &self.tree.joints {
            if j.drive == Drive::Fixed {
                continue;
            }
            out.names.push(j.name.clone());
            let v = values
                .get(&j.name)
                .copied()
                .ok_or_else(|| DescriptionError::NoValue(j.name.clone()))?;
            out.positions.push(v);
        }
        Ok(out)
    }

    /// [`Description::joint_states`] at the pose the forward kinematics gives for the
    /// actuated joints `q` (q order of CONVENTIONS.md), starting from `guess`; with the pose.
    pub fn joint_states_from_joints(
        &self,
        q: &kinematics_core::vectors::Joints<f64>,
        guess: &Pose<f64>,
    ) -> Result<(Pose<f64>, JointStates), DescriptionError> {
        let fk = forward(&self.robot, q, self.branch, guess, &FkConfig::default())
            .map_err(DescriptionError::Fk)?;
        let pose = fk.pose;
        Ok((pose, self.joint_states(&pose)?))
    }

    /// Where each pin's centre and the platform frame are, by the tree, for the joint
    /// states: chain i's pin frame `pin<i>_link` and `platform`, in {0}.
    pub fn link_poses(
        &self,
        states: &JointStates,
    ) -> Result<HashMap<String, Isometry3<f64>>, crate::model::MissingJoint> {
        self.tree.link_poses(&states.as_map())
    }

    /// The platform joint pp_i of chain `chain` in {p}.
    pub fn platform_joint(&self, chain: Chain) -> Vector3<f64> {
        self.chains
            .get(chain.index())
            .map_or_else(Vector3::zeros, |f| f.platform_joint)
    }
}

/// Chain `chain`'s first base joint frame in {0}, its lower link's length, the leg's origin
/// (RSPR: the leg's length offset and encoder zero; USR: l2), the platform joint pp_i and
/// its axis r_i in {p}.
fn chain_base(
    robot: &Robot<f64>,
    chain: Chain,
) -> (Isometry3<f64>, f64, f64, Vector3<f64>, Vector3<f64>) {
    let rad = radial::<f64>(chain);
    let per_chain = |g: &PerChainGeometry<f64>| {
        let d = &g.chains()[chain];
        let a = d.base_axis;
        // ρ_i: the radial direction made normal to a_i, the zero of φ_i (chain_geometry).
        let rho = (rad - a * rad.dot(&a)).normalize();
        let frame =
            Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[rho, a.cross(&rho), a]));
        // θ_i = φ_i − link_zero: the joint frame is turned by link_zero.
        let r = UnitQuaternion::from_rotation_matrix(&frame) * rot_z(d.link_zero);
        (
            iso(d.base_pivot, r),
            d.link_length,
            d.leg_offset + d.leg_zero,
            d.platform_joint,
            d.platform_axis,
        )
    };
    match robot {
        Robot::Rspr(g) => per_chain(&PerChainGeometry::from(*g)),
        Robot::RsprPerChain(g) => per_chain(g),
        Robot::Usr(g) => {
            let frame = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
                rad,
                Vector3::z().cross(&rad),
                Vector3::z(),
            ]));
            (
                // Eq. 6.2: e_i = e [cos ξ_i, sin ξ_i, 0].
                iso(rad * g.e, UnitQuaternion::from_rotation_matrix(&frame)),
                g.l1,
                g.l2,
                // Eq. 6.4: pp_i = rp [cos ξ_i, sin ξ_i, 0], r_i = z × radial.
                rad * g.rp,
                Vector3::new(-rad.y, rad.x, 0.0),
            )
        }
    }
}
