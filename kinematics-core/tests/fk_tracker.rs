#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The FK tracker (one Newton step per control tick) agrees with the full forward
//! kinematics of the same joint readings, tick after tick, along random paths at the
//! speed limits, in f64 and f32.

use crate::common;

use common::*;
use kinematics_core::*;
use nalgebra::Vector3;
use proptest::prelude::*;

proptest! {
    #![proptest_config(proptest_config::cases(64))]

    /// 300 ticks at 25 mm/s and 30 deg/s (while the parallel measure stays above the
    /// guards' warn level 0.03 and the joints within the reference speed limits): the
    /// tracker takes at most two steps per tick (never the full solver), one with the
    /// factors of an earlier tick (a chord step) on most ticks, its joint residual stays
    /// below TRACK_RESIDUAL_MAX and its pose equals the full FK's to 1e-6 m / 3e-6 rad (f64:
    /// the residual a chord step leaves at this speed, up to an eighth of
    /// TRACK_RESIDUAL_MAX before the factors are taken again; the encoders resolve 1.5 µm
    /// and 87 µrad) and 2 µm / 2e-5 rad (f32, against the f64 full FK).
    #[test]
    fn tracker_follows_the_full_solver(
        start in pose_near_box(0.16),
        dir in proptest::array::uniform3(-1.0f64..1.0),
        axis in proptest::array::uniform3(-1.0f64..1.0),
    ) {
        let g = RsprGeometry::<f64>::reference();
        let g32 = RsprGeometry::<f32>::reference();
        let cfg = FkConfig::<f64>::default();
        let cfg32 = FkConfig::<f32>::default();
        let d = Vector3::from(dir).normalize() * 25e-6;
        let w = Vector3::from(axis).normalize() * 30f64.to_radians() * 1e-3;
        let Ok(s0) = inverse(&g, &start, Branch::OUTER) else { return Ok(()) };
        let mut tr = FkTracker::new(&g, &s0.q(), Branch::OUTER, &start, &cfg).unwrap();
        let mut tr32 = FkTracker::new(&g32, &s0.q().cast::<f32>(), Branch::OUTER,
            &start.cast::<f32>(), &cfg32).unwrap();
        let mut pose = start;
        let limits = kinematics_core::guards::Limits::<f64>::reference();
        let mut q_prev = s0.q();
        for k in 0..300 {
            pose = pose.displaced(&d, &w);
            let Ok(s) = inverse(&g, &pose, Branch::OUTER) else { break };
            // Inside the guards' parallel warn level and joint speed limits (the robot never
            // goes further or faster).
            if measures(&g, &s).map_or(true, |m| m.parallel_inv_cond < 0.03) {
                break;
            }
            let q = s.q();
            let dq = q - q_prev;
            q_prev = q;
            let too_fast = (0..6).any(|j| {
                let lim = if j < 3 { limits.joint_speed[0] } else { limits.joint_speed[1] };
                dq[j].abs() > lim * 1e-3
            });
            if too_fast {
                break;
            }
            let t = tr.update(&g, &q, &cfg).unwrap();
            prop_assert!(!matches!(t, Tracked::Solved { .. }),
                "tick {k}: {t:?}");
            let full = forward(&g, &q, Branch::OUTER, &pose, &cfg).unwrap();
            let (el, ea) = pose_error(tr.pose(), &full.pose);
            prop_assert!(tr.residual() <= fk::TRACK_RESIDUAL_MAX, "tick {k}: residual {:e}", tr.residual());
            prop_assert!(el < 1e-6 && ea < 3e-6, "tick {k}: f64 {el:e} m {ea:e} rad");
            let t32 = tr32.update(&g32, &q.cast::<f32>(), &cfg32);
            prop_assert!(matches!(t32, Ok(Tracked::Stepped { .. } | Tracked::Unchanged)), "tick {k}: f32 {t32:?}");
            let (el, ea) = pose_error(&tr32.pose().cast::<f64>(), &full.pose);
            prop_assert!(el < 2e-6 && ea < 2e-5, "tick {k}: f32 {el:e} m {ea:e} rad");
        }

    }
}

/// Standing still, the tracker does no work (no step) once converged.
#[test]
fn tracker_is_idle_while_the_joints_stand_still() {
    let g = RsprGeometry::<f64>::reference();
    let cfg = FkConfig::<f64>::default();
    let p = Pose::central(g.hc);
    let q = inverse(&g, &p, Branch::OUTER).unwrap().q();
    let mut tr = FkTracker::new(&g, &q, Branch::OUTER, &p, &cfg).unwrap();
    for _ in 0..10 {
        assert_eq!(tr.update(&g, &q, &cfg).unwrap(), Tracked::Unchanged);
    }
    assert!(tr.residual() <= cfg.tol_linear);
}

/// A jump of the readings (e.g. after re-homing) is followed by the full solver, and a
/// non-finite reading is refused without losing the estimate.
#[test]
fn tracker_recovers_from_a_jump_and_refuses_nan() {
    let g = RsprGeometry::<f64>::reference();
    let cfg = FkConfig::<f64>::default();
    let p = Pose::central(g.hc);
    let q = inverse(&g, &p, Branch::OUTER).unwrap().q();
    let mut tr = FkTracker::new(&g, &q, Branch::OUTER, &p, &cfg).unwrap();
    let far = p.displaced(
        &Vector3::new(0.02, -0.015, -0.01),
        &Vector3::new(0.2, 0.1, 0.0),
    );
    let q_far = inverse(&g, &far, Branch::OUTER).unwrap().q();
    let t = tr.update(&g, &q_far, &cfg).unwrap();
    assert!(matches!(t, Tracked::Solved { .. }), "{t:?}");
    let (el, ea) = pose_error(tr.pose(), &far);
    assert!(el < 1e-9 && ea < 1e-9);
    let mut bad = q_far;
    bad[4] = f64::NAN;
    assert_eq!(
        tr.update(&g, &bad, &cfg),
        Err(FkError::NonFiniteInput { index: 4 })
    );
    assert_eq!(tr.pose(), &tr.pose().clone());
    let (el, _) = pose_error(tr.pose(), &far);
    assert!(el < 1e-9);
}
