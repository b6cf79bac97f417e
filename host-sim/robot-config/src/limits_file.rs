//! Limits files: the guards' [`Limits`] in TOML, in millimetres, degrees, newtons and
//! newton-metres, every key carrying its unit (CONVENTIONS.md, "Units").
//!
//! ```toml
//! stroke_min_mm = 144.0
//! tilt_max_deg = 30
//! box_half_mm = [20, 20, 10]
//! ```
//!
//! Every key is optional and defaults to [`Limits::reference`], so a file may override a
//! few; unknown keys are rejected. Every length, angle, speed and acceleration must lie in
//! a plausible range ([`crate::plausible`]; a stroke of 0.144 is metres in a millimetre
//! key, a tilt of 0.52 radians in a degree key), and the result is checked with
//! [`Limits::validate`]. Every
//! error names the file and the key. `limits/reference.toml` lists every key with its
//! meaning and where its default comes from.

use crate::plausible::{Implausible, PlausibleRange};
use crate::toml_error::TomlError;
use crate::units::{deg_to_rad, mm_to_m};
use kinematics_core::guards::{Limits, LimitsError};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The keys of a limits file. Each is optional; absent keys keep the reference value.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct LimitsFile {
    stroke_min_mm: Option<f64>,
    stroke_max_mm: Option<f64>,
    link_angle_max_deg: Option<f64>,
    pitch_max_deg: Option<f64>,
    tilt_max_deg: Option<f64>,
    collision_plane_height_mm: Option<f64>,
    collision_radius_mm: Option<f64>,
    box_half_mm: Option<[f64; 3]>,
    box_margin_mm: Option<f64>,
    tilt_cone_deg: Option<f64>,
    serial_warn: Option<f64>,
    serial_stop: Option<f64>,
    parallel_warn: Option<f64>,
    parallel_stop: Option<f64>,
    tip_speed_mm_s: Option<f64>,
    angular_speed_deg_s: Option<f64>,
    tip_accel_mm_s2: Option<f64>,
    angular_accel_deg_s2: Option<f64>,
    joint_speed_linear_mm_s: Option<f64>,
    joint_speed_angular_deg_s: Option<f64>,
    joint_accel_linear_mm_s2: Option<f64>,
    joint_accel_angular_deg_s2: Option<f64>,
    payload_fx_n: Option<f64>,
    payload_fy_n: Option<f64>,
    payload_fz_n: Option<f64>,
    payload_tx_nm: Option<f64>,
    payload_ty_nm: Option<f64>,
    payload_tz_nm: Option<f64>,
    payload_lever_x_mm: Option<f64>,
    payload_lever_y_mm: Option<f64>,
    payload_lever_z_mm: Option<f64>,
    force_warn_n: Option<f64>,
    force_stop_n: Option<f64>,
    torque_warn_nm: Option<f64>,
    torque_stop_nm: Option<f64>,
}

/// Every key a limits file accepts, in the order of `limits/reference.toml`.
pub const KEYS: [&str; 35] = [
    "stroke_min_mm",
    "stroke_max_mm",
    "link_angle_max_deg",
    "pitch_max_deg",
    "tilt_max_deg",
    "collision_plane_height_mm",
    "collision_radius_mm",
    "box_half_mm",
    "box_margin_mm",
    "tilt_cone_deg",
    "serial_warn",
    "serial_stop",
    "parallel_warn",
    "parallel_stop",
    "tip_speed_mm_s",
    "angular_speed_deg_s",
    "tip_accel_mm_s2",
    "angular_accel_deg_s2",
    "joint_speed_linear_mm_s",
    "joint_speed_angular_deg_s",
    "joint_accel_linear_mm_s2",
    "joint_accel_angular_deg_s2",
    "payload_fx_n",
    "payload_fy_n",
    "payload_fz_n",
    "payload_tx_nm",
    "payload_ty_nm",
    "payload_tz_nm",
    "payload_lever_x_mm",
    "payload_lever_y_mm",
    "payload_lever_z_mm",
    "force_warn_n",
    "force_stop_n",
    "torque_warn_nm",
    "torque_stop_nm",
];

/// Overwrites `slot` with the converted value when the key is present.
fn set(slot: &mut f64, value: Option<f64>, to_si: fn(f64) -> f64) {
    if let Some(v) = value {
        *slot = to_si(v);
    }
}

/// The identity, for keys already in SI (dimensionless measures, N, N m).
fn si(x: f64) -> f64 {
    x
}

impl LimitsFile {
    /// The keys with a plausible range, their values (when given) and the range.
    fn ranged(&self) -> Vec<(&'static str, Option<f64>, PlausibleRange)> {
        let length = PlausibleRange::mm(1.0, 2000.0);
        let angle = PlausibleRange::deg(1.0, 180.0);
        let speed = PlausibleRange::mm(0.1, 1e4);
        let accel = PlausibleRange::mm(1.0, 1e6);
        let angular_speed = PlausibleRange::deg(0.1, 1e4);
        let angular_accel = PlausibleRange::deg(1.0, 1e6);
        let lever = PlausibleRange::mm(-2000.0, 2000.0);
        let mut out = vec![
            ("stroke_min_mm", self.stroke_min_mm, length),
            ("stroke_max_mm", self.stroke_max_mm, length),
            ("link_angle_max_deg", self.link_angle_max_deg, angle),
            ("pitch_max_deg", self.pitch_max_deg, angle),
            ("tilt_max_deg", self.tilt_max_deg, angle),
            ("tilt_cone_deg", self.tilt_cone_deg, angle),
            (
                "collision_plane_height_mm",
                self.collision_plane_height_mm,
                lever,
            ),
            (
                "collision_radius_mm",
                self.collision_radius_mm,
                PlausibleRange::mm(0.0, 2000.0),
            ),
            (
                "box_margin_mm",
                self.box_margin_mm,
                PlausibleRange::mm(0.0, 1000.0),
            ),
            ("tip_speed_mm_s", self.tip_speed_mm_s, speed),
            (
                "angular_speed_deg_s",
                self.angular_speed_deg_s,
                angular_speed,
            ),
            ("tip_accel_mm_s2", self.tip_accel_mm_s2, accel),
            (
                "angular_accel_deg_s2",
                self.angular_accel_deg_s2,
                angular_accel,
            ),
            (
                "joint_speed_linear_mm_s",
                self.joint_speed_linear_mm_s,
                speed,
            ),
            (
                "joint_speed_angular_deg_s",
                self.joint_speed_angular_deg_s,
                angular_speed,
            ),
            (
                "joint_accel_linear_mm_s2",
                self.joint_accel_linear_mm_s2,
                accel,
            ),
            (
                "joint_accel_angular_deg_s2",
                self.joint_accel_angular_deg_s2,
                angular_accel,
            ),
            ("payload_lever_x_mm", self.payload_lever_x_mm, lever),
            ("payload_lever_y_mm", self.payload_lever_y_mm, lever),
            ("payload_lever_z_mm", self.payload_lever_z_mm, lever),
        ];
        if let Some(h) = self.box_half_mm {
            for v in h {
                out.push(("box_half_mm", Some(v), PlausibleRange::mm(1.0, 1000.0)));
            }
        }
        out
    }

    /// Checks every given value against its plausible range.
    fn plausible(&self) -> Result<(), Implausible> {
        for (key, value, range) in self.ranged() {
            if let Some(v) = value {
                range.check(key, v)?;
            }
        }
        Ok(())
    }

    /// The reference limits with this file's keys applied, in SI.
    fn apply(&self, l: &mut Limits<f64>) {
        set(&mut l.stroke[0], self.stroke_min_mm, mm_to_m);
        set(&mut l.stroke[1], self.stroke_max_mm, mm_to_m);
        set(&mut l.link_angle_max, self.link_angle_max_deg, deg_to_rad);
        set(&mut l.pitch_max, self.pitch_max_deg, deg_to_rad);
        set(&mut l.tilt_max, self.tilt_max_deg, deg_to_rad);
        set(
            &mut l.collision_plane_height,
            self.collision_plane_height_mm,
            mm_to_m,
        );
        set(&mut l.collision_radius, self.collision_radius_mm, mm_to_m);
        if let Some(h) = self.box_half_mm {
            for (slot, v) in l.box_half.iter_mut().zip(h) {
                *slot = mm_to_m(v);
            }
        }
        set(&mut l.box_margin, self.box_margin_mm, mm_to_m);
        set(&mut l.tilt_cone, self.tilt_cone_deg, deg_to_rad);
        set(&mut l.serial.warn, self.serial_warn, si);
        set(&mut l.serial.stop, self.serial_stop, si);
        set(&mut l.parallel.warn, self.parallel_warn, si);
        set(&mut l.parallel.stop, self.parallel_stop, si);
        set(&mut l.tip_speed, self.tip_speed_mm_s, mm_to_m);
        set(&mut l.angular_speed, self.angular_speed_deg_s, deg_to_rad);
        set(&mut l.tip_accel, self.tip_accel_mm_s2, mm_to_m);
        set(&mut l.angular_accel, self.angular_accel_deg_s2, deg_to_rad);
        set(&mut l.joint_speed[0], self.joint_speed_linear_mm_s, mm_to_m);
        set(
            &mut l.joint_speed[1],
            self.joint_speed_angular_deg_s,
            deg_to_rad,
        );
        set(
            &mut l.joint_accel[0],
            self.joint_accel_linear_mm_s2,
            mm_to_m,
        );
        set(
            &mut l.joint_accel[1],
            self.joint_accel_angular_deg_s2,
            deg_to_rad,
        );
        let payload = [
            self.payload_fx_n,
            self.payload_fy_n,
            self.payload_fz_n,
            self.payload_tx_nm,
            self.payload_ty_nm,
            self.payload_tz_nm,
        ];
        for (slot, v) in l.payload.iter_mut().zip(payload) {
            set(slot, v, si);
        }
        let lever = [
            self.payload_lever_x_mm,
            self.payload_lever_y_mm,
            self.payload_lever_z_mm,
        ];
        for (slot, v) in l.payload_lever.iter_mut().zip(lever) {
            set(slot, v, mm_to_m);
        }
        set(&mut l.force.warn, self.force_warn_n, si);
        set(&mut l.force.stop, self.force_stop_n, si);
        set(&mut l.torque.warn, self.torque_warn_nm, si);
        set(&mut l.torque.stop, self.torque_stop_nm, si);
    }
}

/// The keys of a limits file that a group named by [`Limits::validate`] stands for
/// (`serial`, `force`, `payload`, ...); `None` when the core names one key.
fn keys_of(field: &str) -> Option<&'static str> {
    Some(match field {
        "serial" => "serial_warn, serial_stop",
        "parallel" => "parallel_warn, parallel_stop",
        "force" => "force_warn_n, force_stop_n",
        "torque" => "torque_warn_nm, torque_stop_nm",
        "payload" => "payload_fx_n .. payload_tz_nm, payload_lever_x_mm .. payload_lever_z_mm",
        _ => return None,
    })
}

/// What is wrong with the text of a limits file (the file is named by
/// [`LimitsFileError`]).
#[derive(Clone, Debug, PartialEq, Error)]
pub enum LimitsTextError {
    /// Not TOML, an unknown key, a value of the wrong type.
    #[error(transparent)]
    Toml(#[from] TomlError),
    /// A value outside its key's plausible range (metres, radians).
    #[error(transparent)]
    Implausible(#[from] Implausible),
    /// Limits that [`Limits::validate`] refuses; `keys` lists the file's keys when the
    /// core names a group of them.
    #[error("{error}{}", keys.map(|k| format!(" (keys {k})")).unwrap_or_default())]
    Inconsistent {
        error: LimitsError,
        keys: Option<&'static str>,
    },
}

impl From<LimitsError> for LimitsTextError {
    fn from(error: LimitsError) -> Self {
        LimitsTextError::Inconsistent {
            keys: keys_of(error.field),
            error,
        }
    }
}

/// A limits file that cannot be read or is invalid; names the file.
#[derive(Debug, Error)]
pub enum LimitsFileError {
    #[error("limits file {}: cannot read: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("limits file {}: {error}", path.display())]
    Invalid {
        path: PathBuf,
        error: LimitsTextError,
    },
}

/// Parses and validates the text of a limits file; messages name the key but not the
/// file (see [`load`]).
pub fn parse(text: &str) -> Result<Limits<f64>, LimitsTextError> {
    let file: LimitsFile = toml::from_str(text).map_err(|e| TomlError::located(text, &e))?;
    let mut limits = Limits::reference();
    file.apply(&mut limits);
    // The core's reasons (negative, inconsistent) first, then the plausible ranges.
    limits.validate()?;
    file.plausible()?;
    Ok(limits)
}

/// Loads a limits file. Errors read `limits file PATH: ...`.
pub fn load(path: &Path) -> Result<Limits<f64>, LimitsFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| LimitsFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text).map_err(|error| LimitsFileError::Invalid {
        path: path.to_path_buf(),
        error,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    const SHIPPED: &str = include_str!("../limits/reference.toml");

    #[test]
    fn shipped_reference_file_equals_the_core_reference() {
        assert_eq!(parse(SHIPPED).unwrap(), Limits::reference());
    }

    #[test]
    fn shipped_reference_file_sets_every_key_once() {
        for key in KEYS {
            let set = SHIPPED
                .lines()
                .filter(|l| l.split('=').next().map(str::trim) == Some(key))
                .count();
            assert_eq!(set, 1, "{key} in reference.toml");
        }
        // Every key is commented: the line above it is a comment.
        let lines: Vec<&str> = SHIPPED.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.contains('=') && !line.starts_with('#') {
                assert!(
                    i > 0 && lines[i - 1].starts_with('#'),
                    "no comment above {line:?}"
                );
            }
        }
    }

    #[test]
    fn limits_in_metres_or_radians_are_refused_with_the_reason() {
        let e = parse("stroke_min_mm = 0.144\n").unwrap_err().to_string();
        assert!(e.contains("stroke_min_mm = 0.144"), "{e}");
        assert!(e.contains("looks like metres (144 mm)"), "{e}");
        let e = parse("tilt_max_deg = 0.5\n").unwrap_err().to_string();
        assert!(e.contains("looks like radians"), "{e}");
        let e = parse("box_half_mm = [0.02, 0.02, 0.01]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("box_half_mm = 0.02"), "{e}");
        assert!(parse("stroke_max_mm = 5000\n").is_err());
    }

    #[test]
    fn an_empty_file_is_the_reference_and_a_few_keys_override_it() {
        assert_eq!(parse("").unwrap(), Limits::reference());
        let l = parse("stroke_min_mm = 140\ntilt_cone_deg = 10\npayload_tz_nm = -1.5\n").unwrap();
        let mut want = Limits::<f64>::reference();
        want.stroke[0] = 0.140;
        want.tilt_cone = 10f64.to_radians();
        want.payload[5] = -1.5;
        assert_eq!(l, want);
        let l = parse("box_half_mm = [10, 15, 5]\n").unwrap();
        assert_eq!(l.box_half, nalgebra::Vector3::new(0.010, 0.015, 0.005));
    }

    /// The message of a text that fails to parse.
    fn parse_err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn errors_name_the_key() {
        let e = parse_err("stroke_min_mm = 144\nstroke_minimum_mm = 1\n");
        assert!(
            e.contains("line 2") && e.contains("stroke_minimum_mm"),
            "{e}"
        );
        let e = parse_err("tilt_max_deg = -3\n");
        assert_eq!(e, "tilt_max_deg: is negative");
        let e = parse_err("stroke_min_mm = 215\n");
        assert_eq!(e, "stroke_min_mm: must be below stroke_max_mm");
        let e = parse_err("tip_speed_mm_s = \"fast\"\n");
        assert!(e.contains("tip_speed_mm_s"), "{e}");
        let e = parse_err("serial_stop = 0.5\n");
        assert!(
            e.starts_with("serial: ") && e.contains("serial_stop"),
            "{e}"
        );
        let e = parse_err("torque_stop_nm = 0.4\n");
        assert!(e.contains("torque_stop_nm"), "{e}");
        let e = parse_err("box_half_mm = [20, 20]\n");
        assert!(e.contains("box_half_mm"), "{e}");
        let e = parse_err("payload_fx_n = nan\n");
        assert!(e.contains("payload_fx_n"), "{e}");
    }

    #[test]
    fn a_group_of_keys_is_named_with_the_core_reason() {
        match parse("serial_stop = 0.5\n").unwrap_err() {
            LimitsTextError::Inconsistent { error, keys } => {
                assert_eq!(error.field, "serial");
                assert_eq!(keys, Some("serial_warn, serial_stop"));
            }
            other => panic!("{other:?}"),
        }
    }
}
