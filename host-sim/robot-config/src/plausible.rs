//! Plausible ranges of the values people type into geometry and limits files.
//!
//! A file's lengths are millimetres and its angles degrees (CONVENTIONS.md, "Units"). A
//! value in the wrong unit often still passes the core's checks (a base radius of 0.09 is
//! positive, a tilt limit of 0.52 is below 180), and the robot it describes is then a
//! thousand times too small or its limits sixty times too tight. Every such key has a
//! range that brackets any robot of this family (a few millimetres to two metres, one to
//! 180 degrees); a value outside it is refused with the reason, and a value below it that
//! would be plausible in metres (radians) says so.

use thiserror::Error;

/// The unit of a key, from its suffix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeUnit {
    /// `_mm`, `_mm_s`, `_mm_s2`: a length (or its rate) in millimetres.
    Millimetres,
    /// `_deg`, `_deg_s`, `_deg_s2`: an angle (or its rate) in degrees.
    Degrees,
}

/// The range a key's value must lie in, in the key's unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlausibleRange {
    pub min: f64,
    pub max: f64,
    pub unit: EdgeUnit,
}

impl PlausibleRange {
    /// A length range in millimetres.
    pub const fn mm(min: f64, max: f64) -> Self {
        PlausibleRange {
            min,
            max,
            unit: EdgeUnit::Millimetres,
        }
    }

    /// An angle range in degrees.
    pub const fn deg(min: f64, max: f64) -> Self {
        PlausibleRange {
            min,
            max,
            unit: EdgeUnit::Degrees,
        }
    }

    /// Checks `value` of `key`.
    pub fn check(&self, key: &str, value: f64) -> Result<(), Implausible> {
        if (self.min..=self.max).contains(&value) {
            return Ok(());
        }
        let scaled = match self.unit {
            EdgeUnit::Millimetres => value * 1e3,
            EdgeUnit::Degrees => value.to_degrees(),
        };
        let hint = (value.abs() < self.min.abs().max(1.0)
            && value != 0.0
            && (self.min..=self.max).contains(&scaled))
        .then(|| match self.unit {
            EdgeUnit::Millimetres => format!("{value} looks like metres ({scaled} mm)"),
            EdgeUnit::Degrees => format!("{value} looks like radians ({scaled:.3} deg)"),
        });
        Err(Implausible {
            key: key.to_string(),
            value,
            range: *self,
            hint,
        })
    }
}

/// A value outside its key's plausible range.
#[derive(Clone, Debug, PartialEq, Error)]
#[error(
    "{key} = {value} is outside the plausible range {} .. {} {}{}",
    range.min,
    range.max,
    match range.unit { EdgeUnit::Millimetres => "mm", EdgeUnit::Degrees => "deg" },
    hint.as_ref().map(|h| format!(": the file's values are {}, and {h}", match range.unit {
        EdgeUnit::Millimetres => "millimetres",
        EdgeUnit::Degrees => "degrees",
    })).unwrap_or_default()
)]
pub struct Implausible {
    /// The key, e.g. `rb_mm`.
    pub key: String,
    /// The value given.
    pub value: f64,
    /// The range it is outside.
    pub range: PlausibleRange,
    /// Why it is probably wrong, when a unit explains it.
    pub hint: Option<String>,
}

/// A dimension of a robot, mm: from 1 mm to 2 m.
pub const DIMENSION: PlausibleRange = PlausibleRange::mm(1.0, 2000.0);
/// A dimension that may be zero (the RSPR's eccentricity), mm.
pub const DIMENSION_OR_ZERO: PlausibleRange = PlausibleRange::mm(0.0, 2000.0);

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn metres_and_radians_are_named_and_millimetres_pass() {
        assert!(DIMENSION.check("rb_mm", 90.0).is_ok());
        let e = DIMENSION.check("rb_mm", 0.09).unwrap_err().to_string();
        assert!(e.contains("rb_mm = 0.09"), "{e}");
        assert!(e.contains("looks like metres (90 mm)"), "{e}");
        let e = PlausibleRange::deg(1.0, 180.0)
            .check("tilt_max_deg", 0.5)
            .unwrap_err()
            .to_string();
        assert!(e.contains("looks like radians (28.648 deg)"), "{e}");
        // Too large: no unit explains it, the range alone is the reason.
        let e = DIMENSION.check("hc_mm", 16000.0).unwrap_err();
        assert_eq!(e.hint, None);
        assert!(e.to_string().contains("1 .. 2000 mm"), "{e}");
    }
}
