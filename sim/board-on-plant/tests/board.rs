//! The board and the mechanics around the plant: the stops, the switches, the safety
//! chain, the platform's loads.

use board_on_plant::{AtStop, BoardOnPlant, Layout, Platform, Tool, Wall};
use hal::{Brakes, LimitSwitches, MotorOutputs, SafeOutputs, SafetyChain};
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use nalgebra::Vector3;
use plant::{Plant, PlantConfig};

type TestResult = Result<(), Box<dyn std::error::Error>>;

fn central() -> Result<[f64; 6], Box<dyn std::error::Error>> {
    let g = RsprGeometry::<f64>::reference();
    let q = inverse(&g, &Pose::central(g.hc), Branch::OUTER)
        .map_err(|e| format!("{e:?}"))?
        .q();
    Ok(std::array::from_fn(|j| q[j]))
}

fn board_at(q: [f64; 6]) -> Result<BoardOnPlant, Box<dyn std::error::Error>> {
    Ok(BoardOnPlant::at_rest(
        Plant::new(&PlantConfig::default())?,
        q,
    )?)
}

/// Property: a link driven into its lower stop stays within a step's travel of it, its
/// switch actuated near it; driven back out, it leaves; a leg driven up is caught by its
/// upper stop.
#[test]
fn stops_catch_the_joints_driven_into_them_and_free_them_driven_out() -> TestResult {
    let q = [0.170, 0.170, 0.170, 0.0, 0.0, 0.0];
    let mut l = Layout::NONE;
    l.stop_below[3] = Some(-0.02);
    l.switch_below[3] = Some(-0.015);
    l.stop_above[0] = Some(0.172);
    let mut b = board_at(q)?.with_layout(&l);
    b.enable();
    b.set_brakes_released(true);
    let mut d = [0.0; 6];
    d[3] = -0.3;
    d[0] = 0.1;
    b.set_duties(&d);
    for _ in 0..500 {
        b.step_ms();
    }
    let at = b.plant.joint_positions();
    assert_eq!(b.at_stop()[3], Some(AtStop::Lower));
    assert_eq!(b.at_stop()[0], Some(AtStop::Upper));
    assert!((at[3] + 0.02).abs() < 1e-3, "link at {}", at[3]);
    assert!((at[0] - 0.172).abs() < 0.2e-3, "leg at {}", at[0]);
    assert!(b.switches()[3]);
    assert!(b.steps_at_stop[3] > 0);
    d[3] = 0.3;
    d[0] = -0.1;
    b.set_duties(&d);
    for _ in 0..100 {
        b.step_ms();
    }
    let away = b.plant.joint_positions();
    assert_eq!(b.at_stop(), [None; 6]);
    assert!(
        away[3] > -0.02 + 1e-3 && away[0] < 0.172 - 0.1e-3,
        "{away:?}"
    );
    assert!(!b.switches()[3] || away[3] <= -0.015);
    Ok(())
}

/// Property: a stop holds the load pressed into it. A link on its lower stop, pressed
/// into it by an external torque of 0.1 N m (a tool's weight), driven away at a duty
/// whose stall effort cannot lift it (0.005: `n Kt eta V d / R` = 36 x 0.0234 x 0.9 x
/// 0.12 V / 2.14 ohm = 0.043 N m), stays on its stop: it never passes the stop's
/// position, and the stop holds it throughout. (A stop that let go whenever the duty
/// pointed away let the weight carry the load through it.)
#[test]
fn a_stop_holds_a_load_pressed_into_it_against_a_weaker_drive() -> TestResult {
    let q = [0.170, 0.170, 0.170, 0.0, 0.0, 0.0];
    let stop = -0.02;
    let mut l = Layout::NONE;
    l.stop_below[3] = Some(stop);
    let mut b = board_at(q)?.with_layout(&l);
    b.enable();
    b.set_brakes_released(true);
    let mut d = [0.0; 6];
    d[3] = -0.3;
    b.set_duties(&d);
    for _ in 0..500 {
        b.step_ms();
    }
    assert_eq!(b.at_stop()[3], Some(AtStop::Lower));
    let rest = b.plant.joint_positions()[3];
    b.plant.set_external_load([0.0, 0.0, 0.0, -0.1, 0.0, 0.0])?;
    d[3] = 0.005;
    b.set_duties(&d);
    let mut deepest = rest;
    let mut let_go = 0;
    for _ in 0..300 {
        b.step_ms();
        deepest = deepest.min(b.plant.joint_positions()[3]);
        if b.at_stop()[3].is_none() {
            let_go += 1;
        }
    }
    assert!(
        deepest >= rest.min(stop) - 1e-9,
        "the link went {} rad past where it rested on its stop",
        rest.min(stop) - deepest
    );
    assert_eq!(
        let_go, 0,
        "the stop let go of the pressed link for {let_go} ms"
    );
    Ok(())
}

/// Property: the relay open (the button, unless welded; or failed open) takes the bridges'
/// and the brakes' power whatever the MCU drives, and the MCU reads it; forcing the outputs
/// safe applies the brakes and turns the drivers off.
#[test]
fn the_relay_removes_the_drivers_and_the_brakes_power() -> TestResult {
    let mut b = board_at([0.170, 0.170, 0.170, 0.0, 0.0, 0.0])?;
    b.enable();
    b.set_brakes_released(true);
    assert_eq!(b.plant.bridges_on(), [true; 6]);
    b.press_estop(true);
    assert!(b.estop_pressed() && SafetyChain::relay_open(&mut b));
    assert_eq!(b.plant.bridges_on(), [false; 6]);
    b.step_ms();
    b.step_ms();
    b.step_ms();
    assert!(b.enabled, "the MCU's enable is its own");
    b.relay_welded = true;
    b.press_estop(true);
    assert!(!SafetyChain::relay_open(&mut b));
    assert_eq!(b.plant.bridges_on(), [true; 6]);
    b.relay_welded = false;
    b.press_estop(false);
    b.relay_stuck_open = true;
    b.step_ms();
    assert!(SafetyChain::relay_open(&mut b) && !b.estop_pressed());
    assert_eq!(b.plant.bridges_on(), [false; 6]);
    b.relay_stuck_open = false;
    b.force_safe();
    b.step_ms();
    assert!(!b.enabled && !b.brakes_released && !b.link_brakes_released);
    assert_eq!(b.plant.bridges_on(), [false; 6]);
    for _ in 0..30 {
        b.step_ms();
    }
    assert_eq!(b.plant.brakes_holding(), [true; 6]);
    Ok(())
}

/// Property: the reference layout puts the switches and stops where the firmware's
/// reference mechanics say (here: a leg switch at 143 mm, a monitored range of 142..212 mm
/// and 80 + 3 deg, stops 85 deg from central).
#[test]
fn the_reference_layout_follows_the_mechanics() -> TestResult {
    let c = central()?;
    let deg = f64::to_radians;
    let leg = [0.142, 0.212];
    let link = |j: usize| [c[j] - deg(83.0), c[j] + deg(83.0)];
    let l = Layout::reference(&board_on_plant::ReferenceMechanics {
        central_q: c,
        leg_switch_m: 0.143,
        link_stop_below_central_rad: deg(85.0),
        range: [leg, leg, leg, link(3), link(4), link(5)],
    });
    for j in 0..3 {
        assert_eq!(l.switch_below[j], Some(0.143));
        assert_eq!(l.stop_below[j], Some(0.141));
        assert_eq!(l.stop_above[j], Some(0.213));
    }
    for (j, cj) in c.iter().enumerate().skip(3) {
        let lower = l.stop_below[j].ok_or("a link stop")?;
        assert!((cj - lower - deg(85.0)).abs() < 1e-12);
        assert!((l.stop_above[j].ok_or("a link stop")? - cj - deg(85.0)).abs() < 1e-12);
        assert!((l.switch_below[j].ok_or("a link switch")? - lower - deg(2.0)).abs() < 1e-12);
    }
    Ok(())
}

/// Property: the tool's loads do the virtual work of its wrench (τ · q̇ = s_e · [v; ω],
/// CONVENTIONS.md "Forces"): a small motion of the joints against the loads costs the
/// work of lifting the tool; a wall pushes back only once the platform is in it.
#[test]
fn the_tools_loads_are_its_weight_through_the_jacobian() -> TestResult {
    let c = central()?;
    let mut p = Platform::new(c, 0.0)?;
    p.tool = Some(Tool::THESIS);
    let loads = p.joint_loads().ok_or("loads at the centre")?;
    // Raise the platform by 1 µm: the joints move by dq, the loads do -m g dz of work.
    let g = RsprGeometry::<f64>::reference();
    let up = Pose::central(g.hc + 1e-6);
    let q_up = inverse(&g, &up, Branch::OUTER)
        .map_err(|e| format!("{e:?}"))?
        .q();
    let work: f64 = (0..6).map(|j| loads[j] * (q_up[j] - c[j])).sum();
    let expected = -1.2 * 9.81 * 1e-6;
    assert!(
        (work - expected).abs() < 1e-3 * expected.abs(),
        "work {work} expected {expected}"
    );
    p.tool = None;
    p.wall = Some(Wall {
        point: Vector3::new(0.0, 0.0, g.hc - 0.001),
        normal: Vector3::new(0.0, 0.0, 1.0),
        stiffness_n_per_m: 1e5,
        damping_n_s_per_m: 0.0,
    });
    assert_eq!(p.joint_loads(), Some([0.0; 6]));
    assert_eq!(p.wall_force(), Vector3::zeros());
    p.wall = Some(Wall {
        point: Vector3::new(0.0, 0.0, g.hc + 0.001),
        ..p.wall.ok_or("the wall")?
    });
    let pushed = p.joint_loads().ok_or("loads in the wall")?;
    assert!(
        (p.wall_force().z - 100.0).abs() < 1e-9,
        "{}",
        p.wall_force()
    );
    assert!(pushed.iter().any(|l| l.abs() > 1.0), "{pushed:?}");
    Ok(())
}
