//! The pose guards: the workspace box and tilt cone, reach (inverse kinematics), joint
//! ranges, spherical-joint tilts, the collision circle (11.4), the serial and parallel
//! singularity measures (Eq. 10.6, 10.11; CONVENTIONS) and the actuator efforts of the
//! declared payload (Eq. 7.10).

use crate::branch::Branch;
use crate::chain::Chain;
use crate::ik::{inverse_into, Solution};
use crate::jacobian::{jacobian_into, tripod_jacobian, Jacobians};
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::{rotation_angle, Pose};
use crate::scalar::{lit, wrap_angle, Real};
use crate::singularity::ConditionEstimator;
use crate::statics::{forces_with_inv_cond, Statics};
use crate::tilt::tilt_angles;
use nalgebra::Vector3;

use super::readings::{
    lower, stop_only, unreachable, upper, Guard, Reading, Severity, Subject, Verdict,
};
use super::setup::Guards;

/// Scratch space of one guard evaluation on the control path
/// ([`Guards::evaluate_pose_into`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation<T: Real> {
    /// The inverse-kinematics solution (valid unless [`Solved::No`]).
    pub sol: Solution<T>,
    /// The Jacobians (valid with [`Solved::WithJacobian`]).
    pub jac: Jacobians<T>,
}

impl<T: Real> Evaluation<T> {
    /// Empty scratch space.
    pub fn new(branch: Branch) -> Self {
        Evaluation {
            sol: Solution::zeroed(branch),
            jac: Jacobians::zeroed(),
        }
    }
}

/// How far a solution is from each group of stop levels, as fractions of their ranges:
/// 1 far away (at the middle of a range), 0 at the stop level, negative beyond it (see
/// [`Guards::margins_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuardMargins<T: Real> {
    /// Prismatic stroke (RSPR) or lower-link yaw (USR).
    pub stroke: T,
    /// Rotating-link angle (RSPR) or lower-link pitch (USR).
    pub link_angle: T,
    /// Spherical-joint tilt.
    pub tilt: T,
    /// Collision circle (1 when disabled).
    pub collision: T,
    /// Task box with its margin, and the tilt cone.
    pub workspace: T,
    /// Serial singularity measure.
    pub serial: T,
}

/// How much of the guards an evaluation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    /// Every pose guard.
    Full,
    /// Every guard that follows from the inverse kinematics and the Jacobian (reach,
    /// workspace, joint ranges, tilt, collision, serial singularity), not the parallel
    /// measure (an SVD) nor the payload statics (an LU): for a pose between two poses
    /// where those were checked (the supervisor's setpoints, see its documentation).
    Kinematic,
}

/// What a guard evaluation could compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solved {
    /// No inverse-kinematics solution (a Reach reading was given).
    No,
    /// A solution, but no Jacobian (a serial singularity, or the measures failed).
    WithoutJacobian,
    /// A solution and its Jacobians.
    WithJacobian,
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// Evaluates every pose guard at `pose`, handing each reading to `visit` (violations
    /// and fine ones alike). Returns the inverse-kinematics solution when there is one
    /// (the convenience form of [`Guards::evaluate_pose_into`], with a cold SVD).
    // Off the control tick (a start, the park move's check, clearing a stop): out of line,
    // the visitor a trait object, so that a firmware image holds one copy of the whole
    // evaluation whatever its callers' closures (each closure type would be a copy).
    #[inline(never)]
    pub fn evaluate_pose(
        &self,
        pose: &Pose<T>,
        visit: &mut dyn FnMut(&Reading<T>),
    ) -> Option<Solution<T>> {
        let mut e = Evaluation::new(self.branch);
        match self.evaluate_pose_into(
            pose,
            &mut |r: &Reading<T>| visit(r),
            &mut ConditionEstimator::new(),
            &mut e,
            Depth::Full,
        ) {
            Solved::No => None,
            Solved::WithoutJacobian | Solved::WithJacobian => Some(e.sol),
        }
    }

    /// Evaluates the pose guards of `depth` at `pose` in place, the control path's form:
    /// the solution and the Jacobians are written into `out` (no copies of returned values;
    /// about 600 bytes on the Cortex-M4) and the result says which of them are valid; the
    /// parallel measure's SVD is warm-started by `cond` (keep one estimator per stream of
    /// nearby poses: the readings are those of a cold start to the SVD's tolerance).
    pub fn evaluate_pose_into(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
        cond: &mut ConditionEstimator<T>,
        out: &mut Evaluation<T>,
        depth: Depth,
    ) -> Solved {
        self.workspace_readings(pose, visit);
        if let Err(e) = inverse_into(&self.robot, pose, self.branch, &mut out.sol) {
            visit(&unreachable(e.chain));
            return Solved::No;
        }
        if self.solution_readings(&out.sol, visit, cond, &mut out.jac, depth) {
            Solved::WithJacobian
        } else {
            Solved::WithoutJacobian
        }
    }

    /// At a pose whose motion from a safe setpoint a certificate covers
    /// ([`crate::guards::certificate`]): no stop-level guard can be violated there, so only
    /// what a setpoint needs is computed into `out`: the inverse kinematics, the serial
    /// singularity readings (their warn level, which the certificate does not carry) and
    /// the Jacobians. What [`Self::evaluate_pose_into`] at [`Depth::Kinematic`] would solve.
    pub fn solve_certified(
        &self,
        pose: &Pose<T>,
        visit: &mut impl FnMut(&Reading<T>),
        out: &mut Evaluation<T>,
    ) -> Solved {
        if let Err(e) = inverse_into(&self.robot, pose, self.branch, &mut out.sol) {
            visit(&unreachable(e.chain));
            return Solved::No;
        }
        self.serial_readings(&out.sol, visit);
        if jacobian_into(&self.robot, &out.sol, &mut out.jac).is_ok() {
            Solved::WithJacobian
        } else {
            Solved::WithoutJacobian
        }
    }

    /// The kinematic guard margins of a solution the caller has (e.g. the supervisor's
    /// setpoint): no inverse kinematics, no SVD; each the smallest over the chains, as a
    /// fraction of its range ([`GuardMargins`]).
    pub fn margins_at(&self, sol: &Solution<T>) -> GuardMargins<T> {
        let l = &self.limits;
        let one = T::one();
        let half_stroke = (l.stroke[1] - l.stroke[0]) * lit(0.5);
        let mut m = GuardMargins {
            stroke: one,
            link_angle: one,
            tilt: one,
            collision: one,
            workspace: one,
            serial: one,
        };
        let keep = |slot: &mut T, x: T| {
            if !(x >= *slot) {
                *slot = x;
            }
        };
        let mut visit = |r: &Reading<T>| match r.guard {
            Guard::Stroke => keep(&mut m.stroke, r.margin / half_stroke),
            Guard::Yaw => keep(&mut m.stroke, r.margin / l.link_angle_max),
            Guard::LinkAngle => keep(&mut m.link_angle, r.margin / l.link_angle_max),
            Guard::Pitch => keep(&mut m.link_angle, r.margin / l.pitch_max),
            Guard::Tilt => keep(&mut m.tilt, r.margin / l.tilt_max),
            Guard::Collision => keep(&mut m.collision, r.margin / l.collision_radius),
            Guard::Workspace => keep(
                &mut m.workspace,
                r.margin / (l.box_half.max() + l.box_margin),
            ),
            Guard::TiltCone => keep(&mut m.workspace, r.margin / l.tilt_cone),
            Guard::SerialSingularity => keep(&mut m.serial, r.margin / (one - l.serial.stop)),
            _ => {}
        };
        self.workspace_readings(&sol.pose, &mut visit);
        self.kinematic_readings(sol, &mut visit);
        m
    }

    /// The verdict at a pose: every violation, with its severity.
    pub fn check_pose(&self, pose: &Pose<T>) -> (Verdict<T>, Option<Solution<T>>) {
        let mut v = Verdict::default();
        let sol = self.evaluate_pose(pose, &mut |r| v.record(r));
        (v, sol)
    }

    /// `r` as people read it at `pose`: a workspace reading's value becomes the platform
    /// centre's coordinate on the reading's axis in {0} and its limit the face of the task
    /// box (with its margin) on that side of the box's centre [0, 0, hc], both m (the
    /// reading itself measures the distance from that centre); margin and severity stay.
    /// Every other reading is returned as it is.
    pub fn in_world(&self, r: &Reading<T>, pose: &Pose<T>) -> Reading<T> {
        let (Guard::Workspace, Subject::Axis(k)) = (r.guard, r.subject) else {
            return *r;
        };
        let (x, centre) = match k {
            0 => (pose.t.x, T::zero()),
            1 => (pose.t.y, T::zero()),
            _ => (pose.t.z, self.robot.hc()),
        };
        let face = if x >= centre {
            centre + r.limit
        } else {
            centre - r.limit
        };
        Reading {
            value: x,
            limit: face,
            ..*r
        }
    }

    pub(super) fn workspace_readings(&self, pose: &Pose<T>, visit: &mut impl FnMut(&Reading<T>)) {
        let l = &self.limits;
        let d = Vector3::new(pose.t.x, pose.t.y, pose.t.z - self.robot.hc());
        // The worst axis of the box (the one closest to or furthest beyond its face).
        let mut worst: Option<Reading<T>> = None;
        for (k, (di, hi)) in d.iter().zip(l.box_half.iter()).enumerate() {
            let r = upper(
                Guard::Workspace,
                Subject::Axis(k as u8),
                di.abs(),
                stop_only(*hi + l.box_margin),
            );
            if worst.is_none_or(|w| r.margin < w.margin || !(r.margin >= w.margin)) {
                worst = Some(r);
            }
        }
        if let Some(w) = worst {
            visit(&w);
        }
        // Platform tilt: angle between n = R z and z0.
        let r = pose.r.matrix();
        let (nx, ny, nz) = (r.m13, r.m23, r.m33);
        let tilt = crate::scalar::sqrt(nx * nx + ny * ny).atan2(nz);
        visit(&upper(
            Guard::TiltCone,
            Subject::Robot,
            tilt,
            stop_only(l.tilt_cone),
        ));
    }

    /// The readings that need the solution; true when `jac` holds its Jacobians.
    pub(super) fn solution_readings(
        &self,
        sol: &Solution<T>,
        visit: &mut impl FnMut(&Reading<T>),
        cond: &mut ConditionEstimator<T>,
        jac: &mut Jacobians<T>,
        depth: Depth,
    ) -> bool {
        self.kinematic_readings(sol, visit);
        let jac_ok = jacobian_into(&self.robot, sol, jac).is_ok();
        if depth == Depth::Kinematic {
            return jac_ok;
        }
        let Some(inv_cond) = self.parallel_reading(sol, jac_ok.then_some(&*jac), cond, visit)
        else {
            return false;
        };
        // Forces for the declared payload.
        if !jac_ok {
            return false; // a serial singularity: already a serial reading
        }
        self.statics_readings(jac, &sol.pose, inv_cond, visit);
        true
    }

    /// Joint ranges, spherical-joint tilts, the collision radius and the serial
    /// singularity measures: what follows from the inverse kinematics alone.
    pub(super) fn kinematic_readings(
        &self,
        sol: &Solution<T>,
        visit: &mut impl FnMut(&Reading<T>),
    ) {
        let l = &self.limits;
        let kinds = self.robot.joint_kinds();
        let (guard_a, guard_b) = match kinds[0] {
            JointKind::Linear => (Guard::Stroke, Guard::LinkAngle),
            JointKind::Angular => (Guard::Yaw, Guard::Pitch),
        };
        let tilts = tilt_angles(sol, &self.axes);
        for chain in Chain::ALL {
            let subject = Subject::Chain(chain);
            let (qa, qb) = (sol.chains[chain].qa, sol.chains[chain].qb);
            let (ca, cb) = self.central[chain];
            // Joint ranges.
            match kinds[0] {
                JointKind::Linear => {
                    let low = lower(guard_a, subject, qa, stop_only(l.stroke[0]));
                    let high = upper(guard_a, subject, qa, stop_only(l.stroke[1]));
                    visit(if low.margin < high.margin {
                        &low
                    } else {
                        &high
                    });
                    visit(&upper(
                        guard_b,
                        subject,
                        wrap_angle(qb - cb).abs(),
                        stop_only(l.link_angle_max),
                    ));
                }
                JointKind::Angular => {
                    visit(&upper(
                        guard_a,
                        subject,
                        wrap_angle(qa - ca).abs(),
                        stop_only(l.link_angle_max),
                    ));
                    visit(&upper(
                        guard_b,
                        subject,
                        wrap_angle(qb - cb).abs(),
                        stop_only(l.pitch_max),
                    ));
                }
            }
            // Spherical-joint tilt.
            visit(&upper(
                Guard::Tilt,
                subject,
                tilts[chain],
                stop_only(l.tilt_max),
            ));
            // Section 11.4: the leg axis must pierce the motors' plane outside the circle.
            if l.collision_radius > T::zero() {
                let c = &sol.chains[chain];
                let radius = if c.s1.z.abs() > T::default_epsilon() {
                    let k = (l.collision_plane_height - c.b.z) / c.s1.z;
                    let (px, py) = (c.b.x + c.s1.x * k, c.b.y + c.s1.y * k);
                    crate::scalar::sqrt(px * px + py * py)
                } else {
                    // A horizontal leg never meets the plane.
                    T::max_value().unwrap_or(T::one() / T::default_epsilon())
                };
                visit(&lower(
                    Guard::Collision,
                    subject,
                    radius,
                    stop_only(l.collision_radius),
                ));
            }
        }
        // Singularities (CONVENTIONS.md measures): serial per chain from the serial
        // blocks, parallel from the SVD of the scaled Jtilde, which the Jacobian computes
        // anyway (it is only recomputed alone at a serial singularity, where J is not).
        self.serial_readings(sol, visit);
    }

    /// The serial singularity measure of each chain (from its serial block).
    fn serial_readings(&self, sol: &Solution<T>, visit: &mut impl FnMut(&Reading<T>)) {
        for (chain, c) in sol.chains.iter() {
            visit(&lower(
                Guard::SerialSingularity,
                Subject::Chain(chain),
                self.robot.serial_measure(c).1,
                self.limits.serial,
            ));
        }
    }

    /// The parallel singularity measure from the SVD of the scaled Jtilde (that of `jac`
    /// when there is one, else computed from `sol`): its value, or None after a stop
    /// reading when the SVD failed.
    pub(super) fn parallel_reading(
        &self,
        sol: &Solution<T>,
        jac: Option<&Jacobians<T>>,
        cond: &mut ConditionEstimator<T>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<T> {
        let computed;
        let jtilde = match jac {
            Some(j) => &j.jtilde,
            None => {
                computed = tripod_jacobian(sol);
                &computed
            }
        };
        self.parallel_verdict(cond.inv_cond(jtilde, self.robot.rp()), visit)
    }

    /// The reading of the parallel measure (a stop when the SVD failed); its value.
    pub(super) fn parallel_verdict(
        &self,
        result: Result<T, crate::singularity::SvdDidNotConverge>,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<T> {
        let l = &self.limits;
        let Ok(inv_cond) = result else {
            visit(&Reading {
                guard: Guard::ParallelSingularity,
                subject: Subject::Robot,
                value: T::zero(),
                limit: l.parallel.stop,
                margin: -l.parallel.stop,
                severity: Some(Severity::Stop),
            });
            return None;
        };
        visit(&lower(
            Guard::ParallelSingularity,
            Subject::Robot,
            inv_cond,
            l.parallel,
        ));
        Some(inv_cond)
    }

    /// The actuator forces and torques that hold the declared payload at `pose`
    /// ([`super::Limits::payload_at`]); the statics, when they could be computed.
    pub(super) fn statics_readings(
        &self,
        jac: &Jacobians<T>,
        pose: &Pose<T>,
        inv_cond: T,
        visit: &mut impl FnMut(&Reading<T>),
    ) -> Option<Statics<T>> {
        let l = &self.limits;
        let kinds = self.robot.joint_kinds();
        let se = l.payload_at(&pose.r);
        let Ok(st) = forces_with_inv_cond(jac, &se, inv_cond, l.parallel.stop) else {
            return None; // already a parallel reading
        };
        for (j, (tau, kind)) in st.tau.iter().zip(kinds.iter()).enumerate() {
            let (guard, levels) = match kind {
                JointKind::Linear => (Guard::Force, l.force),
                JointKind::Angular => (Guard::Torque, l.torque),
            };
            visit(&upper(
                guard,
                Subject::Joint(j as u8 + 1),
                tau.abs(),
                levels,
            ));
        }
        Some(st)
    }
}

/// Rotation angle between two orientations (rad).
pub fn orientation_distance<T: Real>(a: &Pose<T>, b: &Pose<T>) -> T {
    rotation_angle(&(a.r.inverse() * b.r))
}
