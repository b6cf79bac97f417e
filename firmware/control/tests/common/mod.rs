//! The plant model behind the hardware traits, shared by the integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::indexing_slicing)]

use hal::{
    Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage, QuadratureCounter, SafetyChain,
};
use plant::{Plant, PlantConfig};

/// The plant behind the hardware traits, with optional home switches and hard stops (a
/// stop seizes the load side when driven into it, and frees it when driven back out).
#[derive(Clone)]
pub struct PlantHw {
    pub plant: Plant,
    /// Drives on: duties reach the plant only while enabled.
    pub enabled: bool,
    /// Joint `j`'s switch is closed at or below this position.
    pub switch_below: [Option<f64>; 6],
    /// Joint `j` hits a hard stop at or below this position.
    pub stop_below: [Option<f64>; 6],
    pub seized: [bool; 6],
    /// How many times the outputs were disabled.
    pub disables: u32,
    /// The e-stop button is pressed.
    pub estop: bool,
    /// The safety relay's contacts are welded shut (it does not open with the button).
    pub relay_welded: bool,
    /// The safety relay is open without the button (a failed coil or a cut wire).
    pub relay_stuck_open: bool,
    /// The brakes' coils are powered (released), as the MCU drives them.
    pub brakes_released: bool,
    /// Counts added to each encoder's reading (a braked motor settled a count away, within
    /// its brake's play).
    pub count_offset: [i16; 6],
}

impl PlantHw {
    /// The default plant at `q`, drives off, no switches or stops.
    pub fn new(q: [f64; 6]) -> Self {
        let mut plant = Plant::new(&PlantConfig::default()).unwrap();
        plant.set_joint_positions(q).unwrap();
        PlantHw {
            plant,
            enabled: false,
            switch_below: [None; 6],
            stop_below: [None; 6],
            seized: [false; 6],
            disables: 0,
            estop: false,
            relay_welded: false,
            relay_stuck_open: false,
            brakes_released: false,
            count_offset: [0; 6],
        }
        .wired()
    }

    /// The safety relay: open while the button is pressed (unless welded); open, it
    /// removes the drivers' power and the brakes' coils' power.
    pub fn relay_open(&self) -> bool {
        (self.estop && !self.relay_welded) || self.relay_stuck_open
    }

    /// Applies what the MCU commands and the safety chain allows to the plant.
    fn wired(mut self) -> Self {
        self.apply();
        self
    }

    fn apply(&mut self) {
        let powered = !self.relay_open();
        self.plant.set_bridges_enabled(self.enabled && powered);
        self.plant
            .set_brakes_released([self.brakes_released && powered; 6]);
    }

    /// Presses or releases the e-stop button.
    pub fn press_estop(&mut self, pressed: bool) {
        self.estop = pressed;
        self.apply();
    }

    /// The default plant at `q` with home switches on the legs at `switch` and hard
    /// stops on the links at `stops`.
    pub fn homing(q: [f64; 6], switch: f64, stops: [f64; 3]) -> Self {
        let mut hw = Self::new(q);
        for (j, stop) in stops.into_iter().enumerate() {
            hw.switch_below[j] = Some(switch);
            hw.stop_below[j + 3] = Some(stop);
        }
        hw
    }

    /// One millisecond of the plant: 10 steps of 100 µs, with the hard stops.
    pub fn step_ms(&mut self) {
        self.apply();
        for _ in 0..10 {
            self.plant.step(1e-4).unwrap();
            let q = self.plant.joint_positions();
            let duty = self.plant.duty();
            for j in 0..6 {
                if let Some(s) = self.stop_below[j] {
                    if !self.seized[j] && q[j] <= s && duty[j] < 0.0 {
                        self.plant.inject(j, plant::Fault::LoadSeized).unwrap();
                        self.seized[j] = true;
                    } else if self.seized[j] && duty[j] > 0.0 {
                        self.plant.clear_faults(j).unwrap();
                        self.seized[j] = false;
                    }
                }
            }
        }
    }
}

impl QuadratureCounter for PlantHw {
    fn counts(&mut self) -> [u16; 6] {
        let mut c = self.plant.encoder_counts();
        for (c, o) in c.iter_mut().zip(self.count_offset) {
            *c = c.wrapping_add_signed(o);
        }
        c
    }
}

impl MotorOutputs<f64> for PlantHw {
    fn set_duties(&mut self, duty: &[f64; 6]) {
        let d = if self.enabled { *duty } else { [0.0; 6] };
        let _ = self
            .plant
            .set_duty(d.map(|x| if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) }));
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.disables += 1;
        let _ = self.plant.set_duty([0.0; 6]);
        self.apply();
    }
    fn enable(&mut self) {
        self.enabled = true;
        self.apply();
    }
}

impl Brakes for PlantHw {
    fn set_brakes_released(&mut self, released: bool) {
        self.brakes_released = released;
        self.apply();
    }
}

impl PowerStage<f64> for PlantHw {
    fn supply_voltage(&mut self) -> f64 {
        self.plant.supply_voltage()
    }
    fn driver_fault(&mut self) -> bool {
        self.plant.driver_fault()
    }
}

impl SafetyChain for PlantHw {
    fn estop_pressed(&mut self) -> bool {
        self.estop
    }
    fn relay_open(&mut self) -> bool {
        PlantHw::relay_open(self)
    }
}

impl LimitSwitches for PlantHw {
    fn switches(&mut self) -> [bool; 6] {
        let q = self.plant.joint_positions();
        std::array::from_fn(|j| self.switch_below[j].is_some_and(|s| q[j] <= s))
    }
}

impl CurrentSense<f64> for PlantHw {
    fn currents(&mut self) -> [f64; 6] {
        self.plant.currents()
    }
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

/// The homing fixture: the plant with the reference mechanics' home switches on the legs
/// (143 mm) and hard stops on the links (85 deg below the central angles), started at leg
/// lengths `legs` and the links `above_stops` rad above their stops; and the reference
/// runtime configuration for that rest position. Returns the plant, the central joints
/// and the configuration.
pub fn homing_fixture(
    legs: [f64; 3],
    above_stops: [f64; 3],
) -> (PlantHw, [f64; 6], control::runtime::RuntimeConfig<f64>) {
    let c = central_q();
    let mech =
        control::runtime::reference_mechanics(&c, &kinematics_core::guards::Limits::reference());
    let stops = [3, 4, 5].map(|j| c[j] - mech.link_stop_below_central_rad);
    let hw = PlantHw::homing(
        [
            legs[0],
            legs[1],
            legs[2],
            stops[0] + above_stops[0],
            stops[1] + above_stops[1],
            stops[2] + above_stops[2],
        ],
        mech.leg_switch_m,
        stops,
    );
    let cfg = control::runtime::reference_config_for(
        &kinematics_core::RsprGeometry::reference(),
        kinematics_core::Branch::OUTER,
        None,
        Some(hw_rest(&hw)),
    )
    .unwrap();
    (hw, c, cfg)
}

/// Where the fixture's plant rests.
fn hw_rest(hw: &PlantHw) -> [f64; 6] {
    hw.plant.joint_positions()
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
/// from o_p along x_0) at the platform pose of the load-side joints `q`: the platform's
/// wrench on the tool s_e = [m g z0; c x m g z0] mapped by tau = J^-T s_e (Eq. 7.10), the
/// loads -tau.
pub fn tool_loads(q: &[f64; 6]) -> [f64; 6] {
    use kinematics_core::{forward, jacobian, statics::forces_with_inv_cond, Branch, Pose};
    use kinematics_core::{RsprGeometry, Wrench};
    let g = RsprGeometry::<f64>::reference();
    let qv = nalgebra::Vector6::from_row_slice(q);
    let fk = forward(
        &g,
        &qv,
        Branch::OUTER,
        &Pose::central(g.hc),
        &Default::default(),
    )
    .unwrap();
    let f = nalgebra::Vector3::new(0.0, 0.0, 1.2 * 9.81);
    let c = fk.pose.r * nalgebra::Vector3::new(0.100, 0.0, 0.0);
    let m = c.cross(&f);
    let se = Wrench::from_row_slice(&[f.x, f.y, f.z, m.x, m.y, m.z]);
    let jac = jacobian(&g, &fk.solution).unwrap();
    let st = forces_with_inv_cond(&jac, &se, 1.0, 0.0).unwrap();
    std::array::from_fn(|j| -st.tau[j])
}

/// The true platform pose of the plant's load-side joints.
pub fn true_pose(hw: &PlantHw) -> kinematics_core::Pose<f64> {
    use kinematics_core::{forward, Branch, Pose, RsprGeometry};
    let g = RsprGeometry::<f64>::reference();
    let q = nalgebra::Vector6::from_row_slice(&hw.plant.joint_positions());
    forward(
        &g,
        &q,
        Branch::OUTER,
        &Pose::central(g.hc),
        &Default::default(),
    )
    .unwrap()
    .pose
}
