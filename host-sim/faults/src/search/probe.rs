//! What the search reads of the simulated board: the board's outputs (the driver enable,
//! the brakes), the robot's truth (the platform's pose and speed, the load-side joints,
//! hard-stop contact), the status the board reports. Nothing else of the board
//! application's internals: porting the search to another version of the board
//! application means changing this module alone.

use board_on_plant::AtStop;
use master_link::{RobotState, StatusReport};
use nalgebra::Vector3;
use simulation::board::BoardSim;

/// The status the board reports now.
pub fn status(b: &BoardSim) -> StatusReport {
    b.runtime().status()
}

/// The state the board reports now.
pub fn state(b: &BoardSim) -> RobotState {
    b.runtime().state()
}

/// The park pose's position (the central pose: o_p at [0, 0, hc]), m.
pub fn park_position(b: &BoardSim) -> Vector3<f64> {
    let _ = b;
    Vector3::new(
        0.0,
        0.0,
        kinematics_core::RsprGeometry::<f64>::reference().hc,
    )
}

/// The board has its references (homed): what its `Ready` state and every state after
/// it report.
pub fn homed(b: &BoardSim) -> bool {
    b.runtime().homed()
}

/// The MCU's driver enable output.
pub fn drives_on(b: &BoardSim) -> bool {
    b.hw.enabled
}

/// The drivers have their supply and are enabled: a motor can be driven (the safety
/// relay closed, the MCU's enable high).
pub fn powered(b: &BoardSim) -> bool {
    b.hw.enabled && !b.hw.relay_open()
}

/// The duty each bridge applies now.
pub fn duties(b: &BoardSim) -> [f64; 6] {
    b.hw.plant.duty()
}

/// Either brake group's coils powered (released) by the MCU.
pub fn brakes_released(b: &BoardSim) -> bool {
    b.hw.brakes_released || b.hw.link_brakes_released
}

/// The platform's true position, m, and speed, m/s.
pub fn platform(b: &BoardSim) -> (Vector3<f64>, f64) {
    let t = b.truth();
    (t.pose.t, t.velocity.norm())
}

/// The true load-side joints and their speeds.
pub fn joints(b: &BoardSim) -> ([f64; 6], [f64; 6]) {
    (b.truth().q, b.hw.plant.joint_velocities())
}

/// Each joint against a hard stop now (the plant's stop holds its load side).
pub fn at_hard_stop(b: &BoardSim) -> [bool; 6] {
    b.hw.at_stop()
        .map(|s| matches!(s, Some(AtStop::Lower | AtStop::Upper)))
}

/// Each joint's measured current as a fraction of its peak rating.
pub fn current_fraction(b: &BoardSim) -> [f64; 6] {
    let rt = b.runtime();
    let i = rt.inputs().currents;
    std::array::from_fn(|j| i[j].abs() / rt.monitors().current.peak_current(j))
}

/// The safety relay is open (the drivers' and the brakes' supply cut).
pub fn relay_open(b: &BoardSim) -> bool {
    b.hw.relay_open()
}

/// The e-stop button is pressed.
pub fn button(b: &BoardSim) -> bool {
    b.hw.estop
}
