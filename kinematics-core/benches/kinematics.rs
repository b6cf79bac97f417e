#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Cost per call of the core verbs in f32 and f64 at a task pose (platform at a box corner,
//! rotated 20 deg about [1,1,0]): `cargo bench -p kinematics-core`.

use criterion::{criterion_group, criterion_main, Criterion};
use kinematics_core::*;
use nalgebra::{Vector3, Vector6};
use std::hint::black_box;

fn bench_scalar<T: Real>(c: &mut Criterion, name: &str) {
    let g = RsprGeometry::<T>::reference();
    let s = |x: f64| scalar::lit::<T>(x);
    let axis = Vector3::new(s(1.0), s(1.0), s(0.0)).normalize();
    let pose = Pose::from_position_rotation_vector(
        Vector3::new(s(0.02), s(-0.02), s(0.17)),
        axis * s(20f64.to_radians()),
    )
    .unwrap_or(Pose::central(g.hc));
    let sol = inverse(&g, &pose, Branch::OUTER).unwrap();
    let jac = jacobian(&g, &sol).unwrap();
    let wrench = Vector6::new(s(7.0), s(7.0), s(7.0), s(0.7), s(0.7), s(0.7));
    let q = sol.q();
    let guess = pose.displaced(
        &Vector3::new(s(1e-5), s(-1e-5), s(1e-5)),
        &Vector3::new(s(1e-4), s(0.0), s(-1e-4)),
    );
    let cfg = FkConfig::default();
    let mut group = c.benchmark_group(name);
    group.bench_function("ik", |b| {
        b.iter(|| inverse(&g, black_box(&pose), Branch::OUTER))
    });
    group.bench_function("jacobian", |b| b.iter(|| jacobian(&g, black_box(&sol))));
    group.bench_function("forces", |b| {
        b.iter(|| actuator_forces(black_box(&jac), g.rp, black_box(&wrench), s(1e-6)))
    });
    group.bench_function("measures", |b| b.iter(|| measures(&g, black_box(&sol))));
    group.bench_function("fk_warm", |b| {
        b.iter(|| forward(&g, black_box(&q), Branch::OUTER, black_box(&guess), &cfg))
    });
    group.bench_function("fk_from_central", |b| {
        b.iter(|| forward(&g, black_box(&q), Branch::OUTER, &Pose::central(g.hc), &cfg))
    });
    // One supervisor tick while moving towards a verified target (guards at the candidate
    // and at its braking point, plus the path check of a freshly submitted target).
    let mut sup = kinematics_core::supervisor::Supervisor::new(
        g,
        Branch::OUTER,
        kinematics_core::guards::Limits::reference(),
        kinematics_core::supervisor::SupervisorConfig::default(),
        &Pose::central(g.hc),
    )
    .unwrap();
    let far = Pose::from_position_rotation_vector(
        Vector3::new(s(0.015), s(-0.01), s(0.165)),
        Vector3::new(s(0.1), s(0.05), s(0.0)),
    )
    .unwrap();
    let mut stamp = 1u64;
    group.bench_function("supervisor_tick", |b| {
        b.iter(|| {
            if sup.tick().mode == kinematics_core::supervisor::Mode::Holding {
                stamp += 1;
                let target = if (sup.setpoint().t - far.t).norm() < s(1e-6) {
                    Pose::central(g.hc)
                } else {
                    far
                };
                let _ = sup.submit(&target, stamp, stamp);
            }
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_scalar::<f32>(c, "f32");
    bench_scalar::<f64>(c, "f64");
}

criterion_group!(group, benches);
criterion_main!(group);
