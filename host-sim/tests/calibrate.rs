//! `host-sim calibrate`: the simulation writes measurements, `calibrate` identifies a
//! geometry from them, the geometry file works with `--geometry`, `calibrate plan` writes
//! the poses to visit; the errors name what is wrong.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{host_sim, ok};
use std::path::PathBuf;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("host-sim-calibrate-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn simulate_then_calibrate_then_use_the_geometry() {
    let sim = temp_dir("sim");
    let out = ok(
        &[
            "calibrate",
            "simulate",
            "--poses",
            "40",
            "--validation",
            "60",
            "--out",
            sim.to_str().unwrap(),
        ],
        "",
    );
    assert!(
        out.contains("after calibration:") && out.contains("noise limit"),
        "{out}"
    );
    for f in [
        "report.txt",
        "measurements.csv",
        "validation.png",
        "residuals.png",
    ] {
        assert!(sim.join(f).is_file(), "{f}");
    }
    let cal = temp_dir("cal");
    let measurements = sim.join("measurements.csv");
    let out = ok(
        &[
            "calibrate",
            "--measurements",
            measurements.to_str().unwrap(),
            "--version",
            "4",
            "--out",
            cal.to_str().unwrap(),
        ],
        "",
    );
    assert!(
        out.contains("combinations determined") && out.contains("calibrated:"),
        "{out}"
    );
    let geometry = cal.join("calibrated.toml");
    let text = std::fs::read_to_string(&geometry).unwrap();
    assert!(text.contains("robot = \"rspr-per-chain\"") && text.contains("version = 4"));
    // The calibrated robot's joints at the central pose differ from the nominal's by the
    // identified deviations (tenths of a millimetre), not by more.
    let pose = ["--pose", "0,0,160,0,0,0"];
    let cal_ik = ok(
        &[&["--geometry", geometry.to_str().unwrap(), "ik"][..], &pose].concat(),
        "",
    );
    let nom_ik = ok(&[&["ik"][..], &pose].concat(), "");
    let last = |s: &str| -> Vec<f64> {
        let line = s.lines().last().unwrap().to_string();
        line.split(',').filter_map(|x| x.parse().ok()).collect()
    };
    let (a, b) = (last(&cal_ik), last(&nom_ik));
    assert_eq!(a.len(), b.len());
    let d = a
        .iter()
        .zip(&b)
        .skip(6)
        .take(3)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(
        d > 1e-3 && d < 3.0,
        "leg change {d} mm: {cal_ik} vs {nom_ik}"
    );
    // The report takes it; the simulation refuses it with the reason.
    ok(&["--geometry", geometry.to_str().unwrap(), "report"], "");
    let r = host_sim(&["--geometry", geometry.to_str().unwrap(), "sim"], "");
    assert_ne!(r.code, Some(0));
    assert!(r.stderr.contains("per-chain"), "{}", r.stderr);
}

#[test]
fn plan_writes_the_poses_to_visit() {
    let dir = temp_dir("plan");
    let path = dir.join("plan.csv");
    let out = ok(
        &[
            "calibrate",
            "plan",
            "--poses",
            "20",
            "--out",
            path.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.contains("observability index"), "{out}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("pose,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,l1_mm"));
    assert_eq!(text.lines().count(), 21);
}

#[test]
fn errors_name_the_problem() {
    let r = host_sim(&["--robot", "usr", "calibrate", "plan"], "");
    assert!(r.stderr.contains("RSPR"), "{}", r.stderr);
    let r = host_sim(&["calibrate"], "");
    assert!(r.stderr.contains("--measurements"), "{}", r.stderr);
    let r = host_sim(&["calibrate", "simulate", "--robust", "tukey:2"], "");
    assert!(r.stderr.contains("--robust"), "{}", r.stderr);
    let dir = temp_dir("bad");
    let bad = dir.join("bad.csv");
    std::fs::write(
        &bad,
        "l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,x_mm,y_mm,zz_mm\n",
    )
    .unwrap();
    let r = host_sim(&["calibrate", "--measurements", bad.to_str().unwrap()], "");
    assert!(r.stderr.contains("zz_mm"), "{}", r.stderr);
}

/// Simulated measurements (40 planned poses, seed 19) and their header and rows.
fn simulated_measurements(name: &str) -> (PathBuf, Vec<String>) {
    let sim = temp_dir(name);
    ok(
        &[
            "calibrate",
            "simulate",
            "--poses",
            "40",
            "--validation",
            "20",
            "--out",
            sim.to_str().unwrap(),
        ],
        "",
    );
    let text = std::fs::read_to_string(sim.join("measurements.csv")).unwrap();
    (sim, text.lines().map(str::to_string).collect())
}

#[test]
fn a_typo_row_is_refused_with_row_and_column_or_dropped_on_request() {
    let (dir, mut lines) = simulated_measurements("typo");
    // Row 3: l1 typed as 100 mm (stroke 144 .. 210 mm).
    let mut cells: Vec<String> = lines[3].split(',').map(str::to_string).collect();
    let l1 = lines[0].split(',').position(|c| c == "l1_mm").unwrap();
    cells[l1] = "100".into();
    lines[3] = cells.join(",");
    let file = dir.join("typo.csv");
    std::fs::write(&file, lines.join("\n") + "\n").unwrap();
    let out = dir.join("out");
    let args = [
        "calibrate",
        "--measurements",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let r = host_sim(&args, "");
    assert_eq!(r.code, Some(1), "{}", r.stdout);
    assert!(
        r.stderr
            .contains("row 3: l1_mm = 100 is outside the robot's range"),
        "{}",
        r.stderr
    );
    let r = host_sim(&[&args[..], &["--drop-out-of-range"]].concat(), "");
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stderr.contains("dropped 1 rows"), "{}", r.stderr);
    assert!(
        r.stdout.contains("Calibration from 39 measured poses"),
        "{}",
        r.stdout
    );
}

#[test]
fn five_poses_warn_and_exit_non_zero_unless_forced() {
    let (dir, lines) = simulated_measurements("five");
    let file = dir.join("five.csv");
    std::fs::write(&file, lines[..6].join("\n") + "\n").unwrap();
    let out = dir.join("out");
    let args = [
        "calibrate",
        "--measurements",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let r = host_sim(&args, "");
    assert_eq!(r.code, Some(1), "{}", r.stdout);
    assert!(
        r.stdout.contains("WARNING: the 5 measured poses determine"),
        "{}",
        r.stdout
    );
    assert!(r.stderr.contains("more poses"), "{}", r.stderr);
    assert!(r.stderr.contains("--force"), "{}", r.stderr);
    let report = std::fs::read_to_string(out.join("report.txt")).unwrap();
    assert!(report.contains("WARNING"), "{report}");
    let r = host_sim(&[&args[..], &["--force"]].concat(), "");
    assert_eq!(r.code, Some(0), "{}", r.stderr);
}
