#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The per-chain geometry (`PerChainGeometry`).
//!
//! 1. Its symmetric instance (`From<RsprGeometry>`) is the reference robot: IK, the
//!    Jacobians, FK, the statics and every guard reading agree with `RsprGeometry`'s, in
//!    f64 and f32, to rounding. The two compute the spherical joint by different routes
//!    (the symmetric code pierces the base plane along the platform normal, the per-chain
//!    code along the leg plane), so they agree to a few dozen ulps of the lengths involved
//!    (0.2 m), amplified by the conditioning of each step: the roots of Eq. 6.22 by
//!    1/(serial measure) (the discriminant vanishes at a serial singularity), J and the
//!    forces once more by 1/(serial measure) and by the parallel condition number, FK by
//!    both. Each bound below is `K · ε · L ·` that amplification, K = 64.
//! 2. A perturbed instance (±0.5 mm on positions and lengths, ±0.5 deg on axes, ±20 counts
//!    on the encoder zeros) is self-consistent: IK then FK gives the pose back, and J equals
//!    finite differences of its IK.

use crate::common;

use common::*;
use kinematics_core::guards::{Guards, Limits, Reading};
use kinematics_core::scalar::lit;
use kinematics_core::*;
use nalgebra::{Rotation3, Vector3, Vector6};
use proptest::prelude::*;

const K: f64 = 64.0;
/// The length the rounding is relative to (the legs are 0.14..0.21 m).
const L: f64 = 0.2;

/// Per-chain deviations: base pivot, base axis tilt (2), link length, platform joint,
/// platform axis tilt (2), leg offset, leg zero, link zero.
type Deviation = [f64; 14];

fn deviation() -> impl Strategy<Value = [Deviation; 3]> {
    let mm = 0.5e-3;
    let deg = 0.5 * DEG;
    let one = (
        prop::array::uniform3(-mm..mm),
        prop::array::uniform2(-deg..deg),
        -mm..mm,
        prop::array::uniform3(-mm..mm),
        prop::array::uniform2(-deg..deg),
        -mm..mm,
        // ±20 counts: 0.0015 mm and 0.005 deg per count.
        -20.0 * 1.5e-6..20.0 * 1.5e-6,
        -20.0 * 0.005 * DEG..20.0 * 0.005 * DEG,
    )
        .prop_map(|(c, a, rb, p, r, lo, lz, tz)| {
            [
                c[0], c[1], c[2], a[0], a[1], rb, p[0], p[1], p[2], r[0], r[1], lo, lz, tz,
            ]
        });
    [one.clone(), one.clone(), one]
}

/// The reference robot with `dev` applied chain by chain (axes tilted by small rotations).
fn perturbed(dev: &[Deviation; 3]) -> PerChainGeometry<f64> {
    let g = RsprGeometry::<f64>::reference();
    let sym = PerChainGeometry::from(g);
    let chains = sym.chains().map(|c, d| {
        let x = &dev[c.index()];
        let tilt = |v: &Vector3<f64>, a: f64, b: f64| {
            Rotation3::from_scaled_axis(Vector3::new(a, b, 0.0)) * v
        };
        ChainDimensions {
            base_pivot: d.base_pivot + Vector3::new(x[0], x[1], x[2]),
            base_axis: tilt(&d.base_axis, x[3], x[4]),
            link_length: d.link_length + x[5],
            platform_joint: d.platform_joint + Vector3::new(x[6], x[7], x[8]),
            platform_axis: Rotation3::from_scaled_axis(d.platform_axis.cross(&Vector3::z()) * x[9])
                * Rotation3::from_scaled_axis(Vector3::z() * x[10])
                * d.platform_axis,
            leg_offset: x[11],
            leg_zero: x[12],
            link_zero: x[13],
        }
    });
    PerChainGeometry::new(g, chains).unwrap()
}

/// The smallest dimensionless serial measure of a solution (1/amplification of Eq. 6.22).
fn serial_min<T: Real, M: Mechanism<T>>(m: &M, sol: &Solution<T>) -> f64 {
    sol.chains
        .iter()
        .map(|(_, c)| to64(m.serial_measure(c).1))
        .fold(f64::INFINITY, f64::min)
}

fn to64<T: Real>(x: T) -> f64 {
    x.to_subset().unwrap()
}

fn eps<T: Real>() -> f64 {
    to64(T::default_epsilon())
}

/// The symmetric instance against RsprGeometry at one pose, every branch, in scalar T.
fn symmetric_agrees<T: Real>(pose64: &Pose<f64>) -> Result<(), TestCaseError> {
    let g = RsprGeometry::<T>::reference();
    let p = PerChainGeometry::from(g);
    let pose: Pose<T> = pose64.cast();
    let eps = eps::<T>();
    for branch in Branch::ALL {
        let (a, b) = (inverse(&g, &pose, branch), inverse(&p, &pose, branch));
        let (sa, sb) = match (a, b) {
            (Ok(sa), Ok(sb)) => (sa, sb),
            (Err(ea), Err(eb)) => {
                prop_assert_eq!(ea.chain, eb.chain);
                continue;
            }
            // At the reach boundary one route may round to a tiny discriminant of the
            // other sign: only a pose with a serial measure at rounding level may differ.
            (Ok(s), Err(_)) | (Err(_), Ok(s)) => {
                let rel = to64(
                    s.chains
                        .iter()
                        .map(|(_, c)| g.serial_measure(c).1)
                        .fold(T::max_value().unwrap(), |x, y| x.min(y)),
                );
                prop_assert!(
                    rel < 1e3 * eps.sqrt(),
                    "branch {branch}: one solves, serial measure {rel:e}"
                );
                continue;
            }
        };
        let rel = serial_min(&g, &sa).max(1e-12);
        // Joints, and the points the guards read.
        let tol_q = K * eps * L / rel;
        let (qa, qb) = (sa.q(), sb.q());
        for i in 0..6 {
            let d = if i < 3 {
                to64(qa[i] - qb[i])
            } else {
                to64(scalar::wrap_angle(qa[i] - qb[i])) * L
            };
            prop_assert!(
                d.abs() <= tol_q,
                "branch {branch} q{}: {d:e} > {tol_q:e}",
                i + 1
            );
        }
        for c in Chain::ALL {
            let (ca, cb) = (&sa.chains[c], &sb.chains[c]);
            for (x, y) in [
                (ca.b, cb.b),
                (ca.p, cb.p),
                (ca.s1 * lit::<T>(L), cb.s1 * lit::<T>(L)),
            ] {
                prop_assert!(
                    to64((x - y).norm()) <= tol_q,
                    "branch {branch} {c}: points differ"
                );
            }
        }
        // Jacobians: Jtilde from the points, J through the serial blocks' inverses.
        let (ja, jb) = (jacobian(&g, &sa), jacobian(&p, &sb));
        let (Ok(ja), Ok(jb)) = (ja, jb) else {
            prop_assert!(
                rel < 1e-3,
                "branch {branch}: one Jacobian fails at serial measure {rel:e}"
            );
            continue;
        };
        let jt = to64((ja.jtilde - jb.jtilde).abs().max()) / (1.0 + to64(ja.jtilde.abs().max()));
        prop_assert!(jt <= K * eps / rel, "branch {branch} Jtilde {jt:e}");
        let jj = to64((ja.j - jb.j).abs().max()) / (1.0 + to64(ja.j.abs().max()));
        prop_assert!(jj <= K * eps / (rel * rel), "branch {branch} J {jj:e}");
        // Statics: τ = J⁻ᵀ s_e, amplified by the parallel condition number.
        let se: Wrench<T> = Vector6::new(7.0, 7.0, 7.0, 0.7, 0.7, 0.7).cast();
        let (fa, fb) = (
            actuator_forces(&ja, g.rp(), &se, lit(1e-3)),
            actuator_forces(&jb, p.rp(), &se, lit(1e-3)),
        );
        if let (Ok(fa), Ok(fb)) = (fa, fb) {
            let ic = to64(fa.inv_cond);
            let d = to64((fa.tau - fb.tau).abs().max()) / (1.0 + to64(fa.tau.abs().max()));
            prop_assert!(
                d <= K * eps / (rel * rel * ic),
                "branch {branch} tau {d:e} (inv cond {ic:e})"
            );
            prop_assert!((to64(fa.inv_cond - fb.inv_cond)).abs() <= K * eps / (rel * ic));
        }
        // FK from the joints, warm-started 0.5 mm and 0.5 deg away: both converge to the
        // pose within their tolerances amplified by the conditioning.
        let ms = measures(&g, &sa).map_err(|e| TestCaseError::fail(e.to_string()))?;
        if ms.parallel_inv_cond < lit(0.01) {
            continue;
        }
        let guess = pose.displaced(&Vector3::repeat(lit(3e-4)), &Vector3::repeat(lit(0.005)));
        if inverse(&g, &guess, branch).is_err() {
            continue;
        }
        let cfg = FkConfig::default();
        let fa = forward(&g, &qa, branch, &guess, &cfg);
        let fb = forward(&p, &qb, branch, &guess, &cfg);
        let (Ok(fa), Ok(fb)) = (fa, fb) else {
            return Err(TestCaseError::fail(format!(
                "branch {branch}: FK failed on one"
            )));
        };
        let ic = to64(ms.parallel_inv_cond);
        let (dp, dr) = pose_error(&fa.pose.cast::<f64>(), &fb.pose.cast::<f64>());
        let tol = K * eps * L / (rel * ic);
        prop_assert!(
            dp <= tol && dr * L <= tol,
            "branch {branch} FK: {dp:e} m, {dr:e} rad > {tol:e}"
        );
    }
    Ok(())
}

/// Every guard reading of the symmetric instance against RsprGeometry's at one pose.
fn guards_agree<T: Real>(pose64: &Pose<f64>) -> Result<(), TestCaseError> {
    let g = RsprGeometry::<T>::reference();
    let ga = Guards::new(g, Branch::OUTER, Limits::reference()).unwrap();
    let gb = Guards::new(
        PerChainGeometry::from(g),
        Branch::OUTER,
        Limits::reference(),
    )
    .unwrap();
    let pose: Pose<T> = pose64.cast();
    let mut ra: Vec<Reading<T>> = Vec::new();
    let mut rb: Vec<Reading<T>> = Vec::new();
    let sa = ga.evaluate_pose(&pose, &mut |r| ra.push(*r));
    gb.evaluate_pose(&pose, &mut |r| rb.push(*r));
    let rel = sa.map_or(1.0, |s| serial_min(&g, &s)).max(1e-12);
    let eps = eps::<T>();
    prop_assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(rb.iter()) {
        prop_assert_eq!((x.guard, x.subject), (y.guard, y.subject));
        // Forces (N, N m) and measures scale with their own size; lengths with L; angles are
        // within 2π. The payload statics meet the parallel condition number as well.
        let scale = 1.0 + to64(x.value.abs());
        let tol = K * eps * scale / (rel * rel * 1e-2);
        let d = to64((x.value - y.value).abs());
        prop_assert!(
            d <= tol,
            "{} {}: {:e} vs {:e}",
            x.guard,
            x.subject,
            to64(x.value),
            to64(y.value)
        );
        if to64(x.margin.abs()) > tol {
            prop_assert_eq!(x.severity, y.severity, "{} {}", x.guard, x.subject);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// The symmetric instance is the reference robot in f64: IK, J, statics, FK.
    #[test]
    fn symmetric_instance_is_the_reference_robot_f64(pose in pose_near_box(0.160)) {
        symmetric_agrees::<f64>(&pose)?;
    }

    /// The same in f32, the board's scalar.
    #[test]
    fn symmetric_instance_is_the_reference_robot_f32(pose in pose_near_box(0.160)) {
        symmetric_agrees::<f32>(&pose)?;
    }

    /// Every guard gives the same reading, and the same severity away from its limit, in
    /// f64 and f32.
    #[test]
    fn symmetric_instance_has_the_same_guard_readings(pose in pose_near_box(0.160)) {
        guards_agree::<f64>(&pose)?;
        guards_agree::<f32>(&pose)?;
    }

    /// A perturbed robot is self-consistent: IK then FK returns the pose (f64: 1e-9 m and
    /// rad; f32: 2 µm and 2e-5 rad, as the reference robot's f32 FK) on the prototype's
    /// branch wherever it is solvable and conditioned (inverse condition number ≥ 0.01).
    #[test]
    fn perturbed_ik_then_fk_returns_the_pose(dev in deviation(), pose in pose_near_box(0.160), (dv, dw) in perturbation()) {
        let g = perturbed(&dev);
        let Ok(sol) = inverse(&g, &pose, Branch::OUTER) else { return Ok(()) };
        prop_assume!(measures(&g, &sol).is_ok_and(|m| m.parallel_inv_cond >= 0.01));
        let guess = pose.displaced(&dv, &dw);
        prop_assume!(inverse(&g, &guess, Branch::OUTER).is_ok());
        let fk = forward(&g, &sol.q(), Branch::OUTER, &guess, &FkConfig::default())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let (dp, dr) = pose_error(&fk.pose, &pose);
        prop_assert!(dp < 1e-9 && dr < 1e-9, "f64: {dp:e} m, {dr:e} rad");
        let g32 = g.cast::<f32>().unwrap();
        let sol32 = inverse(&g32, &pose.cast(), Branch::OUTER).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let fk32 = forward(&g32, &sol32.q(), Branch::OUTER, &guess.cast(), &FkConfig::default())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let (dp, dr) = pose_error(&fk32.pose.cast::<f64>(), &pose);
        prop_assert!(dp < 2e-6 && dr < 2e-5, "f32: {dp:e} m, {dr:e} rad");
    }

    /// On a perturbed robot the analytic J equals Richardson-extrapolated central
    /// differences of the IK (as for the reference robot in `properties.rs`): the serial
    /// blocks with the tilted axes are right.
    #[test]
    fn perturbed_jacobian_matches_finite_differences(dev in deviation(), pose in pose_near_box(0.160)) {
        let g = perturbed(&dev);
        let h = 1e-6;
        let q_at = |d: &Vector6<f64>| {
            let p = pose.displaced(&Vector3::new(d[0], d[1], d[2]), &Vector3::new(d[3], d[4], d[5]));
            inverse(&g, &p, Branch::OUTER).ok().map(|s| s.q())
        };
        let central = |k: usize, h: f64| {
            let mut d = Vector6::zeros();
            d[k] = h;
            let (qp, qm) = (q_at(&d)?, q_at(&(-d))?);
            let mut fd = (qp - qm) / (2.0 * h);
            for i in 3..6 {
                fd[i] = scalar::wrap_angle(qp[i] - qm[i]) / (2.0 * h);
            }
            Some(fd)
        };
        let Ok(sol) = inverse(&g, &pose, Branch::OUTER) else { return Ok(()) };
        let Ok(jac) = jacobian(&g, &sol) else { return Ok(()) };
        for k in 0..6 {
            let (Some(coarse), Some(fine)) = (central(k, h), central(k, h / 2.0)) else { continue };
            let fd = (fine * 4.0 - coarse) / 3.0;
            let col = jac.j.column(k);
            let err = (fd - col).norm();
            prop_assert!(err <= 1e-5 * (1.0 + col.norm()), "column {k}: |fd - J| = {err:e}");
        }
    }
}

/// The offsets enter the joints as stated: with only encoder zeros and leg offsets, the
/// joints are the reference robot's minus the offsets (the spherical joints do not move).
#[test]
fn offsets_shift_the_joints() {
    let g = RsprGeometry::<f64>::reference();
    let sym = PerChainGeometry::from(g);
    let chains = sym.chains().map(|c, d| ChainDimensions {
        leg_offset: 1e-4 * (c.index() as f64 + 1.0),
        leg_zero: -2e-5,
        link_zero: 0.001 * (c.index() as f64 + 1.0),
        ..*d
    });
    let off = PerChainGeometry::new(g, chains).unwrap();
    let pose = Pose::from_position_rotation_vector(
        Vector3::new(0.01, -0.005, 0.165),
        Vector3::new(0.1, 0.05, 0.0),
    )
    .unwrap();
    let (a, b) = (
        inverse(&g, &pose, Branch::OUTER).unwrap().q(),
        inverse(&off, &pose, Branch::OUTER).unwrap().q(),
    );
    for c in Chain::ALL {
        let i = c.index();
        let d = &off.chains()[c];
        assert!((a[i] - (b[i] + d.leg_offset + d.leg_zero)).abs() < 1e-15);
        assert!(scalar::wrap_angle(a[i + 3] - (b[i + 3] + d.link_zero)).abs() < 1e-14);
    }
}

/// Bad values are refused with the field named.
#[test]
fn invalid_dimensions_are_named() {
    let g = RsprGeometry::<f64>::reference();
    let sym = PerChainGeometry::from(g);
    let mut chains = *sym.chains();
    chains[Chain::Two].base_axis = Vector3::new(0.0, 0.0, 1.1);
    assert_eq!(
        PerChainGeometry::new(g, chains).unwrap_err(),
        GeometryError::NotUnit {
            field: "chain 2 base_axis",
            norm: 1.1
        }
    );
    let mut chains = *sym.chains();
    chains[Chain::Three].link_length = f64::NAN;
    assert_eq!(
        PerChainGeometry::new(g, chains).unwrap_err(),
        GeometryError::NonFinite {
            field: "chain 3 link_length"
        }
    );
    let mut chains = *sym.chains();
    chains[Chain::One].base_axis = Vector3::new(1.0, 0.0, 0.0);
    assert_eq!(
        PerChainGeometry::new(g, chains).unwrap_err(),
        GeometryError::AxisOutOfRange {
            field: "chain 1 base_axis"
        }
    );
    let mut chains = *sym.chains();
    chains[Chain::One].base_pivot = Vector3::new(0.02, 0.5, 0.0);
    assert!(matches!(
        PerChainGeometry::new(g, chains).unwrap_err(),
        GeometryError::NotAssemblable { .. }
    ));
    // The symmetric instance validates; its axes are unit to rounding already.
    let v = PerChainGeometry::new(g, *sym.chains()).unwrap();
    for c in Chain::ALL {
        let (a, b) = (&v.chains()[c], &sym.chains()[c]);
        assert!((a.base_axis - b.base_axis).norm() < 1e-15);
        assert!((a.platform_axis - b.platform_axis).norm() < 1e-15);
    }
}
