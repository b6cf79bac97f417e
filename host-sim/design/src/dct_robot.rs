//! The spatial double circular-triangular robot (thesis Appendix A, sections 2.3 and 3.3,
//! Eq. 13-16, Table 4.1): two planar circle-triangle mechanisms ([`crate::dct`]) in
//! parallel horizontal planes, a U joint at each triangle's centre, and the output link
//! along the line through the two centres, held by the upper U joint through a prismatic
//! joint and by the lower one through a helical joint (nut and lead screw). Inverse
//! kinematics, the Jacobian J = dq/dx (derived here: the appendix's Eq. 13 and g_j are
//! missing), the statics τ = J⁻ᵀ s_e with the screw's efficiency, and forward kinematics.
//!
//! # Geometry (what the appendix leaves to its figures; CONVENTIONS.md, "The double
//! circular-triangular robot")
//!
//! - World frame {0} as for the other robots; the lower mechanism's plane is z = 0, the
//!   upper one's z = H, both circles centred on the z axis, with the same radius rc and
//!   triangle side (Table 4.1 gives one value for Rb, Rp and one for Lb, Lp).
//! - The output link is the line through the triangle centres c_b (lower) and c_p (upper),
//!   direction u = R ẑ. The tool point o_e lies on it at the distance s from c_b; at the
//!   central configuration (u = ẑ, no spin) s = s0 = H + Bo, i.e. Bo above the upper plane
//!   (Table 4.1's Bo, read as that offset).
//! - The U joints: a cross whose first pin a is fixed in the triangle (horizontal, turning
//!   with ψ: a = [cos ψ, sin ψ, 0]) and whose second pin b is fixed in the output yoke,
//!   b ⟂ a and b ⟂ u, so b = (a × u)/|a × u| and, back, a = (ẑ × b)/|ẑ × b| (the Cardan
//!   joint, exactly; its transmission ratio is the appendix's g_j). The upper yoke turns
//!   with the link (prismatic joint: the link slides but does not turn in it); its pin is
//!   the link's marker m = R·[0, -1, 0] (so that ψ_p = 0 at R = I). The lower yoke carries
//!   the nut: the link turns in it by γ about u, b_b = Rot(u, -γ) m, and advances by the
//!   right-handed lead: s = s0 + l γ / (2π).
//! - Joints q = [q_b1, q_b2, q_b3, q_p1, q_p2, q_p3]: the arc lengths rc φ of the lower,
//!   then the upper sliders (m), φ wrapped to (-π, π] (the actuators turn without limit; a
//!   position gives the joints modulo a turn). Branch: 6 bits, the lower mechanism's three
//!   in bits 0-2 and the upper's in bits 3-5, each as [`crate::dct::Planar::inverse`].
//!
//! # Jacobian (derived here, in place of Eq. 13-16)
//!
//! For the twist [v; ω] of o_e (both in {0}), u̇ = ω × u. The centres are the link's
//! points on the two planes, c = o_e + λ u with λ_b = -o_z/u_z and λ_p = (H - o_z)/u_z, so
//! ċ = v + λ̇ u + λ u̇ with λ̇_b = -v_z/u_z + o_z u̇_z/u_z² and
//! λ̇_p = -v_z/u_z - (H - o_z) u̇_z/u_z². A Cardan cross turns at ψ̇ ẑ + α̇ a relative to
//! the base and its output yoke at that plus β̇ b, so an output yoke turning at Ω needs
//! ψ̇ = Ω·(a × b) / (ẑ·(a × b)) (a, b, ẑ are independent while u_z ≠ 0). The upper yoke
//! turns at Ω_p = ω; the nut at Ω_b = ω - γ̇ u, where γ̇ = 2π ṡ / l and
//! ṡ = (v - ċ_b)·u. With the planar Jacobians J̄ (Eq. 11, corrected in [`crate::dct`]),
//! q̇_b = J̄_b [ċ_b,x; ċ_b,y; ψ̇_b] and q̇_p = J̄_p [ċ_p,x; ċ_p,y; ψ̇_p]. Every step is linear
//! in [v; ω], so J's columns are the images of the six unit twists (exact, not finite
//! differences). Statics: τ = J⁻ᵀ s_e (virtual work, τ·q̇ = s_e·[v; ω], tested). The lead
//! screw's efficiency η enters as the appendix's Eq. 15 has it, a nut torque of
//! F l / (2π η) for the axial force F: J with the lead l/η in the screw's row; virtual work
//! then holds only at η = 1.

// `!(x > limit)` is deliberate, as in `kinematics-core`: unlike `x <= limit` it is also
// true for NaN, so a NaN can never pass a check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::dct::{Planar, PlanarError, PlanarPose};
use kinematics_core::Pose;
use nalgebra::{Matrix3, Matrix6, Rotation3, Unit, Vector2, Vector3, Vector6};
use std::f64::consts::PI;
use thiserror::Error;

/// The spatial robot's dimensions (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DctRobot {
    /// The planar mechanism of both planes.
    pub planar: Planar,
    /// Distance H between the planes (m).
    pub h: f64,
    /// Lead l of the screw (m per turn).
    pub lead: f64,
    /// The tool point's offset Bo above the upper plane at the central configuration (m).
    pub bo: f64,
}

/// Why the spatial robot has no solution.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum DctError {
    #[error("dimensions: H {h} m, lead {lead} m and Bo {bo} m must be finite, H and lead > 0")]
    Dimensions { h: f64, lead: f64, bo: f64 },
    #[error("the pose is not finite")]
    NonFinite,
    #[error("branch {0} is out of range 0..=63")]
    Branch(u8),
    #[error("the link is parallel to the planes (u_z = {uz:.3e})")]
    LinkParallel { uz: f64 },
    #[error("{plane} mechanism: {error}")]
    Planar {
        plane: &'static str,
        error: PlanarError,
    },
    #[error("the Jacobian is singular (no finite efforts)")]
    Singular,
}

fn planar(plane: &'static str) -> impl Fn(PlanarError) -> DctError {
    move |error| DctError::Planar { plane, error }
}

/// A solution of the inverse kinematics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DctSolution {
    pub pose: Pose<f64>,
    pub branch: u8,
    /// The lower and the upper triangle's pose in its plane.
    pub lower: PlanarPose,
    pub upper: PlanarPose,
    /// The sliders' angles φ (rad): lower, upper.
    pub phi_lower: [f64; 3],
    pub phi_upper: [f64; 3],
    /// The distance s from the lower centre to the tool point along the link (m).
    pub s: f64,
}

impl DctSolution {
    /// The joints q (arc lengths rc φ, m): lower sliders, then upper.
    pub fn q(&self, rc: f64) -> [f64; 6] {
        let [a, b, c] = self.phi_lower;
        let [d, e, f] = self.phi_upper;
        [a, b, c, d, e, f].map(|p| rc * wrap(p))
    }
}

/// An angle wrapped to (-π, π].
pub fn wrap(a: f64) -> f64 {
    let w = a - 2.0 * PI * ((a + PI) / (2.0 * PI)).floor();
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// The horizontal pin a of a U joint at rotation ψ.
fn pin_a(psi: f64) -> Vector3<f64> {
    Vector3::new(psi.cos(), psi.sin(), 0.0)
}

/// ψ of the triangle whose U joint's output pin is b (a = ẑ × b / |ẑ × b|).
fn psi_of(b: &Vector3<f64>) -> f64 {
    let a = Vector3::z().cross(b);
    a.y.atan2(a.x)
}

/// The rate ψ̇ of a triangle whose U joint's output yoke (pin b) turns at Ω.
fn psi_rate(psi: f64, b: &Vector3<f64>, omega: &Vector3<f64>) -> f64 {
    let ab = pin_a(psi).cross(b);
    omega.dot(&ab) / ab.z
}

impl DctRobot {
    /// Checked dimensions (m).
    pub fn new(rc: f64, side: f64, h: f64, lead: f64, bo: f64) -> Result<Self, DctError> {
        let planar = Planar::new(rc, side).map_err(planar("both"))?;
        if !(h.is_finite() && lead.is_finite() && bo.is_finite() && h > 0.0 && lead > 0.0) {
            return Err(DctError::Dimensions { h, lead, bo });
        }
        Ok(DctRobot {
            planar,
            h,
            lead,
            bo,
        })
    }

    /// The robot of Table 4.1 ("Double planar"): Rb = Rp = 199.138 mm, Lb = Lp = 460.320
    /// mm, H = 60 mm, lead 25 mm, Bo = 50 mm.
    pub fn table_4_1() -> Self {
        DctRobot {
            planar: Planar {
                rc: 0.199_138,
                side: 0.460_320,
            },
            h: 0.060,
            lead: 0.025,
            bo: 0.050,
        }
    }

    /// s0 = H + Bo: the tool point's distance from the lower centre at the central
    /// configuration.
    pub fn s0(&self) -> f64 {
        self.h + self.bo
    }

    /// The central configuration: the tool point at [0, 0, H + Bo], R = I.
    pub fn central(&self) -> Pose<f64> {
        Pose::central(self.s0())
    }

    /// The link's marker m = R [0, -1, 0] (the upper U joint's output pin).
    fn marker(pose: &Pose<f64>) -> Vector3<f64> {
        -(pose.r * Vector3::y())
    }

    /// The lower U joint's output pin b_b = Rot(u, -γ) m for the link at s.
    fn lower_pin(&self, pose: &Pose<f64>, s: f64) -> Vector3<f64> {
        let u = Unit::new_unchecked(pose.r * Vector3::z());
        let gamma = 2.0 * PI * (s - self.s0()) / self.lead;
        Rotation3::from_axis_angle(&u, -gamma) * Self::marker(pose)
    }

    /// Inverse kinematics on a branch 0..=63 (lower mechanism bits 0-2, upper 3-5).
    pub fn inverse(&self, pose: &Pose<f64>, branch: u8) -> Result<DctSolution, DctError> {
        if !pose.is_finite() {
            return Err(DctError::NonFinite);
        }
        if branch > 63 {
            return Err(DctError::Branch(branch));
        }
        let u = pose.r * Vector3::z();
        if !(u.z > 1e-9) {
            return Err(DctError::LinkParallel { uz: u.z });
        }
        let o = pose.t;
        let cb = o - u * (o.z / u.z);
        let cp = o + u * ((self.h - o.z) / u.z);
        let s = o.z / u.z;
        let psi_p = psi_of(&Self::marker(pose));
        let psi_b = psi_of(&self.lower_pin(pose, s));
        let lower = PlanarPose {
            p: Vector2::new(cb.x, cb.y),
            psi: psi_b,
        };
        let upper = PlanarPose {
            p: Vector2::new(cp.x, cp.y),
            psi: psi_p,
        };
        let phi_lower = self
            .planar
            .inverse(&lower, branch & 7)
            .map_err(planar("lower"))?;
        let phi_upper = self
            .planar
            .inverse(&upper, branch >> 3)
            .map_err(planar("upper"))?;
        Ok(DctSolution {
            pose: *pose,
            branch,
            lower,
            upper,
            phi_lower,
            phi_upper,
            s,
        })
    }

    /// The planar rates [ċ_b,x, ċ_b,y, ψ̇_b] and [ċ_p,x, ċ_p,y, ψ̇_p] of a twist [v; ω]
    /// (module documentation), with the screw's lead `lead`.
    fn planar_rates(
        &self,
        sol: &DctSolution,
        twist: &Vector6<f64>,
        lead: f64,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let v = Vector3::new(twist[0], twist[1], twist[2]);
        let w = Vector3::new(twist[3], twist[4], twist[5]);
        let o = sol.pose.t;
        let u = sol.pose.r * Vector3::z();
        let du = w.cross(&u);
        let (lb, lp) = (-o.z / u.z, (self.h - o.z) / u.z);
        let dlb = -v.z / u.z + o.z * du.z / (u.z * u.z);
        let dlp = -v.z / u.z - (self.h - o.z) * du.z / (u.z * u.z);
        let dcb = v + u * dlb + du * lb;
        let dcp = v + u * dlp + du * lp;
        let ds = (v - dcb).dot(&u);
        let dgamma = 2.0 * PI * ds / lead;
        let bp = Self::marker(&sol.pose);
        let bb = self.lower_pin(&sol.pose, sol.s);
        let dpsi_p = psi_rate(sol.upper.psi, &bp, &w);
        let dpsi_b = psi_rate(sol.lower.psi, &bb, &(w - u * dgamma));
        (
            Vector3::new(dcb.x, dcb.y, dpsi_b),
            Vector3::new(dcp.x, dcp.y, dpsi_p),
        )
    }

    fn jacobian_with_lead(&self, sol: &DctSolution, lead: f64) -> Result<Matrix6<f64>, DctError> {
        let jb: Matrix3<f64> = self
            .planar
            .jacobian(&sol.lower, &sol.phi_lower)
            .map_err(planar("lower"))?;
        let jp: Matrix3<f64> = self
            .planar
            .jacobian(&sol.upper, &sol.phi_upper)
            .map_err(planar("upper"))?;
        let mut j = Matrix6::zeros();
        for k in 0..6 {
            let (yb, yp) = self.planar_rates(sol, &Vector6::ith(k, 1.0), lead);
            let (qb, qp) = (jb * yb, jp * yp);
            for i in 0..3 {
                j[(i, k)] = qb[i];
                j[(i + 3, k)] = qp[i];
            }
        }
        Ok(j)
    }

    /// J = dq/dx: rows the sliders (lower, upper; q̇ in m/s along the circle), columns the
    /// twist [v; ω] of the tool point.
    pub fn jacobian(&self, sol: &DctSolution) -> Result<Matrix6<f64>, DctError> {
        self.jacobian_with_lead(sol, self.lead)
    }

    /// The sliders' forces along the circle τ = J⁻ᵀ s_e (N) that hold the wrench s_e =
    /// [f (N); t (N m)] the tool point exerts, with the screw's efficiency η in (0, 1].
    pub fn efforts(
        &self,
        sol: &DctSolution,
        se: &Vector6<f64>,
        eta: f64,
    ) -> Result<Vector6<f64>, DctError> {
        if !(se.iter().all(|x| x.is_finite()) && eta > 0.0 && eta <= 1.0) {
            return Err(DctError::NonFinite);
        }
        let j = self.jacobian_with_lead(sol, self.lead / eta)?;
        j.transpose()
            .lu()
            .solve(se)
            .filter(|t| t.iter().all(|x| x.is_finite()))
            .ok_or(DctError::Singular)
    }

    /// Forward kinematics from the sliders' angles φ (lower, upper; rad), the two
    /// mechanisms' assembly modes (bit 0 lower, bit 1 upper: [`Planar::direct`]'s second
    /// root when set), and the screw's turn nearest `s_hint` (m from the lower centre; the
    /// joints give the screw's angle modulo a turn).
    pub fn forward(
        &self,
        phi_lower: &[f64; 3],
        phi_upper: &[f64; 3],
        modes: u8,
        s_hint: f64,
    ) -> Result<Pose<f64>, DctError> {
        let pick = |m: [PlanarPose; 2], bit: u8| if modes & bit == 0 { m[0] } else { m[1] };
        let lower = pick(self.planar.direct(phi_lower).map_err(planar("lower"))?, 1);
        let upper = pick(self.planar.direct(phi_upper).map_err(planar("upper"))?, 2);
        let cb = Vector3::new(lower.p.x, lower.p.y, 0.0);
        let cp = Vector3::new(upper.p.x, upper.p.y, self.h);
        let u = (cp - cb).normalize();
        let bp = pin_a(upper.psi).cross(&u).normalize();
        let bb = pin_a(lower.psi).cross(&u).normalize();
        // The link's frame: z along u, y = -m = -b_p.
        let y = -bp;
        let x = y.cross(&u);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, u]));
        // b_p = Rot(u, γ) b_b: γ modulo a turn, then the turn nearest the hint.
        let gamma0 = bb.cross(&bp).dot(&u).atan2(bb.dot(&bp));
        let turn = self.lead;
        let s_base = self.s0() + turn * gamma0 / (2.0 * PI);
        let s = s_base + turn * ((s_hint - s_base) / turn).round();
        Ok(Pose { t: cb + u * s, r })
    }
}

/// The appendix's verdicts on a robot (section 4): the task box, the envelope and the
/// forces along the diagonal.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdicts {
    /// Task poses (the thesis's box about the central configuration, parallel and turned
    /// 20 deg about [1,1,0]) and how many have an IK on the branch and a regular Jacobian.
    pub task_poses: usize,
    pub task_solved: usize,
    /// The first task pose that failed (mm, deg) and why.
    pub first_failure: Option<([f64; 6], String)>,
    /// The smallest |s_i| (the slider's serial measure, [`crate::dct`]) over the task.
    pub min_serial: f64,
    /// A lower bound of the robot's horizontal extent: the circles' diameter 2 rc (m),
    /// against the 200 mm cube.
    pub envelope_min: f64,
    /// The largest |τ_i| (N) per slider along the diagonal, at efficiency 1.
    pub diagonal_peaks: [f64; 6],
    /// Diagonal samples without efforts.
    pub diagonal_failed: usize,
}

/// The edge of the appendix's envelope cube (m).
pub const ENVELOPE_M: f64 = 0.200;

impl DctRobot {
    /// The joints' serial measure: the smallest |s_i| of both mechanisms.
    fn serial_measure(&self, sol: &DctSolution) -> f64 {
        let m = |x: &PlanarPose, phi: &[f64; 3]| {
            phi.iter()
                .enumerate()
                .map(|(i, f)| {
                    Planar::normal(x.psi, i)
                        .dot(&Vector2::new(-f.sin(), f.cos()))
                        .abs()
                })
                .fold(f64::INFINITY, f64::min)
        };
        m(&sol.lower, &sol.phi_lower).min(m(&sol.upper, &sol.phi_upper))
    }

    /// Evaluates the robot against the appendix's task on branch `branch`: `task` are the
    /// task poses (mm, deg; the box about [0, 0, s0]) and `diagonal` the poses of the
    /// forces path, with the wrench `se` (N, N m).
    pub fn verdicts(
        &self,
        task: &[[f64; 6]],
        diagonal: &[[f64; 6]],
        se: &Vector6<f64>,
        branch: u8,
    ) -> Verdicts {
        let edge = |p: &[f64; 6]| {
            Pose::from_position_rotation_vector(
                Vector3::new(p[0], p[1], p[2]) * 1e-3,
                Vector3::new(p[3], p[4], p[5]).map(f64::to_radians),
            )
            .map_err(|_| DctError::NonFinite)
        };
        let mut v = Verdicts {
            task_poses: task.len(),
            task_solved: 0,
            first_failure: None,
            min_serial: f64::INFINITY,
            envelope_min: 2.0 * self.planar.rc,
            diagonal_peaks: [0.0; 6],
            diagonal_failed: 0,
        };
        for p in task {
            let r = edge(p)
                .and_then(|x| self.inverse(&x, branch))
                .and_then(|s| {
                    self.jacobian(&s)?;
                    Ok(s)
                });
            match r {
                Ok(s) => {
                    v.task_solved += 1;
                    v.min_serial = v.min_serial.min(self.serial_measure(&s));
                }
                Err(e) if v.first_failure.is_none() => v.first_failure = Some((*p, e.to_string())),
                Err(_) => {}
            }
        }
        for p in diagonal {
            match edge(p)
                .and_then(|x| self.inverse(&x, branch))
                .and_then(|s| self.efforts(&s, se, 1.0))
            {
                Ok(t) => {
                    for (pk, x) in v.diagonal_peaks.iter_mut().zip(t.iter()) {
                        *pk = pk.max(x.abs());
                    }
                }
                Err(_) => v.diagonal_failed += 1,
            }
        }
        v
    }
}

/// The appendix's evaluation of a robot, in words: the task box (a `grid` per
/// orientation about the central configuration), the envelope and the diagonal's forces
/// against the reference RSPR's on the same path (thesis Appendix A, section 4 and its
/// conclusion: the double planar robot "exceeds the task limitations with its enveloping
/// volume and requires large actuator forces").
pub fn report(robot: &DctRobot, grid: [usize; 3], branch: u8) -> String {
    use crate::forces_path::{forces_along, path_poses, peaks, PathSpec};
    use kinematics_core::{Robot, RsprGeometry};
    use robot_config::task_box::TaskBox;
    use std::fmt::Write as _;
    let s0_mm = robot.s0() * 1e3;
    let task_box = TaskBox::thesis(grid);
    let task: Vec<[f64; 6]> = task_box.poses(s0_mm).iter().map(|p| p.pose).collect();
    let spec = PathSpec::thesis_diagonal();
    let diagonal: Vec<[f64; 6]> = path_poses(s0_mm, &spec).iter().map(|p| p.1).collect();
    let v = robot.verdicts(&task, &diagonal, &Vector6::from(spec.wrench), branch);
    let rspr = peaks(&forces_along(
        &Robot::Rspr(RsprGeometry::reference()),
        &spec,
    ));
    let dct_peak = v.diagonal_peaks.iter().fold(0.0f64, |a, b| a.max(*b));
    let rspr_leg = rspr.iter().take(3).fold(0.0f64, |a, b| a.max(*b));
    let mut o = String::new();
    let g = robot;
    let _ = writeln!(
        o,
        "double circular-triangular robot: rc {:.3} mm, triangle side {:.3} mm, H {:.1} mm, \
         lead {:.1} mm, Bo {:.1} mm (tool point {:.1} mm above the lower plane), branch {branch}",
        g.planar.rc * 1e3,
        g.planar.side * 1e3,
        g.h * 1e3,
        g.lead * 1e3,
        g.bo * 1e3,
        s0_mm
    );
    let _ = writeln!(
        o,
        "task: {}: {} of {} poses solved with a regular Jacobian; smallest slider measure \
         |s_i| {:.4}",
        task_box.describe(s0_mm),
        v.task_solved,
        v.task_poses,
        v.min_serial
    );
    if let Some((p, why)) = &v.first_failure {
        let _ = writeln!(o, "  first failure at {p:?}: {why}");
    }
    let fits = v.envelope_min <= ENVELOPE_M;
    let _ = writeln!(
        o,
        "envelope: the circles alone span {:.1} mm, {} the {:.0} mm cube",
        v.envelope_min * 1e3,
        if fits { "inside" } else { "exceeding" },
        ENVELOPE_M * 1e3
    );
    let _ = writeln!(
        o,
        "diagonal (20 deg about [1,1,1], s_e = 7,7,7 N, 0.7,0.7,0.7 N m, efficiency 1): \
         peak slider forces {} N ({} samples failed); the reference RSPR's peak leg force \
         on the same path {:.2} N",
        v.diagonal_peaks
            .iter()
            .map(|x| format!("{x:.1}"))
            .collect::<Vec<_>>()
            .join(", "),
        v.diagonal_failed,
        rspr_leg
    );
    let ratio = dct_peak / rspr_leg;
    let _ =
        writeln!(
        o,
        "thesis's conclusion: \"exceeds the task limitations with its enveloping volume\": {}; \
         \"requires large actuator forces\": {} (peak slider force {:.1} N = {:.2} x the \
         RSPR's peak leg force; read as large at 2 x or more)",
        if fits { "not confirmed" } else { "confirmed" },
        if ratio >= 2.0 { "confirmed" } else { "not confirmed by this model" },
        dct_peak,
        ratio
    );
    o
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use proptest::prelude::*;

    fn pose(p: [f64; 3], rotvec: [f64; 3]) -> Pose<f64> {
        Pose::from_position_rotation_vector(Vector3::from(p), Vector3::from(rotvec)).unwrap()
    }

    /// The central configuration: both triangles centred with ψ = 0, s = H + Bo.
    #[test]
    fn central_configuration() {
        let r = DctRobot::table_4_1();
        let s = r.inverse(&r.central(), 0).unwrap();
        assert!(s.lower.p.norm() < 1e-15 && s.upper.p.norm() < 1e-15);
        assert!(s.lower.psi.abs() < 1e-15 && s.upper.psi.abs() < 1e-15);
        assert!((s.s - 0.110).abs() < 1e-15);
    }

    /// A spin about the link's axis turns the upper triangle by the same angle (the U joint
    /// is aligned), and the lower one too (the screw does not move along the axis).
    #[test]
    fn spin_about_the_axis_turns_both_triangles() {
        let r = DctRobot::table_4_1();
        let s = r
            .inverse(&pose([0.0, 0.0, 0.11], [0.0, 0.0, 0.3]), 0)
            .unwrap();
        assert!((s.upper.psi - 0.3).abs() < 1e-12 && (s.lower.psi - 0.3).abs() < 1e-12);
    }

    /// Moving the tool point along the vertical axis by one lead turns the lower triangle
    /// by one turn less (right-handed screw) and leaves the upper one.
    #[test]
    fn translation_along_the_axis_is_the_screw() {
        let r = DctRobot::table_4_1();
        let s = r
            .inverse(&pose([0.0, 0.0, 0.11 + 0.025 / 4.0], [0.0; 3]), 0)
            .unwrap();
        assert!(s.upper.psi.abs() < 1e-12);
        assert!((s.lower.psi + PI / 2.0).abs() < 1e-12, "{}", s.lower.psi);
    }

    fn task_pose() -> impl Strategy<Value = (Pose<f64>, u8)> {
        (
            -0.02..0.02f64,
            -0.02..0.02f64,
            0.10..0.12f64,
            prop::array::uniform3(-0.2..0.2f64),
            0u8..64,
        )
            .prop_map(|(x, y, z, r, b)| (pose([x, y, z], r), b))
    }

    proptest! {
        #![proptest_config(proptest_config::cases(128))]

        /// IK then FK (the assembly modes and screw turn of the solution) returns the pose.
        #[test]
        fn ik_fk_round_trip((p, b) in task_pose()) {
            let r = DctRobot::table_4_1();
            let s = r.inverse(&p, b).unwrap();
            // Which assembly mode each triangle is in: the one FK of its mechanism returns.
            let mode = |m: [PlanarPose; 2], x: &PlanarPose| {
                u8::from((m[1].p - x.p).norm() < (m[0].p - x.p).norm())
            };
            let ml = mode(r.planar.direct(&s.phi_lower).unwrap(), &s.lower);
            let mu = mode(r.planar.direct(&s.phi_upper).unwrap(), &s.upper);
            let back = r.forward(&s.phi_lower, &s.phi_upper, ml | (mu << 1), s.s + 0.01).unwrap();
            prop_assert!((back.t - p.t).norm() < 1e-12, "{} vs {}", back.t, p.t);
            let dr = (back.r.matrix() - p.r.matrix()).norm();
            prop_assert!(dr < 1e-12, "rotation off by {}", dr);
        }

        /// J against central differences of the IK along each unit twist: the error of a
        /// central difference is h²/6 |q'''| plus rounding ε|q|/h; with h = 1e-6 (m, rad)
        /// both are far below 1e-6 of the column's norm.
        #[test]
        fn jacobian_matches_finite_differences((p, b) in task_pose()) {
            let r = DctRobot::table_4_1();
            let s = r.inverse(&p, b).unwrap();
            let j = r.jacobian(&s).unwrap();
            let h = 1e-6;
            for k in 0..6 {
                let e = Vector6::ith(k, h);
                let dv = Vector3::new(e[0], e[1], e[2]);
                let dw = Vector3::new(e[3], e[4], e[5]);
                let q = |sign: f64| {
                    let x = p.displaced(&(dv * sign), &(dw * sign));
                    r.inverse(&x, b).unwrap().q(r.planar.rc)
                };
                let (qp, qm) = (q(1.0), q(-1.0));
                let col = j.column(k);
                for i in 0..6 {
                    let period = 2.0 * PI * r.planar.rc;
                    let d = qp[i] - qm[i];
                    let d = d - period * (d / period).round();
                    let fd = d / (2.0 * h);
                    prop_assert!((fd - col[i]).abs() <= 1e-6 * col.norm(),
                        "J[{},{}] = {} vs {}", i, k, col[i], fd);
                }
            }
        }

        /// Virtual work: τ·(J t) = s_e·t for any twist t, to 1e-9 relative (η = 1).
        #[test]
        fn statics_satisfy_virtual_work((p, b) in task_pose(), t in prop::array::uniform6(-1.0..1.0f64)) {
            let r = DctRobot::table_4_1();
            let s = r.inverse(&p, b).unwrap();
            let se = Vector6::new(7.0, 7.0, 7.0, 0.7, 0.7, 0.7);
            let tau = r.efforts(&s, &se, 1.0).unwrap();
            let t = Vector6::from(t);
            let qdot = r.jacobian(&s).unwrap() * t;
            let (lhs, rhs) = (tau.dot(&qdot), se.dot(&t));
            let scale = tau.abs().max() * qdot.abs().max() + se.abs().max() * t.abs().max();
            prop_assert!((lhs - rhs).abs() <= 1e-9 * scale, "{} vs {}", lhs, rhs);
        }
    }

    /// The efficiency divides only what passes through the screw: at the central
    /// configuration an axial force loads the nut (and, in reaction, the spline of the
    /// upper joint) by F l / (2π η), so every slider's force scales by 1/η; a lateral
    /// force does not move the screw (ṡ = 0 for a lateral v) and is unchanged.
    #[test]
    fn efficiency_scales_the_screw_load() {
        let r = DctRobot::table_4_1();
        let s = r.inverse(&r.central(), 0).unwrap();
        let axial = Vector6::new(0.0, 0.0, 10.0, 0.0, 0.0, 0.0);
        let t1 = r.efforts(&s, &axial, 1.0).unwrap();
        let t2 = r.efforts(&s, &axial, 0.5).unwrap();
        for i in 0..6 {
            assert!(t1[i].abs() > 1e-3, "{t1}");
            assert!(
                (t2[i] - 2.0 * t1[i]).abs() < 1e-9 * t1[i].abs(),
                "{t1} {t2}"
            );
        }
        let lateral = Vector6::new(10.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let t1 = r.efforts(&s, &lateral, 1.0).unwrap();
        let t2 = r.efforts(&s, &lateral, 0.5).unwrap();
        assert!((t1 - t2).norm() < 1e-9 * t1.norm(), "{t1} {t2}");
    }

    #[test]
    fn a_link_parallel_to_the_planes_is_refused() {
        let r = DctRobot::table_4_1();
        let e = r.inverse(&pose([0.0, 0.0, 0.11], [PI / 2.0, 0.0, 0.0]), 0);
        assert!(matches!(e, Err(DctError::LinkParallel { .. })), "{e:?}");
    }
}
