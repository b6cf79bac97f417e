//! Speed of the dimensional synthesis: candidate robots evaluated per second over the
//! thesis's task (design/tasks/thesis.toml: the 40 x 40 x 20 mm box on the 5 x 5 x 3 grid at both
//! orientations, 150 poses per candidate: inverse kinematics, tilt, singularity measures,
//! Jacobian and actuator forces, then the bounds), one thread and every core.
//!
//! `cargo bench -p design --bench synth` (criterion reports "thrpt" in candidates/s).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use design::synth::{candidate, grid, scan, SynthTask};
use kinematics_core::RobotKind;
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let t = SynthTask::thesis().unwrap();
    let mut group = c.benchmark_group("synth");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    for kind in [RobotKind::Rspr, RobotKind::Usr] {
        let k = t.kind(kind);
        // 24 candidates of the default grid, admissible and rejected ones mixed.
        let dims: Vec<Vec<f64>> = grid(&k.axes).into_iter().step_by(9).take(24).collect();
        group.throughput(Throughput::Elements(dims.len() as u64));
        group.bench_function(format!("{kind:?}_candidates_one_thread"), |b| {
            b.iter(|| {
                for d in &dims {
                    black_box(candidate(kind, d.clone(), &t.task, &k.requirements));
                }
            })
        });
        group.bench_function(format!("{kind:?}_candidates_all_cores"), |b| {
            b.iter(|| {
                black_box(scan(kind, dims.clone(), &t.task, &k.requirements, 0, &|| {}).unwrap())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
