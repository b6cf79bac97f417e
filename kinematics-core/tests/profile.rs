#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The supervisor's motion profile (`supervisor::profile`), function by function, on
//! random states: the braking curve stops within the distance, one step never changes the
//! speed by more than a·dt nor exceeds the cap, a profile run from rest reaches the goal
//! without overshoot within the time a trapezoid needs, a controlled stop takes |v|/a,
//! the speed caps and the joint-safe accelerations keep every joint within its limits,
//! and the braking point looks exactly as far as stated, never past the horizon.
//! Bounds are relative rounding of f64 (a few ε on the quantities compared).

use kinematics_core::supervisor::profile::{
    arrived, braking_accels, braking_point, braking_speed, jac_times, joint_safe_accels,
    limit_step, slowing_step, speed_caps, step_braking, step_scales, step_towards, stop_point,
    ProfileLimits, StepLimits, BRAKING_SHARE, RESCALE_SHARE,
};
use kinematics_core::{JointKind, Pose};
use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};
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

/// Joint rates (or changes of them) up to `linear` on the legs and `angular` on the links.
fn joint_rates(linear: f64, angular: f64) -> impl Strategy<Value = Vector6<f64>> {
    (
        prop::array::uniform3(-linear..linear),
        prop::array::uniform3(-angular..angular),
    )
        .prop_map(|(l, a)| Vector6::new(l[0], l[1], l[2], a[0], a[1], a[2]))
}

fn step_limits() -> StepLimits<f64> {
    StepLimits {
        tip_accel: 0.25,
        angular_accel: 300f64.to_radians(),
        joint_speed: [0.06, 3.0],
        joint_accel: [2.0, 60.0],
    }
}

/// Whether the output β·t1 (joint rates β·c) keeps every limit `step_scales` promises,
/// with a relative slack `tol`.
fn step_keeps_limits(
    beta: f64,
    t0: &Vector6<f64>,
    t1: &Vector6<f64>,
    qd0: &Vector6<f64>,
    c: &Vector6<f64>,
    tol: f64,
) -> bool {
    let (l, dt, share) = (step_limits(), 1e-3, RESCALE_SHARE);
    let dt_v = (t1.fixed_rows::<3>(0) * beta - t0.fixed_rows::<3>(0)).norm();
    let dt_w = (t1.fixed_rows::<3>(3) * beta - t0.fixed_rows::<3>(3)).norm();
    let mut ok =
        dt_v <= l.tip_accel * dt * (1.0 + tol) && dt_w <= l.angular_accel * dt * (1.0 + tol);
    for (j, k) in KINDS.iter().enumerate() {
        let i = usize::from(*k == JointKind::Angular);
        ok &= (beta * c[j] - qd0[j]).abs() <= share * l.joint_accel[i] * dt * (1.0 + tol);
        ok &= (beta * c[j]).abs() <= share * l.joint_speed[i] * (1.0 + tol);
    }
    ok
}

proptest! {
    #![proptest_config(proptest_config::cases(2000))]

    /// The braking decelerations keep J·Δ within headroom × each joint's acceleration
    /// limit for the change Δ of braking along the twist, and are never below the
    /// joint-safe accelerations (which bound every direction of change).
    #[test]
    fn braking_accels_bound_every_joint_and_never_undercut_the_joint_safe_ones(
        j in jacobian(), v0 in vector(0.03), w0 in vector(0.6),
    ) {
        let l = limits();
        let joint_accel = [2.0, 60.0];
        let headroom = 0.8;
        let (at, aw) = braking_accels(&j, &KINDS, &v0, &w0, l.tip_accel, l.angular_accel, &joint_accel, headroom);
        prop_assert!(at <= l.tip_accel && aw <= l.angular_accel);
        let (bt, bw) = joint_safe_accels(&j, &KINDS, l.tip_accel, l.angular_accel, &joint_accel, headroom);
        prop_assert!(at >= bt * (1.0 - 1e-12) && aw >= bw * (1.0 - 1e-12), "{at} < {bt} or {aw} < {bw}");
        let (a, b) = (v0.normalize() * at, w0.normalize() * aw);
        let qdd = jac_times(&j, &[a.x, a.y, a.z, b.x, b.y, b.z]);
        for (q, k) in qdd.iter().zip(KINDS) {
            let lim = if k == JointKind::Linear { joint_accel[0] } else { joint_accel[1] };
            prop_assert!(q.abs() <= headroom * lim * (1.0 + 1e-9));
        }
    }

    /// A slowing step changes each speed by at most its Cartesian acceleration in one tick,
    /// towards the desired twist; J·Δ stays within headroom × each joint's acceleration
    /// limit; and it moves at least as far towards the desired twist as a step at the
    /// joint-safe accelerations (which bound every direction of change).
    #[test]
    fn a_slowing_step_is_joint_limited_and_never_weaker_than_the_joint_safe_one(
        j in jacobian(), v0 in vector(0.03), w0 in vector(0.6), kv in 0.0f64..1.0, kw in 0.0f64..1.0,
    ) {
        let l = limits();
        let (joint_accel, headroom, dt) = ([2.0, 60.0], 0.8, 1e-3);
        let (vd, wd) = (v0 * kv, w0 * kw);
        let (at, aw) = joint_safe_accels(&j, &KINDS, l.tip_accel, l.angular_accel, &joint_accel, headroom);
        let (v1, w1) = slowing_step(&j, &KINDS, (&v0, &w0), (&vd, &wd), (at, aw), (l.tip_accel, l.angular_accel), &joint_accel, headroom, dt);
        let (dv, dw) = (v1 - v0, w1 - w0);
        prop_assert!(dv.norm() <= l.tip_accel * dt * (1.0 + 1e-12) && dw.norm() <= l.angular_accel * dt * (1.0 + 1e-12));
        // Along the desired change, never past it.
        prop_assert!(dv.dot(&(vd - v0)) >= -1e-18 && dv.norm() <= (vd - v0).norm() * (1.0 + 1e-12));
        prop_assert!(dw.dot(&(wd - w0)) >= -1e-18 && dw.norm() <= (wd - w0).norm() * (1.0 + 1e-12));
        let qdd = jac_times(&j, &[dv.x, dv.y, dv.z, dw.x, dw.y, dw.z]);
        for (q, k) in qdd.iter().zip(KINDS) {
            let lim = if k == JointKind::Linear { joint_accel[0] } else { joint_accel[1] };
            prop_assert!(q.abs() <= headroom * lim * dt * (1.0 + 1e-9));
        }
        let safe_v = v0 + limit_step(vd - v0, at, dt);
        let safe_w = w0 + limit_step(wd - w0, aw, dt);
        prop_assert!((v1 - vd).norm() <= (safe_v - vd).norm() + 1e-15, "linear: {} > {}", (v1 - vd).norm(), (safe_v - vd).norm());
        prop_assert!((w1 - wd).norm() <= (safe_w - wd).norm() + 1e-13, "angular: {} > {}", (w1 - wd).norm(), (safe_w - wd).norm());
    }

    /// Every scale `step_scales` returns keeps the Cartesian accelerations, and the joint
    /// rates within the share of their speed and acceleration limits, the interval lies in
    /// [0, 1]; and when it returns none, no scale on a fine grid of [0, 1] does. The states
    /// are those of a step near a serial singularity: joint rates up to their
    /// limits and changes of up to the acceleration limits in one tick.
    #[test]
    fn step_scales_keep_every_limit_and_miss_none(
        v0 in vector(0.03), w0 in vector(0.6), dv in vector(0.00015), dw in vector(0.003),
        qd0 in joint_rates(0.06, 3.0), dq in joint_rates(0.002, 0.06),
    ) {
        let t0 = Vector6::new(v0.x, v0.y, v0.z, w0.x, w0.y, w0.z);
        let t1 = t0 + Vector6::new(dv.x, dv.y, dv.z, dw.x, dw.y, dw.z);
        let c = qd0 + dq;
        let found = step_scales(&t0, &t1, &qd0, &c, &KINDS, &step_limits(), 1e-3);
        match found {
            Some((lo, hi)) => {
                prop_assert!((0.0..=1.0).contains(&lo) && lo <= hi && hi <= 1.0, "[{lo}, {hi}]");
                for beta in [lo, 0.5 * (lo + hi), hi] {
                    prop_assert!(step_keeps_limits(beta, &t0, &t1, &qd0, &c, 1e-9), "beta {beta}");
                }
            }
            None => {
                for k in 0..=10_000 {
                    let beta = f64::from(k) / 10_000.0;
                    prop_assert!(!step_keeps_limits(beta, &t0, &t1, &qd0, &c, -1e-9), "missed beta {beta}");
                }
            }
        }
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
