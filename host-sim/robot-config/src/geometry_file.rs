//! Geometry files: a robot's dimensions in TOML, millimetres, unit-suffixed keys.
//!
//! ```toml
//! robot = "rspr"   # or "usr"
//! e_mm = 20.0      # RSPR: e_mm, rb_mm, rp_mm, hc_mm; USR: e_mm, rp_mm, l1_mm, l2_mm, hc_mm
//! ```
//!
//! A per-chain (calibrated) RSPR has its own layout, `robot = "rspr-per-chain"`
//! ([`crate::per_chain_file`]); [`parse`] and [`load`] take both.
//!
//! Unknown keys are rejected, a dimension outside 1 .. 2000 mm (the eccentricity 0 ..
//! 2000 mm) is refused as implausible ([`crate::plausible`]: metres in a millimetre key),
//! and every error names the file and the key or value.
//! `geometry/reference-rspr.toml` and `geometry/reference-usr.toml` are the built-in
//! reference robots in this form.

use crate::plausible::{PlausibleRange, DIMENSION, DIMENSION_OR_ZERO};
use crate::toml_error::TomlError;
use crate::units::mm_to_m;
use kinematics_core::{GeometryError, Robot, RsprGeometry, UsrGeometry};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The architecture named by the `robot` key.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum Architecture {
    Rspr,
    Usr,
}

/// The `robot` key alone, read first to pick the layout of the rest.
#[derive(Clone, Copy, Debug, Deserialize)]
struct Header {
    robot: Architecture,
}

/// An RSPR file: dimensions of thesis Fig. 8.2a, mm.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct RsprFile {
    #[allow(dead_code)]
    robot: Architecture,
    e_mm: f64,
    rb_mm: f64,
    rp_mm: f64,
    hc_mm: f64,
}

/// A USR file: dimensions of thesis Fig. 8.2b, mm.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct UsrFile {
    #[allow(dead_code)]
    robot: Architecture,
    e_mm: f64,
    rp_mm: f64,
    l1_mm: f64,
    l2_mm: f64,
    hc_mm: f64,
}

/// What is wrong with the text of a geometry file (the file is named by
/// [`GeometryFileError`]).
#[derive(Clone, Debug, PartialEq, Error)]
pub enum GeometryTextError {
    /// Not TOML, an unknown or missing key, a value of the wrong type.
    #[error(transparent)]
    Toml(#[from] TomlError),
    /// A dimension the core refuses, with the file's key that holds it.
    #[error("{key}: {error}")]
    Dimension {
        /// The key, e.g. `rb_mm`.
        key: String,
        /// The core's reason.
        error: GeometryError,
    },
    /// Dimensions that cannot be assembled (no one key is at fault).
    #[error("{0}")]
    Geometry(GeometryError),
    /// A value no robot of this family has: most often metres in a millimetre key.
    #[error(transparent)]
    Implausible(#[from] crate::plausible::Implausible),
    /// A per-chain geometry file's problem.
    #[error(transparent)]
    PerChain(#[from] crate::per_chain_file::PerChainTextError),
}

impl From<GeometryError> for GeometryTextError {
    /// Names the key of the file that holds the field the core refuses (`rb` -> `rb_mm`).
    fn from(error: GeometryError) -> Self {
        match error {
            GeometryError::NonFinite { field } | GeometryError::NotPositive { field, .. } => {
                GeometryTextError::Dimension {
                    key: format!("{field}_mm"),
                    error,
                }
            }
            GeometryError::NotUnit { field, .. } | GeometryError::AxisOutOfRange { field } => {
                GeometryTextError::Dimension {
                    key: field.to_string(),
                    error,
                }
            }
            GeometryError::NotAssemblable { .. } => GeometryTextError::Geometry(error),
        }
    }
}

/// A geometry file that cannot be read or is invalid; names the file.
#[derive(Debug, Error)]
pub enum GeometryFileError {
    #[error("geometry file {}: cannot read: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("geometry file {}: {error}", path.display())]
    Invalid {
        path: PathBuf,
        error: GeometryTextError,
    },
}

/// Checks the positive, finite dimensions against their plausible ranges (the others are
/// left to the core, whose reasons name them: negative, not finite).
fn plausible(dims: &[(&str, f64, PlausibleRange)]) -> Result<(), GeometryTextError> {
    for &(key, v, range) in dims {
        if v.is_finite() && v > 0.0 {
            range.check(key, v)?;
        }
    }
    Ok(())
}

/// Parses and validates the text of a geometry file; messages name the key or value but
/// not the file (see [`load`]).
pub fn parse(text: &str) -> Result<Robot<f64>, GeometryTextError> {
    if crate::per_chain_file::is_per_chain(text) {
        return Ok(Robot::RsprPerChain(crate::per_chain_file::parse(text)?.0));
    }
    // Two passes, so that the second deserialises straight from the text and its errors
    // keep their position (an internally tagged enum would buffer and lose it).
    let located = |e: toml::de::Error| TomlError::located(text, &e);
    let header: Header = toml::from_str(text).map_err(located)?;
    match header.robot {
        Architecture::Rspr => {
            let g: RsprFile = toml::from_str(text).map_err(located)?;
            plausible(&[
                ("e_mm", g.e_mm, DIMENSION_OR_ZERO),
                ("rb_mm", g.rb_mm, DIMENSION),
                ("rp_mm", g.rp_mm, DIMENSION),
                ("hc_mm", g.hc_mm, DIMENSION),
            ])?;
            Ok(RsprGeometry::new(
                mm_to_m(g.e_mm),
                mm_to_m(g.rb_mm),
                mm_to_m(g.rp_mm),
                mm_to_m(g.hc_mm),
            )
            .map(Robot::Rspr)?)
        }
        Architecture::Usr => {
            let g: UsrFile = toml::from_str(text).map_err(located)?;
            plausible(&[
                ("e_mm", g.e_mm, DIMENSION_OR_ZERO),
                ("rp_mm", g.rp_mm, DIMENSION),
                ("l1_mm", g.l1_mm, DIMENSION),
                ("l2_mm", g.l2_mm, DIMENSION),
                ("hc_mm", g.hc_mm, DIMENSION),
            ])?;
            Ok(UsrGeometry::new(
                mm_to_m(g.e_mm),
                mm_to_m(g.rp_mm),
                mm_to_m(g.l1_mm),
                mm_to_m(g.l2_mm),
                mm_to_m(g.hc_mm),
            )
            .map(Robot::Usr)?)
        }
    }
}

/// Loads a per-chain geometry file with its calibration table (what the board is sent).
/// Errors read `geometry file PATH: ...`.
pub fn load_per_chain(
    path: &Path,
) -> Result<
    (
        kinematics_core::PerChainGeometry<f64>,
        crate::per_chain_file::CalibrationInfo,
    ),
    GeometryFileError,
> {
    let text = std::fs::read_to_string(path).map_err(|source| GeometryFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    crate::per_chain_file::parse(&text).map_err(|e| GeometryFileError::Invalid {
        path: path.to_path_buf(),
        error: GeometryTextError::PerChain(e),
    })
}

/// Loads a geometry file. Errors read `geometry file PATH: ...`.
pub fn load(path: &Path) -> Result<Robot<f64>, GeometryFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| GeometryFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text).map_err(|error| GeometryFileError::Invalid {
        path: path.to_path_buf(),
        error,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn shipped_reference_files_equal_the_built_in_references() {
        let rspr = parse(include_str!("../geometry/reference-rspr.toml")).unwrap();
        assert_eq!(rspr, Robot::Rspr(RsprGeometry::reference()));
        let usr = parse(include_str!("../geometry/reference-usr.toml")).unwrap();
        assert_eq!(usr, Robot::Usr(UsrGeometry::reference()));
    }

    #[test]
    fn a_geometry_in_metres_is_refused_with_the_reason() {
        let e = parse("robot = \"rspr\"\ne_mm = 0.02\nrb_mm = 0.09\nrp_mm = 0.05\nhc_mm = 0.16\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("rb_mm = 0.09"), "{e}");
        assert!(e.contains("looks like metres (90 mm)"), "{e}");
        let e = parse(
            "robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nl2_mm = 80\nhc_mm = 80000\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("hc_mm = 80000 is outside the plausible range"),
            "{e}"
        );
    }

    #[test]
    fn errors_name_the_key() {
        let e =
            parse("robot = \"rspr\"\ne_mm = 20\nrb_mm = 90\nrp_mm = 50\nhc_mm = 160\nfoo_mm = 1\n")
                .unwrap_err()
                .to_string();
        assert!(e.contains("line 6") && e.contains("foo_mm"), "{e}");
        let e = parse("robot = \"rspr\"\ne_mm = 20\nrb_mm = -90\nrp_mm = 50\nhc_mm = 160\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("rb_mm: ") && e.contains("-90"), "{e}");
        let e = parse("robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nhc_mm = 80\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("l2_mm"), "{e}");
        let e = parse("robot = \"delta\"\n").unwrap_err().to_string();
        assert!(e.contains("delta"), "{e}");
        let e =
            parse("robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nl2_mm = 80\nhc_mm = 500\n")
                .unwrap_err()
                .to_string();
        assert!(e.contains("cannot be assembled"), "{e}");
    }

    #[test]
    fn a_refused_dimension_carries_its_key_and_the_core_reason() {
        let e = parse("robot = \"rspr\"\ne_mm = 20\nrb_mm = -90\nrp_mm = 50\nhc_mm = 160\n")
            .unwrap_err();
        match e {
            GeometryTextError::Dimension { key, error } => {
                assert_eq!(key, "rb_mm");
                assert!(matches!(
                    error,
                    GeometryError::NotPositive { field: "rb", .. }
                ));
            }
            other => panic!("{other:?}"),
        }
    }
}
