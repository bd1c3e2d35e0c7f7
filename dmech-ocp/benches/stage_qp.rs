//! The stage QP interior point on the WIP MPC's QPs of a real run: consecutive samples of
//! `wip track --controller mpc` along the eight planned at 4.4 V (nominal plant, the
//! paper's sensors, seed 1), in `dmech_ocp::qp`'s text form (`benches/data/`, written by
//! `cargo run --release -p robots --features bench --example mpc_qps -- dump …`; another
//! file by `STAGE_QP_FILE=PATH`). Per QP: a cold solve, and a warm one from the previous
//! sample's solution shifted by a stage, as the MPC runs. Pin it to one core:
//! `taskset -c 1 cargo bench -p dmech-ocp --features bench --bench stage_qp`.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dmech_ocp::qp::{QpSettings, QpSolution, QpSolver, QpStatus, StageQp};
use std::hint::black_box;

type MpcQp = StageQp<10, 2, 5>;

fn qps() -> Vec<MpcQp> {
    let path = std::env::var("STAGE_QP_FILE").unwrap_or_else(|_| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/benches/data/mpc_eight44_seed1.qps"
        )
        .to_string()
    });
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    MpcQp::all_from_text(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn bench(c: &mut Criterion) {
    let qps = qps();
    // The MPC's settings (robots' `mpc::qp_settings`): a gap tolerance of 1e-6, the cold
    // start centred at μ0 = 0.1.
    let settings = QpSettings::builder()
        .tol(1e-6)
        .start_mu(0.1)
        .build()
        .expect("valid settings");
    let mut solver = QpSolver::<10, 2, 5>::new(settings);
    // The warm starts: each QP from the solution of the one before (cold for the first).
    let mut previous: Option<QpSolution<10, 2, 5>> = None;
    let starts: Vec<_> = qps
        .iter()
        .map(|qp| {
            let start = previous.as_ref().map(QpSolution::shifted);
            let sol = solver.solve(qp);
            assert_eq!(sol.status, QpStatus::Solved);
            previous = Some(sol);
            start
        })
        .collect();
    let mut group = c.benchmark_group("mpc_qp");
    group.throughput(Throughput::Elements(qps.len() as u64));
    group.bench_function("cold", |b| {
        b.iter(|| {
            for qp in &qps {
                black_box(solver.solve(black_box(qp)));
            }
        })
    });
    group.bench_function("warm", |b| {
        b.iter(|| {
            for (qp, start) in qps.iter().zip(&starts) {
                let sol = match start {
                    Some(s) => solver.solve_warm(black_box(qp), s),
                    None => solver.solve(black_box(qp)),
                };
                black_box(sol);
            }
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
