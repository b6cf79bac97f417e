//! `host-sim dct`: the double circular-triangular robot on the command line: the
//! appendix's evaluation prints its verdicts, a pose prints joints, Jacobian and forces,
//! and bad input is refused with the reason.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::Command;

fn host_sim(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("run host-sim");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_evaluation_prints_the_verdicts() {
    let (ok, out, err) = host_sim(&["dct", "--grid", "3,3,3"]);
    assert!(ok, "{err}");
    assert!(
        out.contains("envelope: the circles alone span 398.3 mm, exceeding the 200 mm cube"),
        "{out}"
    );
    assert!(out.contains("of 54 poses solved"), "{out}");
    assert!(out.contains("thesis's conclusion"), "{out}");
}

/// At the central configuration the two mechanisms are in the same configuration, so the
/// lower and the upper joints are equal, and the triangles are centred.
#[test]
fn a_pose_prints_joints_jacobian_and_forces() {
    let (ok, out, err) = host_sim(&["dct", "--pose", "0,0,110,0,0,0"]);
    assert!(ok, "{err}");
    let joints = out.lines().next().unwrap();
    let q: Vec<&str> = joints.split(": ").nth(1).unwrap().split(", ").collect();
    assert_eq!(q.len(), 6);
    assert_eq!(q[..3], q[3..], "{joints}");
    assert!(
        out.contains("lower triangle: centre (0.000000, 0.000000) mm, psi 0.000000 deg"),
        "{out}"
    );
    assert_eq!(
        out.lines().filter(|l| l.starts_with("  ")).count(),
        6,
        "{out}"
    );
    assert!(out.contains("slider forces tau (N, eta 1):"), "{out}");
}

#[test]
fn bad_input_is_refused_with_the_reason() {
    let (ok, _, err) = host_sim(&["dct", "--branch", "64"]);
    assert!(!ok);
    assert!(err.contains("--branch: 64 is out of range 0..=63"), "{err}");
    let (ok, _, err) = host_sim(&["dct", "--pose", "0,0,110,90,0,0"]);
    assert!(!ok);
    assert!(
        err.contains("dct: the link is parallel to the planes"),
        "{err}"
    );
    let (ok, _, err) = host_sim(&["dct", "--pose", "0,0,110,0,0,0", "--eta", "0"]);
    assert!(!ok);
    assert!(err.contains("--eta: 0 is not in (0, 1]"), "{err}");
}
