//! The robot and the limits a host tool works with, each with where it came from (for
//! reports): a built-in reference robot or a geometry file; the reference limits or a
//! limits file.

use crate::geometry_file::{self, GeometryFileError};
use crate::limits_file::{self, LimitsFileError};
use kinematics_core::guards::Limits;
use kinematics_core::{Robot, RobotKind, RsprGeometry, UsrGeometry};
use std::path::Path;

/// A built-in robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuiltinRobot {
    /// The RSPR prototype of thesis chapter 11 (Table 11.1): e 20, rb 90, rp 50, hc 160 mm.
    Rspr,
    /// The USR of thesis Appendix A (Table 4.1): e 30, rp 30, l1 60, l2 80, hc 80 mm.
    Usr,
}

/// The robot a tool works on and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct SelectedRobot {
    /// The validated geometry.
    pub robot: Robot<f64>,
    /// Where it came from, for reports.
    pub source: String,
}

impl SelectedRobot {
    /// A built-in reference robot.
    pub fn builtin(which: BuiltinRobot) -> Self {
        match which {
            BuiltinRobot::Rspr => SelectedRobot {
                robot: Robot::Rspr(RsprGeometry::reference()),
                source: "built-in reference RSPR prototype (thesis Table 11.1)".into(),
            },
            BuiltinRobot::Usr => SelectedRobot {
                robot: Robot::Usr(UsrGeometry::reference()),
                source: "built-in reference USR (thesis Appendix A, Table 4.1)".into(),
            },
        }
    }

    /// The robot of a geometry file.
    pub fn from_file(path: &Path) -> Result<Self, GeometryFileError> {
        Ok(SelectedRobot {
            robot: geometry_file::load(path)?,
            source: format!("geometry file {}", path.display()),
        })
    }
}

/// The limits the guards use and where they came from.
#[derive(Clone, Debug, PartialEq)]
pub struct SelectedLimits {
    /// The validated limits (SI).
    pub limits: Limits<f64>,
    /// Where they came from, for reports.
    pub source: String,
}

impl SelectedLimits {
    /// The reference limits ([`Limits::reference`]).
    pub fn reference() -> Self {
        SelectedLimits {
            limits: Limits::reference(),
            source: "built-in reference limits (Limits::reference())".into(),
        }
    }

    /// The limits of a limits file.
    pub fn from_file(path: &Path) -> Result<Self, LimitsFileError> {
        Ok(SelectedLimits {
            limits: limits_file::load(path)?,
            source: format!("limits file {}", path.display()),
        })
    }
}

/// The architecture's name for people: `RSPR` or `USR`.
pub fn kind_name(kind: RobotKind) -> &'static str {
    match kind {
        RobotKind::Rspr => "RSPR",
        RobotKind::Usr => "USR",
    }
}
