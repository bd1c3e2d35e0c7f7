//! One stage of the planner's VI transcription of the WIP (the eight's start, stage 700):
//! values; the stage equality's Jacobian by the structured route (each block seeded alone,
//! only the terms that read it) and by the generic one (all of `x`, then all of `w`
//! seeded); and everything the solver takes per stage and iteration, for the VI and for
//! RK1.
use criterion::{criterion_group, criterion_main, Criterion};
use dmech::continuous::RungeKutta;
use dmech::Discretisation;
use dmech_lie::dual::seeded;
use dmech_ocp::nlp::derivatives::{generic_constraint_curvature, stage_derivatives, stage_values};
use dmech_ocp::nlp::StageProblem;
use nalgebra::SVector;
use num_dual::DualSVec64;
use robots::wip::algebraic_current::WipAlgebraicCurrent;
use robots::wip::plan::problems::eight;
use robots::wip::plan::{rk_plan, rk_start, varint_plan, varint_start, PlanBounds};
use robots::wip::Wip;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let plan =
        varint_plan::<_, 5, 15, 7>(&wip, &p, PlanBounds::default(), Discretisation::FirstOrder);
    let (x, w) = (xs[700], ws[700]);
    let zeta = SVector::<f64, 8>::repeat(0.1);
    let st = &plan.stages;
    let mut g = c.benchmark_group("plan_stage");
    g.bench_function("values", |b| {
        b.iter(|| stage_values(&plan, 700, black_box(&x), &w))
    });
    g.bench_function("equality_jacobian_structured", |b| {
        b.iter(|| st.equality_jacobian::<3, 5, 2, 15, 7>(black_box(&x), &w))
    });
    g.bench_function("equality_jacobian_generic", |b| {
        b.iter(|| {
            let ex = st.equality::<DualSVec64<15>, 3, 5, 2, 15, 7>(
                &seeded(black_box(&x)),
                &w.map(DualSVec64::<15>::from_re),
            );
            let ew = st.equality::<DualSVec64<7>, 3, 5, 2, 15, 7>(
                &x.map(DualSVec64::<7>::from_re),
                &seeded(&w),
            );
            (ex, ew)
        })
    });
    g.bench_function("stage_derivatives", |b| {
        b.iter(|| stage_derivatives(&plan, 700, black_box(&x), &w, &zeta, None))
    });
    // The exact Hessian: the constraints' curvature by blocks and by the generic path, and
    // everything the solver takes per stage with it.
    let lam = SVector::<f64, 15>::repeat(0.3);
    let nu = SVector::<f64, 5>::repeat(0.7);
    g.bench_function("constraint_curvature_blocks", |b| {
        b.iter(|| plan.constraint_curvature(700, black_box(&x), &w, &lam, &nu))
    });
    g.bench_function("constraint_curvature_generic", |b| {
        b.iter(|| {
            generic_constraint_curvature::<_, 15, 7, 5, 2, 8>(
                &plan,
                700,
                black_box(&x),
                &w,
                &lam,
                &nu,
            )
        })
    });
    g.bench_function("stage_derivatives_exact", |b| {
        b.iter(|| stage_derivatives(&plan, 700, black_box(&x), &w, &zeta, Some(&lam)))
    });
    let rk1 = rk_plan::<_, 5, 15>(&wip, &p, PlanBounds::default(), RungeKutta::Rk1);
    let (xr, wr) = rk_start::<Wip, 5, 15>(&wip, &p);
    let (x1, w1) = (xr[700], wr[700]);
    g.bench_function("stage_derivatives_rk1", |b| {
        b.iter(|| stage_derivatives(&rk1, 700, black_box(&x1), &w1, &zeta, None))
    });
    let rk4 = rk_plan::<_, 5, 15>(&wip, &p, PlanBounds::default(), RungeKutta::Rk4);
    g.bench_function("stage_derivatives_rk4", |b| {
        b.iter(|| stage_derivatives(&rk4, 700, black_box(&x1), &w1, &zeta, None))
    });
    // The generic route of the RK1 dynamics Jacobian (duals nested three deep), against
    // the implicit-function route the solver takes (inside `stage_derivatives_rk1`).
    g.bench_function("rk1_dynamics_jacobian_generic", |b| {
        b.iter(|| {
            let fx = rk1.stages.dynamics::<DualSVec64<15>, 3, 5, 2, 15, 2>(
                &seeded(black_box(&x1)),
                &w1.map(DualSVec64::<15>::from_re),
            );
            let fw = rk1.stages.dynamics::<DualSVec64<2>, 3, 5, 2, 15, 2>(
                &x1.map(DualSVec64::<2>::from_re),
                &seeded(&w1),
            );
            (fx, fw)
        })
    });
    g.bench_function("rk1_dynamics_jacobian", |b| {
        b.iter(|| {
            rk1.stages
                .dynamics_jacobian::<3, 5, 2, 15, 2>(black_box(&x1), &w1)
        })
    });
    // The algebraic-current model (NS = 3, NX = 11): the VI stage.
    let alg = WipAlgebraicCurrent::new(wip);
    let (xa, wa) = varint_start::<_, 3, 11, 5>(&alg, &p);
    let plan_a =
        varint_plan::<_, 3, 11, 5>(&alg, &p, PlanBounds::default(), Discretisation::FirstOrder);
    let (x2, w2) = (xa[700], wa[700]);
    g.bench_function("stage_derivatives_algebraic", |b| {
        b.iter(|| stage_derivatives(&plan_a, 700, black_box(&x2), &w2, &zeta, None))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
