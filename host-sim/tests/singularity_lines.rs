//! `singularity`'s line-geometry columns and `singularity-scan` (thesis chapter 10): a
//! regular pose has rank 6 and nothing else; the platform in the base plane is S1 with
//! rank 3 and its varieties; a scan names every configuration once with the pose of its
//! smallest residual, which `singularity` at that pose confirms.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, Table};

#[test]
fn regular_pose_has_full_rank_and_no_configuration() {
    let t = Table::parse(&ok(&["singularity", "--pose", "10,-5,165,5,0,0"], ""));
    assert_eq!(t.text(0, "rank"), "6");
    for c in [
        "circuits",
        "configurations",
        "complex",
        "gained",
        "serial1_case",
    ] {
        assert_eq!(t.text(0, c), "", "{c}");
    }
}

#[test]
fn platform_in_the_base_plane_is_s1() {
    let t = Table::parse(&ok(&["singularity", "--pose", "0,0,0,0,0,0"], ""));
    assert_eq!(t.text(0, "rank"), "3");
    let circuits = t.text(0, "circuits");
    assert!(circuits.split(' ').any(|c| c == "2b:123"), "{circuits}");
    assert!(circuits.split(' ').any(|c| c == "3D:1245"), "{circuits}");
    let conf = t.text(0, "configurations");
    assert!(conf.split(' ').any(|c| c == "S1"), "{conf}");
    // Three gained motions: the translation along z and the rotations about x and y.
    assert_eq!(t.text(0, "gained").matches("twist=").count(), 3);
}

#[test]
fn scan_reports_each_configuration_and_singularity_agrees() {
    let text = ok(&["singularity-scan", "--grid", "3,3,2"], "");
    let body: String = text.lines().skip(1).collect::<Vec<_>>().join("\n");
    let t = Table::parse(&body);
    assert_eq!(t.rows.len(), 12);
    let names: Vec<&str> = (0..12).map(|r| t.text(r, "configuration")).collect();
    assert_eq!(names[0], "S1");
    assert_eq!(names[11], "S13");
    // The task box is far from every configuration (residuals well above the tolerance).
    for (r, name) in names.iter().enumerate() {
        assert!(t.num(r, "residual") > 0.1, "{name}");
    }
    // S1's residual is the largest distance of a b_i from the platform plane over rp:
    // at the level platform of height z it is z / rp = z / 50 mm.
    let z = t.num(0, "z_mm");
    assert!(
        (t.num(0, "residual") - z / 50.0).abs() < 1e-6,
        "{}",
        t.num(0, "residual")
    );
}
