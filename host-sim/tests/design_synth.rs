//! `synth` on the command line: its outputs and its errors (the scan, the task file, the
//! requirements and the ranking: host-sim/design/tests/synth.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{host_sim, ok, Table};
use std::path::PathBuf;

fn out(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("design-synth-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The CLI scans the task file's grid with the overrides, names the bound the reference
/// robot misses, and writes synth.csv (every robot, scan order), admissible.csv and
/// admissible.md (the admissible ones ranked, with the Table 8.2 columns).
#[test]
fn synth_cli_writes_csv_and_markdown() {
    let dir = out("cli");
    let d = dir.to_str().unwrap();
    let one = [
        "synth",
        "--e-mm",
        "20,20,1",
        "--rb-mm",
        "90,90,1",
        "--rp-mm",
        "50,50,1",
        "--hc-mm",
        "160,160,1",
        "--grid",
        "2,2,2",
        "--out",
        d,
    ];
    let stdout = ok(&one, "");
    assert!(
        stdout.contains("1 robots scanned, 0 admissible"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "the reference robot is NOT admissible: l1_mm min 143.75 < 144 mm (min_length_mm)"
        ),
        "{stdout}"
    );
    let task = dir.join("lower.toml");
    std::fs::write(&task, "[rspr]\nmin_length_mm = 143.0\n").unwrap();
    let mut args = one.to_vec();
    args.extend(["--task", task.to_str().unwrap()]);
    let stdout = ok(&args, "");
    assert!(
        stdout.contains("1 robots scanned, 1 admissible"),
        "{stdout}"
    );
    assert!(
        stdout.contains("the reference robot is admissible"),
        "{stdout}"
    );
    let all = Table::parse(&std::fs::read_to_string(dir.join("synth.csv")).unwrap());
    assert_eq!(all.rows.len(), 1);
    assert_eq!(
        &all.header[..7],
        [
            "e_mm",
            "rb_mm",
            "rp_mm",
            "hc_mm",
            "envelope_volume_cm3",
            "admissible",
            "rejected"
        ]
    );
    assert_eq!(all.text(0, "admissible"), "true");
    let best = Table::parse(&std::fs::read_to_string(dir.join("admissible.csv")).unwrap());
    assert_eq!(best.rows.len(), 1);
    for col in [
        "l_mm_span",
        "theta_deg_span",
        "tilt_deg_max",
        "f_n_max",
        "t_nm_max",
    ] {
        assert!(best.header.iter().any(|h| h == col), "{col}");
    }
    assert!(best.num(0, "f_n_max") > 0.0 && best.num(0, "t_nm_max") < 1.0);
    let md = std::fs::read_to_string(dir.join("admissible.md")).unwrap();
    assert!(
        md.contains("| rank | e_mm | rb_mm | rp_mm | hc_mm |"),
        "{md}"
    );
    assert_eq!(md.lines().filter(|l| l.starts_with("| 1 |")).count(), 1);
    assert_ne!(
        host_sim(&["synth", "--l1-mm", "60,80,10", "--out", d], "").code,
        Some(0)
    );
}

/// A bad task file is rejected by the command with a message naming the file and the
/// field (the library's parsing of task files: host-sim/design/tests/synth.rs).
#[test]
fn a_bad_task_file_is_named_with_its_field() {
    let bad = out("bad-task").join("bad.toml");
    std::fs::write(&bad, "[usr]\nmax_tilt_deg = 0\n").unwrap();
    let r = host_sim(
        &[
            "synth",
            "--task",
            bad.to_str().unwrap(),
            "--out",
            "/nonexistent",
        ],
        "",
    );
    assert_ne!(r.code, Some(0));
    assert!(
        r.stderr.contains("usr.max_tilt_deg") && r.stderr.contains("bad.toml"),
        "{}",
        r.stderr
    );
}
