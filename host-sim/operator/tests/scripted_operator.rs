//! A scripted operator against the board: a position master plays a script
//! through the whole teleoperation path (`operator::teleoperation::run`: the mapping, the
//! buttons sent as Clutch and OperatorPresent, targets streamed at 100 Hz with heartbeats)
//! to the simulated board (the firmware's board application on the plant, wall-clock
//! paced), or the board at `RSPR_BOARD_SOCKET` (see `common`). Each test states the
//! property it checks with the figures it saw; the checks are on positions after the robot
//! has settled, so the host's timing moves the figures by micrometres, not the verdicts.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{master_at, wp, TestBoard, ABSENT, CLUTCHED, PRESENT};
use master_link::{RobotState, StopStatus};
use masters::script::ScriptedMaster;
use masters::{MotionScale, TeleopConfig};
use nalgebra::Vector3;
use operator::conversions::{measured_cp, setpoint_cp};
use operator::teleoperation::{run, RunReport, TeleoperationSettings};
use std::sync::atomic::AtomicBool;

/// Runs `script` on a freshly enabled board with `scale`; the report.
fn run_script(
    board: &TestBoard,
    scale: MotionScale,
    script: Vec<masters::script::Waypoint>,
) -> RunReport {
    let mut b = board.enabled();
    let mut master = ScriptedMaster::new("script", script).unwrap();
    let settings = TeleoperationSettings {
        teleop: TeleopConfig {
            scale,
            ..TeleopConfig::default()
        },
        duration_s: Some(master.duration_s() + 0.3),
        ..TeleoperationSettings::default()
    };
    let report = run(
        &mut b,
        &mut master,
        &settings,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .unwrap();
    eprint!("{}", report.summary());
    dump(&report);
    report
}

/// The script's clock: s after its first tick.
fn t0(r: &RunReport) -> f64 {
    r.trace.inputs.first().unwrap().t_s
}

/// The last status at or before script time `t`.
fn status_at(r: &RunReport, t: f64) -> master_link::StatusReport {
    let t = t0(r) + t;
    r.trace
        .reports
        .iter()
        .rev()
        .find(|(ts, _)| *ts <= t)
        .or(r.trace.reports.first())
        .expect("a status")
        .1
}

/// The measured position of the last status at or before script time `t`, m.
fn measured_at(r: &RunReport, t: f64) -> Vector3<f64> {
    measured_cp(&status_at(r, t)).unwrap().position_m
}

/// The setpoint position of the last status at or before script time `t`, m.
fn setpoint_at(r: &RunReport, t: f64) -> Vector3<f64> {
    setpoint_cp(&status_at(r, t)).unwrap().position_m
}

/// Prints measured and setpoint over the run (every 0.25 s).
fn dump(r: &RunReport) {
    let end = r.trace.reports.last().unwrap().0 - t0(r);
    let mut t = 0.0;
    while t <= end {
        let (m, sp) = (measured_at(r, t), setpoint_at(r, t));
        eprintln!(
            "  t {t:5.2}  measured [{:8.4} {:8.4} {:8.4}]  setpoint [{:8.4} {:8.4} {:8.4}] mm  {:?}",
            m.x * 1e3, m.y * 1e3, m.z * 1e3, sp.x * 1e3, sp.y * 1e3, sp.z * 1e3,
            status_at(r, t).stop
        );
        t += 0.25;
    }
}

/// Largest distance of the measured position from `from` over script times [a, b], m.
fn max_motion(r: &RunReport, a: f64, b: f64, from: &Vector3<f64>) -> f64 {
    let (a, b) = (t0(r) + a, t0(r) + b);
    r.trace
        .reports
        .iter()
        .filter(|(t, _)| (a..=b).contains(t))
        .map(|(_, s)| (measured_cp(s).unwrap().position_m - from).norm())
        .fold(0.0, f64::max)
}

/// No fault and no stop at the end.
fn assert_no_fault(r: &RunReport) {
    let s = r.final_status().unwrap();
    assert_eq!(s.state, RobotState::Enabled, "final state");
    assert!(s.faults.is_empty(), "faults {:?}", s.faults);
    assert_eq!(s.stop, StopStatus::None);
}

/// The board's measured pose is the forward kinematics of the joints: the motor-side
/// encoders less the backlash compensation's offsets (`control::sensing`), so at rest it
/// stands within the servo's error of the setpoint (a few µm here; before the offsets
/// were taken off it stood up to 0.13 mm ahead in the direction of the last motion). The
/// exact properties are checked on the setpoint (the pose the board's supervisor
/// commands); where the robot stops hard (the workspace edge), the measured pose is held
/// to the setpoint's bound plus this: the legs' backlash (0.12 mm), the most the load side
/// can stand off the motor side, with margin.
const BACKLASH_BOUND_M: f64 = 0.15e-3;

/// How far the measured position can move while the servo holds: the position change of
/// `counts` encoder counts on every joint at once at the pose `at` (the reference robot,
/// its outer branch), `sum_j |(J⁻¹)_{v,j}| · counts / cpu_j`, m (J = dq/dx, Eq. 7.18; the
/// encoders' resolutions of `servo::encoder`). A holding servo dithers by a count either
/// side of its setpoint, so two counts peak to peak.
fn hold_band_m(at: &Vector3<f64>, counts: f64) -> f64 {
    use kinematics_core::{inverse, jacobian, Branch, Pose, Robot, RsprGeometry};
    use servo::encoder::EncoderConfig;
    let robot = Robot::Rspr(RsprGeometry::reference());
    let pose = Pose {
        t: *at,
        r: nalgebra::Rotation3::identity(),
    };
    let sol = inverse(&robot, &pose, Branch::OUTER).expect("the held pose is reachable");
    let j = jacobian(&robot, &sol)
        .expect("the held pose is not singular")
        .j;
    let inv = j.try_inverse().expect("J invertible at the held pose");
    let cpu = EncoderConfig::<f64>::default().counts_per_unit;
    (0..6)
        .map(|k| inv.fixed_view::<3, 1>(0, k).norm() * counts / cpu[k])
        .sum()
}

/// Largest distance of the setpoint from `from` over script times [a, b], m.
fn max_setpoint_motion(r: &RunReport, a: f64, b: f64, from: &Vector3<f64>) -> f64 {
    let (a, b) = (t0(r) + a, t0(r) + b);
    r.trace
        .reports
        .iter()
        .filter(|(t, _)| (a..=b).contains(t))
        .map(|(_, s)| (setpoint_cp(s).unwrap().position_m - from).norm())
        .fold(0.0, f64::max)
}

/// 1:5 scaling of translation and rotation: after a first small move in +x (so that the
/// backlash is taken up in that direction), the master moves 20 mm in x and turns 10 deg
/// about z; the robot moves 4 mm and turns 2 deg. The setpoint's motion is a fifth within
/// 1 µm and 0.001 deg (the filter and the limiter end exactly at the commanded pose); the
/// measured pose's, between the two rests, within 10 µm and 0.01 deg (a few encoder
/// counts of 1.5 µm).
#[test]
fn one_to_five_scaling_moves_a_fifth() {
    let board = TestBoard::start();
    let r = run_script(
        &board,
        MotionScale::new(0.2, 0.2).unwrap(),
        vec![
            wp(0.0, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(0.3, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(0.8, master_at(1.0, 0.0, 0.0, 0.0), PRESENT),
            wp(1.8, master_at(1.0, 0.0, 0.0, 0.0), PRESENT),
            wp(3.8, master_at(21.0, 0.0, 0.0, 10.0), PRESENT),
            wp(5.3, master_at(21.0, 0.0, 0.0, 10.0), PRESENT),
        ],
    );
    let (a, b) = (status_at(&r, 1.8), *r.final_status().unwrap());
    let (sa, sb) = (setpoint_cp(&a).unwrap(), setpoint_cp(&b).unwrap());
    let (ma, mb) = (measured_cp(&a).unwrap(), measured_cp(&b).unwrap());
    let ds = sb.position_m - sa.position_m;
    let dm = mb.position_m - ma.position_m;
    let turn_s = (sb.orientation * sa.orientation.inverse()).scaled_axis();
    let turn_m = (mb.orientation * ma.orientation.inverse()).scaled_axis();
    eprintln!(
        "scaling 1:5: master 20 mm in x and 10 deg about z; setpoint moved [{:.4}, {:.4}, {:.4}] mm and turned {:.4} deg (ratio {:.5}); measured moved [{:.4}, {:.4}, {:.4}] mm and turned {:.4} deg (ratio {:.5})",
        ds.x * 1e3, ds.y * 1e3, ds.z * 1e3, turn_s.z.to_degrees(), ds.norm() / 0.020,
        dm.x * 1e3, dm.y * 1e3, dm.z * 1e3, turn_m.z.to_degrees(), dm.norm() / 0.020
    );
    assert!(
        (ds.x - 0.004).abs() < 1e-6,
        "setpoint x moved {} mm",
        ds.x * 1e3
    );
    assert!(
        ds.y.abs() < 1e-6 && ds.z.abs() < 1e-6,
        "setpoint off-axis {ds:?}"
    );
    assert!(
        (turn_s.z.to_degrees() - 2.0).abs() < 1e-3,
        "setpoint turned {turn_s:?}"
    );
    assert!(
        (dm.x - 0.004).abs() < 1e-5,
        "measured x moved {} mm",
        dm.x * 1e3
    );
    assert!(
        dm.y.abs() < 1e-5 && dm.z.abs() < 1e-5,
        "measured off-axis {dm:?}"
    );
    assert!(
        (turn_m.z.to_degrees() - 2.0).abs() < 0.01,
        "measured turned {turn_m:?}"
    );
    assert_no_fault(&r);
}

/// Clutch (indexing): the master moves 5 mm in x and, still moving, is clutched; while
/// clutched it moves 10 mm in y and 5 mm back in x; it is released and rests, then moves
/// 5 mm in x. The board holds while clutched (the setpoint still, the measured pose within
/// the holding servo's band of two encoder counts on every joint, once stopped); nothing jumps at re-engagement (setpoint and measured pose
/// within 0.05 mm, the bound, over the second after it); then the robot follows
/// the master's 5 mm from where it stands (setpoint within 1 µm).
#[test]
fn clutch_move_away_and_reengage_does_not_jump() {
    let board = TestBoard::start();
    let r = run_script(
        &board,
        MotionScale::default(),
        vec![
            wp(0.0, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(0.3, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(1.3, master_at(5.0, 0.0, 0.0, 0.0), PRESENT),
            // Clutched while moving on.
            wp(1.5, master_at(6.0, 0.0, 0.0, 0.0), CLUTCHED),
            wp(2.5, master_at(1.0, 10.0, 0.0, 0.0), CLUTCHED),
            wp(3.0, master_at(1.0, 10.0, 0.0, 0.0), PRESENT),
            wp(4.0, master_at(1.0, 10.0, 0.0, 0.0), PRESENT),
            wp(5.0, master_at(6.0, 10.0, 0.0, 0.0), PRESENT),
            wp(6.5, master_at(6.0, 10.0, 0.0, 0.0), PRESENT),
        ],
    );
    let (held_m, held_s) = (measured_at(&r, 3.0), setpoint_at(&r, 3.0));
    let clutched = (
        max_setpoint_motion(&r, 2.0, 3.0, &held_s),
        max_motion(&r, 2.0, 3.0, &held_m),
    );
    let jump = (
        max_setpoint_motion(&r, 3.0, 4.0, &held_s),
        max_motion(&r, 3.0, 4.0, &held_m),
    );
    let after = setpoint_at(&r, 6.5) - setpoint_at(&r, 4.0);
    eprintln!(
        "clutch: while clutched (after stopping) setpoint moved {:.4} mm, measured {:.4} mm; in the second after re-engaging setpoint {:.4} mm, measured {:.4} mm; then the setpoint moved [{:.4}, {:.4}, {:.4}] mm for the master's 5 mm in x",
        clutched.0 * 1e3, clutched.1 * 1e3, jump.0 * 1e3, jump.1 * 1e3,
        after.x * 1e3, after.y * 1e3, after.z * 1e3
    );
    let band = hold_band_m(&held_m, 2.0);
    eprintln!(
        "the holding servo's band at the held pose (two counts on every joint): {:.4} mm",
        band * 1e3
    );
    assert!(
        clutched.0 < 1e-6 && clutched.1 <= band,
        "moved while clutched: {clutched:?} (band {band})"
    );
    assert!(
        jump.0 < 5e-5 && jump.1 < 5e-5,
        "jumped at re-engagement: {jump:?}"
    );
    assert!(
        (after.x - 0.005).abs() < 1e-6 && after.y.abs() < 1e-6,
        "after: {after:?}"
    );
    assert!(r.stats.hold_clutched > 0);
    assert_no_fault(&r);
}

/// Dead-man: released while the master moves on 10 mm, the robot holds (the setpoint
/// still, the measured pose within 0.01 mm once stopped; the board Enabled, holding under
/// power, no fault); pressed again, it follows from where it stands without a jump
/// (< 0.05 mm).
#[test]
fn dead_man_released_the_robot_holds() {
    let board = TestBoard::start();
    let r = run_script(
        &board,
        MotionScale::default(),
        vec![
            wp(0.0, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(0.3, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(1.3, master_at(0.0, 5.0, 0.0, 0.0), PRESENT),
            wp(1.5, master_at(0.0, 6.0, 0.0, 0.0), ABSENT),
            wp(2.5, master_at(0.0, 16.0, 0.0, 0.0), ABSENT),
            wp(3.0, master_at(0.0, 16.0, 0.0, 0.0), PRESENT),
            wp(4.0, master_at(0.0, 16.0, 0.0, 0.0), PRESENT),
        ],
    );
    let (held_m, held_s) = (measured_at(&r, 3.0), setpoint_at(&r, 3.0));
    let absent = (
        max_setpoint_motion(&r, 2.0, 3.0, &held_s),
        max_motion(&r, 2.0, 3.0, &held_m),
    );
    let jump = (
        max_setpoint_motion(&r, 3.0, 4.0, &held_s),
        max_motion(&r, 3.0, 4.0, &held_m),
    );
    let holding: Vec<_> = r
        .trace
        .reports
        .iter()
        .filter(|(t, _)| (t0(&r) + 2.0..=t0(&r) + 3.0).contains(t))
        .map(|(_, s)| (s.state, s.stop))
        .collect();
    eprintln!(
        "dead-man: while released (after stopping) setpoint moved {:.4} mm, measured {:.4} mm; after pressing again setpoint {:.4} mm, measured {:.4} mm; board {:?}",
        absent.0 * 1e3, absent.1 * 1e3, jump.0 * 1e3, jump.1 * 1e3,
        holding.first()
    );
    assert!(
        absent.0 < 1e-6 && absent.1 < 1e-5,
        "moved with the dead-man released: {absent:?}"
    );
    assert!(
        holding
            .iter()
            .all(|(st, stop)| *st == RobotState::Enabled && *stop != StopStatus::None),
        "the board did not hold: {holding:?}"
    );
    assert!(jump.0 < 5e-5 && jump.1 < 5e-5, "jumped: {jump:?}");
    assert!(r.stats.hold_operator_absent > 0);
    assert_no_fault(&r);
}

/// Past the workspace edge: the master pushes 40 mm in +x from the centre, beyond the task
/// box with its margin (x <= 25 mm, `Limits::reference`). The robot stops at the boundary:
/// the setpoint never beyond it and finally within 0.5 mm of it (the supervisor's path
/// check refuses the targets beyond), the measured pose within the backlash bound of it,
/// the board Enabled without a fault or a stop, the operator's cue at the edge. Then a
/// second master connects and enables the robot again where the first left it.
#[test]
fn pushing_past_the_workspace_edge_stops_at_the_boundary() {
    let board = TestBoard::start();
    let r = run_script(
        &board,
        MotionScale::default(),
        vec![
            wp(0.0, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(0.3, master_at(0.0, 0.0, 0.0, 0.0), PRESENT),
            wp(4.3, master_at(40.0, 0.0, 0.0, 0.0), PRESENT),
            wp(5.5, master_at(40.0, 0.0, 0.0, 0.0), PRESENT),
        ],
    );
    let x_max = |f: &dyn Fn(&master_link::StatusReport) -> f64| {
        r.trace
            .reports
            .iter()
            .map(|(_, s)| f(s))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let sp_max = x_max(&|s| setpoint_cp(s).unwrap().position_m.x);
    let m_max = x_max(&|s| measured_cp(s).unwrap().position_m.x);
    let last = r.final_status().unwrap();
    let sp_end = setpoint_cp(last).unwrap().position_m.x;
    let cue_events: Vec<&str> = r
        .trace
        .events
        .iter()
        .filter(|e| e.kind == masters::recording::EventKind::Cue)
        .map(|e| e.detail.as_str())
        .collect();
    eprintln!(
        "workspace edge (x <= 25 mm): setpoint stopped at {:.4} mm (largest {:.4}), measured largest {:.4} mm; nearest margin {:.4}; cue {cue_events:?}; refused at once {:?}, by the path check {}",
        sp_end * 1e3,
        sp_max * 1e3,
        m_max * 1e3,
        last.margins.nearest,
        r.targets_refused,
        last.targets_refused
    );
    assert!(
        sp_max <= 0.025 + 1e-6,
        "setpoint beyond the boundary: {} mm",
        sp_max * 1e3
    );
    assert!(
        sp_end >= 0.0245,
        "stopped {} mm short",
        (0.025 - sp_end) * 1e3
    );
    assert!(
        m_max <= 0.025 + BACKLASH_BOUND_M,
        "measured {} mm",
        m_max * 1e3
    );
    assert!(cue_events.contains(&"at_edge"), "cue {cue_events:?}");
    assert_no_fault(&r);
    // A second master in this process: the first one's connection closed when its link
    // was dropped (the board serves one master at a time), and the new one enables the
    // robot where the first left it, disabled at the edge (on a board that outlives the
    // test, the first master took it back to the centre before it left). The enable check
    // takes the measured pose: the joints', less the backlash compensation's offsets,
    // within the servo's error of the setpoint that stopped at the boundary.
    let b = board.enabled();
    let s = b.status().map(|(_, s)| *s).unwrap();
    eprintln!(
        "second master: Enabled at x = {:.4} mm (measured)",
        f64::from(s.position_m[0]) * 1e3
    );
    assert_eq!(s.state, RobotState::Enabled);
}
