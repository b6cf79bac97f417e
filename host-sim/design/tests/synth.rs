//! `synth`: the task file, the scan (parallel, deterministic), the requirements and the
//! ranking (the command and its files: host-sim/tests/design_synth.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::ranges;
use design::synth::{
    candidate, envelope_volume_cm3, grid, markdown, ranked, robot_of, scan, Requirements, SynthTask,
};
use kinematics_core::RobotKind;
use robot_config::task_box::TaskBox;
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

fn thesis() -> SynthTask {
    SynthTask::thesis().unwrap()
}

/// The shipped `design/tasks/thesis.toml` is the embedded default, and it holds the thesis's
/// task and bounds: the 40 x 40 x 20 mm box at +20 deg about [1,1,0] on the 10 mm grid,
/// RSPR 30 N, 1.0 N m, 30 deg tilt, actuator 144 mm + 66 mm stroke; USR 2.0 N m and the
/// open ranges -90 < alpha < 90, 0 < gamma < 90, 0 < delta < 180 deg (Table 8.3).
#[test]
fn the_thesis_task_file_is_the_default() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks/thesis.toml");
    let t = SynthTask::load(&file).unwrap();
    assert_eq!(t, thesis());
    assert_eq!(t.task, TaskBox::thesis([5, 5, 3]));
    let r = &t.rspr.requirements;
    assert_eq!(
        (r.max_force_n, r.max_torque_nm, r.max_tilt_deg),
        (30.0, 1.0, 30.0)
    );
    assert_eq!((r.min_length_mm, r.stroke_mm), (144.0, 66.0));
    assert_eq!(r.wrench, [7.0, 7.0, 7.0, 0.7, 0.7, 0.7]);
    let u = &t.usr.requirements;
    assert_eq!(u.max_torque_nm, 2.0);
    assert_eq!(
        u.open_ranges_deg,
        [
            ("alpha_deg".to_string(), -90.0, 90.0),
            ("gamma_deg".to_string(), 0.0, 90.0),
            ("delta_deg".to_string(), 0.0, 180.0)
        ]
    );
    // The reference RSPR is on the default grid.
    let g = grid(&t.rspr.axes);
    assert!(g.contains(&vec![20.0, 90.0, 50.0, 160.0]));
    assert_eq!(Requirements::thesis(RobotKind::Usr).unwrap(), *u);
}

/// A task file overrides only the keys it names; a bad value, an unknown key or a wrong
/// type is rejected with a message naming the field.
#[test]
fn task_files_override_keys_and_name_bad_fields() {
    let t = SynthTask::parse("[rspr]\nmax_torque_nm = 0.5\n[task]\ngrid = [3, 3, 2]\n").unwrap();
    assert_eq!(t.rspr.requirements.max_torque_nm, 0.5);
    assert_eq!(t.task.grid, [3, 3, 2]);
    assert_eq!(t.usr, thesis().usr);
    for (text, field) in [
        ("[rspr]\nmax_torque_nm = -1\n", "rspr.max_torque_nm"),
        ("[rspr]\nmax_force_n = nan\n", "rspr.max_force_n"),
        ("[usr]\nhc_mm = [100, 60, 10]\n", "usr.hc_mm"),
        ("[usr]\nl1_mm = [60, 80, 0]\n", "usr.l1_mm"),
        ("[rspr]\ne_mm = [-10, 10, 10]\n", "rspr.e_mm"),
        ("[usr]\ngamma_deg = [90, 0]\n", "usr.gamma_deg"),
        ("[task]\ngrid = [5, 5, 0]\n", "task.grid"),
        ("[task]\nbox_mm = [40, -1, 20]\n", "task.box_mm"),
        ("[rspr]\nstroke = 66\n", "rspr.stroke"),
        ("[rspr]\nrb_mm = [60, \"x\", 10]\n", "rspr.rb_mm"),
        ("rspr = 1\n", "rspr"),
    ] {
        let e = SynthTask::parse(text).unwrap_err().to_string();
        assert!(e.contains(field), "{text:?}: {e}");
    }
}

/// The scan keeps the grid's order (first dimension slowest) whatever the number of
/// threads, and reports its progress once per robot.
#[test]
fn the_scan_is_deterministic_across_thread_counts() {
    let t = thesis();
    let task = TaskBox::thesis([3, 3, 2]);
    let req = &t.rspr.requirements;
    let dims = grid(&[
        vec![10.0, 20.0],
        vec![60.0, 90.0],
        vec![50.0],
        vec![120.0, 160.0],
    ]);
    assert_eq!(dims.len(), 8);
    assert_eq!(dims[1], [10.0, 60.0, 50.0, 160.0]);
    assert_eq!(dims[7], [20.0, 90.0, 50.0, 160.0]);
    let evaluated = AtomicUsize::new(0);
    let progress = || {
        evaluated.fetch_add(1, Ordering::Relaxed);
    };
    let one = scan(RobotKind::Rspr, dims.clone(), &task, req, 1, &progress).unwrap();
    assert_eq!(evaluated.load(Ordering::Relaxed), 8);
    let three = scan(RobotKind::Rspr, dims.clone(), &task, req, 3, &progress).unwrap();
    let all = scan(RobotKind::Rspr, dims.clone(), &task, req, 0, &progress).unwrap();
    assert_eq!(one, three);
    assert_eq!(one, all);
    assert_eq!(
        one.iter().map(|c| c.dims_mm.clone()).collect::<Vec<_>>(),
        dims
    );
}

/// Applies the thesis's RSPR bounds by hand to the per-chain ranges (not through
/// `synth::check`): every pose solved, singularity measures at or above the guards' warn
/// levels, |f_i| <= 30 N, |t_i| <= 1 N m, tilt <= 30 deg, 144 <= l_i <= 210 mm.
fn rspr_admissible_by_hand(r: &ranges::Ranges) -> bool {
    let t = |q: String| r.get(&q, "task").unwrap();
    r.failures.is_empty()
        && r.parallel_inv_cond_min >= 0.03
        && r.serial_relative_min >= 0.15
        && (1..=3).all(|i| {
            let (f, m, tilt, l) = (
                t(format!("f{i}_n")),
                t(format!("t{i}_nm")),
                t(format!("tilt{i}_deg")),
                t(format!("l{i}_mm")),
            );
            f.min >= -30.0
                && f.max <= 30.0
                && m.min >= -1.0
                && m.max <= 1.0
                && tilt.max <= 30.0
                && l.min >= 144.0
                && l.max <= 210.0
        })
}

/// On a 16-robot RSPR grid (e 10, 20; rb 90, 100; rp 40, 50; hc 140, 160 mm) the scan
/// admits exactly the robots that pass the bounds applied by hand to their `ranges`, and
/// that set is the four (e, rb, rp, hc) = (10, 90, 40, 160), (10, 100, 40, 160),
/// (10, 100, 50, 160), (20, 90, 40, 160) mm.
#[test]
fn a_small_rspr_grid_admits_the_set_derived_by_hand() {
    let t = thesis();
    let dims = grid(&[
        vec![10.0, 20.0],
        vec![90.0, 100.0],
        vec![40.0, 50.0],
        vec![140.0, 160.0],
    ]);
    let found = scan(
        RobotKind::Rspr,
        dims.clone(),
        &t.task,
        &t.rspr.requirements,
        0,
        &|| {},
    )
    .unwrap();
    let by_scan: BTreeSet<Vec<i64>> = found
        .iter()
        .filter(|c| c.rejected.is_none())
        .map(|c| c.dims_mm.iter().map(|&x| x as i64).collect())
        .collect();
    let by_hand: BTreeSet<Vec<i64>> = dims
        .iter()
        .filter(|d| {
            let robot = robot_of(RobotKind::Rspr, d).unwrap();
            let r = ranges::evaluate(
                &robot,
                &t.task,
                [7.0, 7.0, 7.0, 0.7, 0.7, 0.7],
                kinematics_core::Branch::OUTER,
                1e-9,
            )
            .unwrap();
            rspr_admissible_by_hand(&r)
        })
        .map(|d| d.iter().map(|&x| x as i64).collect())
        .collect();
    assert_eq!(by_scan, by_hand);
    let expected: BTreeSet<Vec<i64>> = [
        [10, 90, 40, 160],
        [10, 100, 40, 160],
        [10, 100, 50, 160],
        [20, 90, 40, 160],
    ]
    .iter()
    .map(|d| d.to_vec())
    .collect();
    assert_eq!(by_scan, expected);
    // Ranked by size: the envelope cylinder grows with e + rb.
    let best = ranked(&found);
    assert_eq!(best.len(), 4);
    assert_eq!(best[0].dims_mm, [10.0, 90.0, 40.0, 160.0]);
    assert!(best
        .windows(2)
        .all(|w| w[0].envelope_volume_cm3 <= w[1].envelope_volume_cm3));
}

/// The reference RSPR (e = 20, rb = 90, rp = 50, hc = 160 mm) misses exactly one bound of
/// the thesis's task: the actuator's shortest length, l1 = 143.75 mm < 144 mm at the
/// rotated corner (20, 20, 150) mm. With that bound 1 mm lower it is admissible. Its size
/// is the cylinder of radius e + rb = 110 mm (b_i radial at the central configuration) and
/// height 160 mm. The Appendix A USR (e = rp = 30, l1 = 60, l2 = 80, hc = 80 mm) is
/// admissible.
#[test]
fn the_reference_robots_against_the_thesis_bounds() {
    let t = thesis();
    let mut req = t.rspr.requirements.clone();
    let c = candidate(
        RobotKind::Rspr,
        vec![20.0, 90.0, 50.0, 160.0],
        &t.task,
        &req,
    );
    assert_eq!(
        c.rejected.as_ref().map(ToString::to_string).as_deref(),
        Some("l1_mm min 143.75 < 144 mm (min_length_mm)")
    );
    let v = std::f64::consts::PI * 110.0 * 110.0 * 160.0 / 1000.0;
    assert!(
        (c.envelope_volume_cm3 - v).abs() < 1e-6,
        "{}",
        c.envelope_volume_cm3
    );
    req.min_length_mm = 143.0;
    let c = candidate(
        RobotKind::Rspr,
        vec![20.0, 90.0, 50.0, 160.0],
        &t.task,
        &req,
    );
    assert_eq!(c.rejected, None);
    let robot = robot_of(RobotKind::Rspr, &c.dims_mm).unwrap();
    assert_eq!(envelope_volume_cm3(&robot).unwrap(), c.envelope_volume_cm3);
    let u = candidate(
        RobotKind::Usr,
        vec![30.0, 30.0, 60.0, 80.0, 80.0],
        &t.task,
        &t.usr.requirements,
    );
    assert_eq!(u.rejected, None);
}

/// The thesis's Table 8.3 lists the first 20 of its 95 admissible USR robots in the order
/// (e, rp, hc, l1, l2). On the grid e = 20, rp = 20 and 30, hc = 60..110, l1 and l2 =
/// 60..80 mm (step 10; 108 robots) the scan admits exactly those 20 robots. (The 9 robots
/// with rp = 30, hc = 110 come after row 20 in the table's order, so the table does not
/// decide them; the scan rejects them all.)
#[test]
fn a_usr_grid_admits_exactly_the_robots_of_table_8_3() {
    let t = thesis();
    let dims = grid(&[
        vec![20.0],
        vec![20.0, 30.0],
        vec![60.0, 70.0, 80.0],
        vec![60.0, 70.0, 80.0],
        vec![60.0, 70.0, 80.0, 90.0, 100.0, 110.0],
    ]);
    assert_eq!(dims.len(), 108);
    let found = scan(
        RobotKind::Usr,
        dims,
        &t.task,
        &t.usr.requirements,
        0,
        &|| {},
    )
    .unwrap();
    // (e, rp, hc, l1, l2) in cm, the table's order.
    let table: [[i64; 5]; 20] = [
        [2, 2, 6, 6, 8],
        [2, 2, 7, 6, 7],
        [2, 2, 7, 6, 8],
        [2, 2, 8, 6, 7],
        [2, 2, 8, 6, 8],
        [2, 2, 8, 7, 8],
        [2, 2, 9, 7, 6],
        [2, 2, 9, 7, 7],
        [2, 2, 9, 7, 8],
        [2, 2, 10, 7, 8],
        [2, 2, 10, 8, 7],
        [2, 2, 10, 8, 8],
        [2, 2, 11, 8, 7],
        [2, 2, 11, 8, 8],
        [2, 3, 6, 7, 8],
        [2, 3, 7, 7, 8],
        [2, 3, 8, 7, 7],
        [2, 3, 8, 7, 8],
        [2, 3, 9, 8, 8],
        [2, 3, 10, 8, 8],
    ];
    let expected: BTreeSet<[i64; 5]> = table.into_iter().collect();
    let admitted: BTreeSet<[i64; 5]> = found
        .iter()
        .filter(|c| c.rejected.is_none())
        .map(|c| {
            // dims_mm: e, rp, l1, l2, hc -> the table's e, rp, hc, l1, l2 in cm.
            let d = &c.dims_mm;
            [d[0], d[1], d[4], d[2], d[3]].map(|x| (x / 10.0).round() as i64)
        })
        .collect();
    assert_eq!(admitted, expected);
}

/// The Markdown table has one row per ranked robot under a header and separator of equal
/// width.
#[test]
fn markdown_rows_match_the_header() {
    let t = thesis();
    let c = candidate(
        RobotKind::Usr,
        vec![30.0, 30.0, 60.0, 80.0, 80.0],
        &TaskBox::thesis([2, 2, 2]),
        &t.usr.requirements,
    );
    let found = [c];
    let md = markdown(RobotKind::Usr, &ranked(&found), "t");
    let rows: Vec<&str> = md.lines().filter(|l| l.starts_with('|')).collect();
    assert_eq!(rows.len(), 3);
    let cells = |l: &str| l.matches('|').count();
    assert!(rows.iter().all(|l| cells(l) == cells(rows[0])));
    assert!(rows[0].contains("delta_deg_span") && rows[0].contains("t_beta_nm_max"));
}
