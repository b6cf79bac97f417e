//! The runtimes the `commands` target starts from, taken once per process on the plant
//! model (`sim/plant`, as in `firmware/control/tests`): booted (`Disabled`, not
//! homed), in the middle of homing, homed (`Ready`), in the brake check (`Enabling`) and
//! following (`Enabled`, holding the central pose). Homing on the plant takes a few
//! simulated seconds, far too slow to repeat for every input; a runtime is `Clone`, so each
//! input starts from a copy and continues on the fake hardware, from the counters the plant
//! left. The runtime runs inside the board's tick service from the boot on, as on the
//! board, so that a copy continues with the service's timing (the first tick after a
//! snapshot is checked against the last one before it).

use control::link::{Command, Request};
use control::runtime::{reference_config_for, reference_mechanics, Runtime};
use control::service::{ServiceConfig, TickService};
use control::state_machine::State;
use hal::{
    Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage, QuadratureCounter, SafetyChain,
    NUM_JOINTS,
};
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::{BoardToMaster, ResetCause};
use plant::{Plant, PlantConfig};

/// The runtime of the reference robot on f64.
pub type Rt = Runtime<f64, RsprGeometry<f64>>;

/// The tick service around it.
pub type Service = TickService<f64, RsprGeometry<f64>>;

/// A runtime and the moment and counters it was taken at.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// The runtime, in its tick service (`None` before the boot: the service is built
    /// around a booted runtime).
    pub service: Option<Service>,
    /// The runtime.
    pub runtime: Rt,
    /// Its time, µs.
    pub now_us: u64,
    /// The counters as the runtime last read them (the fake hardware goes on from there).
    pub counts: [u16; NUM_JOINTS],
    /// The outputs as the runtime left them: bridges on, duties, brakes released.
    pub outputs: (bool, [f64; NUM_JOINTS], bool),
}

/// Every starting point.
#[derive(Clone, Debug)]
pub struct Snapshots {
    /// Constructed, not booted (the input chooses the reset cause of the boot).
    pub unbooted: Snapshot,
    /// Booted after a power-on reset: `Disabled`, not homed.
    pub booted: Snapshot,
    /// 300 ms into homing.
    pub homing: Snapshot,
    /// Homed, the stop after homing done: `Ready`.
    pub ready: Snapshot,
    /// 10 ms into the brake check: `Enabling`, pushing against the brakes.
    pub enabling: Snapshot,
    /// Enabled, holding the central pose for 300 ms.
    pub enabled: Snapshot,
}

/// The plant behind the hardware traits, with home switches on the legs and hard stops
/// on the links (as `firmware/control/tests/common`).
struct PlantHw {
    plant: Plant,
    enabled: bool,
    brakes_released: bool,
    switch_below: [Option<f64>; NUM_JOINTS],
    stop_below: [Option<f64>; NUM_JOINTS],
    seized: [bool; NUM_JOINTS],
    /// The counters at the runtime's last read.
    last_read: [u16; NUM_JOINTS],
}

fn ok<T, E: core::fmt::Debug>(r: Result<T, E>, what: &str) -> T {
    match r {
        Ok(x) => x,
        Err(e) => panic!("snapshots: {what}: {e:?}"),
    }
}

impl PlantHw {
    fn apply(&mut self) {
        self.plant.set_bridges_enabled(self.enabled);
        self.plant
            .set_brakes_released([self.brakes_released; NUM_JOINTS]);
    }

    /// One millisecond: ten plant steps of 100 µs, with the hard stops.
    fn step_ms(&mut self) {
        self.apply();
        for _ in 0..10 {
            ok(self.plant.step(1e-4), "plant step");
            let q = self.plant.joint_positions();
            let duty = self.plant.duty();
            for j in 0..NUM_JOINTS {
                let Some(s) = self.stop_below[j] else {
                    continue;
                };
                if !self.seized[j] && q[j] <= s && duty[j] < 0.0 {
                    ok(self.plant.inject(j, plant::Fault::LoadSeized), "seize");
                    self.seized[j] = true;
                } else if self.seized[j] && duty[j] > 0.0 {
                    ok(self.plant.clear_faults(j), "free");
                    self.seized[j] = false;
                }
            }
        }
    }
}

impl QuadratureCounter for PlantHw {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        self.last_read = self.plant.encoder_counts();
        self.last_read
    }
}
impl MotorOutputs<f64> for PlantHw {
    fn set_duties(&mut self, duty: &[f64; NUM_JOINTS]) {
        let d = if self.enabled {
            duty.map(|x| if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) })
        } else {
            [0.0; NUM_JOINTS]
        };
        ok(self.plant.set_duty(d), "set duty");
    }
    fn disable(&mut self) {
        self.enabled = false;
        ok(self.plant.set_duty([0.0; NUM_JOINTS]), "set duty");
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
        false
    }
    fn relay_open(&mut self) -> bool {
        false
    }
}
impl LimitSwitches for PlantHw {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        let q = self.plant.joint_positions();
        std::array::from_fn(|j| self.switch_below[j].is_some_and(|s| q[j] <= s))
    }
}
impl CurrentSense<f64> for PlantHw {
    fn currents(&mut self) -> [f64; NUM_JOINTS] {
        self.plant.currents()
    }
}

/// One control period with a heartbeat, as the board's control task runs it (execution
/// time `cycles`), then a millisecond of the plant.
fn step(sv: &mut Service, hw: &mut PlantHw, t: &mut u64, cycles: u32) {
    *t += 1000;
    sv.begin(*t, 0, control::estop::EStopTrip::NONE);
    let beat = Request {
        seq: 0,
        command: Command::Heartbeat,
    };
    let _ = sv.request(&beat, *t);
    sv.tick(hw, *t);
    let _ = sv.finish(*t, cycles);
    hw.step_ms();
}

fn snap(sv: Option<&Service>, rt: &Rt, hw: &mut PlantHw, t: u64) -> Snapshot {
    Snapshot {
        service: sv.cloned(),
        runtime: rt.clone(),
        now_us: t,
        counts: hw.last_read,
        outputs: (hw.enabled, hw.plant.duty(), hw.brakes_released),
    }
}

/// Takes every snapshot: the reference robot resting with its legs at 160 mm and its links
/// 0.2 rad above their hard stops, homed, parked and enabled on the plant (a few seconds of
/// simulated time), in the tick service `cfg` with ticks of `cycles` cycles.
pub fn build(cfg_service: ServiceConfig, cycles: u32) -> Snapshots {
    let g = RsprGeometry::<f64>::reference();
    let central = ok(
        inverse(&g, &Pose::central(g.hc), Branch::OUTER),
        "central pose",
    )
    .q();
    let c: [f64; NUM_JOINTS] = std::array::from_fn(|j| central[j]);
    let mech = reference_mechanics(&c, &kinematics_core::guards::Limits::reference());
    let stops = [3, 4, 5].map(|j| c[j] - mech.link_stop_below_central_rad);
    let rest = [
        0.16,
        0.161,
        0.159,
        stops[0] + 0.2,
        stops[1] + 0.2,
        stops[2] + 0.2,
    ];
    let mut plant = ok(Plant::new(&PlantConfig::default()), "plant");
    ok(plant.set_joint_positions(rest), "rest");
    let mut hw = PlantHw {
        plant,
        enabled: false,
        brakes_released: false,
        switch_below: [
            Some(mech.leg_switch_m),
            Some(mech.leg_switch_m),
            Some(mech.leg_switch_m),
            None,
            None,
            None,
        ],
        stop_below: [
            None,
            None,
            None,
            Some(stops[0]),
            Some(stops[1]),
            Some(stops[2]),
        ],
        seized: [false; NUM_JOINTS],
        last_read: [0; NUM_JOINTS],
    };
    hw.last_read = hw.plant.encoder_counts();
    hw.apply();
    let mut cfg = ok(
        reference_config_for(&g, Branch::OUTER, None, Some(hw.plant.joint_positions())),
        "configuration",
    );
    // The fuzzed board runs on the fake hardware, whose joints have no backlash: no
    // compensation (its offsets would stand between the fake's motors and joints).
    cfg.controller.servo.backlash = servo::backlash::BacklashConfig::off();
    let mut rt = ok(Rt::new(g, cfg, 0), "runtime");
    let mut t = 0;
    let unbooted = snap(None, &rt, &mut hw, t);
    ok(
        rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None),
        "boot",
    );
    let mut sv = TickService::new(rt, cfg_service);
    let take = |sv: &Service, hw: &mut PlantHw, t: u64| snap(Some(sv), sv.runtime(), hw, t);
    let state = |sv: &Service| sv.runtime().state();
    let fault = |sv: &Service| sv.runtime().status().fault;
    let request = |sv: &mut Service, command: Command, t: u64| {
        let reply = sv.request(&Request { seq: 0, command }, t);
        assert_eq!(
            reply,
            BoardToMaster::Ack { seq: 0 },
            "snapshots: {command:?}"
        );
    };
    let booted = take(&sv, &mut hw, t);

    request(&mut sv, Command::Home { rehome: false }, t);
    for _ in 0..300 {
        step(&mut sv, &mut hw, &mut t, cycles);
    }
    assert_eq!(state(&sv), State::Homing, "snapshots: homing");
    let homing = take(&sv, &mut hw, t);
    while state(&sv) == State::Homing {
        step(&mut sv, &mut hw, &mut t, cycles);
        assert!(t < 60_000_000, "snapshots: homing did not finish");
    }
    for _ in 0..100 {
        step(&mut sv, &mut hw, &mut t, cycles);
    }
    assert_eq!(state(&sv), State::Ready, "snapshots: {:?}", fault(&sv));
    let ready = take(&sv, &mut hw, t);

    request(&mut sv, Command::Enable, t);
    for _ in 0..10 {
        step(&mut sv, &mut hw, &mut t, cycles);
    }
    assert_eq!(state(&sv), State::Enabling, "snapshots: enabling");
    let enabling = take(&sv, &mut hw, t);
    while state(&sv) == State::Enabling {
        step(&mut sv, &mut hw, &mut t, cycles);
        assert!(t < 70_000_000, "snapshots: enabling did not finish");
    }
    for _ in 0..300 {
        step(&mut sv, &mut hw, &mut t, cycles);
    }
    assert_eq!(state(&sv), State::Enabled, "snapshots: {:?}", fault(&sv));
    let enabled = take(&sv, &mut hw, t);

    Snapshots {
        unbooted,
        booted,
        homing,
        ready,
        enabling,
        enabled,
    }
}
