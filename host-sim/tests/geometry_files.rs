//! The shipped reference geometry files give the same output as the built-in references
//! (that they load and equal them: host-sim/robot-config/tests/geometry_files.rs); a file
//! with an unknown key or a negative length fails, naming the file and the key.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{geometry, host_sim, ok};
use std::path::PathBuf;

#[test]
fn reference_files_give_the_same_output_as_the_built_in_robots() {
    let poses = "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n5,-3,85,4,-2,6,0\n0,0,80,0,0,0,7\n";
    for (file, robot, poses) in [
        (
            "reference-rspr.toml",
            "rspr",
            poses.replace(",85,", ",165,"),
        ),
        ("reference-usr.toml", "usr", poses.to_string()),
    ] {
        let path = geometry(file);
        for cmd in ["ik", "singularity"] {
            assert_eq!(
                ok(&["--geometry", &path, cmd, "--csv"], &poses),
                ok(&["--robot", robot, cmd, "--csv"], &poses),
                "{file} {cmd}"
            );
        }
    }
}

/// A temporary geometry file, removed when dropped.
struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, text: &str) -> TempFile {
        let path =
            std::env::temp_dir().join(format!("host-sim-test-{}-{name}", std::process::id()));
        std::fs::write(&path, text).unwrap();
        TempFile(path)
    }
    fn arg(&self) -> &str {
        self.0.to_str().unwrap()
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Runs `ik` with a geometry file and asserts a one-line error containing every needle.
fn rejected(file: &TempFile, needles: &[&str]) {
    let r = host_sim(
        &["--geometry", file.arg(), "ik", "--pose", "0,0,160,0,0,0"],
        "",
    );
    assert_eq!(r.code, Some(1), "{}", r.stderr);
    assert_eq!(r.stderr.lines().count(), 1, "{:?}", r.stderr);
    assert!(
        r.stderr.contains(file.arg()),
        "names the file: {}",
        r.stderr
    );
    for n in needles {
        assert!(r.stderr.contains(n), "{:?} lacks {n:?}", r.stderr);
    }
}

#[test]
fn bad_geometry_files_are_rejected_naming_the_key() {
    let unknown = TempFile::new(
        "unknown.toml",
        "robot = \"rspr\"\ne_mm = 20\nrb_mm = 90\nrp_mm = 50\nhc_mm = 160\nrb_m = 0.09\n",
    );
    rejected(&unknown, &["line 6", "unknown field `rb_m`"]);
    let negative = TempFile::new(
        "negative.toml",
        "robot = \"rspr\"\ne_mm = 20\nrb_mm = 90\nrp_mm = -50\nhc_mm = 160\n",
    );
    rejected(&negative, &["rp_mm: rp must be positive, got -50 mm"]);
    let missing = TempFile::new(
        "missing.toml",
        "robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nhc_mm = 80\n",
    );
    rejected(&missing, &["missing field `l2_mm`"]);
    let text = TempFile::new(
        "text.toml",
        "robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = \"sixty\"\nl2_mm = 80\nhc_mm = 80\n",
    );
    rejected(&text, &["line 4", "l1_mm = \"sixty\""]);
    let robot = TempFile::new("robot.toml", "robot = \"delta\"\n");
    rejected(&robot, &["unknown variant `delta`"]);
    let absent = TempFile(std::env::temp_dir().join("host-sim-test-no-such-file.toml"));
    rejected(&absent, &["cannot read"]);
}
