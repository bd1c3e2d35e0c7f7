//! What a stage of the KKT solve costs at state sizes `NX` = 15, 13 and 11 (`NU` = 2,
//! `NE` = 5): the Riccati recursion's backward step, and the condensing's products
//! `Q + H_xv D + (H_xv D)ᵀ + Dᵀ H_vv D` and `A = F_x + F_v D` (`D` the dependent
//! velocity's `NE × NX` sensitivity). 15 is the WIP's VI state; 13 and 11 are that state
//! without the wheel angles, and without the charges too, which its equations of motion
//! do not read (the transcriptions' reduced layout). Random stages, 4235 of them (the eight at
//! 5 ms), so that each pass streams its data as the solver's does.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use dmech_lie::lcg::Lcg;
use dmech_ocp::solver::riccati::{BackwardSweep, LqStage};
use nalgebra::{SMatrix, SVector};
use std::hint::black_box;

const STAGES: usize = 4235;

fn random<const R: usize, const C: usize>(seed: &mut Lcg) -> SMatrix<f64, R, C> {
    SMatrix::from_fn(|_, _| seed.uniform())
}

/// Stages whose backward sweep stays positive definite: `Q ⪰ I`, `R = I`, `A` near `I`.
fn lq_stages<const NX: usize>() -> Vec<LqStage<NX, 2>> {
    let mut seed = Lcg(7);
    (0..STAGES)
        .map(|_| {
            let mut st = LqStage::<NX, 2>::zeros();
            let m: SMatrix<f64, NX, NX> = random(&mut seed);
            st.q_mat = m * m.transpose() * 0.01 + SMatrix::identity();
            st.r_mat = SMatrix::identity();
            st.a = SMatrix::identity() + random::<NX, NX>(&mut seed) * 0.05;
            st.b = random(&mut seed);
            st.c = random(&mut seed);
            st.q = random(&mut seed);
            st
        })
        .collect()
}

type CondenseInput<const NX: usize> = (
    SMatrix<f64, 5, NX>,
    SMatrix<f64, NX, 5>,
    SMatrix<f64, 5, 5>,
    SMatrix<f64, NX, NX>,
    SMatrix<f64, NX, NX>,
);

fn sweep<const NX: usize>(c: &mut Criterion) {
    let stages = lq_stages::<NX>();
    let (q_n, q_vec_n) = (SMatrix::identity(), SVector::zeros());
    let mut sweep = BackwardSweep::new(STAGES, &q_n, &q_vec_n, 0.0);
    c.bench_with_input(BenchmarkId::new("riccati_sweep", NX), &NX, |b, _| {
        b.iter(|| {
            sweep.restart(STAGES, &q_n, &q_vec_n, 0.0);
            sweep
                .sweep_all(black_box(&stages))
                .expect("positive definite");
        })
    });
}

fn condense<const NX: usize>(c: &mut Criterion) {
    let mut seed = Lcg(3);
    let input: Vec<CondenseInput<NX>> = (0..STAGES)
        .map(|_| {
            (
                random(&mut seed),
                random(&mut seed),
                random(&mut seed),
                random(&mut seed),
                random(&mut seed),
            )
        })
        .collect();
    let mut out: Vec<(SMatrix<f64, NX, NX>, SMatrix<f64, NX, NX>)> = (0..STAGES)
        .map(|_| (SMatrix::zeros(), SMatrix::zeros()))
        .collect();
    c.bench_with_input(BenchmarkId::new("condensing_products", NX), &NX, |b, _| {
        b.iter(|| {
            for ((d, h_xv, h_vv, h_xx, f_x), o) in black_box(&input).iter().zip(out.iter_mut()) {
                let hvv_d = h_vv * d;
                let hxv_d = h_xv * d;
                o.0 = h_xx + hxv_d + hxv_d.transpose() + d.transpose() * hvv_d;
                o.1 = f_x + h_xv * d;
            }
        })
    });
}

fn bench(c: &mut Criterion) {
    sweep::<15>(c);
    sweep::<13>(c);
    sweep::<11>(c);
    condense::<15>(c);
    condense::<13>(c);
    condense::<11>(c);
}

criterion_group!(benches, bench);
criterion_main!(benches);
