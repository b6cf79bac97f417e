//! On-target tests: the kinematics core's accuracy checks and the control application's
//! unit behaviour, in f32 on the (emulated) Cortex-M4 FPU. See README.md for the list.
#![no_std]
// Test code on the target: a panic is a failed test (semihosting exits non-zero).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]
#![no_main]

use control::{Controller, ControllerConfig, PoseStatus, Sensing};
use cortex_m_rt::entry;
use hal::{MotorOutputs, QuadratureCounter};
use kinematics_core::guards::{Guard, Guards, Levels, Limits, Reading, Severity, Subject};
use kinematics_core::pose::rotation_angle;
use kinematics_core::supervisor::{Mode, Refusal, Supervisor, SupervisorConfig};
use kinematics_core::{
    forward, inverse, jacobian, scalar::wrap_angle, Branch, Chain, FkConfig, JointKind, Joints,
    Mechanism, Pose, RsprGeometry,
};
use nalgebra::{Matrix3, Rotation3, Vector3, Vector6};
use on_target::harness::{Ctx, Runner};
use on_target::reference::{RefPoint, GRID};
use on_target::stub::PlantStub;
use on_target::{check, hprintln};
use panic_semihosting as _;
use servo::{
    AntiWindup, CountExtender, JointEncoder, JointServo, Pid, PidGains, PidInput, ServoConfig,
};

const DEG: f64 = core::f64::consts::PI / 180.0;

type G32 = RsprGeometry<f32>;

fn ref_pose(p: &RefPoint) -> Pose<f64> {
    Pose {
        t: Vector3::from(p.t),
        r: Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(&p.r)),
    }
}

/// Position (m) and rotation (rad) error between two poses, in f64.
fn pose_error(a: &Pose<f64>, b: &Pose<f64>) -> (f64, f64) {
    ((a.t - b.t).norm(), rotation_angle(&(a.r.inverse() * b.r)))
}

/// A deterministic sequence in [-1, 1) (a 32-bit LCG), for warm-start offsets.
struct Lcg(u32);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (self.0 >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }
    fn vec3(&mut self, scale: f32) -> Vector3<f32> {
        Vector3::new(
            self.next() * scale,
            self.next() * scale,
            self.next() * scale,
        )
    }
}

// ---------------------------------------------------------------------------------------
// Kinematics accuracy (f32 on the FPU against f64 computed on the host).

/// f32 IK over the task grid against the host's f64 joints: below the encoder
/// resolution (0.0015 mm on the legs, 0.005 deg on the links), as the host test claims.
fn ik_f32_joints_match_host_f64_below_encoder_resolution(ctx: &mut Ctx) {
    let g = G32::reference();
    let (mut worst_len, mut worst_ang) = (0.0f64, 0.0f64);
    for (k, p) in GRID.iter().enumerate() {
        let pose = ref_pose(p).cast::<f32>();
        let Ok(sol) = inverse(&g, &pose, Branch::OUTER) else {
            check!(ctx, false, "grid point {}: no f32 IK solution", k);
            continue;
        };
        let q = sol.q();
        for i in 0..3 {
            worst_len = worst_len.max((f64::from(q[i]) - p.q[i]).abs());
            worst_ang = worst_ang.max(wrap_angle(f64::from(q[i + 3]) - p.q[i + 3]).abs());
        }
    }
    hprintln!(
        "    {} grid poses: worst leg error {:.3e} mm, worst link-angle error {:.3e} deg",
        GRID.len(),
        worst_len * 1e3,
        worst_ang / DEG
    );
    check!(ctx, worst_len < 1.5e-6, "leg error {:e} m", worst_len);
    check!(
        ctx,
        worst_ang < 0.005 * DEG,
        "angle error {:e} rad",
        worst_ang
    );
}

/// IK then FK in f32 returns the pose to 1 µm and 1e-5 rad over the task grid, warm
/// started up to 0.5 mm / 0.5 deg away (20 control ticks of motion at full speed).
fn ik_then_fk_f32_returns_the_pose_over_the_task_grid(ctx: &mut Ctx) {
    let g = G32::reference();
    let mut rng = Lcg(12345);
    let (mut worst_p, mut worst_r, mut max_it) = (0.0f64, 0.0f64, 0u32);
    for (k, p) in GRID.iter().enumerate() {
        let exact = ref_pose(p);
        let pose = exact.cast::<f32>();
        let Ok(sol) = inverse(&g, &pose, Branch::OUTER) else {
            check!(ctx, false, "grid point {}: no IK", k);
            continue;
        };
        let guess = pose.displaced(&rng.vec3(0.5e-3), &rng.vec3(0.5 * DEG as f32));
        match forward(&g, &sol.q(), Branch::OUTER, &guess, &FkConfig::default()) {
            Ok(fk) => {
                let (dp, dr) = pose_error(&fk.pose.cast::<f64>(), &exact);
                worst_p = worst_p.max(dp);
                worst_r = worst_r.max(dr);
                max_it = max_it.max(fk.iterations);
                check!(
                    ctx,
                    dp < 1e-6 && dr < 1e-5,
                    "grid point {}: {:e} m, {:e} rad",
                    k,
                    dp,
                    dr
                );
            }
            Err(e) => check!(ctx, false, "grid point {}: FK failed: {}", k, e),
        }
    }
    hprintln!(
        "    worst pose error {:.3e} µm, {:.3e} rad (at most {} Newton steps)",
        worst_p * 1e6,
        worst_r,
        max_it
    );
}

/// FK in f32 from the host's f64 joints (rounded to f32) lands within 1 µm / 1e-5 rad of
/// the f64 pose.
fn fk_f32_from_host_joints_lands_on_the_f64_pose(ctx: &mut Ctx) {
    let g = G32::reference();
    let (mut worst_p, mut worst_r) = (0.0f64, 0.0f64);
    for (k, p) in GRID.iter().enumerate() {
        let exact = ref_pose(p);
        let q = Joints::<f64>::from_row_slice(&p.q).cast::<f32>();
        match forward(&g, &q, Branch::OUTER, &exact.cast(), &FkConfig::default()) {
            Ok(fk) => {
                let (dp, dr) = pose_error(&fk.pose.cast::<f64>(), &exact);
                worst_p = worst_p.max(dp);
                worst_r = worst_r.max(dr);
            }
            Err(e) => check!(ctx, false, "grid point {}: FK failed: {}", k, e),
        }
    }
    hprintln!(
        "    worst pose error {:.3e} µm, {:.3e} rad",
        worst_p * 1e6,
        worst_r
    );
    check!(
        ctx,
        worst_p < 1e-6 && worst_r < 1e-5,
        "{:e} m, {:e} rad",
        worst_p,
        worst_r
    );
}

/// The f32 Jacobian J = dq/dx equals the host's f64 one (relative error per column).
fn jacobian_f32_matches_host_f64(ctx: &mut Ctx) {
    let g = G32::reference();
    let mut worst = 0.0f64;
    for (k, p) in GRID.iter().enumerate() {
        let Ok(sol) = inverse(&g, &ref_pose(p).cast::<f32>(), Branch::OUTER) else {
            check!(ctx, false, "grid point {}: no IK", k);
            continue;
        };
        let Ok(jac) = jacobian(&g, &sol) else {
            check!(ctx, false, "grid point {}: J singular", k);
            continue;
        };
        for c in 0..6 {
            let (mut err, mut norm) = (0.0f64, 0.0f64);
            for r in 0..6 {
                let j64 = p.j[r * 6 + c];
                let d = f64::from(jac.j[(r, c)]) - j64;
                err += d * d;
                norm += j64 * j64;
            }
            let rel =
                nalgebra::ComplexField::sqrt(err) / (1.0 + nalgebra::ComplexField::sqrt(norm));
            worst = worst.max(rel);
        }
    }
    hprintln!(
        "    worst |J32 - J64| / (1 + |J64|) per column: {:.3e}",
        worst
    );
    check!(ctx, worst < 1e-5, "relative Jacobian error {:e}", worst);
}

/// The analytic f32 Jacobian equals central finite differences of the f32 inverse
/// kinematics along each twist direction (h = 1e-3 m / rad; tolerance set by f32
/// rounding of q over 2h and the O(h²) truncation).
fn jacobian_f32_matches_finite_differences(ctx: &mut Ctx) {
    let g = G32::reference();
    let h = 1e-3f32;
    let kinds = g.joint_kinds();
    let mut worst = 0.0f32;
    for (k, p) in GRID.iter().enumerate().step_by(3) {
        let pose = ref_pose(p).cast::<f32>();
        let (Ok(sol), true) = (inverse(&g, &pose, Branch::OUTER), true) else {
            check!(ctx, false, "grid point {}: no IK", k);
            continue;
        };
        let Ok(jac) = jacobian(&g, &sol) else {
            check!(ctx, false, "grid point {}: J singular", k);
            continue;
        };
        for c in 0..6 {
            let mut d = Vector6::<f32>::zeros();
            d[c] = h;
            let at = |d: &Vector6<f32>| {
                let p = pose.displaced(
                    &Vector3::new(d[0], d[1], d[2]),
                    &Vector3::new(d[3], d[4], d[5]),
                );
                inverse(&g, &p, Branch::OUTER).ok().map(|s| s.q())
            };
            let (Some(qp), Some(qm)) = (at(&d), at(&-d)) else {
                check!(ctx, false, "grid point {} column {}: no IK at ±h", k, c);
                continue;
            };
            let mut fd = (qp - qm) / (2.0 * h);
            for (i, kind) in kinds.iter().enumerate() {
                if *kind == JointKind::Angular {
                    fd[i] = wrap_angle(qp[i] - qm[i]) / (2.0 * h);
                }
            }
            let col = jac.j.column(c);
            let rel = (fd - col).norm() / (1.0 + col.norm());
            worst = worst.max(rel);
        }
    }
    hprintln!("    worst |FD - J| / (1 + |J|) per column: {:.3e}", worst);
    check!(ctx, worst < 2e-3, "relative error {:e}", worst);
}

// ---------------------------------------------------------------------------------------
// Guards at their boundaries (f32).

type Gd = Guards<f32, G32>;

fn guards(limits: Limits<f32>) -> Gd {
    match Guards::new(G32::reference(), Branch::OUTER, limits) {
        Ok(g) => g,
        Err(e) => panic!("guards: {}", e),
    }
}

fn reading(g: &Gd, pose: &Pose<f32>, guard: Guard, subject: Subject) -> Option<Reading<f32>> {
    let mut found = None;
    g.evaluate_pose(pose, &mut |r| {
        if r.guard == guard && r.subject == subject {
            found = Some(*r);
        }
    });
    found
}

fn severity_of(g: &Gd, pose: &Pose<f32>, guard: Guard, subject: Subject) -> Option<Severity> {
    let (verdict, _) = g.check_pose(pose);
    verdict
        .violations
        .iter()
        .find(|r| r.guard == guard && r.subject == subject)
        .and_then(|r| r.severity)
}

/// Moves a guard's stop level just inside and just outside the value it measures at
/// `pose` (relative 1e-5, well above f32 rounding): fine inside, Stop outside, with the
/// value and the limit in the reading.
fn at_boundary(
    ctx: &mut Ctx,
    guard: Guard,
    subject: Subject,
    pose: Pose<f32>,
    set: impl Fn(&mut Limits<f32>, f32),
    lower_bound: bool,
) {
    let Some(r0) = reading(&guards(Limits::reference()), &pose, guard, subject) else {
        check!(ctx, false, "no reading for {} {}", guard, subject);
        return;
    };
    let value = r0.value;
    let rel = 1e-5f32;
    let (inside, outside) = if lower_bound {
        (value * (1.0 - rel), value * (1.0 + rel))
    } else {
        (value * (1.0 + rel), value * (1.0 - rel))
    };
    let mut l = Limits::reference();
    set(&mut l, inside);
    let g = guards(l);
    check!(
        ctx,
        severity_of(&g, &pose, guard, subject).is_none(),
        "{} {} just inside",
        guard,
        subject
    );
    let mut l = Limits::reference();
    set(&mut l, outside);
    let g = guards(l);
    check!(
        ctx,
        severity_of(&g, &pose, guard, subject) == Some(Severity::Stop),
        "{} {} just outside",
        guard,
        subject
    );
    if let Some(r) = reading(&g, &pose, guard, subject) {
        // The limit may be formed from several fields (box half-size + margin): equal to
        // `outside` up to f32 rounding.
        let same_limit = (r.limit - outside).abs() <= 4.0 * f32::EPSILON * outside.abs();
        check!(
            ctx,
            r.value == value && same_limit && r.margin < 0.0,
            "{} {} reading {:?}",
            guard,
            subject,
            r
        );
    }
}

fn task_pose() -> Pose<f32> {
    let axis = Vector3::new(1.0f32, 1.0, 0.0).normalize();
    Pose {
        t: Vector3::new(0.012, -0.008, 0.165),
        r: Rotation3::from_scaled_axis(axis * (12.0 * DEG as f32)),
    }
}

fn guards_stroke_collision_workspace_at_their_limits(ctx: &mut Ctx) {
    let central = Pose::central(0.160f32);
    // Every leg of the central pose is sqrt(60² + 160²) = 170.880 mm.
    let r = reading(
        &guards(Limits::reference()),
        &central,
        Guard::Stroke,
        Subject::Chain(Chain::Two),
    );
    check!(
        ctx,
        r.is_some_and(|r| (r.value - 0.170_880_08).abs() < 1e-6),
        "stroke {:?}",
        r
    );
    at_boundary(
        ctx,
        Guard::Stroke,
        Subject::Chain(Chain::Two),
        central,
        |l, v| l.stroke[0] = v,
        true,
    );
    at_boundary(
        ctx,
        Guard::Stroke,
        Subject::Chain(Chain::Two),
        central,
        |l, v| {
            l.stroke[0] = 0.1;
            l.stroke[1] = v
        },
        false,
    );
    // The leg from b = (110, 0, 0) to p = (50, 0, 160) mm pierces z = 60 mm at 87.5 mm.
    let r = reading(
        &guards(Limits::reference()),
        &central,
        Guard::Collision,
        Subject::Chain(Chain::One),
    );
    check!(
        ctx,
        r.is_some_and(|r| (r.value - 0.0875).abs() < 1e-6),
        "collision {:?}",
        r
    );
    at_boundary(
        ctx,
        Guard::Collision,
        Subject::Chain(Chain::One),
        central,
        |l, v| l.collision_radius = v,
        true,
    );
    let p = Pose {
        t: Vector3::new(0.0f32, 0.024, 0.160),
        r: Rotation3::identity(),
    };
    at_boundary(
        ctx,
        Guard::Workspace,
        Subject::Axis(1),
        p,
        |l, v| l.box_half.y = v - l.box_margin,
        false,
    );
    at_boundary(
        ctx,
        Guard::TiltCone,
        Subject::Robot,
        task_pose(),
        |l, v| l.tilt_cone = v,
        false,
    );
}

fn guards_singularity_and_torque_warn_between_levels(ctx: &mut Ctx) {
    let p = task_pose();
    at_boundary(
        ctx,
        Guard::ParallelSingularity,
        Subject::Robot,
        p,
        |l, v| {
            l.parallel.stop = v;
            l.parallel.warn = v
        },
        true,
    );
    at_boundary(
        ctx,
        Guard::SerialSingularity,
        Subject::Chain(Chain::One),
        p,
        |l, v| {
            l.serial.stop = v;
            l.serial.warn = v
        },
        true,
    );
    let Some(par) = reading(
        &guards(Limits::reference()),
        &p,
        Guard::ParallelSingularity,
        Subject::Robot,
    ) else {
        check!(ctx, false, "no parallel reading");
        return;
    };
    let mut l = Limits::reference();
    l.parallel = Levels {
        warn: par.value * 1.01,
        stop: par.value * 0.99,
    };
    let g = guards(l);
    check!(
        ctx,
        severity_of(&g, &p, Guard::ParallelSingularity, Subject::Robot) == Some(Severity::Warn)
    );
    check!(
        ctx,
        !g.check_pose(&p).0.is_stop(),
        "a warning must not stop"
    );
    let Some(tq) = reading(
        &guards(Limits::reference()),
        &p,
        Guard::Torque,
        Subject::Joint(4),
    ) else {
        check!(ctx, false, "no torque reading");
        return;
    };
    let mut l = Limits::reference();
    l.torque = Levels {
        warn: tq.value * 0.99,
        stop: tq.value * 1.01,
    };
    check!(
        ctx,
        severity_of(&guards(l), &p, Guard::Torque, Subject::Joint(4)) == Some(Severity::Warn)
    );
}

// ---------------------------------------------------------------------------------------
// Supervisor (f32).

type Sup = Supervisor<f32, G32>;

fn supervisor() -> Sup {
    match Supervisor::new(
        G32::reference(),
        Branch::OUTER,
        Limits::reference(),
        SupervisorConfig::default(),
        &Pose::central(0.160),
    ) {
        Ok(s) => s,
        Err(e) => panic!("supervisor: {}", e),
    }
}

fn supervisor_refuses_bad_targets_at_once(ctx: &mut Ctx) {
    let mut sup = supervisor();
    let now = 10_000_000;
    let nan = Pose {
        t: Vector3::new(0.0, f32::NAN, 0.16),
        r: Rotation3::identity(),
    };
    check!(ctx, sup.submit(&nan, now, now) == Err(Refusal::NonFinite));
    check!(
        ctx,
        matches!(
            sup.submit(&Pose::central(0.16), now - 200_000, now),
            Err(Refusal::Stale { age_us: 200_000 })
        )
    );
    check!(ctx, sup.submit(&Pose::central(0.161), now, now).is_ok());
    check!(
        ctx,
        sup.submit(&Pose::central(0.162), now, now) == Err(Refusal::OutOfOrder)
    );
    check!(
        ctx,
        matches!(
            sup.submit(&Pose::central(3.0), now + 1, now),
            Err(Refusal::TooFar { .. })
        )
    );
    let c = sup.counters();
    check!(
        ctx,
        (c.non_finite, c.stale, c.out_of_order, c.too_far) == (1, 1, 1, 1),
        "{:?}",
        c
    );
}

fn supervisor_refuses_a_target_outside_the_workspace_and_holds(ctx: &mut Ctx) {
    let mut sup = supervisor();
    let target = Pose {
        t: Vector3::new(0.035f32, 0.0, 0.16),
        r: Rotation3::identity(),
    };
    check!(ctx, sup.submit(&target, 1000, 1000).is_ok());
    let out = sup.tick();
    check!(
        ctx,
        matches!(sup.last_refusal(), Some(Refusal::Path { reading, .. }) if reading.guard == Guard::Workspace),
        "{:?}",
        sup.last_refusal()
    );
    for _ in 0..100 {
        let o = sup.tick();
        check!(ctx, o.pose == out.pose && o.mode == Mode::Holding);
    }
    check!(ctx, sup.counters().path_refused == 1);
}

fn supervisor_reaches_a_safe_target_at_the_speed_limit(ctx: &mut Ctx) {
    let mut sup = supervisor();
    let target = Pose {
        t: Vector3::new(0.015f32, -0.010, 0.165),
        r: Rotation3::from_scaled_axis(Vector3::new(0.1, 0.05, 0.0)),
    };
    check!(ctx, sup.submit(&target, 1000, 1000).is_ok());
    let (mut peak, mut ticks) = (0.0f32, 0u32);
    loop {
        let o = sup.tick();
        peak = peak.max(o.twist.fixed_rows::<3>(0).norm());
        check!(ctx, o.stop.is_none(), "stopped: {:?}", o.stop);
        ticks += 1;
        if o.mode == Mode::Holding && ticks > 10 {
            break;
        }
        if ticks >= 10_000 {
            check!(ctx, false, "did not arrive");
            return;
        }
    }
    let (dp, dr) = pose_error(&sup.setpoint().cast(), &target.cast());
    hprintln!(
        "    arrived in {} ticks, peak speed {:.2} mm/s, {:.2e} m / {:.2e} rad off",
        ticks,
        peak * 1e3,
        dp,
        dr
    );
    check!(ctx, dp < 1e-6 && dr < 1e-5, "{:e} m {:e} rad off", dp, dr);
    check!(
        ctx,
        peak > 0.9 * 0.025 && peak <= 0.025,
        "peak speed {}",
        peak
    );
}

/// A master streaming targets (a new one every 10 ms, rotating back and forth) keeps the
/// supervisor moving; its f32 setpoint rotation must stay a rotation (|RᵀR - I| at f32
/// rounding level). KNOWN ISSUE: it drifts by ~2.4e-8 per tick (1.1e-4 after these 5 s,
/// 7e-4 after 30 s, growing linearly): `Rotation3::from_scaled_axis` of the per-tick
/// increments (< 2.4e-4 rad) rounds 1 - cos θ to 0 in f32, so each increment is
/// I + sin θ [u]x with RᵀR = I + O(θ²), and `Pose::displaced` never re-orthonormalises.
fn supervisor_setpoint_rotation_stays_orthonormal_under_streamed_targets(ctx: &mut Ctx) {
    let mut sup = supervisor();
    let mut now = 1000u64;
    let mut worst = 0.0f32;
    for k in 0..5_000u32 {
        if k % 10 == 0 {
            let s = k as f32 * 1e-3 * core::f32::consts::PI / 2.0; // 4 s period
            let (sn, cs) = (libm_sin(s), libm_sin(s + core::f32::consts::FRAC_PI_2));
            let t = Pose {
                t: Vector3::new(0.004 * sn, 0.004 * cs - 0.004, 0.160),
                r: Rotation3::from_scaled_axis(Vector3::new(
                    0.25 * sn,
                    0.0,
                    0.1 * libm_sin(2.0 * s),
                )),
            };
            check!(
                ctx,
                sup.submit(&t, now, now).is_ok(),
                "target {} refused",
                k
            );
        }
        sup.tick();
        now += 1000;
        let m = sup.setpoint().r.matrix();
        worst = worst.max((m.transpose() * m - Matrix3::identity()).abs().max());
    }
    hprintln!(
        "    worst |RtR - I| of the setpoint over 5000 streamed ticks: {:.2e}",
        worst
    );
    check!(ctx, worst <= 1e-6, "|RtR - I| = {:e}", worst);
}

fn libm_sin(x: f32) -> f32 {
    nalgebra::ComplexField::sin(x)
}

// ---------------------------------------------------------------------------------------
// Servo building blocks (f32).

fn pid_p_only_saturates_at_the_limit(ctx: &mut Ctx) {
    let dt = 1e-3f32;
    let mut pid = Pid::new(PidGains::proportional(2.0f32));
    let out = pid.update(&PidInput::new(0.3, 0.0), dt);
    check!(
        ctx,
        (out.duty - 0.6).abs() < 1e-6 && !out.saturated,
        "{:?}",
        out
    );
    let out = pid.update(&PidInput::new(-2.0, 0.0), dt);
    check!(ctx, out.duty == -1.0 && out.saturated, "{:?}", out);
    let mut g = PidGains::proportional(2.0f32);
    g.output_limit = 0.4;
    let mut pid = Pid::new(g);
    let out = pid.update(&PidInput::new(0.3, 0.0), dt);
    check!(ctx, out.duty == 0.4 && out.saturated, "{:?}", out);
    // Absurd but finite inputs still give a finite duty within the limit.
    let out = Pid::new(PidGains::<f32>::leg()).update(
        &PidInput::new(f32::MAX, -f32::MAX).with_velocity(f32::MAX),
        dt,
    );
    check!(ctx, out.duty == 1.0 && out.error.is_none(), "{:?}", out);
    // Non-finite input: duty 0 and an error.
    let out = pid.update(&PidInput::new(f32::NAN, 0.0), dt);
    check!(ctx, out.duty == 0.0 && out.error.is_some(), "{:?}", out);
}

fn pid_clamp_anti_windup_freezes_the_integral_while_saturated(ctx: &mut Ctx) {
    let dt = 1e-3f32;
    let mut g = PidGains::<f32>::leg();
    g.anti_windup = AntiWindup::Clamp;
    let mut pid = Pid::new(g);
    // 50 mm error: far into saturation; the integral must not move.
    for _ in 0..100 {
        let out = pid.update(&PidInput::new(0.05, 0.0), dt);
        check!(ctx, out.saturated && out.duty == 1.0);
    }
    check!(ctx, pid.integral() == 0.0, "integral {}", pid.integral());
    // Without anti-windup it winds up to its bound.
    g.anti_windup = AntiWindup::None;
    let mut pid = Pid::new(g);
    for _ in 0..100 {
        pid.update(&PidInput::new(0.05, 0.0), dt);
    }
    check!(
        ctx,
        pid.integral() == g.integral_limit,
        "integral {}",
        pid.integral()
    );
}

fn encoder_extension_follows_wraps_in_both_directions(ctx: &mut Ctx) {
    let raw = |c: i64| c.rem_euclid(1 << 16) as u16;
    let mut ext = CountExtender::new();
    check!(ctx, ext.update(65531) == -5, "first read is signed");
    check!(ctx, ext.update(3) == 3);
    let mut ext = CountExtender::new();
    check!(ctx, ext.update(32767) == 32767);
    let mut ext = CountExtender::new();
    check!(
        ctx,
        ext.update(32768) == -32768,
        "half a range reads as -32768"
    );
    // Long runs of large steps up and down from near the top of the counter.
    let mut rng = Lcg(7);
    let mut truth = 65_000i64;
    let mut ext = CountExtender::starting_at(raw(truth), truth);
    let mut wraps = 0;
    for run in 0..20 {
        for _ in 0..100 {
            let step = 20_000 + ((rng.next() + 1.0) * 6383.0) as i64; // 20000..=32766
            let before = raw(truth);
            truth += if run % 2 == 0 { step } else { -step };
            let after = raw(truth);
            if (run % 2 == 0 && after < before) || (run % 2 == 1 && after > before) {
                wraps += 1;
            }
            if ext.update(after) != truth {
                check!(ctx, false, "count {} != {}", ext.count(), truth);
                return;
            }
        }
    }
    check!(ctx, wraps > 100, "only {} wraps", wraps);
    // f32 joint units keep one-count resolution 10^8 counts away from power-up.
    let mut e = JointEncoder::<f32>::new(
        board_profile::BoardProfile::REFERENCE.joints[0].counts_per_unit() as f32,
    );
    let mut truth = 0i64;
    for _ in 0..4000 {
        truth += 25_000;
        e.update(raw(truth));
    }
    check!(ctx, e.count() == 100_000_000);
    e.set_position(0.1);
    e.update(raw(truth + 1));
    check!(
        ctx,
        (e.position() - (0.1 + 1.5e-6)).abs() < 1e-8,
        "position {}",
        e.position()
    );
}

fn joint_servo_non_finite_input_latches_and_zeroes_every_duty(ctx: &mut Ctx) {
    let Ok(mut s) = JointServo::<f32>::new(&ServoConfig::default()) else {
        check!(ctx, false, "default config invalid");
        return;
    };
    let q = [0.17f32, 0.17, 0.17, 0.0, 0.0, 0.0];
    s.reset(&q);
    let sp = [0.1701f32, 0.17, 0.17, 0.0, 0.0, 0.0];
    let out = s.update(&sp, &[0.0; 6], &q, 1e-3);
    check!(
        ctx,
        out.fault.is_none() && out.duty[0] > 0.0,
        "{:?}",
        out.duty
    );
    let mut bad = q;
    bad[4] = f32::NAN;
    let out = s.update(&sp, &[0.0; 6], &bad, 1e-3);
    check!(
        ctx,
        out.fault.is_some_and(|f| f.joint == Some(4)),
        "{:?}",
        out.fault
    );
    check!(ctx, out.duty.iter().all(|d| *d == 0.0));
    // Latched until reset.
    let out = s.update(&sp, &[0.0; 6], &q, 1e-3);
    check!(
        ctx,
        out.fault.is_some() && out.duty.iter().all(|d| *d == 0.0)
    );
    s.reset(&q);
    check!(ctx, s.update(&sp, &[0.0; 6], &q, 1e-3).fault.is_none());
}

// ---------------------------------------------------------------------------------------
// The control application with the hardware stub (f32).

/// The controller at the central configuration on the motor stub, with the sensing as the
/// runtime has it after homing (the counters `raw0` read the central joints).
fn start_controller(
    cfg: ControllerConfig<f32>,
    raw0: [u16; 6],
) -> (Controller<f32, G32>, Sensing<f32, G32>, PlantStub) {
    let g = G32::reference();
    let q = match inverse(&g, &Pose::central(g.hc), Branch::OUTER) {
        Ok(s) => s.q(),
        Err(e) => panic!("central IK: {}", e),
    };
    let q0 = [q[0], q[1], q[2], q[3], q[4], q[5]];
    let plant = PlantStub::new(q0.map(f64::from), raw0);
    let sensing = match Sensing::homed_at(g, Branch::OUTER, &cfg.encoders, cfg.fk, plant.raw(), &q0)
    {
        Ok(s) => s,
        Err(e) => panic!("sensing: {}", e),
    };
    match Controller::new(g, cfg, sensing.measured()) {
        Ok(c) => (c, sensing, plant),
        Err(e) => panic!("controller: {}", e),
    }
}

/// The whole tick (encoders -> FK -> supervisor -> PIDs -> duties) follows a target with
/// the motor stub and its wrapping counters: no FK failure, no fault, the supervisor ends
/// holding at the target. With the default (backlash-compensated) servo every measured
/// joint ends within half the backlash plus 2 counts of its setpoint; with the
/// compensation off the measured pose (FK of the encoders) ends within 10 µm of the target.
fn controller_follows_a_target_with_the_motor_stub(ctx: &mut Ctx) {
    let target = Pose {
        t: Vector3::new(0.008f32, -0.005, 0.163),
        r: Rotation3::from_scaled_axis(Vector3::new(0.05, -0.03, 0.0)),
    };
    let mut off = ControllerConfig::<f32>::default();
    off.servo.backlash = servo::BacklashConfig::off();
    for (name, cfg) in [
        ("default", ControllerConfig::default()),
        ("backlash off", off),
    ] {
        let (mut ctl, mut sensing, mut plant) =
            start_controller(cfg, [65_500, 10, 32_000, 65_530, 0, 40_000]);
        check!(ctx, ctl.submit(&target, 1_000, 1_000).is_ok());
        let mut last = None;
        for _ in 0..1500 {
            let m = sensing.update(&mut plant);
            let r = ctl.tick(m);
            r.apply(&mut plant);
            ctl.evaluate();
            plant.step(1e-3);
            let fk = sensing.measured().status;
            if matches!(fk, PoseStatus::Failed(_)) || r.servo.fault.is_some() {
                check!(
                    ctx,
                    false,
                    "{}: fk {:?} fault {:?}",
                    name,
                    fk,
                    r.servo.fault
                );
                return;
            }
            last = Some(r);
        }
        let Some(r) = last else { return };
        let measured = *sensing.measured();
        let Some(measured_pose) = measured.pose else {
            check!(ctx, false, "{}: no measured pose", name);
            return;
        };
        let (dp, dr) = pose_error(&measured_pose.cast(), &target.cast());
        let mut worst_joint = [0.0f32; 2];
        for j in 0..6 {
            let e = (measured.q[j] - ctl.supervisor().setpoint_joints()[j]).abs();
            worst_joint[j / 3] = worst_joint[j / 3].max(e);
        }
        hprintln!(
            "    {}: measured pose {:.2} µm / {:.2e} rad from the target, joints {:.2} µm / {:.2e} rad from the setpoints, FK <= {} iterations",
            name,
            dp * 1e6,
            dr,
            worst_joint[0] * 1e6,
            worst_joint[1],
            sensing.counters().fk_max_iterations
        );
        let setpoint = *ctl.supervisor().setpoint();
        let (sp, sr) = pose_error(&setpoint.cast(), &target.cast());
        let m = setpoint.r.matrix();
        let ortho = (m.transpose() * m - Matrix3::identity()).abs().max();
        hprintln!(
            "    {}: setpoint {:.2e} m / {:.2e} rad from the target, |RtR - I| = {:.2e}",
            name,
            sp,
            sr,
            ortho
        );
        check!(
            ctx,
            r.mode == Mode::Holding && sp < 1e-7 && sr < 1e-5,
            "{}: mode {:?}, {:e} m, {:e} rad",
            name,
            r.mode,
            sp,
            sr
        );
        check!(
            ctx,
            plant.writes == 1500 && plant.disables == 0,
            "{}: outputs",
            name
        );
        if name == "default" {
            let leg = 0.06e-3 + 2.0 * 1.5e-6;
            let link = 4.85e-5 + 2.0 * 8.73e-5;
            check!(
                ctx,
                worst_joint[0] <= leg && worst_joint[1] <= link,
                "{}: joints {:?}",
                name,
                worst_joint
            );
        } else {
            check!(
                ctx,
                dp < 10e-6 && dr < 1e-4,
                "{}: {:e} m, {:e} rad",
                name,
                dp,
                dr
            );
        }
    }
}

/// A counter that stops counting trips the tracking fault; every output goes off.
fn controller_disables_the_outputs_on_a_stuck_encoder(ctx: &mut Ctx) {
    struct Stuck<'a>(&'a mut PlantStub, u16);
    impl QuadratureCounter for Stuck<'_> {
        fn counts(&mut self) -> [u16; 6] {
            let mut c = self.0.counts();
            c[0] = self.1;
            c
        }
    }
    impl MotorOutputs<f32> for Stuck<'_> {
        fn set_duties(&mut self, d: &[f32; 6]) {
            self.0.set_duties(d)
        }
        fn disable(&mut self) {
            self.0.disable()
        }
        fn enable(&mut self) {
            self.0.enable()
        }
    }
    let (mut ctl, mut sensing, mut plant) = start_controller(ControllerConfig::default(), [0; 6]);
    let stuck = plant.raw()[0];
    let target = Pose {
        t: Vector3::new(0.0f32, 0.0, 0.170),
        r: Rotation3::identity(),
    };
    check!(ctx, ctl.submit(&target, 1_000, 1_000).is_ok());
    let mut tripped = None;
    for k in 0..1000 {
        let mut hw = Stuck(&mut plant, stuck);
        let m = sensing.update(&mut hw);
        let r = ctl.tick(m);
        r.apply(&mut hw);
        ctl.evaluate();
        plant.step(1e-3);
        if r.servo.fault.is_some() {
            tripped = Some(k);
            break;
        }
    }
    hprintln!("    tripped after {:?} ticks", tripped);
    check!(
        ctx,
        tripped.is_some_and(|k| k < 300),
        "tripped at {:?}",
        tripped
    );
    check!(
        ctx,
        plant.disables >= 1 && plant.duty().iter().all(|d| *d == 0.0)
    );
}

#[entry]
fn main() -> ! {
    let mut t = Runner::new();
    t.run(
        "ik_f32_joints_match_host_f64_below_encoder_resolution",
        ik_f32_joints_match_host_f64_below_encoder_resolution,
    );
    t.run(
        "ik_then_fk_f32_returns_the_pose_over_the_task_grid",
        ik_then_fk_f32_returns_the_pose_over_the_task_grid,
    );
    t.run(
        "fk_f32_from_host_joints_lands_on_the_f64_pose",
        fk_f32_from_host_joints_lands_on_the_f64_pose,
    );
    t.run(
        "jacobian_f32_matches_host_f64",
        jacobian_f32_matches_host_f64,
    );
    t.run(
        "jacobian_f32_matches_finite_differences",
        jacobian_f32_matches_finite_differences,
    );
    t.run(
        "guards_stroke_collision_workspace_at_their_limits",
        guards_stroke_collision_workspace_at_their_limits,
    );
    t.run(
        "guards_singularity_and_torque_warn_between_levels",
        guards_singularity_and_torque_warn_between_levels,
    );
    t.run(
        "supervisor_refuses_bad_targets_at_once",
        supervisor_refuses_bad_targets_at_once,
    );
    t.run(
        "supervisor_refuses_a_target_outside_the_workspace_and_holds",
        supervisor_refuses_a_target_outside_the_workspace_and_holds,
    );
    t.run(
        "supervisor_reaches_a_safe_target_at_the_speed_limit",
        supervisor_reaches_a_safe_target_at_the_speed_limit,
    );
    t.run(
        "supervisor_setpoint_rotation_stays_orthonormal_under_streamed_targets",
        supervisor_setpoint_rotation_stays_orthonormal_under_streamed_targets,
    );
    t.run(
        "pid_p_only_saturates_at_the_limit",
        pid_p_only_saturates_at_the_limit,
    );
    t.run(
        "pid_clamp_anti_windup_freezes_the_integral_while_saturated",
        pid_clamp_anti_windup_freezes_the_integral_while_saturated,
    );
    t.run(
        "encoder_extension_follows_wraps_in_both_directions",
        encoder_extension_follows_wraps_in_both_directions,
    );
    t.run(
        "joint_servo_non_finite_input_latches_and_zeroes_every_duty",
        joint_servo_non_finite_input_latches_and_zeroes_every_duty,
    );
    t.run(
        "controller_follows_a_target_with_the_motor_stub",
        controller_follows_a_target_with_the_motor_stub,
    );
    t.run(
        "controller_disables_the_outputs_on_a_stuck_encoder",
        controller_disables_the_outputs_on_a_stuck_encoder,
    );
    t.finish()
}
