//! The scalar of the control application: a nalgebra real that is also a `num_traits`
//! float (in practice `f32` on the MCU, `f64` on the host), and the literals in it.

use kinematics_core::Real;
use num_traits::Float;

/// The control application's scalar.
pub trait Scalar: Real + Float {}
impl<S: Real + Float> Scalar for S {}

/// `x` in the scalar type (`S::from` of a literal; 0 if it cannot be represented, which
/// for `f32` and `f64` never happens).
pub fn lit<S: Float>(x: f64) -> S {
    S::from(x).unwrap_or_else(S::zero)
}
