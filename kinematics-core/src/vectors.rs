//! The six-component vectors of the robot: the joints in `q` order, the platform's twist
//! and the wrench it exerts (`CONVENTIONS.md`: joints, pose and twist, forces).

/// Joint vector, in `q` order (see the crate docs).
pub type Joints<T> = nalgebra::Vector6<T>;
/// Wrench `[f; t]` exerted by the platform on its environment, moment about o_p, in {0}.
pub type Wrench<T> = nalgebra::Vector6<T>;
/// Twist `[v; ω]` of the platform in {0}.
pub type Twist<T> = nalgebra::Vector6<T>;
