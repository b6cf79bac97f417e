#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The whole board application on the plant (`simulation::board`), driven over the wire
//! protocol by the in-process master (`simulation::bench`).

use master_link::{MasterToBoard, ResetCause, RobotState};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

fn bench() -> Bench {
    let cfg = BoardSimConfig::reference(None).unwrap();
    Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x5e55,
    )
}

/// Property: a master brings the simulated board up over the link (hello, home with the
/// park move, enable with the brake check) in virtual time, and a streamed target is
/// followed.
#[test]
fn a_master_brings_the_board_up_and_it_follows() {
    let mut b = bench();
    let t0 = std::time::Instant::now();
    b.bring_up().unwrap();
    let up = b.now_us();
    assert_eq!(b.board.runtime().state(), RobotState::Enabled);
    let target = MasterToBoard::PoseTarget {
        timestamp_us: b.now_us(),
        position_m: [0.003, 0.0, 0.161],
        rotation_vector_rad: [0.0; 3],
    };
    b.command(&target).unwrap();
    b.run_ms(1500).unwrap();
    let p = b.board.truth().pose.t;
    println!(
        "brought up in {:.2} s virtual ({:.2} s wall); at {:?}",
        up as f64 * 1e-6,
        t0.elapsed().as_secs_f64(),
        p
    );
    assert!(
        (p.x - 0.003).abs() < 0.1e-3 && (p.z - 0.161).abs() < 0.1e-3,
        "{p:?}"
    );
    let st = b.master.last_status().unwrap();
    assert_eq!(st.state, RobotState::Enabled);
}

/// Property (the stops issue): driven at 25 mm/s into a stiff wall (100 N/mm) 1 mm ahead,
/// the actuators' force stays within the configured limits (220 N per leg, 0.5 N m per
/// link: the motor's effort `n Kt i` times the transmission's efficiency, which the current
/// limit caps), the sustained overload trips within 10 ms, and the stop is STO. The peak
/// efforts the transmissions carried (with the load sides' inertia) are reported.
#[test]
fn pushing_into_a_wall_stays_within_the_force_limits_and_trips_the_overload() {
    use master_link::{FaultCause, StopStatus};
    use simulation::board::Wall;
    let mut b = bench();
    b.bring_up().unwrap();
    let p0 = b.board.truth().pose.t;
    b.board.set_wall(Some(Wall {
        point: nalgebra::Vector3::new(p0.x + 0.001, 0.0, 0.0),
        normal: nalgebra::Vector3::new(-1.0, 0.0, 0.0),
        stiffness_n_per_m: 1e5,
        damping_n_s_per_m: 200.0,
    }));
    // Targets 5 mm into the wall, streamed at 100 Hz as a ramp at 25 mm/s.
    let t0 = b.now_us();
    let mut peak_motor = [0.0f64; 6];
    let mut peak_transmitted = [0.0f64; 6];
    let mut peak_wall = 0.0f64;
    let mut at_limit_from: [Option<u64>; 6] = [None; 6];
    let mut trip: Option<(u64, u64)> = None;
    for k in 0..1500u64 {
        if k % 10 == 0 {
            let t = b.now_us();
            let x = p0.x + (0.025 * (t - t0) as f64 * 1e-6).min(0.006);
            b.send(&MasterToBoard::PoseTarget {
                timestamp_us: t,
                position_m: [x as f32, p0.y as f32, p0.z as f32],
                rotation_vector_rad: [0.0; 3],
            });
        }
        b.tick().unwrap();
        let truth = *b.board.truth();
        let rt = b.board.runtime();
        for j in 0..6 {
            peak_motor[j] = peak_motor[j].max(truth.peak_motor_effort[j]);
            peak_transmitted[j] = peak_transmitted[j].max(truth.peak_transmitted[j]);
            let at = rt.inputs().currents[j].abs() >= 0.9 * rt.monitors().current.peak_current(j);
            at_limit_from[j] = match (at_limit_from[j], at) {
                (None, true) => Some(b.now_us()),
                (f, true) => f,
                (_, false) => None,
            };
        }
        peak_wall = peak_wall.max(truth.wall_force.norm());
        if trip.is_none() && rt.state() == RobotState::Fault {
            let f = rt.status().fault;
            let j = usize::from(f.joint);
            trip = Some((
                b.now_us(),
                at_limit_from.get(j).copied().flatten().unwrap_or(0),
            ));
            assert_eq!(f.cause, FaultCause::Overload, "{f:?}");
            assert_eq!(rt.status().stop, StopStatus::SafeTorqueOff);
        }
    }
    let (t_trip, t_limit) = trip.expect("the overload trips");
    let cfg = b.board.config().plant.clone();
    let eff = |j: usize| {
        if j < 3 {
            let p = cfg.prismatic[j];
            p.drive.gear_efficiency * p.leadscrew_efficiency
        } else {
            cfg.rotary[j - 3].drive.gear_efficiency
        }
    };
    println!(
        "wall: peak contact force {:.1} N; overload tripped {:.1} ms after the current came to 90 % of its peak",
        peak_wall,
        (t_trip - t_limit) as f64 * 1e-3
    );
    let limit = [220.0, 220.0, 220.0, 0.5, 0.5, 0.5];
    for j in 0..6 {
        let delivered = peak_motor[j] * eff(j);
        println!(
            "  joint {j}: motor effort x efficiency {delivered:.3} (limit {}), transmission peak {:.3}",
            limit[j], peak_transmitted[j]
        );
        assert!(delivered <= limit[j] * 1.001, "joint {j}: {delivered}");
    }
    assert!(t_trip - t_limit <= 10_000, "{} us", t_trip - t_limit);
}
