//! The parser of the edge's input values: column names of the CSV edge, a row's fields
//! found by column name ([`Row`]), the checks of one value (a finite number, a branch
//! 0..=7) and the readers that turn a row's fields into the core's SI types. The command
//! line reads text through it; the Python module checks its numbers with the same
//! functions ([`finite`], [`branch_from_bits`]), so both refuse the same values with the
//! same words. Every name carries its unit (CONVENTIONS.md, "Units"); the pose and joint
//! names and their conversions are [`crate::edge`]'s.

use crate::edge::{joint_columns, joints_from_edge, pose_from_edge, EdgeError, POSE};
use kinematics_core::{Branch, Joints, Pose, Robot, Wrench};
use thiserror::Error;

/// The initial pose of the forward kinematics (same units as [`POSE`]).
pub const INITIAL_POSE: [&str; 6] = ["x0_mm", "y0_mm", "z0_mm", "rx0_deg", "ry0_deg", "rz0_deg"];
/// The inverse-kinematics branch, 0..=7 (CONVENTIONS.md, "Branches").
pub const BRANCH: &str = "branch";
/// The wrench the platform exerts on its environment, moment about o_p, in {0}.
pub const WRENCH: [&str; 6] = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"];

/// A field of a row (or a value of a flag) that is not what its column needs; names the
/// column.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum FieldError {
    #[error("{column}: empty")]
    Empty { column: String },
    #[error("{column}: \"{text}\" is not a finite number")]
    NotFinite { column: String, text: String },
    #[error("{column}: \"{text}\" is not a number")]
    NotANumber { column: String, text: String },
    #[error("{column}: missing")]
    Missing { column: String },
    #[error("{BRANCH}: \"{text}\" is not an integer 0..=7")]
    BranchNotInteger { text: String },
    #[error("{BRANCH}: {bits} is out of range 0..=7")]
    BranchOutOfRange { bits: i64 },
    /// Values that do not make a pose.
    #[error(transparent)]
    Pose(#[from] EdgeError),
    /// Some but not all initial-pose columns.
    #[error("{0} (give all six initial-pose columns or none)")]
    PartialInitialPose(Box<FieldError>),
}

/// One input row, its fields found by column name.
#[derive(Clone, Copy, Debug)]
pub struct Row<'a> {
    header: &'a [String],
    fields: &'a [String],
}

impl<'a> Row<'a> {
    /// A row of `fields` under `header` (extra or missing fields are tolerated here).
    pub fn new(header: &'a [String], fields: &'a [String]) -> Self {
        Row { header, fields }
    }

    /// The field of a column, if the column exists and the row has it.
    pub fn get(&self, column: &str) -> Option<&'a str> {
        let i = self.header.iter().position(|h| h == column)?;
        self.fields.get(i).map(String::as_str)
    }

    /// A required numeric field.
    pub fn number(&self, column: &str) -> Result<f64, FieldError> {
        match self.get(column) {
            Some(text) => parse_number(column, text),
            None => Err(FieldError::Missing {
                column: column.into(),
            }),
        }
    }

    /// Several required numeric fields; the first bad one is reported.
    pub fn numbers<const N: usize>(&self, columns: &[&str; N]) -> Result<[f64; N], FieldError> {
        let mut out = [0.0; N];
        for (o, c) in out.iter_mut().zip(columns.iter()) {
            *o = self.number(c)?;
        }
        Ok(out)
    }
}

/// Parses one numeric field; the message names the column.
pub fn parse_number(column: &str, text: &str) -> Result<f64, FieldError> {
    let text = text.trim();
    if text.is_empty() {
        return Err(FieldError::Empty {
            column: column.into(),
        });
    }
    match text.parse::<f64>() {
        // The text as typed ("nan", "inf"), not the number's own spelling.
        Ok(v) if !v.is_finite() => Err(FieldError::NotFinite {
            column: column.into(),
            text: text.into(),
        }),
        Ok(v) => Ok(v),
        Err(_) => Err(FieldError::NotANumber {
            column: column.into(),
            text: text.into(),
        }),
    }
}

/// A value of a column that must be a finite number (NaN and infinities are refused; the
/// message spells the value as Rust prints it: "NaN", "inf").
pub fn finite(column: &str, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(FieldError::NotFinite {
            column: column.into(),
            text: v.to_string(),
        })
    }
}

/// Values of several columns that must be finite numbers; the first bad one is reported.
pub fn finite_values<const N: usize>(
    columns: &[&str; N],
    values: [f64; N],
) -> Result<[f64; N], FieldError> {
    for (c, v) in columns.iter().zip(values) {
        finite(c, v)?;
    }
    Ok(values)
}

/// A branch from its number 0..=7.
pub fn branch_from_bits(bits: i64) -> Result<Branch, FieldError> {
    u32::try_from(bits)
        .ok()
        .and_then(|b| Branch::new(b).ok())
        .ok_or(FieldError::BranchOutOfRange { bits })
}

/// Parses a branch number 0..=7.
pub fn parse_branch(text: &str) -> Result<Branch, FieldError> {
    let text = text.trim();
    if text.is_empty() {
        return Err(FieldError::Empty {
            column: BRANCH.into(),
        });
    }
    let bits: u32 = text
        .parse()
        .map_err(|_| FieldError::BranchNotInteger { text: text.into() })?;
    branch_from_bits(i64::from(bits))
}

/// Checks one field of a column this module knows (the branch or a number).
pub fn check_field(column: &str, text: &str) -> Result<(), FieldError> {
    if column == BRANCH {
        parse_branch(text).map(|_| ())
    } else {
        parse_number(column, text).map(|_| ())
    }
}

/// The pose columns of a row, in SI.
pub fn read_pose(row: &Row<'_>) -> Result<Pose<f64>, FieldError> {
    Ok(pose_from_edge(&POSE, row.numbers(&POSE)?)?)
}

/// The branch column of a row.
pub fn read_branch(row: &Row<'_>) -> Result<Branch, FieldError> {
    match row.get(BRANCH) {
        Some(text) => parse_branch(text),
        None => Err(FieldError::Missing {
            column: BRANCH.into(),
        }),
    }
}

/// The joint columns of a row, in SI.
pub fn read_joints(row: &Row<'_>, robot: &Robot<f64>) -> Result<Joints<f64>, FieldError> {
    Ok(joints_from_edge(
        robot,
        row.numbers(&joint_columns(robot.kind()))?,
    ))
}

/// The wrench columns of a row (N, N m).
pub fn read_wrench(row: &Row<'_>) -> Result<Wrench<f64>, FieldError> {
    Ok(Wrench::from(row.numbers(&WRENCH)?))
}

/// The optional initial pose of a row: `None` when all six columns are absent or empty.
pub fn read_initial_pose(row: &Row<'_>) -> Result<Option<Pose<f64>>, FieldError> {
    let given = INITIAL_POSE
        .iter()
        .any(|c| row.get(c).is_some_and(|t| !t.trim().is_empty()));
    if !given {
        return Ok(None);
    }
    let values = row
        .numbers(&INITIAL_POSE)
        .map_err(|e| FieldError::PartialInitialPose(Box::new(e)))?;
    Ok(Some(pose_from_edge(&INITIAL_POSE, values)?))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// A number read from text and the same number given as a value are refused with the
    /// same words (the command line and the Python module share them).
    #[test]
    fn text_and_values_are_refused_alike() {
        for (text, v) in [
            ("NaN", f64::NAN),
            ("inf", f64::INFINITY),
            ("-inf", f64::NEG_INFINITY),
        ] {
            let from_text = parse_number("z_mm", text).unwrap_err();
            let from_value = finite("z_mm", v).unwrap_err();
            assert_eq!(from_text, from_value);
        }
        assert_eq!(finite("z_mm", 160.0), Ok(160.0));
        assert_eq!(parse_number("z_mm", " 160 "), Ok(160.0));
        // The command line quotes what the user typed.
        assert_eq!(
            parse_number("z_mm", "nan").unwrap_err().to_string(),
            "z_mm: \"nan\" is not a finite number"
        );
    }

    /// Branches 0..=7 only, from text or from a number, with the same words.
    #[test]
    fn branches_are_checked_alike() {
        assert_eq!(parse_branch("5").unwrap(), branch_from_bits(5).unwrap());
        assert_eq!(
            parse_branch("8").unwrap_err(),
            branch_from_bits(8).unwrap_err()
        );
        assert_eq!(
            branch_from_bits(-1).unwrap_err().to_string(),
            "branch: -1 is out of range 0..=7"
        );
        assert_eq!(
            parse_branch("x").unwrap_err().to_string(),
            "branch: \"x\" is not an integer 0..=7"
        );
    }
}
