//! Geometry files: a robot's dimensions in TOML, millimetres, unit-suffixed keys.
//!
//! ```toml
//! robot = "rspr"   # or "usr"
//! e_mm = 20.0      # RSPR: e_mm, rb_mm, rp_mm, hc_mm; USR: e_mm, rp_mm, l1_mm, l2_mm, hc_mm
//! ```
//!
//! Unknown keys are rejected, and every error names the file and the key or value.

use crate::units::mm_to_m;
use kinematics_core::{GeometryError, Robot, RsprGeometry, UsrGeometry};
use serde::Deserialize;
use std::path::Path;

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

/// The key of the file that holds a core geometry field (`rb` -> `rb_mm`).
fn key_of(error: &GeometryError) -> Option<String> {
    match error {
        GeometryError::NonFinite { field } | GeometryError::NotPositive { field, .. } => {
            Some(format!("{field}_mm"))
        }
        GeometryError::NotAssemblable { .. } => None,
    }
}

/// Where a byte offset lies in `text`: its 1-based line number and the line's text.
fn line_at(text: &str, offset: usize) -> (usize, &str) {
    let start = text
        .get(..offset)
        .and_then(|b| b.rfind('\n'))
        .map_or(0, |i| i + 1);
    let number = text.get(..start).map_or(0, |b| b.matches('\n').count()) + 1;
    let line = text
        .get(start..)
        .and_then(|rest| rest.lines().next())
        .unwrap_or("");
    (number, line.trim())
}

/// A TOML error of `text` with the line it points at: "line N `key = value`: message".
/// Shared by the geometry and limits files.
pub(crate) fn located(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().to_string();
    match e.span() {
        Some(span) => {
            let (number, line) = line_at(text, span.start);
            format!("line {number} `{line}`: {message}")
        }
        None => message,
    }
}

/// Parses and validates the text of a geometry file; messages name the key or value but
/// not the file (see [`load`]).
pub fn parse(text: &str) -> Result<Robot<f64>, String> {
    // Two passes, so that the second deserialises straight from the text and its errors
    // keep their position (an internally tagged enum would buffer and lose it).
    let located = |e: toml::de::Error| located(text, &e);
    let header: Header = toml::from_str(text).map_err(located)?;
    let checked = |error: GeometryError| match key_of(&error) {
        Some(key) => format!("{key}: {error}"),
        None => error.to_string(),
    };
    match header.robot {
        Architecture::Rspr => {
            let g: RsprFile = toml::from_str(text).map_err(located)?;
            RsprGeometry::new(
                mm_to_m(g.e_mm),
                mm_to_m(g.rb_mm),
                mm_to_m(g.rp_mm),
                mm_to_m(g.hc_mm),
            )
            .map(Robot::Rspr)
            .map_err(checked)
        }
        Architecture::Usr => {
            let g: UsrFile = toml::from_str(text).map_err(located)?;
            UsrGeometry::new(
                mm_to_m(g.e_mm),
                mm_to_m(g.rp_mm),
                mm_to_m(g.l1_mm),
                mm_to_m(g.l2_mm),
                mm_to_m(g.hc_mm),
            )
            .map(Robot::Usr)
            .map_err(checked)
        }
    }
}

/// Loads a geometry file. Errors read `geometry file PATH: ...`.
pub fn load(path: &Path) -> Result<Robot<f64>, String> {
    let shown = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("geometry file {shown}: cannot read: {e}"))?;
    parse(&text).map_err(|e| format!("geometry file {shown}: {e}"))
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
    fn errors_name_the_key() {
        let e =
            parse("robot = \"rspr\"\ne_mm = 20\nrb_mm = 90\nrp_mm = 50\nhc_mm = 160\nfoo_mm = 1\n")
                .unwrap_err();
        assert!(e.contains("line 6") && e.contains("foo_mm"), "{e}");
        let e = parse("robot = \"rspr\"\ne_mm = 20\nrb_mm = -90\nrp_mm = 50\nhc_mm = 160\n")
            .unwrap_err();
        assert!(e.starts_with("rb_mm: ") && e.contains("-90"), "{e}");
        let e =
            parse("robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nhc_mm = 80\n").unwrap_err();
        assert!(e.contains("l2_mm"), "{e}");
        let e = parse("robot = \"delta\"\n").unwrap_err();
        assert!(e.contains("delta"), "{e}");
        let e =
            parse("robot = \"usr\"\ne_mm = 30\nrp_mm = 30\nl1_mm = 60\nl2_mm = 80\nhc_mm = 500\n")
                .unwrap_err();
        assert!(e.contains("cannot be assembled"), "{e}");
    }
}
