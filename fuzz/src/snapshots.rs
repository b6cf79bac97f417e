//! The runtimes the `commands` target starts from, taken once per process on the plant
//! model (`host-sim/plant`, as in `firmware/control/tests`): booted (`Disabled`, not
//! homed), in the middle of homing, homed (`Ready`), in the brake check (`Enabling`) and
//! following (`Enabled`, holding the central pose). Homing on the plant takes a few
//! simulated seconds, far too slow to repeat for every input; a runtime is `Clone`, so each
//! input starts from a copy and continues on the fake hardware, from the counters the plant
//! left. The runtime runs inside the board's tick service from the boot on, as on the
//! board, so that a copy continues with the service's timing (the first tick after a
//! snapshot is checked against the last one before it).

use board_on_plant::{BoardOnPlant, Layout, ReferenceMechanics};
use control::link::Request;
use control::modes::State;
use control::runtime::{reference_config_for, reference_mechanics, Runtime};
use control::service::{ServiceConfig, TickService};
use hal::{QuadratureCounter, NUM_JOINTS};
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::MasterToBoard as Command;
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

fn ok<T, E: core::fmt::Debug>(r: Result<T, E>, what: &str) -> T {
    match r {
        Ok(x) => x,
        Err(e) => panic!("snapshots: {what}: {e:?}"),
    }
}

/// One control period with a heartbeat, as the board's control task runs it (execution
/// time `cycles`), then a millisecond of the plant.
fn step(sv: &mut Service, hw: &mut BoardOnPlant, t: &mut u64, cycles: u32) {
    *t += 1000;
    sv.begin(*t, 0, control::estop::EStopTrip::NONE);
    let beat = Request::new(0, Command::Heartbeat);
    let _ = sv.request(&beat, *t);
    sv.tick(hw, *t);
    let _ = sv.finish(*t, cycles);
    hw.step_ms();
}

fn snap(sv: Option<&Service>, rt: &Rt, hw: &mut BoardOnPlant, t: u64) -> Snapshot {
    Snapshot {
        service: sv.cloned(),
        runtime: rt.clone(),
        now_us: t,
        counts: hw.last_counts(),
        outputs: (hw.enabled, hw.plant.duty(), hw.brakes_released),
    }
}

/// Takes every snapshot: the reference robot resting with its legs at 160 mm and its links
/// 0.2 rad above their hard stops, homed, parked and enabled on the plant (a few seconds of
/// simulated time), in the tick service `cfg` with ticks of `cycles` cycles.
/// The nonce of the master that brought the snapshots' board up (homing on), and the
/// session the board issued it: a board started from one of them has it open.
pub const OWNER_NONCE: u32 = 0x0F0F_0F0F;
/// See [`OWNER_NONCE`].
pub const OWNER_SESSION: u32 = 0x5e55_0001;

pub fn build(cfg_service: ServiceConfig, cycles: u32) -> Snapshots {
    let g = RsprGeometry::<f64>::reference();
    let central = ok(
        inverse(&g, &Pose::central(g.hc), Branch::OUTER),
        "central pose",
    )
    .q();
    let c: [f64; NUM_JOINTS] = std::array::from_fn(|j| central[j]);
    let mech = reference_mechanics(&kinematics_core::guards::Limits::reference());
    let stops = [3, 4, 5].map(|j| c[j] - mech.link_stop_below_central_rad);
    let rest = [
        0.16,
        0.161,
        0.159,
        stops[0] + 0.2,
        stops[1] + 0.2,
        stops[2] + 0.2,
    ];
    let layout = Layout::reference(&ReferenceMechanics {
        central_q: c,
        leg_switch_m: mech.leg_switch_m,
        link_stop_below_central_rad: mech.link_stop_below_central_rad,
        range: mech.range,
    });
    let plant = ok(Plant::new(&PlantConfig::default()), "plant");
    let mut hw = ok(BoardOnPlant::at_rest(plant, rest), "rest").with_layout(&layout);
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
    let take = |sv: &Service, hw: &mut BoardOnPlant, t: u64| snap(Some(sv), sv.runtime(), hw, t);
    let state = |sv: &Service| sv.runtime().state();
    let fault = |sv: &Service| sv.runtime().status().fault;
    let request = |sv: &mut Service, message: Command, t: u64| {
        let reply = sv.request(&Request::new(0, message), t);
        assert_eq!(
            reply,
            BoardToMaster::Ack { seq: 0 },
            "snapshots: {message:?}"
        );
    };
    let booted = take(&sv, &mut hw, t);
    // The master says Hello (it owns the board from now on) and that its operator is
    // present.
    let hello = Request {
        seq: 0,
        message: Command::Hello {
            protocol_version: master_link::PROTOCOL_VERSION,
            nonce: OWNER_NONCE,
            clock_us: t,
        },
        session: OWNER_SESSION,
    };
    let reply = sv.request(&hello, t);
    assert!(
        matches!(
            reply,
            BoardToMaster::HelloReply {
                session: OWNER_SESSION,
                ..
            }
        ),
        "snapshots: {reply:?}"
    );
    request(&mut sv, Command::OperatorPresent { present: true }, t);

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
