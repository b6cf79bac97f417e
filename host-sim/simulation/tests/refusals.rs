#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Every refused target gets its own answer naming the guard or rule that refused it, the
//! value and the limit with their unit: the whole board application on the plant
//! (`simulation::board`) over the wire protocol, rendered by `board_words` as every front
//! end renders it.

use master_link::{BoardToMaster, GuardId, MasterToBoard, NackReason, RefusedTarget, ResetCause};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

/// A target (position mm, rotation vector deg), the guard and rule expected, the words,
/// and whether the path check refuses it after its Ack.
type Case = ([f32; 3], [f32; 3], GuardId, NackReason, &'static str, bool);

fn bench() -> Bench {
    let cfg = BoardSimConfig::reference(None).unwrap();
    Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        0x5e55,
    )
}

/// Sends a pose target (position mm, rotation vector deg) and runs 300 ms; the board's
/// answer to it: the reply to its frame when refused at once, else a refusal of the path
/// check naming its stamp, if any.
fn refusal_of(b: &mut Bench, mm: [f32; 3], deg: [f32; 3]) -> Option<RefusedTarget> {
    let stamp = b.now_us();
    let seq = b.send(&MasterToBoard::PoseTarget {
        timestamp_us: stamp,
        position_m: mm.map(|x| x * 1e-3),
        rotation_vector_rad: deg.map(f32::to_radians),
    });
    b.run_ms(300).unwrap();
    if let Some((_, BoardToMaster::TargetRefused(r))) = b.master.replies.get(&seq) {
        assert_eq!(r.reply_to, Some(seq));
        return Some(*r);
    }
    b.master
        .refused
        .iter()
        .find(|r| r.reply_to.is_none() && r.timestamp_us == stamp)
        .copied()
}

/// One target per guard: just outside the box (z = 177 mm against 175: refused by the
/// path check after its Ack, and still answered), far outside it (z = 400 mm: the
/// workspace, not the step to it, is named), tilted past the platform's tilt cone; and a
/// target before homing (the rule, "not homed"). The text names the guard, the subject,
/// the value and the limit.
#[test]
fn every_refused_target_is_answered_with_guard_value_and_limit() {
    let mut b = bench();
    let hello = b.hello_msg();
    b.request(&hello, 100).unwrap();
    // Before homing: the rule.
    let seq = b.send(&MasterToBoard::PoseTarget {
        timestamp_us: b.now_us(),
        position_m: [0.0, 0.0, 0.16],
        rotation_vector_rad: [0.0; 3],
    });
    b.run_ms(20).unwrap();
    let Some((_, BoardToMaster::Nack { reason, .. })) = b.master.replies.get(&seq) else {
        panic!("no Nack: {:?}", b.master.replies.get(&seq));
    };
    assert_eq!(
        board_words::reason(*reason),
        "not homed: home the robot first"
    );

    b.bring_up().unwrap();
    b.run_ms(200).unwrap();
    let cases: [Case; 3] = [
        (
            [0.0, 0.0, 177.0],
            [0.0; 3],
            GuardId::Workspace,
            NackReason::OutOfWorkspace,
            "workspace z 177.0 mm > 175.0 mm",
            true,
        ),
        (
            [0.0, 0.0, 400.0],
            [0.0; 3],
            GuardId::Workspace,
            NackReason::OutOfWorkspace,
            "workspace z 400.0 mm > 175.0 mm",
            false,
        ),
        (
            [0.0, 0.0, 160.0],
            [28.0, 0.0, 0.0],
            GuardId::TiltCone,
            NackReason::OutOfWorkspace,
            "platform tilt 28.0 deg > 25.0 deg",
            true,
        ),
    ];
    for (mm, deg, guard, reason, text, later) in cases {
        let r = refusal_of(&mut b, mm, deg).unwrap_or_else(|| panic!("{text}: no answer"));
        assert_eq!(r.breach.guard, guard, "{text}");
        assert_eq!(r.reason, reason, "{text}");
        assert_eq!(r.reply_to.is_none(), later, "{text}: refused later");
        assert_eq!(board_words::refusal(&r), text);
    }
    // Each refused target is counted once.
    assert_eq!(b.master.refused.len(), 3);
}
