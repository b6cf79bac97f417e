//! The line-geometry singularity analysis (thesis chapter 10): configurations built from
//! each geometric condition of Table 10.3 (the pose is constructed from the condition, or
//! found as the root of the condition's signed measure along a family of poses, never
//! typed in) get the variety and the S-configuration the thesis derives; the rank agrees
//! with nalgebra's SVD (an independent implementation); and at every parallel singularity
//! found as a root of det Jtilde one of the thesis's independent conditions S1, S9, S12,
//! S13 holds, with the gained twist in the null space of Jtilde.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinematics_core::ik::inverse;
use kinematics_core::jacobian::tripod_jacobian;
use kinematics_core::mechanism::Mechanism;
use kinematics_core::singularity::configurations::{residuals, Configuration};
use kinematics_core::singularity::lines::{analyse, LineAnalysis, Tolerances, Variety};
use kinematics_core::singularity::serial_cases::{rspr_cases, usr_cases};
use kinematics_core::{Branch, Chain, Pose, RsprGeometry, Solution, UsrGeometry};
use nalgebra::{Matrix4, Matrix6, Rotation3, Vector3};
use proptest::prelude::*;

const MM: f64 = 1e-3;
const DEG: f64 = std::f64::consts::PI / 180.0;

fn tol() -> Tolerances<f64> {
    Tolerances::default()
}

fn rspr() -> RsprGeometry<f64> {
    RsprGeometry::reference()
}

fn solve<M: Mechanism<f64>>(m: &M, pose: &Pose<f64>, branch: u32) -> Option<Solution<f64>> {
    inverse(m, pose, Branch::new(branch).ok()?).ok()
}

fn has_circuit(a: &LineAnalysis<f64>, lines: &[u8], variety: Variety) -> bool {
    let mask = lines.iter().fold(0u8, |m, &l| m | (1 << (l - 1)));
    a.circuits
        .iter()
        .any(|c| c.lines == mask && c.variety == variety)
}

fn residual(sol: &Solution<f64>, rp: f64, c: Configuration) -> f64 {
    residuals(sol, rp)
        .iter()
        .find(|r| r.configuration == c)
        .map(|r| r.residual)
        .unwrap_or(f64::INFINITY)
}

/// σ_min / σ_max of the scaled, row-normalised Jtilde by nalgebra's SVD.
fn nalgebra_sigmas(sol: &Solution<f64>, rp: f64) -> Vec<f64> {
    let mut j = tripod_jacobian(sol);
    for r in 0..6 {
        for c in 3..6 {
            j[(r, c)] /= rp;
        }
        let n = j.row(r).norm();
        for c in 0..6 {
            j[(r, c)] /= n;
        }
    }
    let s = j.svd(false, false).singular_values;
    let max = s.max();
    let mut v: Vec<f64> = s.iter().map(|x| x / max).collect();
    v.sort_by(|a, b| b.partial_cmp(a).unwrap());
    v
}

/// The twist is reciprocal to every line: |Jtilde t| against |Jtilde| |t|.
fn assert_gained_in_null_space(sol: &Solution<f64>, rp: f64, a: &LineAnalysis<f64>) {
    let j = tripod_jacobian(sol);
    for g in &a.gained {
        let scaled = (g.twist.fixed_rows::<3>(0).norm_squared()
            + rp * rp * g.twist.fixed_rows::<3>(3).norm_squared())
        .sqrt();
        assert!((scaled - 1.0).abs() < 1e-9, "{scaled}");
        let r = (j * g.twist).norm();
        assert!(r < 1e-6, "Jtilde·twist = {r}");
    }
}

/// A root of `f` in [a, b] where f changes sign, by bisection to 60 halvings.
fn bisect(f: &dyn Fn(f64) -> Option<f64>, mut a: f64, mut b: f64) -> Option<f64> {
    let mut fa = f(a)?;
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        let fm = f(m)?;
        if fm == 0.0 {
            return Some(m);
        }
        if (fm > 0.0) == (fa > 0.0) {
            a = m;
            fa = fm;
        } else {
            b = m;
        }
    }
    Some(0.5 * (a + b))
}

/// Scans `family(s)`, s in [-1, 1], on every branch for a sign change of `g` where the
/// solution is continuous, and returns the solution at the root.
fn find_root<M: Mechanism<f64>>(
    m: &M,
    family: &dyn Fn(f64) -> Pose<f64>,
    g: &dyn Fn(&Solution<f64>) -> f64,
) -> Option<Solution<f64>> {
    for branch in 0..8 {
        let f = |s: f64| solve(m, &family(s), branch).map(|sol| g(&sol));
        let n = 400;
        let mut prev: Option<(f64, f64)> = None;
        for k in 0..=n {
            let s = -1.0 + 2.0 * k as f64 / n as f64;
            let Some(v) = f(s) else {
                prev = None;
                continue;
            };
            if let Some((sp, vp)) = prev {
                if (v > 0.0) != (vp > 0.0) {
                    if let Some(root) = bisect(&f, sp, s) {
                        let lo = solve(m, &family(root - 1e-12), branch);
                        let hi = solve(m, &family(root + 1e-12), branch);
                        let sol = solve(m, &family(root), branch);
                        if let (Some(lo), Some(hi), Some(sol)) = (lo, hi, sol) {
                            let jump = Chain::ALL
                                .iter()
                                .map(|&c| (lo.chains[c].b - hi.chains[c].b).norm())
                                .fold(0.0, f64::max);
                            if jump < 1e-6 * MM {
                                return Some(sol);
                            }
                        }
                    }
                }
            }
            prev = Some((s, v));
        }
    }
    None
}

fn pose(t: [f64; 3], rv_deg: [f64; 3]) -> Pose<f64> {
    Pose {
        t: Vector3::new(t[0], t[1], t[2]) * MM,
        r: Rotation3::from_scaled_axis(Vector3::new(rv_deg[0], rv_deg[1], rv_deg[2]) * DEG),
    }
}

/// The signed volume of the four planes pF_1, pF_2, pF_3 and B0 (S12 when zero).
fn s12_signed(sol: &Solution<f64>, rp: f64) -> f64 {
    let [b1, b2, b3] = [0, 1, 2].map(|i| sol.chains.0[i].b);
    let nb = (b2 - b1).cross(&(b3 - b1)).normalize();
    let mut m = Matrix4::zeros();
    for (i, c) in sol.chains.0.iter().enumerate() {
        let nf = c.s1.cross(&c.s2).normalize();
        m.set_row(
            i,
            &nalgebra::RowVector4::new(nf.x, nf.y, nf.z, -nf.dot(&c.b) / rp),
        );
    }
    m.set_row(
        3,
        &nalgebra::RowVector4::new(nb.x, nb.y, nb.z, -nb.dot(&b1) / rp),
    );
    m.determinant()
}

#[test]
fn a_regular_pose_has_full_rank_and_no_configuration() {
    let g = rspr();
    let sol = solve(&g, &Pose::central(g.hc), 0).unwrap();
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert_eq!(a.rank, 6);
    assert!(a.circuits.is_empty() && a.gained.is_empty() && a.complex.is_none());
    assert!(residuals(&sol, g.rp).iter().all(|r| !r.holds(&tol())));
}

#[test]
fn s1_platform_in_the_base_plane_is_a_plane_of_lines() {
    // Condition: B0 = P0. The RSPR's spherical joints move in the base plane, so the
    // platform at height zero, parallel to the base.
    let g = rspr();
    let sol = solve(&g, &pose([0.0, 0.0, 0.0], [0.0; 3]), 0).unwrap();
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert_eq!(a.rank, 3, "{:?}", a.relative_sigma);
    // The thesis: B0 = P0 puts l_n in T_jk; here the legs are radial, so l1, l2, l3 form
    // a flat pencil, and every other dependent subset is coplanar.
    assert!(
        has_circuit(&a, &[1, 2, 3], Variety::FlatPencil),
        "{:?}",
        a.circuits
    );
    assert!(a
        .circuits
        .iter()
        .all(|c| matches!(c.variety, Variety::Plane | Variety::FlatPencil)));
    assert!(has_circuit(&a, &[1, 2, 4, 5], Variety::Plane));
    assert_eq!(a.gained.len(), 3);
    assert_gained_in_null_space(&sol, g.rp, &a);
    assert!(residual(&sol, g.rp, Configuration::S1) < 1e-12);
}

/// A pose of the RSPR whose spherical joints j and k (on their circles at the link
/// angles given) lie in the platform plane, the platform tilted by `tilt` about the line
/// b_j b_k, with o_p at b_j + λ along the platform's radial direction of chain j.
fn s9_pose(g: &RsprGeometry<f64>, theta: [f64; 2], tilt: f64, at_op: bool) -> Pose<f64> {
    let xi = |i: usize| 2.0 * std::f64::consts::PI * i as f64 / 3.0;
    let b = |i: usize, th: f64| {
        let e = Vector3::new(xi(i).cos(), xi(i).sin(), 0.0) * g.e;
        e + Vector3::new((xi(i) + th).cos(), (xi(i) + th).sin(), 0.0) * g.rb
    };
    let (bj, bk) = (b(0, theta[0]), b(1, theta[1]));
    let along = (bk - bj).normalize();
    // The platform normal, tilted by `tilt` about b_j b_k from vertical.
    let n = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(along), tilt) * Vector3::z();
    // The yaw about n that makes the platform's radial directions u_1, u_2 meet b_j, b_k
    // from a common o_p: o_p = b_j - λ_j u_1 = b_k - λ_k u_2 needs b_k - b_j in span(u1,
    // u2), true for any yaw (both lie in the plane ⊥ n, and so does b_k - b_j); choose the
    // yaw so that u_1 is along b_j - b_k rotated by 60 deg in the plane (an equilateral
    // platform's u_1, u_2 are 120 deg apart).
    let tilt_r = Rotation3::rotation_between(&Vector3::z(), &n).unwrap();
    let mut best = None;
    for k in 0..3600 {
        let yaw = k as f64 * 0.1 * DEG;
        let r = tilt_r * Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
        let u1 = r * Vector3::x();
        let u2 = r * Vector3::new(xi(1).cos(), xi(1).sin(), 0.0);
        // Solve bj - l1 u1 = bk - l2 u2 in the plane (least squares).
        let m = nalgebra::Matrix3x2::from_columns(&[u1, -u2]);
        let rhs = bj - bk;
        let l = (m.transpose() * m).try_inverse().unwrap() * m.transpose() * rhs;
        let op = bj - u1 * l[0];
        // Want o_p above the base and, for S2, at b_j (λ_j = 0): the yaw that gives it.
        let score = if at_op { l[0].abs() } else { -(op.z) };
        if op.z >= -1e-12
            && best
                .as_ref()
                .is_none_or(|(s, _): &(f64, Pose<f64>)| score < *s)
        {
            best = Some((score, Pose { t: op, r }));
        }
    }
    best.unwrap().1
}

#[test]
fn s9_two_legs_in_the_platform_plane_is_a_plane_of_four_lines() {
    let g = rspr();
    let p = s9_pose(&g, [40.0 * DEG, -40.0 * DEG], 60.0 * DEG, false);
    let sol = (0..8).find_map(|br| {
        let s = solve(&g, &p, br)?;
        (residual(&s, g.rp, Configuration::S9) < 1e-9).then_some(s)
    });
    let sol = sol.expect("a branch puts b_1 and b_2 at the constructed points");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert!(a.rank < 6);
    assert!(
        has_circuit(&a, &[1, 2, 4, 5], Variety::Plane),
        "{:?}",
        a.circuits
    );
    assert_gained_in_null_space(&sol, g.rp, &a);
    assert!(residual(&sol, g.rp, Configuration::S5) < 1e-9);
}

#[test]
fn s8_coincident_spherical_joints_form_a_bundle() {
    // b_1 = b_2 at an intersection of the two links' circles, on the platform's normal
    // through o_p (the thesis: b_1 = b_2 = n ∩ B0).
    let g = rspr();
    let (e1, e2) = (
        Vector3::new(g.e, 0.0, 0.0),
        Vector3::new(-0.5 * g.e, 0.5 * 3f64.sqrt() * g.e, 0.0),
    );
    let mid = (e1 + e2) / 2.0;
    let d = (e2 - e1).norm();
    let h = (g.rb * g.rb - d * d / 4.0).sqrt();
    let perp = Vector3::new(-(e2 - e1).y, (e2 - e1).x, 0.0).normalize();
    let x = mid + perp * h;
    let p = Pose {
        t: x + Vector3::new(0.0, 0.0, g.hc),
        r: Rotation3::identity(),
    };
    let sol = (0..8)
        .find_map(|br| {
            let s = solve(&g, &p, br)?;
            ((s.chains[Chain::One].b - x).norm() < 1e-12
                && (s.chains[Chain::Two].b - x).norm() < 1e-12)
                .then_some(s)
        })
        .expect("a branch has b_1 = b_2 = x");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert!(
        has_circuit(&a, &[1, 2, 4, 5], Variety::Bundle),
        "{:?}",
        a.circuits
    );
    assert!(residual(&sol, g.rp, Configuration::S8) < 1e-12);
    assert!(
        residual(&sol, g.rp, Configuration::S13) < 1e-12,
        "S8 is a case of S13"
    );
    assert_eq!(a.complex.is_some(), a.rank == 5);
    assert_gained_in_null_space(&sol, g.rp, &a);
}

#[test]
fn s3_all_spherical_joints_coincide_only_without_eccentricity() {
    // With e = 0 the three links share one circle: b_1 = b_2 = b_3 = x on it, under o_p.
    let g = RsprGeometry::new(0.0, 0.09, 0.05, 0.16).unwrap();
    let x = Vector3::new(0.0, g.rb, 0.0);
    let p = Pose {
        t: x + Vector3::new(0.0, 0.0, g.hc),
        r: Rotation3::identity(),
    };
    let sol = (0..8)
        .find_map(|br| {
            let s = solve(&g, &p, br)?;
            s.chains
                .0
                .iter()
                .all(|c| (c.b - x).norm() < 1e-12)
                .then_some(s)
        })
        .expect("a branch has every b at x");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert_eq!(a.rank, 3, "all six lines through one point: a bundle");
    assert!(a
        .circuits
        .iter()
        .all(|c| matches!(c.variety, Variety::Bundle | Variety::FlatPencil)));
    // The thesis: r_i ∥ p_j p_k puts l_n in T_jk, (j, k, n) ∈ {(1,2,6), (2,3,4), (3,1,5)}.
    for t in [[1, 2, 6], [2, 3, 4], [1, 3, 5]] {
        assert!(
            has_circuit(&a, &t, Variety::FlatPencil),
            "{t:?}: {:?}",
            a.circuits
        );
    }
    assert!(
        has_circuit(&a, &[1, 2, 4, 5], Variety::Bundle),
        "{:?}",
        a.circuits
    );
    assert!(residual(&sol, g.rp, Configuration::S3) < 1e-12);
    // With e > 0 the circles (radius rb about points e from the centre) have no common
    // point: the triangle of the b's never shrinks to a point.
    let r = rspr();
    assert!(r.e > 0.0 && (r.rb - r.e).abs() > 0.0);
}

#[test]
fn s2_a_spherical_joint_at_the_platform_centre_adds_a_flat_pencil() {
    // o_p = b_1 and b_2 on the platform's radial line of chain 2 (so l_1, l_2 in P0):
    // b_1, b_2 on their circles; u_2 = (b_2 - b_1)/|b_2 - b_1|; the platform tilted
    // about u_2; x_p is u_2 turned back by 120 deg about the normal.
    let g = rspr();
    let xi = |i: usize| 2.0 * std::f64::consts::PI * i as f64 / 3.0;
    let b = |i: usize, th: f64| {
        Vector3::new(xi(i).cos(), xi(i).sin(), 0.0) * g.e
            + Vector3::new((xi(i) + th).cos(), (xi(i) + th).sin(), 0.0) * g.rb
    };
    let construct = |th1: f64, th2: f64, tilt: f64| {
        let (b1, b2) = (b(0, th1), b(1, th2));
        let u2 = (b2 - b1).normalize();
        let n = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(u2), tilt) * Vector3::z();
        let xp = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(n), -xi(1)) * u2;
        let yp = n.cross(&xp);
        let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[xp, yp, n]));
        Pose { t: b1, r }
    };
    // Over link angles and tilts, the first construction every chain can reach.
    let mut found = None;
    'search: for th1 in (-8..=8).map(|k| k as f64 * 20.0 * DEG) {
        for th2 in (-8..=8).map(|k| k as f64 * 20.0 * DEG) {
            for tilt in [30.0, 50.0, 70.0, -30.0, -50.0, -70.0].map(|d| d * DEG) {
                let p = construct(th1, th2, tilt);
                for br in 0..8 {
                    if let Some(s) = solve(&g, &p, br) {
                        if residual(&s, g.rp, Configuration::S2) < 1e-9 {
                            found = Some(s);
                            break 'search;
                        }
                    }
                }
            }
        }
    }
    let sol = found.expect("a construction realises S2");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert!(
        has_circuit(&a, &[1, 2, 4], Variety::FlatPencil),
        "{:?}",
        a.circuits
    );
    assert!(
        residual(&sol, g.rp, Configuration::S9) < 1e-9,
        "a case of S9"
    );
    assert_gained_in_null_space(&sol, g.rp, &a);
}

#[test]
fn s6_s7_lines_4_5_6_concurrent_with_the_platform_parallel_to_the_base() {
    let g = rspr();
    // Family: platform parallel to the base, translated along x; condition: l4, l5, l6
    // (in the base plane) through one point: the determinant of their homogeneous
    // coordinates in the plane.
    let fam = |s: f64| pose([120.0 * s, 15.0, 150.0], [0.0, 0.0, 10.0]);
    let g3 = |sol: &Solution<f64>| {
        let rows: Vec<[f64; 3]> = sol
            .chains
            .0
            .iter()
            .map(|c| {
                let nrm = Vector3::new(-c.s2.y, c.s2.x, 0.0);
                [nrm.x, nrm.y, -nrm.dot(&c.b) / g.rp]
            })
            .collect();
        nalgebra::Matrix3::from_fn(|i, j| rows[i][j]).determinant()
    };
    let sol = find_root(&g, &fam, &g3).expect("a branch where l4, l5, l6 meet");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert!(
        has_circuit(&a, &[4, 5, 6], Variety::FlatPencil),
        "{:?}",
        a.circuits
    );
    assert!(residual(&sol, g.rp, Configuration::S6S7) < 1e-6);
    assert!(
        residual(&sol, g.rp, Configuration::S12) < 1e-6,
        "a case of S12"
    );
}

#[test]
fn s12_four_planes_through_a_point_is_a_general_complex() {
    let g = rspr();
    let fam = |s: f64| pose([30.0 * s, -10.0, 60.0 + 40.0 * s], [25.0, 50.0 * s, 5.0]);
    let sol = find_root(&g, &fam, &|s| s12_signed(s, g.rp)).expect("an S12 root");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert_eq!(a.rank, 5, "{:?}", a.relative_sigma);
    assert_eq!(a.complex, Some(Variety::GeneralComplex));
    assert_gained_in_null_space(&sol, g.rp, &a);
    assert!(residual(&sol, g.rp, Configuration::S12) < 1e-6);
}

#[test]
fn s13_collinear_spherical_joints_is_a_special_complex() {
    let g = rspr();
    let fam = |s: f64| pose([100.0 * s, 10.0, 120.0], [0.0, 15.0, 0.0]);
    let area = |sol: &Solution<f64>| {
        let [b1, b2, b3] = [0, 1, 2].map(|i| sol.chains.0[i].b);
        (b2 - b1).cross(&(b3 - b1)).z / (g.rp * g.rp)
    };
    let sol = find_root(&g, &fam, &area).expect("a branch with collinear b's");
    let a = analyse(&sol, g.rp, &tol()).unwrap();
    assert_eq!(a.rank, 5, "{:?}", a.relative_sigma);
    assert_eq!(a.complex, Some(Variety::SpecialComplex));
    assert!(residual(&sol, g.rp, Configuration::S13) < 1e-9);
    // The gained motion is a rotation (pitch 0) about the line of the b's.
    let m = a.gained[0];
    assert!(m.pitch.unwrap().abs() < 1e-6 * g.rp);
    let w = m.twist.fixed_rows::<3>(3).normalize();
    let line = (sol.chains[Chain::Two].b - sol.chains[Chain::One].b).normalize();
    assert!(w.cross(&line).norm() < 1e-6);
}

#[test]
fn rspr_serial_cases_a_and_c_where_the_two_roots_meet() {
    // At the boundary of a chain's reach the line of the leg's plane in the base plane is
    // tangent to the link's circle: Cn2 = 0 (case a); with the platform level, ŝ2 is
    // horizontal and l_b ∥ ŝ2 (case c).
    let g = rspr();
    for (tilt, expect_c) in [(0.0, true), (20.0, false)] {
        let fam = |s: f64| pose([200.0 * (s + 1.0), 0.0, 160.0], [0.0, tilt, 0.0]);
        // Bisect the boundary of solvability of chain 1 on the outer branch.
        let ok = |s: f64| solve(&g, &fam(s), 0).is_some();
        let (mut a, mut b) = (-1.0, 1.0);
        assert!(ok(a) && !ok(b));
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if ok(m) {
                a = m
            } else {
                b = m
            }
        }
        let sol = solve(&g, &fam(a), 0).unwrap();
        let cases: Vec<_> = sol.chains.0.iter().map(|c| rspr_cases(c, &tol())).collect();
        let singular = cases.iter().filter(|c| c.has('a')).count();
        assert!(singular >= 1, "{cases:?}");
        assert!(cases.iter().all(|c| !c.has('b') && !c.has('d')));
        assert_eq!(cases.iter().any(|c| c.has('c')), expect_c, "{cases:?}");
    }
}

#[test]
fn usr_serial_case_f_where_the_determinant_vanishes() {
    let g = UsrGeometry::<f64>::reference();
    let fam = |s: f64| pose([0.0, 0.0, 80.0 + 60.0 * (s + 1.0)], [0.0, 0.0, 0.0]);
    let det = |sol: &Solution<f64>| g.serial_block(&sol.chains[Chain::One]).det();
    let ok = |s: f64| solve(&g, &fam(s), 0).is_some();
    // The reach boundary (the roots of Eq. 6.32 meet) or a sign change of the determinant.
    let sol = find_root(&g, &fam, &det).or_else(|| {
        let (mut a, mut b) = (-1.0, 1.0);
        if !ok(a) || ok(b) {
            return None;
        }
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if ok(m) {
                a = m
            } else {
                b = m
            }
        }
        solve(&g, &fam(a), 0)
    });
    let sol = sol.expect("a serial singularity of the USR along the vertical");
    let c = usr_cases(&g, &sol.chains[Chain::One], &tol());
    assert!(c.has('F'), "{c:?}");
}

/// Every chain stretched straight up: on the reference USR (e = rp) the level platform at
/// height l1 + l2 (the end of the reach along the vertical, found by bisection) puts each p_i straight above e_i at the links' full length, so each
/// chain's two links are collinear (C) and along the yaw axis (B); then ŝn × l_b = 0 and
/// ŝr × l_b is horizontal and perpendicular to the vertical ŝ1 and to ŝ2 (horizontal,
/// along r_i, itself along ŝr), so both Cn (A) and both Cr (E) vanish, and with them the
/// determinant (F). ŝ2 is horizontal and l_b vertical, so D does not hold.
#[test]
fn usr_serial_cases_a_b_c_e_with_every_chain_stretched_vertically() {
    let g = UsrGeometry::<f64>::reference();
    // The reach's end along the vertical, from below (l1 + l2 itself may round outside).
    let level = |h: f64| Pose::central(h);
    let (mut a, mut b) = (g.hc, g.l1 + g.l2 + MM);
    assert!(solve(&g, &level(a), 0).is_some() && solve(&g, &level(b), 0).is_none());
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if solve(&g, &level(m), 0).is_some() {
            a = m
        } else {
            b = m
        }
    }
    assert!((a - (g.l1 + g.l2)).abs() < 1e-12, "{a}");
    let h = a / MM;
    let sol = solve(&g, &level(a), 0).unwrap();
    for c in Chain::ALL {
        let cases = usr_cases(&g, &sol.chains[c], &tol());
        for letter in ['A', 'B', 'C', 'E', 'F'] {
            assert!(cases.has(letter), "chain {c:?}: {letter} not in {cases:?}");
        }
        assert!(!cases.has('D'), "chain {c:?}: {cases:?}");
    }
    // A millimetre lower the knees bend: none of the cases holds.
    let lower = solve(&g, &pose([0.0, 0.0, h - 1.0], [0.0; 3]), 0).unwrap();
    for c in Chain::ALL {
        assert!(usr_cases(&g, &lower.chains[c], &tol()).is_empty());
    }
}

/// Turning the platform about x0 at a fixed height, chain 1 (whose revolute axis r_1 is
/// along y_p) reaches the end of its reach where the two roots of Eq. 6.32 meet: found by
/// bisection on the inverse kinematics' success (the failure beyond names chain 1). There
/// the upper revolute axis ŝ2 lies along the lower link (D) and the chain's Cn vanish (A).
#[test]
fn usr_serial_case_d_where_chain_1s_roots_meet() {
    let g = UsrGeometry::<f64>::reference();
    let fam = |s: f64| pose([0.0, 0.0, 100.0], [80.0 * s, 0.0, 0.0]);
    let (mut a, mut b) = (0.0, 1.0);
    assert!(solve(&g, &fam(a), 0).is_some() && solve(&g, &fam(b), 0).is_none());
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if solve(&g, &fam(m), 0).is_some() {
            a = m
        } else {
            b = m
        }
    }
    let beyond = inverse(&g, &fam(b), Branch::OUTER).unwrap_err();
    assert_eq!(beyond.chain, Chain::One);
    let sol = solve(&g, &fam(a), 0).unwrap();
    let cases = usr_cases(&g, &sol.chains[Chain::One], &tol());
    assert!(
        cases.has('D') && cases.has('A') && cases.has('F'),
        "{cases:?}"
    );
    assert!(!cases.has('B') && !cases.has('C'), "{cases:?}");
}

/// Nelder-Mead on f over R^6 from x0 with initial steps `step`: the simplex method,
/// derivative-free, for the residuals (a max of distances: not smooth).
fn nelder_mead(
    f: &dyn Fn(&[f64; 6]) -> f64,
    x0: [f64; 6],
    step: f64,
    iters: usize,
) -> ([f64; 6], f64) {
    let mut pts: Vec<([f64; 6], f64)> = (0..7)
        .map(|k| {
            let mut x = x0;
            if k > 0 {
                x[k - 1] += step;
            }
            (x, f(&x))
        })
        .collect();
    let comb = |a: &[f64; 6], b: &[f64; 6], t: f64| -> [f64; 6] {
        std::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
    };
    for _ in 0..iters {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        let c: [f64; 6] =
            std::array::from_fn(|i| pts[..6].iter().map(|p| p.0[i]).sum::<f64>() / 6.0);
        let (worst, fw) = pts[6];
        let r = comb(&c, &worst, -1.0);
        let fr = f(&r);
        if fr < pts[0].1 {
            let e = comb(&c, &worst, -2.0);
            let fe = f(&e);
            pts[6] = if fe < fr { (e, fe) } else { (r, fr) };
        } else if fr < pts[5].1 {
            pts[6] = (r, fr);
        } else {
            let k = comb(&c, &worst, 0.5);
            let fk = f(&k);
            if fk < fw {
                pts[6] = (k, fk);
            } else {
                let best = pts[0].0;
                for p in pts.iter_mut().skip(1) {
                    p.0 = comb(&best, &p.0, 0.5);
                    p.1 = f(&p.0);
                }
            }
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    pts[0]
}

/// S4, S10 and S11 (special cases of S12 in Table 10.3) on the reference RSPR: each is
/// found as a zero of its own residual, minimised (Nelder-Mead over the pose, mm and deg)
/// from a start near it (a rough point of a search over random starts), to below 1e-9.
/// There the condition holds, S12 holds too (the thesis's inclusion), the six lines have
/// rank 5 (a linear complex), and Jtilde is singular (inverse condition number below
/// 1e-9).
#[test]
fn s4_s10_s11_are_reachable_special_cases_of_s12() {
    let g = rspr();
    let rp = g.rp;
    for (conf, start) in [
        (Configuration::S4, [-9.4, -85.0, 0.5, -0.4, -1.2, -38.8]),
        (Configuration::S10, [9.0, 36.0, 42.0, 11.0, 56.0, -12.0]),
        (Configuration::S11, [-49.0, -11.0, 0.3, 2.0, 1.0, -15.0]),
    ] {
        let f = |x: &[f64; 6]| {
            solve(&g, &pose([x[0], x[1], x[2]], [x[3], x[4], x[5]]), 0)
                .map_or(1e3, |sol| residual(&sol, rp, conf))
        };
        let mut best = (start, f(&start));
        for step in [1.0, 0.1, 0.01] {
            best = nelder_mead(&f, best.0, step, 3000);
        }
        assert!(best.1 < 1e-9, "{conf}: residual {} at {:?}", best.1, best.0);
        let x = best.0;
        let sol = solve(&g, &pose([x[0], x[1], x[2]], [x[3], x[4], x[5]]), 0).unwrap();
        assert!(
            residual(&sol, rp, Configuration::S12) < 1e-6,
            "{conf} without S12 at {x:?}"
        );
        let a = analyse(&sol, rp, &tol()).unwrap();
        assert_eq!(a.rank, 5, "{conf} at {x:?}");
        let inv_cond =
            kinematics_core::singularity::parallel_inv_cond(&tripod_jacobian(&sol), rp).unwrap();
        assert!(inv_cond < 1e-9, "{conf}: {inv_cond}");
    }
}

proptest! {
    // About a third of the segments cross a parallel singularity (measured: 22 of 64;
    // on the USR mostly S12, on the RSPR S13 and S12).
    #![proptest_config(proptest_config::cases(256))]

    /// At random poses the rank is nalgebra's numerical rank; at roots of det Jtilde along
    /// random segments it is below 6, the twist gained is in Jtilde's null space, and one
    /// of the thesis's independent conditions (S1, S9, S12, S13) holds.
    #[test]
    fn rank_matches_nalgebra_and_singularities_meet_the_thesis_conditions(
        t0 in prop::array::uniform3(-0.12..0.12f64),
        t1 in prop::array::uniform3(-0.12..0.12f64),
        r0 in prop::array::uniform3(-2.0..2.0f64),
        r1 in prop::array::uniform3(-2.0..2.0f64),
        usr in any::<bool>(),
    ) {
        let rsp = rspr();
        let us = UsrGeometry::<f64>::reference();
        let (rp, hc) = if usr { (us.rp, us.hc) } else { (rsp.rp, rsp.hc) };
        let fam = |s: f64| {
            let k = 0.5 * (s + 1.0);
            let t = Vector3::from(t0) * (1.0 - k) + Vector3::from(t1) * k;
            Pose {
                t: t + Vector3::new(0.0, 0.0, hc),
                r: Rotation3::from_scaled_axis(Vector3::from(r0) * (1.0 - k) + Vector3::from(r1) * k),
            }
        };
        let det = |sol: &Solution<f64>| {
            let mut j: Matrix6<f64> = tripod_jacobian(sol);
            for r in 0..6 { for c in 3..6 { j[(r, c)] /= rp; } }
            j.determinant()
        };
        let check = |sol: &Solution<f64>| {
            let a = analyse(sol, rp, &tol()).unwrap();
            let s = nalgebra_sigmas(sol, rp);
            let nrank = s.iter().filter(|&&x| x > tol().rank).count() as u8;
            (a, nrank)
        };
        // Rank at the segment's start.
        let start = if usr { solve(&us, &fam(-1.0), 0) } else { solve(&rsp, &fam(-1.0), 0) };
        if let Some(sol) = start {
            let (a, nrank) = check(&sol);
            prop_assert_eq!(a.rank, nrank);
        }
        let root = if usr { find_root(&us, &fam, &det) } else { find_root(&rsp, &fam, &det) };
        if let Some(sol) = root {
            let (a, nrank) = check(&sol);
            prop_assert_eq!(a.rank, nrank);
            prop_assert!(a.rank < 6, "{:?}", a.relative_sigma);
            assert_gained_in_null_space(&sol, rp, &a);
            let res = residuals(&sol, rp);
            let best = res
                .iter()
                .filter(|r| r.configuration.is_independent())
                .map(|r| r.residual)
                .fold(f64::INFINITY, f64::min);
            prop_assert!(best < 1e-6, "no independent condition holds: {:?}", res);
        }
    }
}
