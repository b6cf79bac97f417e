//! The plant model behind the hardware traits, shared by the integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::indexing_slicing)]

use hal::{CurrentSense, LimitSwitches, MotorOutputs, QuadratureCounter};
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
        }
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
        self.plant.encoder_counts()
    }
}

impl MotorOutputs<f64> for PlantHw {
    fn set_duties(&mut self, duty: &[f64; 6]) {
        let d = if self.enabled { *duty } else { [0.0; 6] };
        let _ = self.plant.set_duty(d.map(|x| x.clamp(-1.0, 1.0)));
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.disables += 1;
        let _ = self.plant.set_duty([0.0; 6]);
    }
    fn enable(&mut self) {
        self.enabled = true;
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

/// The homing fixture: the plant with home switches at 150 mm on the legs and hard stops
/// 60 deg below the central angles on the links, started at leg lengths `legs` and the
/// links `above_stops` rad above their stops; and the reference runtime configuration
/// (quick park). Returns the plant, the central joints and the configuration.
pub fn homing_fixture(
    legs: [f64; 3],
    above_stops: [f64; 3],
) -> (PlantHw, [f64; 6], control::runtime::RuntimeConfig<f64>) {
    let c = central_q();
    let stops = [3, 4, 5].map(|j| c[j] - 60f64.to_radians());
    let hw = PlantHw::homing(
        [
            legs[0],
            legs[1],
            legs[2],
            stops[0] + above_stops[0],
            stops[1] + above_stops[1],
            stops[2] + above_stops[2],
        ],
        0.150,
        stops,
    );
    let mut cfg = control::runtime::reference_config(c);
    cfg.homing.park_speed = [0.02, 0.02, 0.02, 0.5, 0.5, 0.5];
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
