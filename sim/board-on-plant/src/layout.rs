//! Where the robot's switches and hard stops are: the firmware's reference mechanics,
//! handed in as plain data, turned into positions on the joints.

use plant::NUM_JOINTS;

/// The firmware's reference mechanics as plain data (what
/// `control::runtime::reference_mechanics` returns for the reference robot, with its
/// central joints): this crate does not depend on the control application, whose own
/// tests run on it. Joint units: m (legs), rad (links).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceMechanics {
    /// The joints at the central configuration.
    pub central_q: [f64; NUM_JOINTS],
    /// The legs' home switches are actuated at and below this length.
    pub leg_switch_m: f64,
    /// The links' hard stops are this far below (and above) their central angles.
    pub link_stop_below_central_rad: f64,
    /// Every joint's monitored range `[low, high]`: beyond it the firmware faults.
    pub range: [[f64; 2]; NUM_JOINTS],
}

/// The legs' end stops sit this far beyond the monitored range, m.
pub const LEG_STOP_BEYOND_RANGE_M: f64 = 0.001;

/// A link's limit switch is actuated this close to its lower hard stop, rad (2 deg).
pub const LINK_SWITCH_ABOVE_STOP_RAD: f64 = 2.0 * core::f64::consts::PI / 180.0;

/// Where each joint's switch and hard stops are (`None`: none). A switch is actuated (its
/// normally-closed contact open) at and below its position; a lower stop catches the load
/// side at and below its position, an upper one at and above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// Each joint's switch is actuated at and below this position.
    pub switch_below: [Option<f64>; NUM_JOINTS],
    /// Each joint's lower hard stop.
    pub stop_below: [Option<f64>; NUM_JOINTS],
    /// Each joint's upper hard stop.
    pub stop_above: [Option<f64>; NUM_JOINTS],
}

impl Layout {
    /// No switch and no stop anywhere (the bare plant).
    pub const NONE: Layout = Layout {
        switch_below: [None; NUM_JOINTS],
        stop_below: [None; NUM_JOINTS],
        stop_above: [None; NUM_JOINTS],
    };

    /// Where the firmware expects them: each leg's home switch at `leg_switch_m` (143 mm
    /// for the reference robot, 1 mm below the shortest stroke), each link's hard stops
    /// `link_stop_below_central_rad` below and above its central angle (85 deg) with a
    /// limit switch actuated within [`LINK_SWITCH_ABOVE_STOP_RAD`] of the lower one, and the
    /// legs' end stops [`LEG_STOP_BEYOND_RANGE_M`] beyond their monitored range, where the
    /// firmware never drives them in operation (a joint outside that range is a fault).
    pub fn reference(m: &ReferenceMechanics) -> Self {
        let mut l = Layout::NONE;
        for j in 0..NUM_JOINTS {
            let [low, high] = m.range[j];
            if j < 3 {
                l.switch_below[j] = Some(m.leg_switch_m);
                l.stop_below[j] = Some(low - LEG_STOP_BEYOND_RANGE_M);
                l.stop_above[j] = Some(high + LEG_STOP_BEYOND_RANGE_M);
            } else {
                let lower = m.central_q[j] - m.link_stop_below_central_rad;
                l.switch_below[j] = Some(lower + LINK_SWITCH_ABOVE_STOP_RAD);
                l.stop_below[j] = Some(lower);
                l.stop_above[j] = Some(m.central_q[j] + m.link_stop_below_central_rad);
            }
        }
        l
    }
}
