#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The parameter file: shipped defaults, overrides, validation messages.

use plant::config::SHIPPED_TOML;
use plant::{ConfigError, Plant, PlantConfig};

type TestResult = Result<(), Box<dyn std::error::Error>>;

fn with(replace: &str, by: &str) -> String {
    assert!(
        SHIPPED_TOML.contains(replace),
        "fixture: `{replace}` not in plant.toml"
    );
    SHIPPED_TOML.replacen(replace, by, 1)
}

fn rejected(text: &str) -> String {
    match PlantConfig::from_toml_str(text) {
        Ok(_) => panic!("accepted a bad config"),
        Err(e) => e.to_string(),
    }
}

/// Property: the file on disk, the embedded copy and `Default` are the same parameters,
/// and they build a plant.
#[test]
fn shipped_file_equals_default() -> TestResult {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/plant.toml");
    let on_disk = std::fs::read_to_string(path)?;
    assert_eq!(on_disk, SHIPPED_TOML);
    assert_eq!(
        PlantConfig::from_toml_str(&on_disk)?,
        PlantConfig::default()
    );
    Plant::new(&PlantConfig::default())?;
    Ok(())
}

/// Property: out-of-range, non-finite, negative values are rejected with a message that
/// names the key and the value.
#[test]
fn bad_values_are_rejected_naming_the_key() {
    let cases = [
        (
            with("resistance_ohm = 0.317", "resistance_ohm = -1.0"),
            "prismatic.resistance_ohm",
            "-1",
        ),
        (
            with("inductance_h = 0.238e-3", "inductance_h = nan"),
            "rotary.inductance_h",
            "NaN",
        ),
        (
            with("supply_v = 24.0", "supply_v = inf"),
            "hbridge.supply_v",
            "inf",
        ),
        (
            with("gear_efficiency = 0.95", "gear_efficiency = 1.5"),
            "prismatic.gear_efficiency",
            "1.5",
        ),
        (
            with("backlash_mm = 0.12", "backlash_mm = -0.1"),
            "prismatic.backlash_mm",
            "-0.1",
        ),
        (
            with("lines_per_rev = 500", "lines_per_rev = -500"),
            "encoder.lines_per_rev",
            "-500",
        ),
        (
            format!("{SHIPPED_TOML}\n[joint.theta2]\nbacklash_arcsec = 1e9\n"),
            "joint.theta2.backlash_arcsec",
            "1000000000",
        ),
    ];
    for (text, key, value) in cases {
        let msg = rejected(&text);
        assert!(msg.contains(key), "`{msg}` does not name `{key}`");
        assert!(msg.contains(value), "`{msg}` does not show `{value}`");
    }
}

/// Property: unknown keys (typos, a key of the other joint kind), wrong types, a bad
/// quadrature factor and Kt != Ke are rejected, naming the key.
#[test]
fn unknown_keys_wrong_types_and_inconsistencies_are_rejected() {
    let cases = [
        (
            format!("{SHIPPED_TOML}\n[joint.theta1]\nlead_mm = 2.0\n"),
            "joint.theta1.lead_mm",
        ),
        (
            with("lead_mm = 6.0", "lead_mm = 6.0\nleed_mm = 6.0"),
            "prismatic.leed_mm",
        ),
        (
            with("supply_v = 24.0", "supply_v = \"24\""),
            "hbridge.supply_v",
        ),
        (
            with("quadrature_factor = 4", "quadrature_factor = 3"),
            "encoder.quadrature_factor",
        ),
        (
            with(
                "back_emf_v_s_per_rad = 0.0234",
                "back_emf_v_s_per_rad = 0.05",
            ),
            "rotary.back_emf_v_s_per_rad",
        ),
        (
            format!("{SHIPPED_TOML}\n[joint.l4]\nlead_mm = 2.0\n"),
            "joint.l4",
        ),
        (format!("{SHIPPED_TOML}\n[extra]\n"), "extra"),
    ];
    for (text, key) in cases {
        let msg = rejected(&text);
        assert!(msg.contains(key), "`{msg}` does not name `{key}`");
    }
    assert!(matches!(
        PlantConfig::from_toml_str("this is = not toml ="),
        Err(ConfigError::Parse(_))
    ));
}

/// Property: a per-joint table overrides only that joint.
#[test]
fn per_joint_overrides_apply_to_one_joint() -> TestResult {
    let text = format!(
        "{SHIPPED_TOML}\n[joint.l2]\nbacklash_mm = 0.2\n\n[joint.theta3]\ngear_ratio = 40\n"
    );
    let cfg = PlantConfig::from_toml_str(&text)?;
    assert_eq!(cfg.prismatic[0].backlash_mm, 0.12);
    assert_eq!(cfg.prismatic[1].backlash_mm, 0.2);
    assert_eq!(cfg.prismatic[2].backlash_mm, 0.12);
    assert_eq!(cfg.rotary[1].gear_ratio, 36.0);
    assert_eq!(cfg.rotary[2].gear_ratio, 40.0);
    Ok(())
}

/// Property: a configuration built in code is validated by `Plant::new`, the error naming
/// the joint and the key.
#[test]
fn plant_new_validates_configs_built_in_code() {
    let mut cfg = PlantConfig::default();
    cfg.prismatic[2].lead_mm = f64::NAN;
    match Plant::new(&cfg) {
        Err(e) => assert!(e.to_string().contains("l3.lead_mm"), "{e}"),
        Ok(_) => panic!("accepted NaN lead"),
    }
    let mut cfg = PlantConfig::default();
    cfg.rotary[0].load_inertia_kg_m2 = 0.0;
    match Plant::new(&cfg) {
        Err(e) => assert!(e.to_string().contains("theta1.load_inertia_kg_m2"), "{e}"),
        Ok(_) => panic!("accepted zero inertia"),
    }
}
