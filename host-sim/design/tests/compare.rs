//! The comparison of `host-sim compare`: the RSPR with zero eccentricity against the RRPS
//! robot (thesis Appendix A, Fig. 4.4), checked against an independent derivation of the
//! torque ratio (the command itself: host-sim/tests/compare.rs).
//!
//! The independent ratio: the RSPR torques come from `kinematics_core::{inverse, jacobian,
//! actuator_forces}` (RsprGeometry with e = 0); the RRPS torques are derived twice without
//! the RRPS Jacobian or statics code:
//! 1. static equilibrium written out here from the geometry alone (no library call): each
//!    chain pushes on the platform with a force f_i ŝ_i + g_i â_i through p_i (the
//!    spherical joint carries no moment, the passive axis â_i through b_i none either), the
//!    six unknowns balance s_e, and the motor torque is the moment of that force about the
//!    first revolute axis, τ_θi = ((p_i - e_i) × (f_i ŝ_i + g_i â_i)) · z0;
//! 2. virtual work on a finite-difference Jacobian dq/dx of the RRPS inverse kinematics,
//!    solved with a QR factorisation: J_fdᵀ τ = s_e.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::compare::{compare_along, Pair};
use design::forces_path::PathSpec;
use design::rrps::{rrps_inverse, RrpsGeometry};
use kinematics_core::scalar::wrap_angle;
use kinematics_core::{actuator_forces, inverse, jacobian, Branch, Pose, RsprGeometry};
use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};

const RB: f64 = 0.090;
const RP: f64 = 0.050;
const HC: f64 = 0.160;

fn se() -> Vector6<f64> {
    Vector6::new(7.0, 7.0, 7.0, 0.7, 0.7, 0.7)
}

/// The thesis's diagonal: 101 poses from [-20,-20,-10] to [20,20,10] mm about [0, 0, hc],
/// 20 deg about [1,1,1].
fn diagonal() -> Vec<Pose<f64>> {
    let r = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(1.0, 1.0, 1.0)),
        20f64.to_radians(),
    );
    (0..101)
        .map(|i| {
            let s = i as f64 / 100.0;
            let d = Vector3::new(-0.020, -0.020, -0.010) * (1.0 - s)
                + Vector3::new(0.020, 0.020, 0.010) * s;
            Pose {
                t: Vector3::new(0.0, 0.0, HC) + d,
                r,
            }
        })
        .collect()
}

/// RRPS rotary torques by static equilibrium, from the geometry alone (outer branch, e = 0).
fn rrps_torques_by_equilibrium(pose: &Pose<f64>) -> [f64; 3] {
    let mut a_mat = Matrix6::zeros();
    let mut pts = [Vector3::zeros(); 3];
    let mut dirs = [(Vector3::zeros(), Vector3::zeros()); 3];
    for i in 0..3 {
        let xi = 2.0 * std::f64::consts::PI * i as f64 / 3.0;
        let p = pose.t + pose.r * Vector3::new(RP * xi.cos(), RP * xi.sin(), 0.0);
        // The link points at p's horizontal projection; the second axis is z × link.
        let u = Vector3::new(p.x, p.y, 0.0).normalize();
        let a = Vector3::z().cross(&u);
        let s = (p - u * RB).normalize();
        let arm = p - pose.t;
        for (col, dir) in [(i, s), (i + 3, a)] {
            let m = arm.cross(&dir);
            for k in 0..3 {
                a_mat[(k, col)] = dir[k];
                a_mat[(k + 3, col)] = m[k];
            }
        }
        pts[i] = p;
        dirs[i] = (s, a);
    }
    let x = a_mat.lu().solve(&se()).unwrap();
    let mut tau = [0.0; 3];
    for i in 0..3 {
        let force = dirs[i].0 * x[i] + dirs[i].1 * x[i + 3];
        tau[i] = pts[i].cross(&force).z;
    }
    tau
}

/// RRPS τ by virtual work on a finite-difference Jacobian of the IK (QR solve).
fn rrps_tau_by_fd(g: &RrpsGeometry<f64>, pose: &Pose<f64>) -> Vector6<f64> {
    let h = 1e-6;
    let mut j = Matrix6::zeros();
    for k in 0..6 {
        let mut d = Vector6::zeros();
        d[k] = h;
        let q = |d: Vector6<f64>| {
            let p = pose.displaced(&d.fixed_rows::<3>(0).into(), &d.fixed_rows::<3>(3).into());
            rrps_inverse(g, &p, Branch::OUTER).unwrap().q()
        };
        let (qp, qm) = (q(d), q(-d));
        for r in 0..6 {
            let dq = if r < 3 {
                qp[r] - qm[r]
            } else {
                wrap_angle(qp[r] - qm[r])
            };
            j[(r, k)] = dq / (2.0 * h);
        }
    }
    j.transpose().qr().solve(&se()).unwrap()
}

fn peak(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0, |m, x| m.max(x.abs()))
}

#[test]
fn torque_ratio_matches_an_independent_derivation() {
    let rspr = RsprGeometry::new(0.0, RB, RP, HC).unwrap();
    let rrps = RrpsGeometry::new(0.0, RB, RP, HC).unwrap();
    let poses = diagonal();
    let mut rspr_t = Vec::new();
    let mut eq_t = Vec::new();
    let mut fd_t = Vec::new();
    for p in &poses {
        let sol = inverse(&rspr, p, Branch::OUTER).unwrap();
        let jac = jacobian(&rspr, &sol).unwrap();
        let st = actuator_forces(&jac, RP, &se(), 1e-6).unwrap();
        rspr_t.extend([st.tau[3], st.tau[4], st.tau[5]]);
        let eq = rrps_torques_by_equilibrium(p);
        let fd = rrps_tau_by_fd(&rrps, p);
        for i in 0..3 {
            assert!((eq[i] - fd[3 + i]).abs() < 1e-5, "{eq:?} vs {fd}");
        }
        eq_t.extend(eq);
        fd_t.extend([fd[3], fd[4], fd[5]]);
    }
    let rspr_peak = peak(rspr_t.into_iter());
    let independent = rspr_peak / peak(eq_t.into_iter());
    let by_fd = rspr_peak / peak(fd_t.into_iter());
    assert!((independent - by_fd).abs() < 1e-5);

    let c = compare_along(&Pair::thesis(), &PathSpec::thesis_diagonal());
    assert_eq!(c.failed(), 0);
    assert!(
        (c.torque_ratio() - independent).abs() < 1e-9,
        "{} vs {independent}",
        c.torque_ratio()
    );
    // The value found (RSPR peak 0.5812 N m, RRPS 0.7199 N m): the RSPR needs about 19%
    // less rotary torque, not the thesis's "about 37%" (a ratio of about 0.63).
    assert!((independent - 0.8074).abs() < 5e-4, "{independent}");
}

/// The three readings of `compare` (design README, "The RSPR/RRPS comparison"): their
/// bounds (mean ≤ peak, peak-to-peak ≤ 2 peak, by definition) and the figures the README
/// states, at e = 0, both robots at the prototype's e = 20 mm, and the prototype RSPR
/// against the RRPS at e = 0.
#[test]
fn readings_at_both_eccentricities() {
    use design::compare::{readings, reductions};
    let spec = PathSpec::thesis_diagonal();
    let e0 = Pair::new(RB, RP, HC).unwrap();
    let e20 = Pair::with_eccentricity(0.020, RB, RP, HC).unwrap();
    let mixed = Pair {
        rspr: e20.rspr,
        rrps: e0.rrps,
    };
    let mut got = Vec::new();
    for pair in [e0, e20, mixed] {
        let c = compare_along(&pair, &spec);
        assert_eq!(c.failed(), 0);
        let (a, b) = readings(&c.rspr, &c.rrps, 3..6);
        for r in [a, b] {
            assert!(r.mean <= r.peak && r.peak_to_peak <= 2.0 * r.peak, "{r:?}");
        }
        got.push(reductions(&a, &b).map(|x| (x * 1000.0).round() / 10.0));
    }
    assert_eq!(got[0], [19.3, 4.5, 72.4], "e = 0");
    assert_eq!(got[1], [89.7, 36.8, 96.9], "e = 20 mm on both");
    assert_eq!(got[2], [32.1, 33.6, 71.0], "RSPR e = 20 mm, RRPS e = 0");
}
