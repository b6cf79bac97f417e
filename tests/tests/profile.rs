#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The board profile is the one owner of the board's control period, CPU clock and encoder
//! resolutions (and of its drive trains and joint ranges): its TOML form is the same
//! profile, everything that needs those facts takes them from it, the plant model is
//! equal to it, and no literal of them is written anywhere else in the code.

use board_profile::{BoardProfile, JointKind};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Property: `firmware/profile/reference.toml` is `BoardProfile::REFERENCE`, field by
/// field, and both pass the profile's checks.
#[test]
fn the_reference_toml_is_the_reference_profile() {
    let text = std::fs::read_to_string(root().join("firmware/profile/reference.toml")).unwrap();
    let file = BoardProfile::from_toml_str(&text).unwrap();
    assert_eq!(file, BoardProfile::REFERENCE);
    BoardProfile::REFERENCE.validate().unwrap();
    // A profile in metres where millimetres belong, or a wrong joint kind, is refused.
    let bad = text.replacen("control_period_us = 1000", "control_period_us = 20", 1);
    assert!(BoardProfile::from_toml_str(&bad).is_err());
    let bad = text.replacen("kind = \"prismatic\"", "kind = \"revolute\"", 1);
    assert!(BoardProfile::from_toml_str(&bad).is_err());
}

/// Property: the control application's defaults are the profile's: the encoders' counts
/// per unit, the controller's rate, the watchdog's period, the reference mechanics'
/// ranges.
#[test]
fn the_firmware_defaults_come_from_the_profile() {
    let p = BoardProfile::REFERENCE;
    let enc = servo::encoder::EncoderConfig::<f64>::default();
    assert_eq!(enc.counts_per_unit, p.counts_per_unit());
    let ctl = control::ControllerConfig::<f64>::default();
    assert_eq!(ctl.rate_hz, p.rate_hz());
    let wd = control::watchdog::WatchdogConfig::default();
    assert_eq!(wd.period_us, p.control_period_us);
    let mech =
        control::runtime::reference_mechanics::<f64>(&kinematics_core::guards::Limits::reference());
    assert_eq!(mech.range, p.ranges());
    // The resolutions the thesis states (T11.2): 0.0015 mm and 0.005 deg per count.
    assert!((p.joints[0].unit_per_count() - 0.0015e-3).abs() < 1e-15);
    assert!((p.joints[3].unit_per_count().to_degrees() - 0.005).abs() < 1e-12);
}

/// Property: the plant model's drive trains are the profile's: every joint's encoder
/// counts per motor revolution, gear ratio and (legs) lead.
#[test]
fn the_plant_model_is_the_profile() {
    let plant = plant::PlantConfig::shipped().unwrap();
    let p = BoardProfile::REFERENCE;
    for (j, jp) in p.joints.iter().enumerate() {
        assert_eq!(
            plant.encoder.counts_per_rev(),
            jp.counts_per_rev(),
            "joint {j}"
        );
        match jp.kind {
            JointKind::Prismatic => {
                let c = &plant.prismatic[j];
                assert_eq!(c.gear_ratio, jp.gear_ratio, "joint {j}");
                assert!((c.lead_mm * 1e-3 - jp.lead_m).abs() < 1e-15, "joint {j}");
            }
            JointKind::Revolute => {
                assert_eq!(plant.rotary[j - 3].gear_ratio, jp.gear_ratio, "joint {j}");
            }
        }
    }
}

/// Property: the plant's second position channel is the profile's
/// (`board_profile::position_channel::PositionChannel::REFERENCE`): the potentiometers'
/// travel, and the converter's 16 bits (one count of the plant's 65536 a step).
#[test]
fn the_plant_position_channel_is_the_profile() {
    use board_profile::position_channel::{PositionChannel, READING_COUNTS};
    let plant = plant::PlantConfig::shipped().unwrap();
    let ps = &plant.position_sensor;
    let p = PositionChannel::REFERENCE;
    assert!((ps.leg_travel_mm * 1e-3 - p.leg_travel_m).abs() < 1e-12);
    assert!((ps.link_travel_deg.to_radians() - p.link_travel_rad).abs() < 1e-12);
    assert!((ps.leg_counts_per_m() - p.counts_per_unit(0)).abs() < 1e-6);
    assert!((ps.link_counts_per_rad() - p.counts_per_unit(3)).abs() < 1e-9);
    assert_eq!(p.step_counts(), 1.0);
    assert_eq!(
        READING_COUNTS,
        f64::from(plant::position_sensor::FULL_SCALE) + 1.0
    );
}

/// Every source and build file of the repository that is not the profile's own.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            if !matches!(
                name.as_str(),
                "target" | ".git" | "corpus" | "artifacts" | "profile"
            ) {
                sources(&path, out);
            }
        } else if [".rs", ".toml", ".sh", ".awk"]
            .iter()
            .any(|x| name.ends_with(x))
            && name != "Cargo.lock"
        {
            out.push(path);
        }
    }
}

/// Property: the control period, the CPU clock and the encoder resolution appear as
/// literals only in the board profile (`firmware/profile`): no other source, settings or
/// script file writes 168 MHz, a 1000 µs / 1 kHz control period, or the encoders' 500
/// lines, 2000 counts per revolution, 2000 counts per 3 mm or per 10 deg.
#[test]
fn the_profile_facts_are_written_nowhere_else() {
    let mut files = Vec::new();
    sources(&root(), &mut files);
    assert!(files.len() > 100, "{} files", files.len());
    let forbidden: &[(&str, &str)] = &[
        ("168_000_000", "the CPU clock"),
        ("168000000", "the CPU clock"),
        ("168e6", "the CPU clock"),
        ("PERIOD_US: u32 = 1000", "the control period"),
        ("PERIOD_US: u64 = 1000", "the control period"),
        ("period_us: 1000", "the control period"),
        ("for_period(1000", "the control period"),
        (" rate_hz = 1000", "the control rate"),
        ("\nrate_hz = 1000", "the control rate"),
        ("rate_hz: scalar::lit(1000", "the control rate"),
        ("2000.0 / 0.003", "the legs' encoder resolution"),
        ("0.0015e-3", "the legs' encoder resolution"),
        ("lines_per_rev: 500", "the encoders' lines"),
        ("2000.0 / (10.0", "the links' encoder resolution"),
        (
            "0.005 * std::f64::consts::PI",
            "the links' encoder resolution",
        ),
        (
            "LEG_COUNTS_PER_M",
            "the legs' encoder resolution (a second owner)",
        ),
        (
            "LINK_COUNTS_PER_RAD",
            "the links' encoder resolution (a second owner)",
        ),
        (
            "LEG_COUNT_M",
            "the legs' encoder resolution (a second owner)",
        ),
    ];
    let me = root().join("tests/tests/profile.rs");
    // The plant models the robot as built, not the board's belief about it: its drive
    // trains are tested equal to the profile (`the_plant_model_is_the_profile`).
    let plant = root().join("sim/plant");
    let mut found = Vec::new();
    for f in &files {
        if f.canonicalize().ok() == me.canonicalize().ok() || f.starts_with(&plant) {
            continue;
        }
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let code = format!("\n{}", code.split('#').next().unwrap_or(""));
            for (lit, what) in forbidden {
                if code.contains(lit) {
                    found.push(format!("{}:{}: {what} ({lit})", f.display(), n + 1));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "written outside the board profile:\n{}",
        found.join("\n")
    );
}
