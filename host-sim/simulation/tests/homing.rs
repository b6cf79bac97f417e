#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! Homing on the simulated board (the whole board application on the plant, over the
//! link) when a home switch fails or a tool hangs on the platform: measured on the plant,
//! whatever the firmware intended. The homing must never drive a joint beyond its
//! mechanical range (for a link homing on its hard stop, the range reaches the stop), must
//! move the platform at most 5 mm beyond where a healthy homing takes it, and must name
//! the cause; a homing the tool does not allow is refused before anything moves.

use control::homing::HomingError;
use control::ToolLoad;
use master_link::{FaultCause, MasterToBoard, ResetCause, RobotState};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

/// What one homing run did, measured on the plant.
struct Run {
    /// The state it ended in.
    state: RobotState,
    /// The latched fault.
    fault: master_link::FaultRecord,
    /// Every joint's extreme positions (m, rad).
    low: [f64; 6],
    high: [f64; 6],
    /// The platform's largest distance from where it rested, m.
    platform: f64,
    /// The largest joint motion of the run, m or rad (any joint).
    moved: f64,
}

fn bench(cfg: BoardSimConfig) -> Bench {
    Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x5e55,
    )
}

/// Homes from power-up with `setup` applied to the board first; runs until the homing
/// ends (Ready or Fault) and measures.
fn home(cfg: BoardSimConfig, setup: impl FnOnce(&mut BoardSim)) -> Run {
    let mut b = bench(cfg);
    setup(&mut b.board);
    b.request(&b.hello_msg(), 100).unwrap();
    let p0 = b.board.truth().pose.t;
    let q0 = b.board.truth().q;
    let (mut low, mut high) = (q0, q0);
    let (mut platform, mut moved) = (0.0f64, 0.0f64);
    let _ = b.command(&MasterToBoard::Home { rehome: false });
    for _ in 0..120_000 {
        b.run_ms(1).unwrap();
        let t = b.board.truth();
        for j in 0..6 {
            low[j] = low[j].min(t.q[j]);
            high[j] = high[j].max(t.q[j]);
            moved = moved.max((t.q[j] - q0[j]).abs());
        }
        platform = platform.max((t.pose.t - p0).norm());
        let st = b.board.runtime().state();
        if st == RobotState::Fault || st == RobotState::Ready {
            break;
        }
    }
    // The drives off and the brakes on after a fault: nothing more moves.
    b.run_ms(200).unwrap();
    let st = b.board.runtime().status();
    Run {
        state: st.state,
        fault: st.fault,
        low,
        high,
        platform,
        moved,
    }
}

fn reference() -> BoardSimConfig {
    BoardSimConfig::reference(None).unwrap()
}

/// Where each joint may be while homing: its mechanical range, reaching a link's hard
/// stop.
fn homing_range(cfg: &BoardSimConfig) -> [[f64; 2]; 6] {
    cfg.runtime.homing.joints.map(|h| h.range)
}

/// The largest joint motion of `ms` milliseconds with the tool on and nothing commanded
/// (the brakes' play under the tool's weight).
fn passive_motion(cfg: BoardSimConfig, ms: u64) -> f64 {
    let mut b = bench(cfg);
    b.board.set_tool(Some(ToolLoad::thesis()));
    let q0 = b.board.truth().q;
    let mut moved = 0.0f64;
    for _ in 0..ms {
        b.run_ms(1).unwrap();
        let q = b.board.truth().q;
        for j in 0..6 {
            moved = moved.max((q[j] - q0[j]).abs());
        }
    }
    moved
}

/// The homing failure's code in the fault record (`HomingError::code`).
fn code(e: HomingError) -> f32 {
    e.code()
}

/// Property: a home switch failed either way, on any leg (the legs home on their
/// switches), from the start or once it has closed: the homing fails naming the joint and
/// the failure, no joint leaves its mechanical range (one tick of the approach's speed
/// beyond, at most), and the platform moves at most 5 mm beyond the healthy homing's
/// farthest.
#[test]
fn a_failed_home_switch_drives_no_joint_beyond_its_range() {
    let cfg = reference();
    let range = homing_range(&cfg);
    let healthy = home(cfg.clone(), |_| {});
    assert_eq!(healthy.state, RobotState::Ready, "{:?}", healthy.fault);
    println!(
        "healthy homing: the platform moves up to {:.1} mm from its rest",
        healthy.platform * 1e3
    );
    // One tick at the legs' homing speed limit.
    let late = 0.022 * 1e-3;
    for j in 0..3 {
        let cases: [(&str, Option<bool>, HomingError); 2] = [
            (
                "actuated from the start (a cut wire)",
                Some(true),
                HomingError::SwitchImplausible { joint: j },
            ),
            (
                "never actuated",
                Some(false),
                HomingError::NotFound { joint: j },
            ),
        ];
        for (what, forced, expected) in cases {
            let run = home(cfg.clone(), |b| b.hw.switch_forced[j] = forced);
            println!(
                "l{} switch {what}: {:?} {:?} value {}; l{} {:.2} .. {:.2} mm (range {:.1} .. {:.1}); platform {:.2} mm",
                j + 1,
                run.state,
                run.fault.cause,
                run.fault.value,
                j + 1,
                run.low[j] * 1e3,
                run.high[j] * 1e3,
                range[j][0] * 1e3,
                range[j][1] * 1e3,
                run.platform * 1e3
            );
            assert_eq!(run.state, RobotState::Fault, "l{} {what}", j + 1);
            assert_eq!(usize::from(run.fault.joint), j, "l{} {what}", j + 1);
            // Read actuated from power-up, outside homing, the switch is a limit switch's
            // fault before `Home` (it is refused); at `Home`, the homing's.
            let named = (run.fault.cause == FaultCause::HomingFailed
                && run.fault.value == code(expected))
                || (forced == Some(true) && run.fault.cause == FaultCause::LimitSwitch);
            assert!(named, "l{} {what}: {:?}", j + 1, run.fault);
            for k in 0..6 {
                assert!(
                    run.low[k] >= range[k][0] - late && run.high[k] <= range[k][1] + late,
                    "l{} {what}: joint {k} {} .. {} beyond {:?}",
                    j + 1,
                    run.low[k],
                    run.high[k],
                    range[k]
                );
            }
            assert!(
                run.platform <= healthy.platform + 5e-3,
                "l{} {what}: platform {} m",
                j + 1,
                run.platform
            );
            if forced == Some(true) {
                assert!(run.moved < 1e-5, "l{} {what}: moved {}", j + 1, run.moved);
            }
        }
    }
}

/// Property: a home switch that closes when it should and then stays actuated (a switch
/// stuck once it closed) is a fault within its travel while the leg backs off: the leg
/// moves at most the switch's 3 mm travel off the switch, and the homing names it.
#[test]
fn a_switch_stuck_after_it_closed_is_found_within_its_travel() {
    let cfg = reference();
    let switch = cfg.runtime.mechanics.leg_switch_m;
    let mut b = bench(cfg);
    b.request(&b.hello_msg(), 100).unwrap();
    b.command(&MasterToBoard::Home { rehome: false }).unwrap();
    // Once l1's switch has closed, it stays actuated.
    b.run_until("l1 on its switch", 60_000, |s| s.hw.switch_levels()[0])
        .unwrap();
    b.board.hw.switch_forced[0] = Some(true);
    let mut high = 0.0f64;
    b.run_until("the homing ends", 60_000, |s| {
        high = high.max(s.truth().q[0]);
        s.runtime().state() != RobotState::Homing
    })
    .unwrap();
    let st = b.board.runtime().status();
    println!(
        "l1 stuck on its switch: {:?} value {}; backed off to {:.2} mm (switch {:.1} mm)",
        st.fault.cause,
        st.fault.value,
        high * 1e3,
        switch * 1e3
    );
    assert_eq!(st.fault.cause, FaultCause::HomingFailed);
    assert_eq!(st.fault.value, code(HomingError::SwitchStuck { joint: 0 }));
    assert!(high <= switch + 0.003 + 0.022e-3, "{high}");
}

/// Property: a homing stopped by `Disable` while a leg rests on its home switch (just
/// referenced there, backing off) latches no fault: the board knows the leg is at its
/// switch (its counts since the start put it within the switch's travel of the home
/// position), so the closed switch is not an end of travel. It ends `Disabled`, and the
/// next `Home` leaves the switch and homes to `Ready`. (Latched as a limit switch, the
/// switch still closed would refuse every `ClearFault`, and `Home` is refused in `Fault`:
/// the robot locked out until someone moved the leg by hand.)
#[test]
fn a_homing_stopped_on_a_home_switch_can_home_again() {
    let mut b = bench(reference());
    b.request(&b.hello_msg(), 100).unwrap();
    b.command(&MasterToBoard::Home { rehome: false }).unwrap();
    b.run_until("l1 on its switch", 60_000, |s| s.hw.switch_levels()[0])
        .unwrap();
    b.run_ms(5).unwrap();
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_ms(300).unwrap();
    let st = b.board.runtime().status();
    assert!(
        b.board.hw.switch_levels()[0],
        "the leg left its switch: the case does not test what it says"
    );
    assert_eq!(
        (st.state, st.fault.cause),
        (RobotState::Disabled, FaultCause::None),
        "stopped on its home switch"
    );
    b.command(&MasterToBoard::Home { rehome: false }).unwrap();
    b.run_until("the homing ends", 60_000, |s| {
        s.runtime().state() != RobotState::Homing
    })
    .unwrap();
    b.run_ms(500).unwrap();
    let st = b.board.runtime().status();
    assert_eq!(
        (st.state, st.fault.cause),
        (RobotState::Ready, FaultCause::None)
    );
}

/// Property: with the thesis's tool declared to the board (1.2 kg on a 0.1 m lever), a
/// homing the tool's weight does not allow (it pulls a link against its approach with
/// more than half the push) is refused at `Home`, before anything moves, naming the joint.
#[test]
fn homing_with_a_declared_tool_it_cannot_carry_is_refused_before_any_motion() {
    let mut cfg = reference();
    cfg.runtime.controller.tool = Some(ToolLoad::thesis());
    let run = home(cfg.clone(), |b| b.set_tool(Some(ToolLoad::thesis())));
    let passive = passive_motion(cfg, 300);
    println!(
        "declared tool: {:?} {:?} joint {} value {}; largest joint motion {:.2e}",
        run.state, run.fault.cause, run.fault.joint, run.fault.value, run.moved
    );
    assert_eq!(run.state, RobotState::Fault);
    assert_eq!(run.fault.cause, FaultCause::HomingFailed);
    let joint = usize::from(run.fault.joint);
    assert_eq!(run.fault.value, code(HomingError::LoadTooHeavy { joint }));
    println!("the brakes' play under the tool alone: {passive:.2e}");
    assert!(
        run.moved <= passive + 1e-6,
        "moved {} ({passive})",
        run.moved
    );
}

/// Property: with a tool on the platform the board was not told of, the homing of a
/// link its weight holds back is not taken for its hard stop (a stall before the link
/// moved): it fails naming the joint, and no joint left its range.
#[test]
fn an_undeclared_tool_never_gives_a_false_reference() {
    let cfg = reference();
    let range = homing_range(&cfg);
    let run = home(cfg, |b| b.set_tool(Some(ToolLoad::thesis())));
    println!(
        "undeclared tool: {:?} {:?} joint {} value {}",
        run.state, run.fault.cause, run.fault.joint, run.fault.value
    );
    assert_eq!(run.state, RobotState::Fault);
    assert_eq!(run.fault.cause, FaultCause::HomingFailed);
    let joint = usize::from(run.fault.joint);
    assert!(
        run.fault.value == code(HomingError::NoProgress { joint })
            || run.fault.value == code(HomingError::LoadTooHeavy { joint }),
        "{:?}",
        run.fault
    );
    for k in 0..6 {
        assert!(
            run.low[k] >= range[k][0] - 0.022e-3 && run.high[k] <= range[k][1] + 0.022e-3,
            "joint {k} {} .. {} beyond {:?}",
            run.low[k],
            run.high[k],
            range[k]
        );
    }
}
