#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The supervisor's motion profile (`supervisor::profile`), function by function, on
//! random states: the braking curve stops within the distance, one step never changes the
//! speed by more than a·dt nor exceeds the cap, a profile run from rest reaches the goal
//! without overshoot within the time a trapezoid needs, a controlled stop takes |v|/a,
//! the speed caps and the joint-safe accelerations keep every joint within its limits,
//! and the braking point looks exactly as far as stated, never past the horizon.
//! Bounds are relative rounding of f64 (a few ε on the quantities compared).

use kinematics_core::supervisor::profile::{
    arrived, braking_point, braking_speed, jac_times, joint_safe_accels, limit_step, speed_caps,
    step_braking, step_towards, stop_point, ProfileLimits, BRAKING_SHARE,
};
use kinematics_core::{JointKind, Pose};
use nalgebra::{Matrix6, Rotation3, Vector3};
use proptest::prelude::*;

const EPS: f64 = 1e-12;

fn unit() -> impl Strategy<Value = Vector3<f64>> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
        .prop_filter("not tiny", |(x, y, z)| x * x + y * y + z * z > 0.01)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z).normalize())
}

fn vector(scale: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-scale..scale, -scale..scale, -scale..scale).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

/// A Jacobian of the size of the robot's (rows in m/s or rad/s per m/s or rad/s of the
/// platform): entries up to 20, the first three rows prismatic.
fn jacobian() -> impl Strategy<Value = Matrix6<f64>> {
    proptest::collection::vec(-20.0f64..20.0, 36).prop_map(|v| Matrix6::from_column_slice(&v))
}

const KINDS: [JointKind; 6] = [
    JointKind::Linear,
    JointKind::Linear,
    JointKind::Linear,
    JointKind::Angular,
    JointKind::Angular,
    JointKind::Angular,
];

fn limits() -> ProfileLimits<f64> {
    ProfileLimits {
        tip_speed: 0.025,
        angular_speed: 30f64.to_radians(),
        tip_accel: 0.25,
        angular_accel: 300f64.to_radians(),
    }
}

proptest! {
    #![proptest_config(proptest_config::cases(2000))]

    /// The braking curve's speed v satisfies v·dt + v²/2a' = d (a' = 0.95 a): after the
    /// step the distance left is exactly what braking at a' needs.
    #[test]
    fn braking_speed_stops_within_the_distance(d in 0.0f64..0.1, a in 0.01f64..10.0, dt in 1e-4f64..0.01) {
        let v = braking_speed(d, a, dt);
        let ap = a * BRAKING_SHARE;
        prop_assert!(v >= -EPS);
        let used = v * dt + v * v / (2.0 * ap);
        prop_assert!((used - d).abs() <= EPS * (1.0 + d), "{used} vs {d}");
    }

    /// A limited step is at most a·dt long, keeps its direction, and is unchanged when
    /// already short enough.
    #[test]
    fn limit_step_caps_the_change(dv in vector(1.0), a in 0.01f64..10.0, dt in 1e-4f64..0.01) {
        let s = limit_step(dv, a, dt);
        prop_assert!(s.norm() <= a * dt * (1.0 + EPS));
        if dv.norm() <= a * dt {
            prop_assert_eq!(s, dv);
        } else {
            prop_assert!((s.normalize() - dv.normalize()).norm() < 1e-9);
        }
    }

    /// One step towards the goal changes the speed by at most a·dt and ends no faster than
    /// the larger of the start speed and the cap.
    #[test]
    fn a_step_is_acceleration_and_speed_limited(
        v0 in vector(0.05), dir in unit(), d in 0.0f64..0.05, cap in 0.0f64..0.05,
    ) {
        let (a, dt) = (0.25, 1e-3);
        let v1 = step_towards(&v0, &dir, d, cap, a, dt);
        prop_assert!((v1 - v0).norm() <= a * dt * (1.0 + EPS));
        prop_assert!(v1.norm() <= v0.norm().max(cap) * (1.0 + EPS) + EPS);
    }

    /// From rest, ticking the profile towards a goal d away (the supervisor's loop: the
    /// braking curve on the distance left, the arrival test) never overshoots, never
    /// exceeds the cap or the acceleration, and arrives within the time of the trapezoid
    /// with the planning deceleration plus ten ticks.
    #[test]
    fn a_profile_from_rest_reaches_the_goal_without_overshoot(d in 1e-6f64..0.06, cap in 0.002f64..0.025) {
        let l = limits();
        let dt = 1e-3;
        let (mut x, mut v) = (0.0f64, Vector3::zeros());
        let dir = Vector3::x();
        let ap = l.tip_accel * BRAKING_SHARE;
        let t_accel = cap / ap;
        let trapezoid = if d > cap * t_accel { d / cap + t_accel } else { 2.0 * (d / ap).sqrt() };
        let ticks = (trapezoid / dt).ceil() as usize + 10;
        let mut done = false;
        for _ in 0..ticks {
            let left = d - x;
            if arrived(left.abs(), 0.0, &v, &Vector3::zeros(), &l, dt) {
                done = true;
                break;
            }
            let v1 = step_towards(&v, &dir, left.max(0.0), cap, l.tip_accel, dt);
            prop_assert!((v1 - v).norm() <= l.tip_accel * dt * (1.0 + EPS));
            prop_assert!(v1.norm() <= cap * (1.0 + EPS));
            v = v1;
            x += v.x * dt;
            prop_assert!(x <= d + EPS, "overshoot {x} > {d}");
        }
        prop_assert!(done, "did not arrive within {ticks} ticks: {x} of {d}");
    }

    /// A controlled stop loses a·dt of speed per tick along the same direction, so it
    /// stands after ⌈|v|/(a·dt)⌉ ticks, within |v|²/2a + |v|·dt of where it began, which is
    /// at most one tick's travel beyond the stop point.
    #[test]
    fn a_controlled_stop_takes_v_over_a(v0 in vector(0.03)) {
        let l = limits();
        let dt = 1e-3;
        let mut v = v0;
        let mut travelled = Vector3::zeros();
        let n = (v0.norm() / (l.tip_accel * dt)).ceil() as usize;
        for _ in 0..n {
            let v1 = step_braking(&v, l.tip_accel, dt);
            prop_assert!(v1.norm() <= v.norm());
            if v.norm() > 0.0 && v1.norm() > 0.0 {
                prop_assert!((v1.normalize() - v.normalize()).norm() < 1e-9);
            }
            v = v1;
            travelled += v * dt;
        }
        prop_assert!(v.norm() <= EPS);
        let start = Pose::central(0.16);
        let stop = stop_point(&v0, &Vector3::zeros(), &start, &l);
        let to_stop = (stop.t - start.t).norm();
        prop_assert!((to_stop - v0.norm().powi(2) / (2.0 * l.tip_accel)).abs() <= EPS);
        prop_assert!(travelled.norm() <= to_stop + v0.norm() * dt + EPS);
    }

    /// The speed caps keep J·[v; ω] within headroom × each joint's speed limit, scaling
    /// the tip and angular caps together, never above the limits.
    #[test]
    fn speed_caps_keep_every_joint_within_its_limit(j in jacobian(), dv in unit(), dw in unit()) {
        let l = limits();
        let joint_speed = [0.06, 3.0];
        let headroom = 0.8;
        let (vc, wc) = speed_caps(&j, &KINDS, &l, &joint_speed, headroom, &dv, &dw);
        prop_assert!(vc <= l.tip_speed && wc <= l.angular_speed);
        prop_assert!((vc / l.tip_speed - wc / l.angular_speed).abs() < 1e-12);
        let qd = jac_times(&j, &[dv.x * vc, dv.y * vc, dv.z * vc, dw.x * wc, dw.y * wc, dw.z * wc]);
        for (q, k) in qd.iter().zip(KINDS) {
            let lim = if k == JointKind::Linear { joint_speed[0] } else { joint_speed[1] };
            prop_assert!(q.abs() <= headroom * lim * (1.0 + 1e-9), "{q} > {}", headroom * lim);
        }
    }

    /// With the joint-safe accelerations, no change of twist within them moves a joint's
    /// rate by more than headroom × its acceleration limit per second, whatever its
    /// direction.
    #[test]
    fn joint_safe_accels_bound_every_joint(j in jacobian(), dv in unit(), dw in unit(), sv in 0.0f64..1.0, sw in 0.0f64..1.0) {
        let l = limits();
        let joint_accel = [2.0, 60.0];
        let headroom = 0.8;
        let (at, aw) = joint_safe_accels(&j, &KINDS, l.tip_accel, l.angular_accel, &joint_accel, headroom);
        prop_assert!(at <= l.tip_accel && aw <= l.angular_accel);
        let (a, b) = (dv * (at * sv), dw * (aw * sw));
        let qdd = jac_times(&j, &[a.x, a.y, a.z, b.x, b.y, b.z]);
        for (q, k) in qdd.iter().zip(KINDS) {
            let lim = if k == JointKind::Linear { joint_accel[0] } else { joint_accel[1] };
            prop_assert!(q.abs() <= headroom * lim * (1.0 + 1e-9));
        }
    }

    /// The braking point is v'²/2a + n·v'·dt ahead along the twist (v' = |v| + a(n - 1)dt)
    /// when the horizon is farther, and never past the horizon.
    #[test]
    fn the_braking_point_looks_as_far_as_stated(speed in 1e-4f64..0.025, dir in unit(), horizon_mm in 0.0f64..60.0) {
        let l = limits();
        let dt = 1e-3;
        let n = 39.0;
        let pose = Pose { t: Vector3::new(0.0, 0.0, 0.16), r: Rotation3::identity() };
        let v0 = dir * speed;
        let horizon = Pose { t: pose.t + dir * (horizon_mm * 1e-3), r: pose.r };
        let p = braking_point(&pose, &v0, &Vector3::zeros(), &horizon, &l, n, dt);
        let ahead = (p.t - pose.t).norm();
        let vp = speed + l.tip_accel * (n - 1.0) * dt;
        let stated = vp * vp / (2.0 * l.tip_accel) + n * vp * dt;
        prop_assert!((ahead - stated.min(horizon_mm * 1e-3)).abs() <= 1e-12);
        prop_assert!((p.t - pose.t).dot(&dir) >= -1e-15);
    }
}

/// At the reference limits the braking point at 25 mm/s is 3.7 mm ahead (L = 13 ticks per
/// evaluation, n = 3L), the figure the supervisor's documentation states.
#[test]
fn the_braking_point_at_full_speed_is_3_7_mm() {
    let l = limits();
    let pose = Pose::central(0.16);
    let far = Pose {
        t: pose.t + Vector3::x() * 0.1,
        r: pose.r,
    };
    let p = braking_point(
        &pose,
        &(Vector3::x() * 0.025),
        &Vector3::zeros(),
        &far,
        &l,
        39.0,
        1e-3,
    );
    let ahead_mm = (p.t - pose.t).norm() * 1e3;
    assert!((ahead_mm - 3.7).abs() < 0.05, "{ahead_mm} mm");
}
