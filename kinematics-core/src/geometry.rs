//! Robot geometries, validated on construction, and the reference robots. A robot whose
//! architecture is chosen at run time is a [`crate::robot::Robot`].

use crate::branch::Branch;
use crate::ik::{inverse, IkError};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::{lit, to_f64, Real};
use core::fmt;

/// A geometry that cannot be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GeometryError {
    /// A dimension is NaN or infinite.
    NonFinite { field: &'static str },
    /// A dimension is zero or negative where it must be positive (or negative where it
    /// must be non-negative).
    NotPositive { field: &'static str, value_m: f64 },
    /// The robot cannot be assembled in its central configuration on some branch.
    NotAssemblable { branch: Branch, error: IkError },
    /// A direction given as a unit vector is not one (per-chain geometry).
    NotUnit { field: &'static str, norm: f64 },
    /// A rotating link's axis is more than 60 deg from z0, so the zero of its angle is
    /// undefined (per-chain geometry).
    AxisOutOfRange { field: &'static str },
}

impl fmt::Display for GeometryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GeometryError::NonFinite { field } => write!(f, "{field} is not finite"),
            GeometryError::NotPositive { field, value_m } => {
                write!(f, "{field} must be positive, got {} mm", value_m * 1e3)
            }
            GeometryError::NotAssemblable { branch, error } => write!(
                f,
                "cannot be assembled in the central configuration on branch {branch}: {error}"
            ),
            GeometryError::NotUnit { field, norm } => {
                write!(f, "{field} must be a unit vector, its norm is {norm}")
            }
            GeometryError::AxisOutOfRange { field } => {
                write!(f, "{field} is more than 60 deg from z0")
            }
        }
    }
}

fn check_dim<T: Real>(field: &'static str, v: T, allow_zero: bool) -> Result<(), GeometryError> {
    if !v.is_finite() {
        return Err(GeometryError::NonFinite { field });
    }
    let ok = if allow_zero {
        v >= T::zero()
    } else {
        v > T::zero()
    };
    if ok {
        Ok(())
    } else {
        Err(GeometryError::NotPositive {
            field,
            value_m: to_f64(v),
        })
    }
}

/// Whether the robot can be assembled in its central configuration on every branch.
pub(crate) fn check_central<T: Real, M: Mechanism<T>>(m: &M) -> Result<(), GeometryError> {
    let central = Pose::central(m.hc());
    for branch in Branch::ALL {
        inverse(m, &central, branch)
            .map_err(|error| GeometryError::NotAssemblable { branch, error })?;
    }
    Ok(())
}

/// RSPR dimensions (thesis Fig. 8.2a), metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RsprGeometry<T: Real> {
    /// Eccentricity e: distance of the rotating links' axes from the base centre (≥ 0).
    pub e: T,
    /// Length rb of the rotating links.
    pub rb: T,
    /// Platform radius rp.
    pub rp: T,
    /// Central height hc.
    pub hc: T,
}

impl<T: Real> RsprGeometry<T> {
    /// A validated geometry: every dimension finite, e ≥ 0, the others > 0, and the central
    /// configuration solvable on all 8 branches.
    pub fn new(e: T, rb: T, rp: T, hc: T) -> Result<Self, GeometryError> {
        check_dim("e", e, true)?;
        check_dim("rb", rb, false)?;
        check_dim("rp", rp, false)?;
        check_dim("hc", hc, false)?;
        let g = RsprGeometry { e, rb, rp, hc };
        check_central(&g)?;
        Ok(g)
    }

    /// The prototype of thesis chapter 11 (Table 11.1): e = 20, rb = 90, rp = 50,
    /// hc = 160 mm. Validated by a test (`reference_geometries_validate`).
    pub fn reference() -> Self {
        RsprGeometry {
            e: lit(0.020),
            rb: lit(0.090),
            rp: lit(0.050),
            hc: lit(0.160),
        }
    }
}

/// USR dimensions (thesis Fig. 8.2b), metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UsrGeometry<T: Real> {
    /// Eccentricity e: distance of the universal joints from the base centre (≥ 0).
    pub e: T,
    /// Platform radius rp.
    pub rp: T,
    /// Lower link length l1.
    pub l1: T,
    /// Upper link length l2.
    pub l2: T,
    /// Central height hc.
    pub hc: T,
}

impl<T: Real> UsrGeometry<T> {
    /// A validated geometry (see [`RsprGeometry::new`]).
    pub fn new(e: T, rp: T, l1: T, l2: T, hc: T) -> Result<Self, GeometryError> {
        check_dim("e", e, true)?;
        check_dim("rp", rp, false)?;
        check_dim("l1", l1, false)?;
        check_dim("l2", l2, false)?;
        check_dim("hc", hc, false)?;
        let g = UsrGeometry { e, rp, l1, l2, hc };
        check_central(&g)?;
        Ok(g)
    }

    /// The USR of the thesis's Appendix A, Table 4.1: rp = 30, e = 30, hc = 80, l1 = 60,
    /// l2 = 80 mm. Validated by a test (`reference_geometries_validate`).
    pub fn reference() -> Self {
        UsrGeometry {
            e: lit(0.030),
            rp: lit(0.030),
            l1: lit(0.060),
            l2: lit(0.080),
            hc: lit(0.080),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_geometries_validate() {
        let r = RsprGeometry::<f64>::reference();
        assert_eq!(RsprGeometry::new(r.e, r.rb, r.rp, r.hc), Ok(r));
        let u = UsrGeometry::<f64>::reference();
        assert_eq!(UsrGeometry::new(u.e, u.rp, u.l1, u.l2, u.hc), Ok(u));
        let r32 = RsprGeometry::<f32>::reference();
        assert!(RsprGeometry::new(r32.e, r32.rb, r32.rp, r32.hc).is_ok());
    }

    #[test]
    fn bad_dimensions_are_named() {
        assert_eq!(
            RsprGeometry::new(0.02, f64::NAN, 0.05, 0.16),
            Err(GeometryError::NonFinite { field: "rb" })
        );
        assert!(matches!(
            RsprGeometry::new(0.02, 0.09, -0.05, 0.16),
            Err(GeometryError::NotPositive { field: "rp", .. })
        ));
        // A platform far above the reach of the links cannot be assembled.
        assert!(matches!(
            UsrGeometry::new(0.03, 0.03, 0.06, 0.08, 0.5),
            Err(GeometryError::NotAssemblable { .. })
        ));
    }
}
