//! exp / log / dexp⁻¹ of SE(2) and SE(3), in f64 and in a first-order dual.
use criterion::{criterion_group, criterion_main, Criterion};
use dmech_lie::{LieGroup, Se2, Se3};
use nalgebra::{Vector3, Vector6};
use num_dual::Dual64;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let x2 = Vector3::new(0.3, -0.2, 0.7);
    let x3 = Vector6::new(0.3, -0.2, 0.7, 0.1, 0.4, -0.5);
    let d2 = x2.map(|v| Dual64::from(v).derivative());
    let d3 = x3.map(|v| Dual64::from(v).derivative());
    let g2 = Se2::exp(&x2);
    let g3 = Se3::exp(&x3);
    let g2d = Se2::exp(&d2);
    let g3d = Se3::exp(&d3);

    let mut grp = c.benchmark_group("se2");
    grp.bench_function("exp f64", |b| b.iter(|| Se2::exp(black_box(&x2))));
    grp.bench_function("log f64", |b| b.iter(|| black_box(&g2).log()));
    grp.bench_function("dexp_inv f64", |b| b.iter(|| Se2::dexp_inv(black_box(&x2))));
    grp.bench_function("exp dual", |b| b.iter(|| Se2::exp(black_box(&d2))));
    grp.bench_function("log dual", |b| b.iter(|| black_box(&g2d).log()));
    grp.bench_function("dexp_inv dual", |b| {
        b.iter(|| Se2::dexp_inv(black_box(&d2)))
    });
    grp.finish();

    let mut grp = c.benchmark_group("se3");
    grp.bench_function("exp f64", |b| b.iter(|| Se3::exp(black_box(&x3))));
    grp.bench_function("log f64", |b| b.iter(|| black_box(&g3).log()));
    grp.bench_function("dexp_inv f64", |b| b.iter(|| Se3::dexp_inv(black_box(&x3))));
    grp.bench_function("exp dual", |b| b.iter(|| Se3::exp(black_box(&d3))));
    grp.bench_function("log dual", |b| b.iter(|| black_box(&g3d).log()));
    grp.bench_function("dexp_inv dual", |b| {
        b.iter(|| Se3::dexp_inv(black_box(&d3)))
    });
    grp.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
