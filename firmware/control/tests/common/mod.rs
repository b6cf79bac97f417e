//! The plant model behind the hardware traits (`sim/board-on-plant`), shared by the
//! integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::indexing_slicing)]

use board_on_plant::{BoardOnPlant, Layout, ReferenceMechanics};
use hal::QuadratureCounter;
use plant::{Plant, PlantConfig};

/// The plant with the board around it (`sim/board-on-plant`): drives, brakes, the safety
/// chain, switches and hard stops.
pub type PlantHw = BoardOnPlant;

/// The default plant at rest at `q` (brakes holding), drives off, no switches or stops.
pub fn plant_hw(q: [f64; 6]) -> PlantHw {
    BoardOnPlant::at_rest(Plant::new(&PlantConfig::default()).unwrap(), q).unwrap()
}

/// The reference robot's central joints (branch 0).
pub fn central_q() -> [f64; 6] {
    use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
    let g = RsprGeometry::<f64>::reference();
    let q = inverse(&g, &Pose::central(g.hc), Branch::OUTER)
        .unwrap()
        .q();
    std::array::from_fn(|j| q[j])
}

/// The homing fixture: the plant with the switches and hard stops where the reference
/// mechanics put them (`board_on_plant::Layout::reference`: the legs' home switches at
/// 143 mm, the links' hard stops 85 deg below and above the central angles), started at
/// leg lengths `legs` and the links `above_stops` rad above their lower stops; and the
/// reference runtime configuration for that rest position. Returns the plant, the central
/// joints and the configuration.
pub fn homing_fixture(
    legs: [f64; 3],
    above_stops: [f64; 3],
) -> (PlantHw, [f64; 6], control::runtime::RuntimeConfig<f64>) {
    let c = central_q();
    let mech = control::runtime::reference_mechanics(&kinematics_core::guards::Limits::reference());
    let stops = [3, 4, 5].map(|j| c[j] - mech.link_stop_below_central_rad);
    let layout = Layout::reference(&ReferenceMechanics {
        central_q: c,
        leg_switch_m: mech.leg_switch_m,
        link_stop_below_central_rad: mech.link_stop_below_central_rad,
        range: mech.range,
    });
    let hw = plant_hw([
        legs[0],
        legs[1],
        legs[2],
        stops[0] + above_stops[0],
        stops[1] + above_stops[1],
        stops[2] + above_stops[2],
    ])
    .with_layout(&layout);
    let cfg = control::runtime::reference_config_for(
        &kinematics_core::RsprGeometry::reference(),
        kinematics_core::Branch::OUTER,
        None,
        Some(hw.plant.joint_positions()),
    )
    .unwrap();
    (hw, c, cfg)
}

/// The sensing of a robot homed at `q` on the plant `hw` (its counters read `q` now) with
/// the pose established: what the runtime has after homing.
pub fn homed_sensing(
    hw: &mut PlantHw,
    q: [f64; 6],
) -> control::Sensing<f64, kinematics_core::RsprGeometry<f64>> {
    control::Sensing::homed_at(
        kinematics_core::RsprGeometry::reference(),
        kinematics_core::Branch::OUTER,
        &Default::default(),
        Default::default(),
        hw.counts(),
        &q,
    )
    .unwrap()
}

/// The joint loads (N, N m, in +q) of the thesis tool (1.2 kg, its centre of mass 100 mm
/// from o_p along x_p) at the platform pose of the load-side joints `q`
/// (`board_on_plant::Platform`: -tau, tau = J^-T s_e, Eq. 7.10).
pub fn tool_loads(q: &[f64; 6]) -> [f64; 6] {
    let mut p = board_on_plant::Platform::new(*q, 0.0).unwrap();
    p.tool = Some(board_on_plant::Tool::THESIS);
    p.joint_loads().unwrap()
}

/// The true platform pose of the plant's load-side joints.
pub fn true_pose(hw: &PlantHw) -> kinematics_core::Pose<f64> {
    *board_on_plant::Platform::new(hw.plant.joint_positions(), 0.0)
        .unwrap()
        .pose()
}
