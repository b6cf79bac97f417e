//! The values of the command line's flags: comma-separated numbers, grids, scan ranges, and
//! the task-box flags shared by `report`, `ranges` and `workspace`.

use crate::columns::{parse_number, FieldError};
use design::synth::{range_values, RangeError};
use kinematics_core::RobotKind;
use robot_config::task_box::{TaskBox, TaskBoxError};
use thiserror::Error;

/// A flag whose value cannot be used; names the flag.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum FlagError {
    #[error("{flag}: expected {count} comma-separated numbers, got {given}")]
    Count {
        flag: &'static str,
        count: usize,
        given: usize,
    },
    /// A value that is not a number, or a branch that is not one (the message names the
    /// flag or the column).
    #[error(transparent)]
    Number(#[from] FieldError),
    /// A value of a flag, named by the flag.
    #[error("{flag}: {error}")]
    Field {
        flag: &'static str,
        error: FieldError,
    },
    #[error(transparent)]
    Grid(#[from] TaskBoxError),
    #[error(transparent)]
    Range(#[from] RangeError),
    /// A value out of its range, or a flag that does not go with the others.
    #[error("{flag}: {reason}")]
    Invalid { flag: &'static str, reason: String },
    #[error("{flag} does not apply to the {kind:?} robot")]
    NotForRobot { flag: &'static str, kind: RobotKind },
}

/// Splits a flag's comma-separated numbers; messages name the flag.
pub fn numbers<const N: usize>(flag: &'static str, text: &str) -> Result<[f64; N], FlagError> {
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() != N {
        return Err(FlagError::Count {
            flag,
            count: N,
            given: parts.len(),
        });
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(parts) {
        *o = parse_number(flag, p)?;
    }
    Ok(out)
}

/// A grid `NX,NY,NZ` of whole numbers 1..=1000.
pub fn grid(flag: &'static str, text: &str) -> Result<[usize; 3], FlagError> {
    Ok(TaskBox::grid_from(flag, numbers(flag, text)?)?)
}

/// The values from, from + step, ... <= to of a `FROM,TO,STEP` flag (mm, from >= 0, at
/// most 1001 values).
pub fn steps(flag: &'static str, text: &str) -> Result<Vec<f64>, FlagError> {
    Ok(range_values(flag, numbers(flag, text)?)?)
}

/// `--min-inv-cond`: a number >= 0.
pub fn min_inv_cond(value: f64) -> Result<f64, FlagError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(FlagError::Invalid {
            flag: "--min-inv-cond",
            reason: format!("{value} is not a number >= 0"),
        })
    }
}

/// The task-box flags shared by `report`, `ranges` and `workspace`.
#[derive(Debug, clap::Args)]
pub struct TaskBoxArgs {
    /// Edge lengths of the task box centred at [0, 0, hc], mm.
    #[arg(
        long = "box",
        value_name = "DX_MM,DY_MM,DZ_MM",
        default_value = "40,40,20"
    )]
    pub box_mm: String,
    /// Tilt of the second task orientation: the platform rotated by this angle about
    /// [1,1,0]/sqrt(2) (rotation vector), deg.
    #[arg(
        long,
        value_name = "DEG",
        default_value = "20",
        allow_hyphen_values = true
    )]
    pub tilt_deg: String,
}

impl TaskBoxArgs {
    /// The task box on the grid of `--grid` (`grid`) with these flags.
    pub fn task_box(&self, grid_text: &str) -> Result<TaskBox, FlagError> {
        let grid = grid("--grid", grid_text)?;
        let box_mm: [f64; 3] = numbers("--box", &self.box_mm)?;
        if box_mm.iter().any(|&b| b < 0.0) {
            return Err(FlagError::Invalid {
                flag: "--box",
                reason: "edge lengths must be >= 0 mm".into(),
            });
        }
        let [tilt_deg] = numbers("--tilt-deg", &self.tilt_deg)?;
        Ok(TaskBox {
            grid,
            box_mm,
            tilt_deg,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn grid_flags_are_checked() {
        assert_eq!(grid("--grid", "9,9,5").unwrap(), [9, 9, 5]);
        assert!(grid("--grid", "9,9").unwrap_err().to_string().contains("3"));
        assert!(grid("--grid", "0,9,5")
            .unwrap_err()
            .to_string()
            .contains("whole number"));
        assert!(grid("--grid", "2.5,9,5")
            .unwrap_err()
            .to_string()
            .contains("whole number"));
    }

    #[test]
    fn number_lists_name_the_flag() {
        assert_eq!(
            numbers::<3>("--box", "40,x,20").unwrap_err().to_string(),
            "--box: \"x\" is not a number"
        );
        assert_eq!(
            numbers::<2>("--z", "1,2,3").unwrap_err().to_string(),
            "--z: expected 2 comma-separated numbers, got 3"
        );
        assert_eq!(steps("--e-mm", "10,30,10").unwrap(), vec![10.0, 20.0, 30.0]);
        assert!(steps("--e-mm", "30,10,10")
            .unwrap_err()
            .to_string()
            .starts_with("--e-mm: need [from, to, step]"));
    }
}
