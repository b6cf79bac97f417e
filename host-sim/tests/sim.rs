//! `host-sim sim`: the command writes the summary, the trace and the plots, and names a bad
//! configuration key (the simulation's properties: host-sim/simulation/tests/sim.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

/// The command writes the summary, the trace and the plots, and prints a readable
/// report; a bad configuration key is named in the error.
#[test]
fn the_command_writes_its_report_files() {
    let dir = std::env::temp_dir().join(format!("host-sim-sim-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let cfg_path = dir.join("short.toml");
    std::fs::write(
        &cfg_path,
        "[scenario.step]\nsteps_mm_deg = [[2.0, 0, 0, 0, 0, 0]]\nhold_s = 0.4\n",
    )
    .unwrap();
    let out_dir = dir.join("out");
    let run = common::host_sim(
        &[
            "sim",
            "--scenario",
            "step",
            "--config",
            cfg_path.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    assert!(run.stdout.contains("tracking error"), "{}", run.stdout);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(json["scenario"], "step");
    for key in [
        "tracking",
        "target",
        "joints",
        "actuators",
        "supervisor",
        "faults",
    ] {
        assert!(!json[key].is_null(), "summary lacks {key}");
    }
    assert!(json["speed_up"].as_f64().unwrap() > 1.0);
    let trace = std::fs::read_to_string(out_dir.join("trace.csv")).unwrap();
    let header = trace.lines().next().unwrap();
    assert!(
        header.starts_with("t_s,mode,warning,target_x_mm"),
        "{header}"
    );
    assert!(trace.lines().count() > 10);
    for png in ["path.png", "errors.png"] {
        let bytes = std::fs::read(out_dir.join(png)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{png}");
    }

    std::fs::write(&cfg_path, "[control]\nrate_hz = 50000.0\n").unwrap();
    let bad = common::host_sim(&["sim", "--config", cfg_path.to_str().unwrap()], "");
    assert_eq!(bad.code, Some(1));
    assert!(bad.stderr.contains("control.rate_hz"), "{}", bad.stderr);
    let _ = std::fs::remove_dir_all(&dir);
}
