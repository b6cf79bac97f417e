#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Certified regions (`guards::certificate`): the Lipschitz bounds of every guard's margin
//! along a straight motion, and the region one full evaluation certifies. The property
//! tests try to violate the bounds: poses at the edge of the region, in random directions
//! and in the direction in which the most constraining margin falls fastest.

use crate::common;

use common::*;
use kinematics_core::guards::*;
use kinematics_core::singularity::ConditionEstimator;
use kinematics_core::*;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

type G = Guards<f64, RsprGeometry<f64>>;

fn guards(limits: Limits<f64>) -> G {
    Guards::new(RsprGeometry::reference(), Branch::OUTER, limits).unwrap()
}

/// A staged full evaluation at `pose`, run to the end.
fn staged(g: &G, pose: &Pose<f64>) -> Staged<f64> {
    let mut st = Staged::new(Branch::OUTER);
    st.start(pose);
    let mut cond = ConditionEstimator::new();
    while !st.is_finished() {
        g.advance(&mut st, &mut cond);
    }
    st
}

/// The smallest margin of each guard at `pose` (one-shot evaluation) and the parallel
/// measure; None when a stop-level guard fails.
fn margins(g: &G, pose: &Pose<f64>) -> Option<GuardMinima<f64>> {
    let mut m = GuardMinima::new();
    let mut stop = false;
    g.evaluate_pose(pose, &mut |r| {
        m.record(r.guard, r.margin);
        stop |= r.severity == Some(Severity::Stop);
    })?;
    (!stop).then_some(m)
}

/// The pose reached from `c` by the straight motion of translation `dt` and rotation
/// vector `dw` (world frame, as the supervisor's segments).
fn moved(c: &Pose<f64>, dt: &Vector3<f64>, dw: &Vector3<f64>) -> Pose<f64> {
    Pose {
        t: c.t + dt,
        r: Rotation3::from_scaled_axis(*dw) * c.r,
    }
}

/// The factor k that puts (k|dt|, k|dw|) on the edge of the certificate.
fn to_edge(cert: &Certificate<f64>, dt: f64, dr: f64) -> f64 {
    cert.scaled
        .iter()
        .map(|(a, b)| 1.0 / (a * dt + b * dr))
        .fold(f64::INFINITY, f64::min)
}

/// The quantities the auxiliary bounds of a region keep (the largest angle ψ between
/// z0 × l_b and ŝ2, from |Cn2| = |z0 × l_b| cos ψ, the largest |b - t|, the smallest and
/// largest singular values of the scaled Jtilde by nalgebra's SVD, and |f| of the
/// payload statics), from a full evaluation.
fn aux_quantities(g: &G, pose: &Pose<f64>) -> Option<[f64; 5]> {
    let st = staged(g, pose);
    let full = st.full()?;
    let t = full.sol.pose.t;
    let (mut psi, mut bt, mut rp) = (0.0f64, 0.0f64, 0.0f64);
    for c in Chain::ALL {
        let ch = &full.sol.chains[c];
        let u = Vector3::z().cross(&ch.lb).norm();
        psi = psi.max((full.jac.serial[c].a22.abs() / u).min(1.0).acos());
        bt = bt.max((ch.b - t).norm());
        rp = rp.max((ch.p - t).norm());
    }
    let mut a = full.jac.jtilde;
    for mut col in a.column_iter_mut().skip(3) {
        col /= rp;
    }
    let sv = a.svd(false, false).singular_values;
    let f = (full.statics.f1.norm_squared() + full.statics.f2.norm_squared()).sqrt();
    Some([psi, bt, sv.min(), sv.max(), f])
}

/// Checks the auxiliary bounds of the region between the centre and `x` (they are not
/// guards, so a stop level cannot reveal a wrong one): σ_min falls, ψ, |b - t|, σ_max and
/// |f| grow, each at most by its constraint's rate over the motion (the constraints'
/// order of `certificate_constraints`).
fn check_aux(
    g: &G,
    cons: &[Constraint<f64>],
    c: &Pose<f64>,
    x: &Pose<f64>,
    dt: f64,
    dr: f64,
) -> Result<(), TestCaseError> {
    let (Some(qc), Some(qx)) = (aux_quantities(g, c), aux_quantities(g, x)) else {
        return Err(TestCaseError::fail("no full evaluation inside the region"));
    };
    let by = |k: usize| cons[k].rate.over(dt, dr);
    let checks = [
        ("psi max", qx[0] - qc[0], by(7)),
        ("|b - t| max", qx[1] - qc[1], by(8)),
        ("sigma_min", qc[2] - qx[2], by(10)),
        ("sigma_max", qx[3] - qc[3], by(9)),
        ("|f|", qx[4] - qc[4], by(11)),
    ];
    for (name, change, bound) in checks {
        prop_assert!(
            change <= bound + 1e-12,
            "{name} changed by {change:e} over {:.4} mm, {:.5} rad: above the bound {bound:e}",
            dt * 1e3,
            dr
        );
    }
    Ok(())
}

/// Checks the bound (1) of every guard constraint between the centre and `x`, that `x`
/// violates no stop-level guard, and the auxiliary bounds ([`check_aux`]).
fn check_bounds(
    g: &G,
    cons: &[Constraint<f64>],
    c: &Pose<f64>,
    x: &Pose<f64>,
    dt: f64,
    dr: f64,
) -> Result<(), TestCaseError> {
    let Some(mx) = margins(g, x) else {
        return Err(TestCaseError::fail(format!(
            "a pose {:.4} mm, {:.5} rad from {c:?} inside the region violates a stop level: {:?}",
            dt * 1e3,
            dr,
            g.check_pose(x).0.first_stop()
        )));
    };
    for k in cons {
        let Some(guard) = k.guard else { continue };
        if guard == Guard::ParallelSingularity {
            continue; // its constraint is on the singular values (checked by the stop level)
        }
        let bound = k.margin - k.rate.over(dt, dr);
        prop_assert!(
            mx.get(guard) >= bound - 1e-12,
            "{guard}: margin {} at {:.4} mm, {:.5} rad, below the bound {} (centre {})",
            mx.get(guard),
            dt * 1e3,
            dr,
            bound,
            k.margin
        );
    }
    check_aux(g, cons, c, x, dt, dr)
}

fn unit() -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-1.0f64..1.0)
        .prop_filter("not tiny", |v| v.iter().map(|x| x * x).sum::<f64>() > 0.01)
        .prop_map(|v| Vector3::from_row_slice(&v).normalize())
}

proptest! {
    #![proptest_config(proptest_config::cases(512))]

    /// Every pose of the region certified by a full evaluation at a safe pose (in and
    /// around the task box, tilted up to 25 deg, the tool's payload or the thesis's design
    /// wrench, the stroke and the torque ratings tightened in some cases so that they bind)
    /// violates no stop-level guard, and every guard's margin there is at least its margin
    /// at the centre minus the bound (1): random directions, pushed to 99.9 % of the
    /// region's edge.
    #[test]
    fn the_certified_region_is_safe_and_the_bounds_hold(
        c in pose_near_box(0.160),
        dir_t in unit(), dir_r in unit(), mix in 0.0f64..1.0, edge in 0.5f64..0.999,
        tight in 0u8..4,
    ) {
        let mut limits = Limits::reference();
        match tight {
            1 => limits = limits.with_thesis_design_wrench(),
            2 => { limits.stroke = [0.150, 0.195]; limits.torque = Levels { warn: 0.15, stop: 0.3 }; }
            3 => { limits.force = Levels { warn: 20.0, stop: 40.0 }; limits.collision_radius = 0.06; }
            _ => {}
        }
        let g = guards(limits);
        let st = staged(&g, &c);
        let Some(full) = st.full() else { return Ok(()) };
        let Some(cert) = g.certify(&full) else { return Ok(()) };
        let cons = g.certificate_constraints(&full).unwrap();
        // A direction in (|Δt|, θ): mix of translation and rotation.
        let (dt, dr) = (mix, (1.0 - mix) * 0.2);
        let k = to_edge(&cert, dt, dr) * edge;
        let x = moved(&c, &(dir_t * dt * k), &(dir_r * dr * k));
        prop_assert!(cert.contains(&x));
        check_bounds(&g, &cons, &c, &x, dt * k, dr * k)?;
    }

    /// Inside a certified region the supervisor solves a setpoint with
    /// `Guards::solve_certified` instead of the kinematic guards: at the same poses as
    /// above, the kinematic evaluation finds no stop-level reading, and the shortcut gives
    /// the same outcome (what was solved, the joints, the Jacobian J, the first warn-level
    /// guard), bit for bit.
    #[test]
    fn a_setpoint_in_the_region_is_solved_as_the_kinematic_check_would(
        c in pose_near_box(0.160),
        dir_t in unit(), dir_r in unit(), mix in 0.0f64..1.0, edge in 0.0f64..0.999,
        design in any::<bool>(),
    ) {
        let limits = if design { Limits::reference().with_thesis_design_wrench() } else { Limits::reference() };
        let g = guards(limits);
        let st = staged(&g, &c);
        let Some(full) = st.full() else { return Ok(()) };
        let Some(cert) = g.certify(&full) else { return Ok(()) };
        let (dt, dr) = (mix, (1.0 - mix) * 0.2);
        let k = to_edge(&cert, dt, dr) * edge;
        let x = moved(&c, &(dir_t * dt * k), &(dir_r * dr * k));
        prop_assert!(cert.contains(&x));
        let first_warn = |stop: &mut bool, warn: &mut Option<Guard>, r: &Reading<f64>| {
            match r.severity {
                Some(Severity::Stop) => *stop = true,
                Some(Severity::Warn) if warn.is_none() => *warn = Some(r.guard),
                _ => {}
            }
        };
        let (mut stop_full, mut warn_full) = (false, None);
        let mut full_eval = Evaluation::new(Branch::OUTER);
        let solved_full = g.evaluate_pose_into(
            &x,
            &mut |r| first_warn(&mut stop_full, &mut warn_full, r),
            &mut ConditionEstimator::new(),
            &mut full_eval,
            Depth::Kinematic,
        );
        let (mut stop_cert, mut warn_cert) = (false, None);
        let mut cert_eval = Evaluation::new(Branch::OUTER);
        let solved_cert = g.solve_certified(
            &x,
            &mut |r| first_warn(&mut stop_cert, &mut warn_cert, r),
            &mut cert_eval,
        );
        prop_assert!(!stop_full && !stop_cert, "a stop-level reading in the region");
        prop_assert_eq!(solved_full, solved_cert);
        prop_assert_eq!(full_eval.sol.q(), cert_eval.sol.q());
        prop_assert_eq!(warn_full, warn_cert);
        if solved_full == Solved::WithJacobian {
            prop_assert_eq!(full_eval.jac.j, cert_eval.jac.j);
        }
    }

    /// The same in the direction in which the most constraining guard's margin falls
    /// fastest (its gradient by central differences at the centre), to the edge: the worst
    /// case the bounds must cover.
    #[test]
    fn the_bounds_hold_along_the_steepest_descent(c in pose_near_box(0.160), tight in 0u8..3) {
        let mut limits = Limits::reference();
        if tight == 1 { limits.stroke = [0.152, 0.190]; }
        if tight == 2 { limits.torque = Levels { warn: 0.1, stop: 0.2 }; }
        let g = guards(limits);
        let st = staged(&g, &c);
        let Some(full) = st.full() else { return Ok(()) };
        let Some(cert) = g.certify(&full) else { return Ok(()) };
        let cons = g.certificate_constraints(&full).unwrap();
        let Some(m0) = margins(&g, &c) else { return Ok(()) };
        // The guard with the smallest margin over its pure-translation rate.
        let worst = cons
            .iter()
            .filter(|k| k.guard.is_some_and(|g| g != Guard::ParallelSingularity) && k.rate.v > 0.0)
            .min_by(|a, b| (a.margin / a.rate.v).total_cmp(&(b.margin / b.rate.v)))
            .unwrap();
        let guard = worst.guard.unwrap();
        let h = 1e-6;
        let mut grad_t = Vector3::zeros();
        let mut grad_r = Vector3::zeros();
        for i in 0..3 {
            let e = Vector3::ith(i, 1.0);
            let f = |dt: Vector3<f64>, dw: Vector3<f64>| {
                margins(&g, &moved(&c, &dt, &dw)).map_or(-1.0, |m| m.get(guard))
            };
            grad_t[i] = (f(e * h, Vector3::zeros()) - f(-e * h, Vector3::zeros())) / (2.0 * h);
            grad_r[i] = (f(Vector3::zeros(), e * h) - f(Vector3::zeros(), -e * h)) / (2.0 * h);
        }
        let _ = m0;
        for (dir_t, dir_r, dt, dr) in [
            (-grad_t.normalize(), Vector3::x(), 1.0, 0.0),
            (Vector3::x(), -grad_r.normalize(), 0.0, 1.0),
            (-grad_t.normalize(), -grad_r.normalize(), 0.5, 0.05),
        ] {
            if !(dir_t.iter().all(|x| x.is_finite()) && dir_r.iter().all(|x| x.is_finite())) {
                continue;
            }
            let k = to_edge(&cert, dt, dr) * 0.999;
            let x = moved(&c, &(dir_t * dt * k), &(dir_r * dr * k));
            check_bounds(&g, &cons, &c, &x, dt * k, dr * k)?;
        }
    }
}

/// The size of the regions over the task box (the supervisor's look-ahead needs them well
/// above a braking distance, 1.25 mm at 25 mm/s): printed (the figures the README
/// quotes); more than 100 of the grid's 150 poses are certified.
#[test]
fn regions_over_the_task_box() {
    let g = guards(Limits::reference());
    let (mut t, mut r) = ([f64::INFINITY, 0.0], [f64::INFINITY, 0.0]);
    let (mut t_sum, mut n) = (0.0, 0);
    for pose in task_grid(0.160, 5, 3) {
        let st = staged(&g, &pose);
        let Some(full) = st.full() else { continue };
        let Some(cert) = g.certify(&full) else {
            continue;
        };
        t = [t[0].min(cert.reach_t), t[1].max(cert.reach_t)];
        r = [r[0].min(cert.reach_r), r[1].max(cert.reach_r)];
        t_sum += cert.reach_t;
        n += 1;
    }
    println!(
        "{n} poses: translation reach {:.3} .. {:.3} mm, mean {:.3} mm; rotation reach {:.4} .. {:.4} deg",
        t[0] * 1e3,
        t[1] * 1e3,
        t_sum / n as f64 * 1e3,
        r[0].to_degrees(),
        r[1].to_degrees()
    );
    assert!(n > 100);
}

/// The region at the central pose and at a corner of the task, constraint by constraint
/// (printed): at the centre every guard's own bound reaches at least 1 mm of translation.
/// `GuardMinima` keeps one slot per guard.
#[test]
fn constraints_at_the_centre_and_a_corner() {
    let mut m = GuardMinima::<f64>::new();
    for (k, g) in Guard::ALL.iter().enumerate() {
        m.record(*g, k as f64);
    }
    for (k, g) in Guard::ALL.iter().enumerate() {
        assert_eq!(m.get(*g), k as f64);
    }
    let g = guards(Limits::reference());
    for (name, pose) in [
        ("centre", Pose::central(0.160)),
        ("corner", task_grid(0.160, 5, 3)[120]),
    ] {
        let st = staged(&g, &pose);
        let full = st.full().unwrap();
        for k in g.certificate_constraints(&full).unwrap() {
            println!(
                "{name} {:?}: margin {:.4e}, rate {:.3e} per m/s + {:.3e} per rad/s: {:.3} mm or {:.4} deg",
                k.guard, k.margin, k.rate.v, k.rate.w, k.margin / k.rate.v * 1e3,
                (k.margin / k.rate.w).to_degrees()
            );
            if name == "centre" && k.guard.is_some() {
                assert!(k.margin / k.rate.v > 1e-3);
            }
        }
    }
}

proptest! {
    #![proptest_config(proptest_config::cases(512))]

    /// Property: `angle_bound` bounds the rotation angle of a·bᵀ from above (conservative
    /// region tests) and exceeds it by no more than 2·tan(θ/2) - θ (plus rounding).
    #[test]
    fn angle_bound_is_an_upper_bound(
        ra in prop::array::uniform3(-1.5f64..1.5),
        rb in prop::array::uniform3(-1.5f64..1.5),
    ) {
        let a = Rotation3::from_scaled_axis(Vector3::from(ra));
        let b = Rotation3::from_scaled_axis(Vector3::from(rb));
        let theta = kinematics_core::pose::rotation_angle(&(a * b.inverse()));
        let bound = certificate::angle_bound(&a, &b);
        prop_assert!(bound >= theta - 1e-12, "{bound} < {theta}");
        if theta < 3.1 {
            let exact = 2.0 * (theta / 2.0).tan();
            prop_assert!(bound <= exact * (1.0 + 1e-9) + 1e-7, "{bound} vs {exact}");
        }
    }

    /// Property: `contains_motion` holds what it claims for a straight motion at any
    /// relative pace of its translation and rotation: when it accepts `from` → `to`, every
    /// pose with the translation at fraction `st` and the rotation at fraction `sr` of
    /// the segment keeps every constraint, a·|Δt| + b·θ < 1 with the true angle θ from
    /// the centre. This is the geodesic convexity of the rotation balls (the angle from the
    /// centre along the segment never exceeds its larger end), which the test checks
    /// directly too, with ends up to 80 deg from the centre.
    #[test]
    fn a_contained_motion_keeps_every_constraint_at_any_pace(
        wc in prop::array::uniform3(-1.0f64..1.0),
        wa in prop::array::uniform3(-0.8f64..0.8),
        wb in prop::array::uniform3(-0.8f64..0.8),
        ta in prop::array::uniform3(-2e-3f64..2e-3),
        tb in prop::array::uniform3(-2e-3f64..2e-3),
        coeffs in prop::array::uniform4(0.0f64..2.0),
        paces in prop::collection::vec((0.0f64..=1.0, 0.0f64..=1.0), 16),
    ) {
        use kinematics_core::pose::rotation_angle;
        let rc = Rotation3::from_scaled_axis(Vector3::from(wc));
        let center = Pose { t: Vector3::zeros(), r: rc };
        // Ends within 0.8·√3 rad ≈ 79 deg of the centre (rotation vectors relative to it).
        let end = |w: [f64; 3], t: [f64; 3]| Pose {
            t: Vector3::from(t),
            r: Rotation3::from_scaled_axis(Vector3::from(w)) * rc,
        };
        let (from, to) = (end(wa, ta), end(wb, tb));
        let (th_a, th_b) = (
            rotation_angle(&(from.r * rc.inverse())),
            rotation_angle(&(to.r * rc.inverse())),
        );
        // Two constraints, per mm and per rad, scaled so that the ends lie near the edge.
        let mut scaled = [(0.0, 0.0); certificate::CONSTRAINTS];
        let size = (ta.iter().chain(tb.iter()).map(|x| x.abs()).fold(0.0, f64::max) * 1e3)
            .max(th_a.max(th_b));
        scaled[0] = (coeffs[0] * 1e3 / size / 2.0, coeffs[1] / size / 2.0);
        scaled[1] = (coeffs[2] * 1e3 / size / 2.0, coeffs[3] / size / 2.0);
        let cert = Certificate { center, scaled, reach_t: 0.0, reach_r: 0.0, warn: None };
        let inside = cert.contains_motion(&from, &to);
        for (st, sr) in paces {
            let t = from.t + (to.t - from.t) * st;
            let r = kinematics_core::supervisor::interpolate(&from, &to, sr).r;
            let theta = rotation_angle(&(r * rc.inverse()));
            prop_assert!(
                theta <= th_a.max(th_b) + 1e-12,
                "angle {theta} at fraction {sr} beyond the ends' {th_a}, {th_b}"
            );
            if inside {
                for (a, b) in cert.scaled {
                    prop_assert!(a * t.norm() + b * theta < 1.0 + 1e-12);
                }
            }
        }
    }
}

/// A motion with a NaN or infinite end is never contained (a NaN must not pass as a
/// distance or angle of 0), and `angle_bound` of a matrix with a NaN is beyond any reach.
#[test]
fn a_motion_with_a_nan_end_is_not_contained() {
    let center = Pose::central(0.160);
    let cert = Certificate {
        center,
        scaled: [(1.0, 1.0); certificate::CONSTRAINTS],
        reach_t: 1.0,
        reach_r: 1.0,
        warn: None,
    };
    let near = Pose {
        t: center.t + Vector3::new(1e-4, 0.0, 0.0),
        r: center.r,
    };
    assert!(cert.contains_motion(&center, &near));
    for bad in [f64::NAN, f64::INFINITY] {
        let mut t = near;
        t.t.y = bad;
        assert!(!cert.contains_motion(&center, &t));
        assert!(!cert.contains_motion(&t, &center));
        let mut r = near;
        r.r = Rotation3::from_matrix_unchecked(center.r.matrix().map(|_| bad));
        assert!(!cert.contains_motion(&center, &r));
        assert!(!cert.contains_motion(&r, &center));
        assert!(certificate::angle_bound(&r.r, &center.r) > 1e300);
    }
}

/// The rate of the scaled Jtilde along the straight motion (v, w) through `x`, ‖dA/ds‖_F
/// by central differences of step `h`; None when a differenced pose has no full
/// evaluation.
fn jtilde_rate(g: &G, x: &Pose<f64>, v: &Vector3<f64>, w: &Vector3<f64>, h: f64) -> Option<f64> {
    let a1 = scaled_jtilde(g, &moved(x, &(v * h), &(w * h)))?;
    let a0 = scaled_jtilde(g, &moved(x, &(-v * h), &(-w * h)))?;
    Some((a1 - a0).norm() / (2.0 * h))
}

/// The scaled Jtilde (moment columns over rp) of a full evaluation at `pose`.
fn scaled_jtilde(g: &G, pose: &Pose<f64>) -> Option<nalgebra::Matrix6<f64>> {
    let st = staged(g, pose);
    let full = st.full()?;
    let t = full.sol.pose.t;
    let rp = Chain::ALL
        .iter()
        .map(|c| (full.sol.chains[*c].p - t).norm())
        .fold(0.0, f64::max);
    let mut a = full.jac.jtilde;
    for mut col in a.column_iter_mut().skip(3) {
        col /= rp;
    }
    Some(a)
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: anywhere in a certified region, the scaled Jtilde changes along the
    /// region's straight motions no faster than the rate δ the region's parallel-measure
    /// constraints use (‖dA/ds‖_F by central differences against δ_v|v| + δ_w|ω|): the
    /// first-order check of the bound, which the singular values' changes
    /// ([`check_aux`]) see only through Weyl's inequality. Random directions, from the
    /// centre to 99.9 % of the edge.
    #[test]
    fn jtilde_changes_no_faster_than_delta_in_the_region(
        c in pose_near_box(0.160),
        dir_t in unit(), dir_r in unit(), mix in 0.0f64..=1.0, edge in 0.0f64..0.999,
    ) {
        let g = guards(Limits::reference());
        let st = staged(&g, &c);
        let Some(full) = st.full() else { return Ok(()) };
        let Some(cert) = g.certify(&full) else { return Ok(()) };
        let delta = g.certificate_constraints(&full).unwrap()[9].rate;
        let (dt, dr) = (mix, (1.0 - mix) * 0.2);
        let reach = to_edge(&cert, dt, dr);
        let k = reach * edge;
        let (v, w) = (dir_t * dt, dir_r * dr);
        let x = moved(&c, &(v * k), &(w * k));
        // The differences stay inside the region (a region at a guard's boundary can be
        // far smaller than 1 µm; below 1 nm it is not differenced).
        let h = (0.4 * reach * (1.0 - edge)).min(1e-6);
        if h < 1e-9 {
            return Ok(());
        }
        let Some(rate) = jtilde_rate(&g, &x, &v, &w, h) else {
            return Err(TestCaseError::fail("no full evaluation inside the region"));
        };
        let bound = delta.over(dt, dr);
        prop_assert!(
            rate <= bound * (1.0 + 1e-6),
            "|dA/ds| {rate} above delta {bound} at {:.3} of the way to the edge ({dt}, {dr})",
            edge
        );
    }
}

/// δ against the largest rate of the scaled Jtilde at the centre and at a corner of the
/// task, over 400 directions of translation and 400 of rotation (a Fibonacci sphere;
/// central differences): never below it (soundness at the centre), and within 2x of it
/// for translation and 3x for rotation (printed: the bound's looseness, which sets the
/// regions' size).
#[test]
fn delta_against_the_largest_rate_of_jtilde() {
    let g = guards(Limits::reference());
    let n = 400;
    let sphere = |i: usize| {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
        let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let r = (1.0 - z * z).sqrt();
        Vector3::new(r * phi.cos(), r * phi.sin(), z)
    };
    for (name, c) in [
        ("centre", Pose::central(0.160)),
        ("corner", task_grid(0.160, 5, 3)[120]),
    ] {
        let st = staged(&g, &c);
        let full = st.full().unwrap();
        let delta = g.certificate_constraints(&full).unwrap()[9].rate;
        let h = 1e-6;
        let (mut worst_v, mut worst_w) = (0.0f64, 0.0f64);
        for i in 0..n {
            let d = sphere(i);
            let z = Vector3::zeros();
            worst_v = worst_v.max(jtilde_rate(&g, &c, &d, &z, h).unwrap());
            worst_w = worst_w.max(jtilde_rate(&g, &c, &z, &d, h).unwrap());
        }
        println!(
            "{name}: delta {:.2} per m/s, {:.3} per rad/s; largest |dA/ds|_F {:.2}, {:.3}: {:.2}x, {:.2}x",
            delta.v,
            delta.w,
            worst_v,
            worst_w,
            delta.v / worst_v,
            delta.w / worst_w
        );
        assert!(worst_v <= delta.v && worst_w <= delta.w);
        assert!(delta.v <= 2.0 * worst_v && delta.w <= 3.0 * worst_w);
    }
}
