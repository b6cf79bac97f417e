#![allow(clippy::unwrap_used, clippy::expect_used)]
//! A master target travels over the wire protocol into the setpoint supervisor: frames
//! encoded by the master, garbage and replays on the line, decoded by the board's decoder,
//! turned into a pose and followed by the supervisor.

use kinematics_core::guards::Limits;
use kinematics_core::supervisor::{Supervisor, SupervisorConfig};
use kinematics_core::*;
use master_link::*;
use nalgebra::Vector3;

#[test]
fn pose_targets_over_the_link_reach_the_supervisor() {
    let mut sup: Supervisor<f32, RsprGeometry<f32>> = Supervisor::new(
        RsprGeometry::reference(),
        Branch::OUTER,
        Limits::reference(),
        SupervisorConfig::default(),
        &Pose::central(0.160),
    )
    .unwrap();
    let mut decoder = BoardDecoder::new();
    let mut seq = SeqCounter::default();
    let mut wire = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let target = MasterToBoard::PoseTarget {
        timestamp_us: 1_000,
        position_m: [0.005, -0.004, 0.162],
        rotation_vector_rad: [0.02, 0.0, -0.01],
    };
    let header = Header {
        session: 7,
        seq: seq.next(),
    };
    let n = encode(&target, header, &mut buf).unwrap();
    wire.extend_from_slice(&buf[..n]);
    // Garbage on the line, then the same frame replayed.
    wire.extend_from_slice(&[0x13, 0x37, 0xff, 0x00]);
    wire.extend_from_slice(&buf[..n]);
    let mut accepted = 0;
    for result in decoder.feed(&wire) {
        if let Ok((
            _,
            MasterToBoard::PoseTarget {
                timestamp_us,
                position_m,
                rotation_vector_rad,
            },
        )) = result
        {
            let pose = Pose::from_position_rotation_vector(
                Vector3::from_row_slice(&position_m),
                Vector3::from_row_slice(&rotation_vector_rad),
            )
            .unwrap();
            sup.submit(&pose, timestamp_us, timestamp_us).unwrap();
            accepted += 1;
        }
    }
    let c = decoder.counters();
    assert_eq!(accepted, 1);
    assert!(c.out_of_order >= 1, "the replay is refused: {c:?}");
    assert!(c.rejected() >= 2, "garbage and replay are counted: {c:?}");
    for _ in 0..2000 {
        sup.tick();
    }
    let reached = sup.setpoint().t;
    assert!(
        (reached - Vector3::new(0.005, -0.004, 0.162)).norm() < 1e-6,
        "{reached:?}"
    );
}
