//! `check`: the guards' verdict at a pose (single and batch), each guard at its boundary
//! through a custom `--limits` file, the task-box report for the reference robot, and the
//! limits files' errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::{host_sim, ok, pose_csv, Table};
use kinematics_core::guards::Limits;
use kinematics_core::{inverse, tilt_angles, Branch, Pose, Robot, RsprGeometry, SocketAxes};
use nalgebra::Vector3;
use std::path::PathBuf;

/// One `guard:subject:value:limit` entry.
#[derive(Clone, Debug, PartialEq)]
struct Violation {
    guard: String,
    subject: String,
    value: f64,
    limit: f64,
}

/// Parses the `violations` column.
fn violations(text: &str) -> Vec<Violation> {
    if text.is_empty() {
        return Vec::new();
    }
    text.split(';')
        .map(|v| {
            let parts: Vec<&str> = v.split(':').collect();
            assert_eq!(parts.len(), 4, "{v:?} is not guard:subject:value:limit");
            Violation {
                guard: parts[0].to_string(),
                subject: parts[1].to_string(),
                value: parts[2].parse().unwrap(),
                limit: parts[3].parse().unwrap(),
            }
        })
        .collect()
}

/// The verdict of the single form: ok, severity, violations.
struct Verdict {
    ok: bool,
    severity: String,
    violations: Vec<Violation>,
}

impl Verdict {
    fn of(&self, guard: &str) -> Vec<&Violation> {
        self.violations
            .iter()
            .filter(|v| v.guard == guard)
            .collect()
    }
}

/// A limits file in the test's temporary directory.
fn limits_file(name: &str, text: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("check-{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `check --pose` with an optional limits file text.
fn check(limits: Option<(&str, &str)>, pose: &str) -> Verdict {
    let path = limits.map(|(name, text)| limits_file(name, text));
    let path_text = path.as_ref().map(|p| p.display().to_string());
    let mut args: Vec<&str> = Vec::new();
    if let Some(p) = &path_text {
        args.extend(["--limits", p]);
    }
    args.extend(["check", "--pose", pose]);
    let t = Table::parse(&ok(&args, ""));
    assert_eq!(t.rows.len(), 1);
    assert_eq!(t.text(0, "error"), "");
    let verdict = Verdict {
        ok: match t.text(0, "ok") {
            "true" => true,
            "false" => false,
            other => panic!("ok = {other:?}"),
        },
        severity: t.text(0, "severity").to_string(),
        violations: violations(t.text(0, "violations")),
    };
    // `ok` is "no stop-level violation"; `severity` the worst level seen.
    assert_eq!(verdict.ok, verdict.severity != "stop");
    assert_eq!(verdict.severity.is_empty(), verdict.violations.is_empty());
    verdict
}

/// No payload: the force and torque guards read zero, so only geometry can fail.
const NO_PAYLOAD: &str = "payload_fx_n = 0\npayload_fy_n = 0\npayload_fz_n = 0\n\
                          payload_tx_nm = 0\npayload_ty_nm = 0\npayload_tz_nm = 0\n";

/// The thesis's design wrench as the declared payload (the reference payload is the tool).
const THESIS_WRENCH: &str = "payload_fx_n = 7\npayload_fy_n = 7\npayload_fz_n = 7\n\
                             payload_tx_nm = 0.7\npayload_ty_nm = 0.7\npayload_tz_nm = 0.7\n\
                             payload_lever_x_mm = 0\n";

/// The central pose is ok: no stop. With the thesis wrench as payload the first rotating
/// link needs 0.525 N m, above the 0.5 N m continuous rating (a warning); with the
/// reference payload (the 1.2 kg tool on its 0.1 m lever) and without payload nothing is
/// violated at all.
#[test]
fn central_pose_is_ok() {
    let v = check(None, "0,0,160,0,0,0");
    assert!(
        v.ok && v.severity.is_empty() && v.violations.is_empty(),
        "{:?}",
        v.violations
    );
    let v = check(Some(("thesis-wrench", THESIS_WRENCH)), "0,0,160,0,0,0");
    assert!(v.ok);
    assert_eq!(v.severity, "warn");
    assert_eq!(
        v.violations,
        violations("torque:q4:0.525:0.500"),
        "only the torque warning"
    );
    let v = check(Some(("no-payload", NO_PAYLOAD)), "0,0,160,0,0,0");
    assert!(v.ok && v.severity.is_empty() && v.violations.is_empty());
}

/// 30 mm outside the box in x (x = 50 mm, box half 20 mm + 5 mm margin): a workspace stop
/// on the x axis with the value and limit in mm.
#[test]
fn pose_outside_the_box_is_a_workspace_stop() {
    let v = check(None, "50,0,160,0,0,0");
    assert!(!v.ok);
    assert_eq!(v.severity, "stop");
    assert_eq!(
        v.of("workspace"),
        vec![&violations("workspace:x:50.000:25.000")[0]]
    );
}

/// z = 120 mm with parallel platforms needs legs of sqrt(60² + 120²) = 134.164 mm, below
/// the 144 mm stroke minimum on every chain.
#[test]
fn low_pose_undercuts_the_stroke_on_every_chain() {
    let v = check(None, "0,0,120,0,0,0");
    assert!(!v.ok);
    let strokes = v.of("stroke");
    assert_eq!(strokes.len(), 3, "{:?}", v.violations);
    for (i, s) in strokes.iter().enumerate() {
        assert_eq!(s.subject, (i + 1).to_string());
        assert!((s.value - 60f64.hypot(120.0)).abs() < 1e-3);
        assert_eq!(s.limit, 144.0);
    }
}

/// The batch form keeps one output row per input row, gives good rows the single form's
/// verdict and bad rows an error naming the field, and exits 0.
#[test]
fn batch_keeps_one_row_per_input_row() {
    let input = "note,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n\
                 centre,0,0,160,0,0,0,0\n\
                 text,abc,0,160,0,0,0,0\n\
                 low,0,0,120,0,0,0,0\n\
                 branch9,0,0,160,0,0,0,9\n\
                 short,0,0,160\n\
                 outside,50,0,160,0,0,0,0\n";
    let r = host_sim(&["check", "--csv"], input);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stderr.contains("6 rows, 3 with errors"), "{}", r.stderr);
    let t = Table::parse(&r.stdout);
    assert_eq!(
        t.header,
        "note,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch,ok,severity,violations,error"
            .split(',')
            .collect::<Vec<_>>()
    );
    assert_eq!(t.rows.len(), 6);
    for (row, pose) in [
        (0, "0,0,160,0,0,0"),
        (2, "0,0,120,0,0,0"),
        (5, "50,0,160,0,0,0"),
    ] {
        let single = Table::parse(&ok(&["check", "--pose", pose], ""));
        for c in ["ok", "severity", "violations", "error"] {
            assert_eq!(t.text(row, c), single.text(0, c), "row {row} {c}");
        }
    }
    for (row, what) in [
        (1, "x_mm"),
        (3, "branch"),
        (4, "has 4 fields, the header has 8"),
    ] {
        assert!(t.text(row, "error").contains(what), "row {row}");
        assert_eq!(t.text(row, "ok"), "");
        assert_eq!(t.text(row, "violations"), "");
    }
    // The single form fails only on bad input.
    let r = host_sim(&["check", "--pose", "0,0,abc,0,0,0"], "");
    assert_ne!(r.code, Some(0));
    assert!(r.stderr.contains("z_mm"), "{}", r.stderr);
}

/// The batch form takes `--branch` (0 when not given) for rows without a `branch` column,
/// as `ik --csv` does: the verdict is the one of the same rows with the branch written
/// out, and a `branch` column in the input wins over the flag, row by row.
#[test]
fn batch_without_a_branch_column_takes_the_branch_flag() {
    let plain = "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n0,0,160,0,0,0\n0,0,120,0,0,0\n";
    let with = |b: u32| {
        format!(
            "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n0,0,160,0,0,0,{b}\n0,0,120,0,0,0,{b}\n"
        )
    };
    let implicit = Table::parse(&ok(&["check", "--csv"], plain));
    let explicit = Table::parse(&ok(&["check", "--csv"], &with(0)));
    assert_eq!(implicit.header, explicit.header);
    assert_eq!(implicit.rows, explicit.rows);
    assert_eq!(implicit.text(0, "ok"), "true");
    assert_eq!(implicit.text(1, "ok"), "false");
    // Branch 7 (every chain inner) at the central pose: a verdict of its own, the same as
    // with the branch written out, and not the outer branch's.
    let inner = Table::parse(&ok(&["check", "--csv", "--branch", "7"], plain));
    let inner_explicit = Table::parse(&ok(&["check", "--csv"], &with(7)));
    assert_eq!(inner.text(0, "branch"), "7");
    assert_eq!(inner.rows, inner_explicit.rows);
    assert_ne!(inner.text(0, "violations"), implicit.text(0, "violations"));
    // A branch column wins over the flag.
    let given = Table::parse(&ok(&["check", "--csv", "--branch", "7"], &with(0)));
    assert_eq!(given.rows, explicit.rows);
    // A bad --branch is refused before any row is read, naming the flag.
    let r = host_sim(&["check", "--csv", "--branch", "9"], plain);
    assert_ne!(r.code, Some(0));
    assert!(r.stderr.contains("--branch"), "{}", r.stderr);
}

/// Checks a guard at its boundary: with `key` set `below` the measured value the guard is
/// violated (with that value and limit), set `above` it is not. `lower` tells whether the
/// limit is a lower bound (the value must stay above it).
#[allow(clippy::too_many_arguments)]
fn boundary(
    name: &str,
    pose: &str,
    base: &str,
    key: &str,
    guard: &str,
    value: f64,
    step: f64,
    lower: bool,
) -> Vec<Violation> {
    let (violating, fine) = if lower {
        (value + step, value - step)
    } else {
        (value - step, value + step)
    };
    let v = check(
        Some((
            &format!("{name}-violated"),
            &format!("{base}{key} = {violating}\n"),
        )),
        pose,
    );
    let hits: Vec<Violation> = v.of(guard).into_iter().cloned().collect();
    assert!(!hits.is_empty(), "{key} = {violating}: {:?}", v.violations);
    assert!(
        hits.iter()
            .any(|h| (h.value - value).abs() < 2e-3 && (h.limit - violating).abs() < 6e-4),
        "{key} = {violating}: {hits:?} (value {value})"
    );
    let v = check(
        Some((&format!("{name}-fine"), &format!("{base}{key} = {fine}\n"))),
        pose,
    );
    assert!(v.of(guard).is_empty(), "{key} = {fine}: {:?}", v.violations);
    hits
}

/// The leg length at the central pose: |(50, 0, 160) - (110, 0, 0)| = 170.880 mm.
fn central_leg_mm() -> f64 {
    60f64.hypot(160.0)
}

/// Stroke minimum and maximum around the central leg length: all three chains cross at
/// once.
#[test]
fn stroke_at_its_boundaries() {
    let l = central_leg_mm();
    assert!((l - 170.880).abs() < 1e-3);
    let hits = boundary(
        "stroke-min",
        "0,0,160,0,0,0",
        NO_PAYLOAD,
        "stroke_min_mm",
        "stroke",
        l,
        0.02,
        true,
    );
    assert_eq!(hits.len(), 3);
    let hits = boundary(
        "stroke-max",
        "0,0,160,0,0,0",
        NO_PAYLOAD,
        "stroke_max_mm",
        "stroke",
        l,
        0.02,
        false,
    );
    assert_eq!(hits.len(), 3);
}

/// Tilt cone around a 10 deg platform tilt (rotation about x0).
#[test]
fn tilt_cone_at_its_boundary() {
    let hits = boundary(
        "tilt-cone",
        "0,0,160,10,0,0",
        NO_PAYLOAD,
        "tilt_cone_deg",
        "tilt_cone",
        10.0,
        0.1,
        false,
    );
    assert_eq!(hits[0].subject, "-");
}

/// Collision radius around the piercing radius at the central pose: the leg from
/// b = (110, 0, 0) to p = (50, 0, 160) mm meets z = 60 mm at 110 - 60 * 60 / 160 = 87.5 mm.
#[test]
fn collision_radius_at_its_boundary() {
    let piercing = 110.0 - 60.0 * 60.0 / 160.0;
    let hits = boundary(
        "collision",
        "0,0,160,0,0,0",
        NO_PAYLOAD,
        "collision_radius_mm",
        "collision",
        piercing,
        0.1,
        true,
    );
    assert_eq!(hits.len(), 3, "every chain at the symmetric central pose");
}

/// Box margin around a pose 22 mm out in x: the limit is the box half (20 mm) plus the
/// margin, so a 1.9 mm margin is violated and a 2.1 mm one is not.
#[test]
fn workspace_margin_at_its_boundary() {
    let pose = "22,0,160,0,0,0";
    let v = check(
        Some(("box-1.9", &format!("{NO_PAYLOAD}box_margin_mm = 1.9\n"))),
        pose,
    );
    assert!(!v.ok);
    assert_eq!(v.violations, violations("workspace:x:22.000:21.900"));
    let v = check(
        Some(("box-2.1", &format!("{NO_PAYLOAD}box_margin_mm = 2.1\n"))),
        pose,
    );
    assert!(v.ok && v.violations.is_empty(), "{:?}", v.violations);
    // The box half-extents themselves.
    let v = check(
        Some((
            "box-half",
            &format!("{NO_PAYLOAD}box_half_mm = [16.9, 20, 10]\n"),
        )),
        pose,
    );
    assert_eq!(v.violations, violations("workspace:x:22.000:21.900"));
}

/// The joint-space and measure guards at an off-centre pose, each value taken from the
/// other commands (ik, singularity, forces) or the core.
#[test]
fn joint_and_measure_guards_at_their_boundaries() {
    let pose = "10,-5,165,5,-3,8";
    let row = |cmd: &[&str]| {
        let mut args = cmd.to_vec();
        args.extend(["--pose", pose]);
        Table::parse(&ok(&args, ""))
    };
    // Link angle: |theta_i| (the central value is 0 on branch 0).
    let ik = row(&["ik"]);
    let theta = (1..=3)
        .map(|i| ik.num(0, &format!("theta{i}_deg")).abs())
        .fold(0.0, f64::max);
    boundary(
        "link-angle",
        pose,
        NO_PAYLOAD,
        "link_angle_max_deg",
        "link_angle",
        theta,
        0.01,
        false,
    );
    // Spherical-joint tilt, from the core.
    let robot = Robot::Rspr(RsprGeometry::reference());
    let p = Pose::from_position_rotation_vector(
        Vector3::new(10.0, -5.0, 165.0) / 1000.0,
        Vector3::new(5.0f64, -3.0, 8.0).map(f64::to_radians),
    )
    .unwrap();
    let sol = inverse(&robot, &p, Branch::OUTER).unwrap();
    let axes = SocketAxes::new(&robot).unwrap();
    let tilt = tilt_angles(&sol, &axes)
        .iter()
        .map(|(_, t)| t.to_degrees())
        .fold(0.0, f64::max);
    boundary(
        "tilt",
        pose,
        NO_PAYLOAD,
        "tilt_max_deg",
        "tilt",
        tilt,
        0.01,
        false,
    );
    // Singularity measures (lower bounds): the warn level around the value gives a
    // warning or nothing; a stop level just above it a stop.
    let sing = row(&["singularity"]);
    let serial = (1..=3)
        .map(|i| sing.num(0, &format!("serial{i}_frac")))
        .fold(f64::INFINITY, f64::min);
    let parallel = sing.num(0, "parallel_inv_cond");
    for (measure, value) in [("serial", serial), ("parallel", parallel)] {
        boundary(
            &format!("{measure}-warn"),
            pose,
            NO_PAYLOAD,
            &format!("{measure}_warn"),
            measure,
            value,
            0.001,
            true,
        );
        let stop = value + 0.001;
        let text = format!("{NO_PAYLOAD}{measure}_warn = 0.99\n{measure}_stop = {stop}\n");
        let v = check(Some((&format!("{measure}-stop"), &text)), pose);
        assert!(!v.ok, "{measure}: {:?}", v.violations);
        assert!(v
            .of(measure)
            .iter()
            .any(|h| (h.limit - stop).abs() < 6e-5 && (h.value - value).abs() < 1e-4));
    }
    // Actuator force and torque for the thesis wrench (the reference payload).
    let forces = ok(
        &["forces", "--pose", pose, "--wrench", "7,7,7,0.7,0.7,0.7"],
        "",
    );
    let forces = Table::parse(&forces);
    let force = (1..=3)
        .map(|i| forces.num(0, &format!("f{i}_n")).abs())
        .fold(0.0, f64::max);
    let torque = (1..=3)
        .map(|i| forces.num(0, &format!("t{i}_nm")).abs())
        .fold(0.0, f64::max);
    boundary(
        "force-warn",
        pose,
        THESIS_WRENCH,
        "force_warn_n",
        "force",
        force,
        0.01,
        false,
    );
    let stop = force - 0.01;
    let v = check(
        Some((
            "force-stop",
            &format!("{THESIS_WRENCH}force_warn_n = 1\nforce_stop_n = {stop}\n"),
        )),
        pose,
    );
    assert!(!v.ok);
    assert!(v.of("force").iter().any(|t| (t.limit - stop).abs() < 6e-4));
    boundary(
        "torque-warn",
        pose,
        THESIS_WRENCH,
        "torque_warn_nm",
        "torque",
        torque,
        0.002,
        false,
    );
    let v = check(
        Some((
            "torque-stop",
            &format!("{THESIS_WRENCH}torque_stop_nm = {}\n", torque - 0.002),
        )),
        pose,
    );
    assert!(!v.ok);
    assert!(v
        .of("torque")
        .iter()
        .any(|t| (t.limit - (torque - 0.002)).abs() < 6e-4));
}

/// The task-box report for the reference robot with the default limits and the thesis's
/// design wrench as payload: every static guard listed (no motion guard); the stroke
/// minimum fails by 0.25 mm (l1 = 143.75 mm at a corner of the rotated box) and the
/// rotating-link torque exceeds its 0.5 N m warn level (0.657 N m) while staying below the
/// stop level; nothing else is violated.
#[test]
fn task_box_for_the_reference_robot() {
    let path = limits_file("task-box-thesis-wrench", THESIS_WRENCH)
        .display()
        .to_string();
    let r = host_sim(&["--limits", &path, "check", "--task-box", "--csv"], "");
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let t = Table::parse(&r.stdout);
    assert_eq!(
        t.header,
        "guard,subject,worst_value,limit,margin,x_mm,y_mm,z_mm,orientation,stop_points,warn_points"
            .split(',')
            .collect::<Vec<_>>()
    );
    let guards: Vec<&str> = t.rows.iter().map(|r| r[0].as_str()).collect();
    assert_eq!(
        guards,
        [
            "reach",
            "stroke",
            "link_angle",
            "tilt",
            "collision",
            "workspace",
            "tilt_cone",
            "serial",
            "parallel",
            "force",
            "torque"
        ]
    );
    let row = |g: &str| guards.iter().position(|x| *x == g).unwrap();
    let s = row("stroke");
    assert_eq!(t.text(s, "subject"), "1");
    assert!((t.num(s, "worst_value") - 143.75).abs() < 0.01);
    assert_eq!(t.num(s, "limit"), 144.0);
    assert!((t.num(s, "margin") + 0.25).abs() < 0.01);
    assert_eq!(t.text(s, "orientation"), "rotated");
    assert_eq!(t.num(s, "z_mm"), 150.0, "at the low face of the box");
    assert!(t.num(s, "x_mm").abs() == 20.0 && t.num(s, "y_mm").abs() == 20.0);
    assert!(t.num(s, "stop_points") >= 1.0);
    let q = row("torque");
    assert!((t.num(q, "worst_value") - 0.657).abs() < 0.001);
    assert_eq!(t.num(q, "limit"), 0.5, "the violated warn level");
    assert!((t.num(q, "margin") - (1.0 - 0.657)).abs() < 0.001);
    assert_eq!(t.num(q, "stop_points"), 0.0);
    assert!(t.num(q, "warn_points") > 0.0);
    for (i, g) in guards.iter().enumerate() {
        if !["stroke", "torque"].contains(g) {
            assert_eq!(t.num(i, "stop_points"), 0.0, "{g}");
            assert_eq!(t.num(i, "warn_points"), 0.0, "{g}");
        }
    }
    assert_eq!(
        t.text(row("reach"), "worst_value"),
        "",
        "every point reached"
    );
    // The conclusion (stderr with --csv, the last line of the readable form).
    let conclusion = r.stderr.trim();
    assert!(
        conclusion.starts_with("Conclusion: the reference robot does NOT reach"),
        "{conclusion}"
    );
    assert!(
        conclusion.contains(
            "stroke fails at (20.000, 20.000, 150.000) mm rotated on chain 1 by 0.250 mm"
        ),
        "{conclusion}"
    );
    assert!(
        conclusion.contains("torque exceeds its warn level") && conclusion.contains("0.657 N m"),
        "{conclusion}"
    );
    let text = ok(&["--limits", &path, "check", "--task-box"], "");
    assert_eq!(text.trim_end().lines().last(), Some(conclusion));
    for g in &guards {
        assert!(text.contains(&format!("\n  {g} ")), "{g} in\n{text}");
    }
    for motion in ["tip_speed", "angular_speed", "joint_speed", "joint_accel"] {
        assert!(!text.contains(motion) && !r.stdout.contains(motion));
    }
    assert!(
        text.contains("9 x 9 x 5 grid, branch 0: 810 poses"),
        "{text}"
    );
}

/// With the stroke minimum lowered and the torque warn level raised, the reference robot
/// reaches the whole task box; `--grid` changes the sampling.
#[test]
fn task_box_within_relaxed_limits() {
    let path = limits_file("relaxed", "stroke_min_mm = 143\ntorque_warn_nm = 0.7\n");
    let r = host_sim(
        &[
            "--limits",
            path.to_str().unwrap(),
            "check",
            "--task-box",
            "--grid",
            "3,3,2",
        ],
        "",
    );
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stdout.contains("3 x 3 x 2 grid, branch 0: 36 poses"));
    assert!(r.stdout.trim_end().ends_with(
        "Conclusion: the reference robot reaches the whole task box within the limits."
    ));
    let r = host_sim(&["check", "--task-box", "--grid", "0,3,3"], "");
    assert_ne!(r.code, Some(0));
    assert!(r.stderr.contains("--grid"), "{}", r.stderr);
}

/// The shipped reference file equals `Limits::reference()` and gives the default output.
#[test]
fn shipped_limits_file_is_the_reference() {
    let path = format!(
        "{}/robot-config/limits/reference.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    assert_eq!(
        robot_config::limits_file::load(std::path::Path::new(&path)).unwrap(),
        Limits::reference()
    );
    let input = pose_csv(&[
        ([0.0, 0.0, 160.0, 0.0, 0.0, 0.0], 0),
        ([0.0, 0.0, 120.0, 0.0, 0.0, 0.0], 0),
    ]);
    assert_eq!(
        ok(&["--limits", &path, "check", "--csv"], &input),
        ok(&["check", "--csv"], &input)
    );
}

/// A bad key, a negative value and stroke_min > stroke_max are rejected, naming the file
/// and the key, before anything runs.
#[test]
fn bad_limits_files_are_rejected_naming_the_key() {
    for (name, text, key, why) in [
        (
            "unknown",
            "stroke_min_mm = 140\ntilt_maximum_deg = 3\n",
            "tilt_maximum_deg",
            "unknown field",
        ),
        (
            "negative",
            "collision_radius_mm = -1\n",
            "collision_radius_mm",
            "negative",
        ),
        (
            "stroke",
            "stroke_min_mm = 200\nstroke_max_mm = 180\n",
            "stroke_min_mm",
            "below stroke_max_mm",
        ),
        (
            "levels",
            "force_warn_n = 500\n",
            "force_warn_n",
            "warn <= stop",
        ),
        (
            "type",
            "tilt_max_deg = \"thirty\"\n",
            "tilt_max_deg",
            "invalid type",
        ),
    ] {
        let path = limits_file(&format!("bad-{name}"), text);
        let shown = path.display().to_string();
        let r = host_sim(
            &["--limits", &shown, "check", "--pose", "0,0,160,0,0,0"],
            "",
        );
        assert_ne!(r.code, Some(0), "{name}");
        assert!(r.stdout.is_empty(), "{name}");
        let e = r.stderr.trim();
        assert!(
            e.starts_with(&format!("error: limits file {shown}: ")),
            "{e}"
        );
        assert!(e.contains(key) && e.contains(why), "{name}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    let r = host_sim(
        &[
            "--limits",
            "/nonexistent/limits.toml",
            "check",
            "--task-box",
        ],
        "",
    );
    assert_ne!(r.code, Some(0));
    assert!(r
        .stderr
        .contains("limits file /nonexistent/limits.toml: cannot read"));
}
