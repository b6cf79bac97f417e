//! `host-sim report`: a readable text report of a robot: its dimensions, the inverse
//! kinematics of the central pose on every branch, and, at the central pose and over the
//! thesis's task box on branch 0, the joint ranges, the conditioning of the Jacobian, the
//! serial margins, the spherical-joint tilt and the actuator forces for a wrench.
//! [`render`] returns the report as text.

use crate::ranges::PoseFailure;
use kinematics_core::{
    actuator_forces, inverse, jacobian, measures, tilt_angles, Branch, Chain, JointKind, Measures,
    Mechanism, PerChain, Pose, Robot, RobotKind, SocketAxes, Wrench,
};
use robot_config::edge::{joint_columns, joints_to_edge, pose_from_edge, POSE};
use robot_config::selection::{kind_name, SelectedRobot};
use robot_config::task_box::{pose_label, TaskBox};
use robot_config::units::{fixed, m_to_mm, rad_to_deg};
use std::fmt::Write as _;

/// What the report evaluates.
#[derive(Clone, Debug, PartialEq)]
pub struct Task {
    /// The task box, its grid and its orientations.
    pub task_box: TaskBox,
    /// Wrench, N and N m.
    pub wrench: [f64; 6],
    /// Smallest inverse condition number for the forces.
    pub min_inv_cond: f64,
}

impl Default for Task {
    /// The thesis task: 40 x 40 x 20 mm on a 5 x 5 x 3 grid, +20 deg, [7,7,7,0.7,0.7,0.7].
    fn default() -> Self {
        Task {
            task_box: TaskBox::thesis([5, 5, 3]),
            wrench: [7.0, 7.0, 7.0, 0.7, 0.7, 0.7],
            min_inv_cond: 1e-6,
        }
    }
}

/// The largest or smallest value seen, with the chain and pose where it occurred.
#[derive(Clone, Debug)]
struct Extreme {
    value: f64,
    /// A second value reported alongside (e.g. the relative serial measure).
    other: f64,
    chain: Option<Chain>,
    pose: [f64; 6],
}

impl Extreme {
    fn keep_min(slot: &mut Option<Extreme>, e: Extreme) {
        if slot.as_ref().is_none_or(|s| e.value < s.value) {
            *slot = Some(e);
        }
    }
    fn keep_max(slot: &mut Option<Extreme>, e: Extreme) {
        if slot.as_ref().is_none_or(|s| e.value > s.value) {
            *slot = Some(e);
        }
    }
    fn at(&self) -> String {
        match self.chain {
            Some(c) => format!("on {c} at {}", pose_label(&self.pose)),
            None => format!("at {}", pose_label(&self.pose)),
        }
    }
}

/// A closed range of values.
#[derive(Clone, Copy, Debug)]
struct Range {
    min: f64,
    max: f64,
}

impl Range {
    const EMPTY: Range = Range {
        min: f64::INFINITY,
        max: f64::NEG_INFINITY,
    };
    fn add(&mut self, x: f64) {
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }
    fn is_empty(&self) -> bool {
        self.min > self.max
    }
}

/// What the task sweep found.
#[derive(Debug)]
struct Sweep {
    poses: usize,
    solved: usize,
    joints: [Range; 6],
    inv_cond_min: Option<Extreme>,
    inv_cond_max: Option<Extreme>,
    det_signs: Vec<i8>,
    serial_min: Option<Extreme>,
    tilt_max: Option<Extreme>,
    tau: [Range; 6],
    forces_done: usize,
    /// Poses where some step failed.
    failed_poses: usize,
    failures: Vec<String>,
}

/// The units of a robot's serial measure: (name, SI-to-unit factor, unit, "of" what).
fn serial_units(kind: RobotKind) -> (&'static str, f64, &'static str, &'static str) {
    match kind {
        RobotKind::Rspr => ("|Cn2_i|", 1e3, "mm", "rb"),
        RobotKind::Usr => ("|Cn1_i Cr2_i - Cr1_i Cn2_i|", 1e6, "mm^2", "l1^2"),
    }
}

/// The unit of a joint's force: N on a prismatic joint, N m on a revolute one.
fn force_unit(kind: JointKind) -> &'static str {
    match kind {
        JointKind::Linear => "N",
        JointKind::Angular => "N m",
    }
}

/// Evaluates every task pose on branch 0.
fn sweep(robot: &Robot<f64>, task: &Task, axes: Option<&SocketAxes<f64>>) -> Sweep {
    let hc_mm = m_to_mm(robot.hc());
    let wrench = Wrench::from(task.wrench);
    let poses: Vec<[f64; 6]> = task
        .task_box
        .poses(hc_mm)
        .into_iter()
        .map(|p| p.pose)
        .collect();
    let mut s = Sweep {
        poses: poses.len(),
        solved: 0,
        joints: [Range::EMPTY; 6],
        inv_cond_min: None,
        inv_cond_max: None,
        det_signs: Vec::new(),
        serial_min: None,
        tilt_max: None,
        tau: [Range::EMPTY; 6],
        forces_done: 0,
        failed_poses: 0,
        failures: Vec::new(),
    };
    for p in poses {
        let failures_before = s.failures.len();
        let fail =
            |step: &str, e: &dyn std::fmt::Display| format!("{}: {step}: {e}", pose_label(&p));
        let sol = match pose_from_edge(&POSE, p)
            .map_err(|e| e.to_string())
            .and_then(|pose| inverse(robot, &pose, Branch::OUTER).map_err(|e| e.to_string()))
        {
            Ok(sol) => sol,
            Err(e) => {
                s.failures.push(fail("ik", &e));
                s.failed_poses += 1;
                continue;
            }
        };
        s.solved += 1;
        for (r, q) in s.joints.iter_mut().zip(joints_to_edge(robot, &sol.q())) {
            r.add(q);
        }
        match measures(robot, &sol) {
            Ok(m) => s.add_measures(&m, p),
            Err(e) => s.failures.push(fail("singularity", &e)),
        }
        if let Some(axes) = axes {
            s.add_tilt(&tilt_angles(&sol, axes), p);
        }
        let tau = jacobian(robot, &sol)
            .map_err(|e| fail("jacobian", &e))
            .and_then(|jac| {
                actuator_forces(&jac, robot.rp(), &wrench, task.min_inv_cond)
                    .map_err(|e| fail("forces", &e))
            });
        match tau {
            Ok(st) => {
                s.forces_done += 1;
                for (r, &t) in s.tau.iter_mut().zip(st.tau.iter()) {
                    r.add(t);
                }
            }
            Err(e) => s.failures.push(e),
        }
        s.failed_poses += usize::from(s.failures.len() > failures_before);
    }
    s
}

impl Sweep {
    /// The singularity measures at task pose `p`: the conditioning's extremes, the
    /// determinant's sign, the smallest serial margin.
    fn add_measures(&mut self, m: &Measures<f64>, p: [f64; 6]) {
        let e = |value, other, chain| Extreme {
            value,
            other,
            chain,
            pose: p,
        };
        Extreme::keep_min(&mut self.inv_cond_min, e(m.parallel_inv_cond, 0.0, None));
        Extreme::keep_max(&mut self.inv_cond_max, e(m.parallel_inv_cond, 0.0, None));
        if !self.det_signs.contains(&m.parallel_det_sign) {
            self.det_signs.push(m.parallel_det_sign);
        }
        for (c, &v) in m.serial.iter() {
            Extreme::keep_min(&mut self.serial_min, e(v, m.serial_relative[c], Some(c)));
        }
    }

    /// The spherical joints' tilts at task pose `p`, rad: the largest.
    fn add_tilt(&mut self, tilts: &PerChain<f64>, p: [f64; 6]) {
        for (c, &t) in tilts.iter() {
            Extreme::keep_max(
                &mut self.tilt_max,
                Extreme {
                    value: rad_to_deg(t),
                    other: 0.0,
                    chain: Some(c),
                    pose: p,
                },
            );
        }
    }
}

/// The dimensions section.
fn dimensions(out: &mut String, robot: &Robot<f64>) {
    let rows: Vec<(&str, f64, &str)> = match robot {
        Robot::Rspr(g) => vec![
            ("e_mm", g.e, "eccentricity of the rotating links' axes"),
            ("rb_mm", g.rb, "rotating link length"),
            ("rp_mm", g.rp, "platform radius"),
            ("hc_mm", g.hc, "central height"),
        ],
        Robot::Usr(g) => vec![
            ("e_mm", g.e, "eccentricity of the universal joints"),
            ("rp_mm", g.rp, "platform radius"),
            ("l1_mm", g.l1, "lower link length"),
            ("l2_mm", g.l2, "upper link length"),
            ("hc_mm", g.hc, "central height"),
        ],
        Robot::RsprPerChain(g) => {
            let n = g.nominal();
            vec![
                ("e_mm", n.e, "nominal eccentricity (per-chain geometry)"),
                ("rb_mm", n.rb, "nominal rotating link length"),
                ("rp_mm", n.rp, "nominal platform radius"),
                ("hc_mm", n.hc, "nominal central height"),
            ]
        }
    };
    let _ = writeln!(out, "Dimensions");
    for (name, v, what) in rows {
        let _ = writeln!(out, "  {name:<6} {:>9.3}   {what}", m_to_mm(v));
    }
}

/// The inverse kinematics of the central pose on all branches.
fn central_branches(out: &mut String, robot: &Robot<f64>) {
    let hc_mm = m_to_mm(robot.hc());
    let _ = writeln!(
        out,
        "\nInverse kinematics at the central pose (0, 0, {hc_mm:.1}) mm, R = I"
    );
    let mut head = format!("  {:<7}", "branch");
    for c in joint_columns(robot.kind()) {
        let _ = write!(head, "{c:>12}");
    }
    let _ = writeln!(out, "{head}");
    let central = Pose::central(robot.hc());
    for b in Branch::ALL {
        let _ = write!(out, "  {:<7}", b.bits());
        match inverse(robot, &central, b) {
            Ok(sol) => {
                for q in joints_to_edge(robot, &sol.q()) {
                    let _ = write!(out, "{:>12}", fixed(q, 3));
                }
                let _ = writeln!(out);
            }
            Err(e) => {
                let _ = writeln!(out, "  ik failed: {e}");
            }
        }
    }
}

/// The measures and forces at the central pose on branch 0.
fn central_pose(out: &mut String, robot: &Robot<f64>, task: &Task) {
    let (serial_name, scale, unit, of) = serial_units(robot.kind());
    let _ = writeln!(out, "\nCentral pose, branch 0");
    let sol = match inverse(robot, &Pose::central(robot.hc()), Branch::OUTER) {
        Ok(sol) => sol,
        Err(e) => {
            let _ = writeln!(out, "  ik failed: {e}");
            return;
        }
    };
    match measures(robot, &sol) {
        Ok(m) => {
            let _ = writeln!(
                out,
                "  parallel inv_cond {:.4}, det(Jtilde) sign {:+}",
                m.parallel_inv_cond, m.parallel_det_sign
            );
            for (c, &v) in m.serial.iter() {
                let _ = writeln!(
                    out,
                    "  serial {serial_name} {c}: {:.3} {unit} ({:.3} of {of})",
                    v * scale,
                    m.serial_relative[c]
                );
            }
        }
        Err(e) => {
            let _ = writeln!(out, "  singularity measures failed: {e}");
        }
    }
    let forces = jacobian(robot, &sol)
        .map_err(PoseFailure::Jacobian)
        .and_then(|jac| {
            actuator_forces(
                &jac,
                robot.rp(),
                &Wrench::from(task.wrench),
                task.min_inv_cond,
            )
            .map_err(PoseFailure::Forces)
        });
    match forces {
        Ok(st) => {
            let mut line = "  forces:".to_string();
            for ((i, t), k) in st.tau.iter().enumerate().zip(robot.joint_kinds()) {
                let _ = write!(line, " tau{} {} {}", i + 1, fixed(*t, 3), force_unit(k));
                if i < 5 {
                    line.push(',');
                }
            }
            let _ = writeln!(out, "{line}");
        }
        Err(e) => {
            let _ = writeln!(out, "  {e}");
        }
    }
}

/// The sections over the task box.
fn task_sections(out: &mut String, robot: &Robot<f64>, task: &Task) {
    let hc_mm = m_to_mm(robot.hc());
    let _ = writeln!(
        out,
        "\nTask box: {}, branch 0",
        task.task_box.describe(hc_mm)
    );
    for o in task.task_box.orientations() {
        let r = o.rotation_deg;
        let _ = writeln!(
            out,
            "  orientation {}: r ({:.3}, {:.3}, {:.3}) deg",
            o.label, r[0], r[1], r[2]
        );
    }
    let axes = SocketAxes::new(robot);
    let s = sweep(robot, task, axes.as_ref().ok());
    let _ = writeln!(
        out,
        "  {} poses, {} solved, {} with every quantity computed",
        s.poses,
        s.solved,
        s.poses.saturating_sub(s.failed_poses)
    );
    joint_ranges(out, robot, &s);
    conditioning(out, &s);
    serial_margins(out, robot, &s);
    let _ = writeln!(out, "\nSpherical-joint tilt (ball-in-socket angle)");
    match (&axes, &s.tilt_max) {
        (Err(e), _) => {
            let _ = writeln!(out, "  socket axes unavailable: {e}");
        }
        (Ok(_), Some(e)) => {
            let _ = writeln!(out, "  max {:.3} deg {}", e.value, e.at());
        }
        (Ok(_), None) => {
            let _ = writeln!(out, "  (no pose solved)");
        }
    }
    task_forces(out, robot, task, &s);
    let _ = writeln!(out, "\nFailures");
    if s.failures.is_empty() {
        let _ = writeln!(out, "  none");
    }
    for f in &s.failures {
        let _ = writeln!(out, "  {f}");
    }
}

/// Each joint's range over the solved task poses.
fn joint_ranges(out: &mut String, robot: &Robot<f64>, s: &Sweep) {
    let _ = writeln!(out, "\nJoint ranges over the task");
    for ((name, r), k) in joint_columns(robot.kind())
        .iter()
        .zip(s.joints.iter())
        .zip(robot.joint_kinds())
    {
        if r.is_empty() {
            let _ = writeln!(out, "  {name:<11} (no solved pose)");
        } else {
            let span = r.max - r.min;
            let unit = if k == JointKind::Linear { "mm" } else { "deg" };
            let _ = writeln!(
                out,
                "  {name:<11} min {:>9}  max {:>9}  (span {span:.3} {unit})",
                fixed(r.min, 3),
                fixed(r.max, 3)
            );
        }
    }
}

/// The Jacobian's conditioning over the task: its extremes and the signs of its
/// determinant.
fn conditioning(out: &mut String, s: &Sweep) {
    let _ = writeln!(
        out,
        "\nJacobian conditioning (parallel inv_cond of Jtilde, moment columns / rp)"
    );
    let (Some(lo), Some(hi)) = (&s.inv_cond_min, &s.inv_cond_max) else {
        let _ = writeln!(out, "  (no pose measured)");
        return;
    };
    let _ = writeln!(out, "  min {:.4} {}", lo.value, lo.at());
    let _ = writeln!(out, "  max {:.4} {}", hi.value, hi.at());
    let signs: Vec<String> = s.det_signs.iter().map(|d| format!("{d:+}")).collect();
    let _ = writeln!(
        out,
        "  det(Jtilde) sign over the task: {}{}",
        signs.join(", "),
        if s.det_signs.len() > 1 {
            " (changes sign: the task crosses a parallel singularity)"
        } else {
            ""
        }
    );
}

/// The smallest serial margin over the task.
fn serial_margins(out: &mut String, robot: &Robot<f64>, s: &Sweep) {
    let (serial_name, scale, unit, of) = serial_units(robot.kind());
    let _ = writeln!(out, "\nSerial margins ({serial_name}, Eq. 10.6/10.11)");
    match &s.serial_min {
        Some(e) => {
            let _ = writeln!(
                out,
                "  min {:.3} {unit} ({:.3} of {of}) {}",
                e.value * scale,
                e.other,
                e.at()
            );
        }
        None => {
            let _ = writeln!(out, "  (no pose measured)");
        }
    }
}

/// Each actuator's force range over the task for the task's wrench.
fn task_forces(out: &mut String, robot: &Robot<f64>, task: &Task, s: &Sweep) {
    let [f1, f2, f3, t1, t2, t3] = task.wrench;
    let _ = writeln!(
        out,
        "\nActuator forces for the wrench ({f1}, {f2}, {f3}) N, ({t1}, {t2}, {t3}) N m over {} poses",
        s.forces_done
    );
    for ((i, r), k) in s.tau.iter().enumerate().zip(robot.joint_kinds()) {
        if r.is_empty() {
            let _ = writeln!(out, "  tau{} (none computed)", i + 1);
        } else {
            let _ = writeln!(
                out,
                "  tau{}  min {:>9}  max {:>9} {}",
                i + 1,
                fixed(r.min, 3),
                fixed(r.max, 3),
                force_unit(k)
            );
        }
    }
}

/// The whole report as text.
pub fn render(selected: &SelectedRobot, task: &Task) -> String {
    let robot = &selected.robot;
    let kind = kind_name(robot.kind());
    let mut out = format!("host-sim report: {kind} robot, {}\n\n", selected.source);
    dimensions(&mut out, robot);
    central_branches(&mut out, robot);
    central_pose(&mut out, robot, task);
    task_sections(&mut out, robot, task);
    out
}
