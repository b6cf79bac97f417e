//! The supervisor's motion profile, as pure functions of the state and the limits: the
//! Cartesian speed caps that keep every joint within its speed limit, the accelerations
//! every joint can follow, the discrete braking curve, one acceleration-limited step of the
//! twist, where braking stops, the braking point the checker looks at, and the arrival
//! test. The supervisor's tick composes them; `tests/profile.rs` checks each.

use crate::mechanism::JointKind;
use crate::pose::{rotation_vector, Pose};
use crate::scalar::{lit, norm3, sqrt, Real};
use crate::vectors::{Joints, Twist};
use nalgebra::{Matrix6, Vector3};

/// The Cartesian limits the profile runs within (already scaled to what the joints can
/// follow, see [`joint_safe_accels`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProfileLimits<T: Real> {
    /// Largest tip speed, m/s.
    pub tip_speed: T,
    /// Largest angular speed, rad/s.
    pub angular_speed: T,
    /// Largest tip acceleration, m/s².
    pub tip_accel: T,
    /// Largest angular acceleration, rad/s².
    pub angular_accel: T,
}

/// The share of the braking deceleration the braking curve plans with (5 % in hand: the
/// acceleration scale changes along the way).
pub const BRAKING_SHARE: f64 = 0.95;

/// J·x, written out over J's column arrays (nalgebra's generic product, and loops, cost
/// several times the arithmetic on the Cortex-M4).
pub fn jac_times<T: Real>(j: &Matrix6<T>, x: &[T; 6]) -> [T; 6] {
    let [c0, c1, c2, c3, c4, c5] = &j.data.0;
    let [x0, x1, x2, x3, x4, x5] = *x;
    macro_rules! row {
        ($i:literal) => {
            c0[$i] * x0 + c1[$i] * x1 + c2[$i] * x2 + c3[$i] * x3 + c4[$i] * x4 + c5[$i] * x5
        };
    }
    [row!(0), row!(1), row!(2), row!(3), row!(4), row!(5)]
}

/// The limit of a joint of `kind` from a [prismatic, revolute] pair.
pub fn of_kind<T: Real>(pair: &[T; 2], kind: JointKind) -> T {
    match kind {
        JointKind::Linear => pair[0],
        JointKind::Angular => pair[1],
    }
}

/// The largest factor s ≤ 1 with s·|x_j| ≤ `headroom` × the limit of joint j's kind
/// (`limits`: [prismatic, revolute]) for every joint: how far a motion whose joint rates
/// (or changes of them) are `x` may go.
pub fn joint_scale<T: Real>(x: &[T; 6], kinds: &[JointKind; 6], limits: &[T; 2], headroom: T) -> T {
    let mut scale = T::one();
    for (v, kind) in x.iter().zip(kinds.iter()) {
        let lim = of_kind(limits, *kind) * headroom;
        if v.abs() * scale > lim {
            scale = lim / v.abs();
        }
    }
    scale
}

/// Speed caps (m/s, rad/s) for motion along the unit directions `dir_v`, `dir_w` at the
/// Jacobian `j`: the tip and angular speed limits, scaled down together so that
/// q̇ = J·[v; ω] stays within `headroom` × each joint's speed limit `joint_speed`
/// ([prismatic, revolute]).
pub fn speed_caps<T: Real>(
    j: &Matrix6<T>,
    kinds: &[JointKind; 6],
    limits: &ProfileLimits<T>,
    joint_speed: &[T; 2],
    headroom: T,
    dir_v: &Vector3<T>,
    dir_w: &Vector3<T>,
) -> (T, T) {
    let (vmax, wmax) = (limits.tip_speed, limits.angular_speed);
    let probe = [
        dir_v.x * vmax,
        dir_v.y * vmax,
        dir_v.z * vmax,
        dir_w.x * wmax,
        dir_w.y * wmax,
        dir_w.z * wmax,
    ];
    let scale = joint_scale(&jac_times(j, &probe), kinds, joint_speed, headroom);
    (vmax * scale, wmax * scale)
}

/// The Cartesian acceleration limits (`tip_accel`, `angular_accel`) scaled down so that no
/// joint exceeds `headroom` × its acceleration limit `joint_accel` whatever the direction
/// of the change of twist, at the Jacobian `j`: |J_j·Δ| ≤ |J_j,v|·|Δv| + |J_j,ω|·|Δω|
/// (Cauchy-Schwarz, per row).
pub fn joint_safe_accels<T: Real>(
    j: &Matrix6<T>,
    kinds: &[JointKind; 6],
    tip_accel: T,
    angular_accel: T,
    joint_accel: &[T; 2],
    headroom: T,
) -> (T, T) {
    let (at, aw) = (tip_accel, angular_accel);
    // Squared norms of each row's [v] and [ω] halves, over the column arrays.
    let [c0, c1, c2, c3, c4, c5] = &j.data.0;
    macro_rules! halves {
        ($i:literal) => {
            (
                c0[$i] * c0[$i] + c1[$i] * c1[$i] + c2[$i] * c2[$i],
                c3[$i] * c3[$i] + c4[$i] * c4[$i] + c5[$i] * c5[$i],
            )
        };
    }
    let rows = [
        halves!(0),
        halves!(1),
        halves!(2),
        halves!(3),
        halves!(4),
        halves!(5),
    ];
    let worst = rows.map(|(v2, w2)| sqrt(v2) * at + sqrt(w2) * aw);
    let scale = joint_scale(&worst, kinds, joint_accel, headroom);
    (at * scale, aw * scale)
}

/// The decelerations (tip, angular) of a controlled stop along the twist (`v0`, `w0`) that
/// every joint can follow at the Jacobian `j`: `tip_accel` and `angular_accel` scaled down
/// together until J·Δ stays within `headroom` × each joint's acceleration limit, Δ the
/// change of twist of braking (each part against its own speed, at its own deceleration).
/// For this one direction of change the bound is exact, so it is never below
/// [`joint_safe_accels`] (which bounds every direction): braking along the twist mostly
/// slows each joint down in proportion to its rate, and near a serial singularity, where
/// J is large in some directions, it keeps the full deceleration the braking points were
/// checked with.
#[allow(clippy::too_many_arguments)]
pub fn braking_accels<T: Real>(
    j: &Matrix6<T>,
    kinds: &[JointKind; 6],
    v0: &Vector3<T>,
    w0: &Vector3<T>,
    tip_accel: T,
    angular_accel: T,
    joint_accel: &[T; 2],
    headroom: T,
) -> (T, T) {
    let unit = |x: &Vector3<T>, a: T| {
        let n = norm3(x);
        if n > T::zero() {
            x * (a / n)
        } else {
            Vector3::zeros()
        }
    };
    let (dv, dw) = (unit(v0, tip_accel), unit(w0, angular_accel));
    let jd = jac_times(j, &[dv.x, dv.y, dv.z, dw.x, dw.y, dw.z]);
    let scale = joint_scale(&jd, kinds, joint_accel, headroom);
    (tip_accel * scale, angular_accel * scale)
}

/// The discrete braking curve: the largest speed v with v·dt + v²/2a' ≤ `dist`, a' =
/// [`BRAKING_SHARE`] × `amax`: after this tick's move at v the robot can still stop within
/// `dist` decelerating at a'.
pub fn braking_speed<T: Real>(dist: T, amax: T, dt: T) -> T {
    let a = amax * lit(BRAKING_SHARE);
    sqrt(a * a * dt * dt + lit::<T>(2.0) * a * dist) - a * dt
}

/// The change `dv` limited to `amax`·`dt` in length (the acceleration limit of one tick).
pub fn limit_step<T: Real>(dv: Vector3<T>, amax: T, dt: T) -> Vector3<T> {
    let n = norm3(&dv);
    let m = amax * dt;
    if n > m {
        dv * (m / n)
    } else {
        dv
    }
}

/// One tick of the profile towards a goal `dist` away along the unit direction `dir`:
/// from the speed `v0`, towards `dir` × min(cap, braking curve, dist/dt), the change limited
/// to `amax`·`dt`.
pub fn step_towards<T: Real>(
    v0: &Vector3<T>,
    dir: &Vector3<T>,
    dist: T,
    cap: T,
    amax: T,
    dt: T,
) -> Vector3<T> {
    v0 + limit_step(desired_velocity(dir, dist, cap, amax, dt) - v0, amax, dt)
}

/// The velocity the profile heads for, towards a goal `dist` away along the unit
/// direction `dir`: `dir` × min(cap, braking curve, dist/dt).
pub fn desired_velocity<T: Real>(dir: &Vector3<T>, dist: T, cap: T, amax: T, dt: T) -> Vector3<T> {
    dir * cap.min(braking_speed(dist, amax, dt)).min(dist / dt)
}

/// One tick of the profile while it slows down (neither speed grows), from the twist
/// (`v0`, `w0`) towards the desired (`vd`, `wd`): from the step at the joint-safe
/// accelerations `safe` (tip, angular; [`joint_safe_accels`], within the joint limits
/// whatever the direction of change) as far towards the step at the full Cartesian
/// accelerations `full` as keeps J·Δ within `headroom` × each joint's acceleration limit
/// at the Jacobian `j`. Each speed thus moves at least as far towards its desired value as
/// at `safe`. Near a serial singularity, where J is large in some direction, `safe` leaves
/// the profile too little deceleration to follow its falling speed caps, while slowing down
/// along the motion mostly slows each joint in proportion to its rate.
#[allow(clippy::too_many_arguments)]
pub fn slowing_step<T: Real>(
    j: &Matrix6<T>,
    kinds: &[JointKind; 6],
    (v0, w0): (&Vector3<T>, &Vector3<T>),
    (vd, wd): (&Vector3<T>, &Vector3<T>),
    safe: (T, T),
    full: (T, T),
    joint_accel: &[T; 2],
    headroom: T,
    dt: T,
) -> (Vector3<T>, Vector3<T>) {
    let (sv, sw) = (
        limit_step(vd - v0, safe.0, dt),
        limit_step(wd - w0, safe.1, dt),
    );
    let (fv, fw) = (
        limit_step(vd - v0, full.0, dt),
        limit_step(wd - w0, full.1, dt),
    );
    // J·(safe + t·(full - safe)) = p + t·q, |p| within the limits at t = 0.
    let p = jac_times(j, &[sv.x, sv.y, sv.z, sw.x, sw.y, sw.z]);
    let (ev, ew) = (fv - sv, fw - sw);
    let q = jac_times(j, &[ev.x, ev.y, ev.z, ew.x, ew.y, ew.z]);
    let mut t = T::one();
    for ((pj, qj), kind) in p.iter().zip(q.iter()).zip(kinds.iter()) {
        let lim = of_kind(joint_accel, *kind) * headroom * dt;
        let reach = if *qj > T::zero() {
            (lim - *pj) / *qj
        } else if *qj < T::zero() {
            (-lim - *pj) / *qj
        } else {
            T::one()
        };
        // (A joint already beyond its limit at t = 0 by rounding keeps t = 0.)
        t = t.min(reach.max(T::zero()));
    }
    (v0 + sv + ev * t, w0 + sw + ew * t)
}

/// One tick of a controlled stop: the speed `v0` reduced by `amax`·`dt` along itself (to
/// zero at the end).
pub fn step_braking<T: Real>(v0: &Vector3<T>, amax: T, dt: T) -> Vector3<T> {
    v0 - limit_step(*v0, amax, dt)
}

/// Where braking at full deceleration from the twist (`v`, `w`) at `from` stops.
pub fn stop_point<T: Real>(
    v: &Vector3<T>,
    w: &Vector3<T>,
    from: &Pose<T>,
    limits: &ProfileLimits<T>,
) -> Pose<T> {
    let two = lit::<T>(2.0);
    let sv = norm3(v) / (two * limits.tip_accel);
    let sw = norm3(w) / (two * limits.angular_accel);
    from.displaced(&(v * sv), &(w * sw))
}

/// The braking point the checker evaluates while moving: from `pose`, moving on along its
/// twist (`v0`, `w0`) for `n` ticks while accelerating to v' = |v| + a(n - 1)dt, where
/// braking from v' would stop: v'²/2a + n·v'·dt ahead, but no farther than `horizon` (the
/// goal, or the verified target waiting to replace it). With n = 3L (L the ticks one
/// evaluation takes) this covers everything until the next braking-point check has
/// finished (see the supervisor's tick).
pub fn braking_point<T: Real>(
    pose: &Pose<T>,
    v0: &Vector3<T>,
    w0: &Vector3<T>,
    horizon: &Pose<T>,
    limits: &ProfileLimits<T>,
    n: T,
    dt: T,
) -> Pose<T> {
    let two = lit::<T>(2.0);
    let to_t = norm3(&(horizon.t - pose.t));
    let to_r = norm3(&rotation_vector(&(horizon.r * pose.r.inverse())));
    let reach = |v: &Vector3<T>, amax: T, to_horizon: T| {
        let speed = norm3(v);
        if speed > T::zero() {
            let vp = speed + amax * (n - T::one()) * dt;
            let far = (vp * vp / (two * amax) + n * vp * dt).min(to_horizon);
            v * (far / speed)
        } else {
            Vector3::zeros()
        }
    };
    pose.displaced(
        &reach(v0, limits.tip_accel, to_t),
        &reach(w0, limits.angular_accel, to_r),
    )
}

/// Arrival: within one tick's worth of braking of the goal (`dist`, `angle` away), at a
/// speed (`v0`, `w0`) that one tick of deceleration cancels: the profile snaps onto the
/// goal and stops.
pub fn arrived<T: Real>(
    dist: T,
    angle: T,
    v0: &Vector3<T>,
    w0: &Vector3<T>,
    limits: &ProfileLimits<T>,
    dt: T,
) -> bool {
    let dt2 = dt * dt;
    dist <= limits.tip_accel * dt2
        && angle <= limits.angular_accel * dt2
        && norm3(v0) <= limits.tip_accel * dt
        && norm3(w0) <= limits.angular_accel * dt
}

/// The motion limits a rescaled step keeps ([`step_scales`]): the output's own limits, as
/// the motion guards check them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepLimits<T: Real> {
    /// Largest tip acceleration, m/s².
    pub tip_accel: T,
    /// Largest angular acceleration, rad/s².
    pub angular_accel: T,
    /// Joint speed limits [prismatic, revolute].
    pub joint_speed: [T; 2],
    /// Joint acceleration limits [prismatic, revolute].
    pub joint_accel: [T; 2],
}

/// The share of the joint limits a rescaled step plans with: the candidate's Jacobian
/// moves with the scale, by a second-order amount, which the 5 % in hand covers.
pub const RESCALE_SHARE: f64 = 0.95;

/// The interval [lo, hi] of β with |β·a - b| ≤ m (a, b vectors): the roots of
/// β²|a|² - 2β a·b + |b|² - m² = 0, or [0, 1] when a is zero and every β qualifies (the
/// caller works within [0, 1]). `None` when no β qualifies.
fn scale_interval<T: Real>(a: &[T], b: &[T], m: T) -> Option<(T, T)> {
    let (mut aa, mut ab, mut bb) = (T::zero(), T::zero(), T::zero());
    for (x, y) in a.iter().zip(b.iter()) {
        aa += *x * *x;
        ab += *x * *y;
        bb += *y * *y;
    }
    let slack = bb - m * m;
    if aa == T::zero() {
        // β does not matter: every β or none.
        return (slack <= T::zero()).then_some((T::zero(), T::one()));
    }
    let disc = ab * ab - aa * slack;
    if !(disc >= T::zero()) {
        return None;
    }
    let r = sqrt(disc);
    Some(((ab - r) / aa, (ab + r) / aa))
}

/// The scales β ∈ [0, 1] of a step's twist `t1` with which the output keeps every motion
/// limit when the step alone would not: from the last output's twist `t0` and joint rates
/// `qd0`, with `c` = J₁·t1 the joint rates of the step at the candidate's Jacobian J₁,
/// the output β·t1, β·c changes the twist by at most the Cartesian accelerations and each
/// joint rate by at most [`RESCALE_SHARE`] of its acceleration limit, and stays within
/// that share of each joint speed limit. Near a serial singularity the joint rates change
/// at a constant twist (J̇·twist, which the Cartesian profile does not see); scaling the
/// step down slows the joints against it. `None` when no β qualifies.
///
/// The joint rates scale exactly with β for a fixed J₁; the candidate displaced by β·t1·dt
/// has a Jacobian within O((1 - β)·|t1|·dt) of J₁, which the share keeps in hand.
pub fn step_scales<T: Real>(
    t0: &Twist<T>,
    t1: &Twist<T>,
    qd0: &Joints<T>,
    c: &Joints<T>,
    kinds: &[JointKind; 6],
    limits: &StepLimits<T>,
    dt: T,
) -> Option<(T, T)> {
    let share = lit::<T>(RESCALE_SHARE);
    let (mut lo, mut hi) = (T::zero(), T::one());
    let mut within = |i: Option<(T, T)>| match i {
        Some((a, b)) => {
            lo = lo.max(a);
            hi = hi.min(b);
        }
        None => hi = -T::one(),
    };
    within(scale_interval(
        &[t1[0], t1[1], t1[2]],
        &[t0[0], t0[1], t0[2]],
        limits.tip_accel * dt,
    ));
    within(scale_interval(
        &[t1[3], t1[4], t1[5]],
        &[t0[3], t0[4], t0[5]],
        limits.angular_accel * dt,
    ));
    for ((k, cj), qj) in kinds.iter().zip(c.iter()).zip(qd0.iter()) {
        let accel = of_kind(&limits.joint_accel, *k) * share * dt;
        within(scale_interval(&[*cj], &[*qj], accel));
        let speed = of_kind(&limits.joint_speed, *k) * share;
        within(scale_interval(&[*cj], &[T::zero()], speed));
    }
    (lo <= hi).then_some((lo, hi))
}
