//! The VI transcription's structured equality Jacobian (each block seeded alone, only the
//! terms that read it) against the generic path (all of `x` and `w` seeded through
//! `VarIntStages::equality`), for the three force quadratures and the midpoint scheme; and the RK transcriptions'
//! dynamics Jacobian (the chain rule through the method's stages, each acceleration's
//! Jacobian from the WIP's closed form) against vector duals through the whole step, and
//! their cost curvature (over the velocity and the input) against the whole stage's, for
//! RK1/2/4 and both current models; at the eight's start and at perturbed points. (The
//! closed form against the accelerations derived from `ℓ`: `tests/model/wip_continuous.rs`.)

use dmech::{Discretisation, ForcingQuadrature, RungeKutta};
use dmech_lie::dual::{seeded, split_passes};
use dmech_ocp::nlp::derivatives::generic_cost_curvature;
use dmech_ocp::nlp::StageProblem;
use dmech_ocp::transcription::free_timing::{FreeTiming, FreeTimingTranscription, TotalTime};
use dmech_ocp::transcription::runge_kutta::RkStages;
use dmech_ocp::transcription::variational::VarIntStages;
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;
use robots::wip::algebraic_current::WipAlgebraicCurrent;
use robots::wip::plan::problems::eight;
use robots::wip::plan::problems::PlanProblem;
use robots::wip::plan::{
    rk_start, varint_layout, varint_plan, varint_start, PlanBounds, PlanModel, WipPlan, NC,
};
use robots::wip::Wip;

/// Both are exact derivatives evaluated in double precision along different operation
/// orders: they may differ by round-off, a few hundred ulps of the largest entry.
const ROUND_OFF: f64 = 512.0 * f64::EPSILON;

/// The largest difference between two `(value, ∂/∂x, ∂/∂w)` triples, and the scale it is
/// measured against (the reference Jacobian's largest entry, at least 1).
#[allow(clippy::type_complexity)]
fn jacobian_error<const M: usize, const NX: usize, const NW: usize>(
    got: (SVector<f64, M>, SMatrix<f64, M, NX>, SMatrix<f64, M, NW>),
    want: (SVector<f64, M>, SMatrix<f64, M, NX>, SMatrix<f64, M, NW>),
) -> (f64, f64) {
    let scale = want.1.amax().max(want.2.amax()).max(1.0);
    let err = (got.1 - want.1)
        .amax()
        .max((got.2 - want.2).amax())
        .max((got.0 - want.0).amax());
    (err, scale)
}

#[test]
fn structured_equality_jacobian_equals_generic() {
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let mut rand = lcg(12345);
    for (d, q) in [
        (Discretisation::FirstOrder, ForcingQuadrature::Left),
        (Discretisation::FirstOrder, ForcingQuadrature::Right),
        (Discretisation::FirstOrder, ForcingQuadrature::Midpoint),
        (Discretisation::Midpoint, ForcingQuadrature::Right),
    ] {
        let st = VarIntStages::new::<3, 5, 2>(&wip, p.h, q).with_discretisation(d);
        for k in [0, 1, 700, 2100, 4234] {
            for perturb in [0.0, 0.3] {
                let x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
                let w: SVector<f64, 7> = ws[k].map(|v| v + perturb * rand());
                let (e, ex, ew) = st.equality_jacobian::<3, 5, 2, 15, 7>(&x, &w);
                let gx = st.equality::<DualSVec64<15>, 3, 5, 2, 15, 7>(
                    &seeded(&x),
                    &w.map(DualSVec64::<15>::from_re),
                );
                let gw = st.equality::<DualSVec64<7>, 3, 5, 2, 15, 7>(
                    &x.map(DualSVec64::<7>::from_re),
                    &seeded(&w),
                );
                let (err, scale) = jacobian_error((e, ex, ew), split_passes(&gx, &gw));
                assert!(
                    err <= ROUND_OFF * scale,
                    "{d:?} {q:?}, stage {k}, perturbation {perturb}: error {err:.3e} (scale {scale:.3e})"
                );
            }
        }
    }
}

/// The same on the state the solver plans on (`NX = 11`: the wheel angles and charges,
/// which `ℓ` does not read, left out), where the partials take one pass per interval
/// seeded in its velocity and the carried tilt.
#[test]
fn structured_equality_jacobian_equals_generic_on_the_reduced_state() {
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let layout = varint_layout::<Wip, 5, 11>(&wip);
    let mut rand = lcg(54321);
    for q in [
        ForcingQuadrature::Left,
        ForcingQuadrature::Right,
        ForcingQuadrature::Midpoint,
    ] {
        let st = VarIntStages {
            layout,
            ..VarIntStages::new::<3, 5, 2>(&wip, p.h, q)
        };
        for k in [0, 1, 700, 2100, 4234] {
            for perturb in [0.0, 0.3] {
                // The full state's entries the reduced one keeps: g, α, v, u.
                let full: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
                let x = SVector::<f64, 11>::from_fn(|j, _| full[if j < 4 { j } else { j + 4 }]);
                let w: SVector<f64, 7> = ws[k].map(|v| v + perturb * rand());
                let got = st.equality_jacobian::<3, 5, 2, 11, 7>(&x, &w);
                let gx = st.equality::<DualSVec64<11>, 3, 5, 2, 11, 7>(
                    &seeded(&x),
                    &w.map(DualSVec64::<11>::from_re),
                );
                let gw = st.equality::<DualSVec64<7>, 3, 5, 2, 11, 7>(
                    &x.map(DualSVec64::<7>::from_re),
                    &seeded(&w),
                );
                let (err, scale) = jacobian_error(got, split_passes(&gx, &gw));
                assert!(
                    err <= ROUND_OFF * scale,
                    "{q:?}, stage {k}, perturbation {perturb}: error {err:.3e} (scale {scale:.3e})"
                );
            }
        }
    }
}

/// The VI dynamics' one-pass Jacobian (`w` seeded in the directions of the entries of `x`
/// that the dynamics does not read) against the two-pass default, for both schemes: each
/// direction of a vector dual is propagated alone, so they agree to the bit; a column of
/// an entry that the dynamics did read would differ.
#[test]
fn one_pass_dynamics_jacobian_equals_two_passes() {
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let mut rand = lcg(2024);
    for d in [Discretisation::FirstOrder, Discretisation::Midpoint] {
        let st = VarIntStages::new::<3, 5, 2>(&wip, p.h, ForcingQuadrature::Right)
            .with_discretisation(d);
        for k in [0, 1, 700, 2100, 4234] {
            for perturb in [0.0, 0.3] {
                let x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
                let w: SVector<f64, 7> = ws[k].map(|v| v + perturb * rand());
                let got = st.dynamics_jacobian::<3, 5, 2, 15, 7>(&x, &w);
                let gx = st.dynamics::<DualSVec64<15>, 3, 5, 2, 15, 7>(
                    &seeded(&x),
                    &w.map(DualSVec64::<15>::from_re),
                );
                let gw = st.dynamics::<DualSVec64<7>, 3, 5, 2, 15, 7>(
                    &x.map(DualSVec64::<7>::from_re),
                    &seeded(&w),
                );
                let want = split_passes(&gx, &gw);
                assert_eq!(got, want, "{d:?}, stage {k}, perturbation {perturb}");
            }
        }
    }
}

/// The WIP's first-order VI plan of `p` with a free step ratio per segment between
/// waypoints, in [0.5, 2], the total time fixed.
fn free_timing_plan<'a>(
    wip: &'a Wip,
    p: &'a PlanProblem,
) -> FreeTimingTranscription<'a, Wip, WipPlan<'a, Wip>, 3, 3, 5, 2, 15, 7> {
    let plan =
        varint_plan::<Wip, 5, 15, 7>(wip, p, PlanBounds::default(), Discretisation::FirstOrder);
    let timing = FreeTiming {
        segment_starts: p.stages[..p.stages.len() - 1].to_vec(),
        ratio_bounds: (0.5, 2.0),
        total: TotalTime::Fixed,
    };
    FreeTimingTranscription::new(plan, timing).unwrap()
}

/// The free-timing transcription's equality Jacobian (inside a segment: the fixed step's
/// structured partials at `σ h̄` and a two-lane pass for the ratios; at a segment's first
/// stage: the generic passes) against vector duals through the whole variable-step
/// residual, at the eight's start perturbed, with ratios drawn in [0.5, 2].
#[test]
fn free_timing_equality_jacobian_equals_generic() {
    let wip = Wip::default();
    let p = eight(0.02);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let ft = free_timing_plan(&wip, &p);
    let mut rand = lcg(2024);
    let mut inside = 0;
    let last = ws.len() - 1;
    // Stages inside segments and every segment's first stage (k > 0: two different steps).
    let stages: Vec<usize> = [1, 2, 100, 500, last]
        .into_iter()
        .chain(p.stages[1..p.stages.len() - 1].iter().copied())
        .collect();
    for k in stages {
        let first = p.stages.contains(&k);
        for perturb in [0.0, 0.2] {
            let x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
            let sigma = 1.25 + 0.75 * rand() * 2.0;
            let sigma_prev = if first {
                1.25 - 0.75 * rand().abs()
            } else {
                sigma
            };
            let w = SVector::<f64, 9>::from_fn(|i, _| match i {
                7 => sigma_prev,
                8 => sigma,
                _ => ws[k][i] + perturb * rand(),
            });
            let (e, ex, ew) = StageProblem::<15, 9, 5, 2, NC>::equality_jacobian(&ft, k, &x, &w);
            let gx = StageProblem::<15, 9, 5, 2, NC>::equality(
                &ft,
                k,
                &seeded(&x),
                &w.map(DualSVec64::<15>::from_re),
            );
            let gw = StageProblem::<15, 9, 5, 2, NC>::equality(
                &ft,
                k,
                &x.map(DualSVec64::<9>::from_re),
                &seeded(&w),
            );
            let (err, scale) = jacobian_error((e, ex, ew), split_passes(&gx, &gw));
            assert!(
                err <= ROUND_OFF * scale,
                "stage {k} (first of a segment: {first}), perturbation {perturb}: error {err:.3e} (scale {scale:.3e})"
            );
            inside += usize::from(!first);
        }
    }
    assert!(inside >= 10, "stages inside segments checked: {inside}");
}

/// The free-timing transcription's cost curvature (`xx` zero, `xw` in the ratios'
/// columns, `ww` by one pass) against the generic route over the whole stage, with the
/// inequality multipliers and the cost scale drawn at random, at the eight's start
/// perturbed and ratios in [0.5, 2].
#[test]
fn free_timing_cost_curvature_equals_generic() {
    let wip = Wip::default();
    let p = eight(0.02);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let ft = free_timing_plan(&wip, &p);
    let mut rand = lcg(77);
    let mut largest = 0.0f64;
    for k in [0, 1, 2, 100, 500, ws.len() - 1] {
        for perturb in [0.0, 0.2] {
            let x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
            let w = SVector::<f64, 9>::from_fn(|i, _| match i {
                7 | 8 => 1.25 + 1.5 * rand(),
                _ => ws[k][i] + perturb * rand(),
            });
            let zeta = SVector::<f64, NC>::from_fn(|_, _| 10.0 * rand());
            let scale = 0.5 + rand();
            let (hxx, hxw, hww) =
                StageProblem::<15, 9, 5, 2, NC>::cost_curvature(&ft, k, &x, &w, scale, &zeta);
            let (rxx, rxw, rww) =
                generic_cost_curvature::<_, 15, 9, 5, 2, NC>(&ft, k, &x, &w, scale, &zeta);
            let size = rxx.amax().max(rxw.amax()).max(rww.amax()).max(1.0);
            let err = (hxx - rxx)
                .amax()
                .max((hxw - rxw).amax())
                .max((hww - rww).amax());
            assert!(
                err <= ROUND_OFF * size,
                "stage {k}, perturbation {perturb}: error {err:.3e} (size {size:.3e})"
            );
            largest = largest.max(rxw.amax());
        }
    }
    // The ratios do meet the state (the rate limit's previous input): the check has a
    // nonzero cross block to compare.
    assert!(largest > 0.0);
}

/// `(f, F_x, F_w)` of an RK transcription by its route (the stages composed in `f64`, each
/// acceleration's Jacobian from the closed form) against vector duals through
/// `RkStages::dynamics`; the worst error relative to the Jacobian's largest entry.
fn rk_jacobian_error<M, const NS: usize, const NX: usize>(model: &M, method: RungeKutta) -> f64
where
    M: PlanModel<NS>,
{
    let p = eight(0.005);
    let st = RkStages::new::<3, NS, 2>(model, p.h, method);
    let mut worst = 0.0f64;
    for (_, x, w) in rk_test_points::<M, NS, NX>(model, 777) {
        let (f, fx, fw) = st.dynamics_jacobian::<3, NS, 2, NX, 2>(&x, &w);
        let gx = st.dynamics::<DualSVec64<NX>, 3, NS, 2, NX, 2>(
            &seeded(&x),
            &w.map(DualSVec64::<NX>::from_re),
        );
        let gw = st.dynamics::<DualSVec64<2>, 3, NS, 2, NX, 2>(
            &x.map(DualSVec64::<2>::from_re),
            &seeded(&w),
        );
        let (f_ref, fx_ref, fw_ref) = split_passes(&gx, &gw);
        let scale = fx_ref.amax().max(fw_ref.amax()).max(1.0);
        let err = (fx - fx_ref)
            .amax()
            .max((fw - fw_ref).amax())
            .max((f - f_ref).amax());
        worst = worst.max(err / scale);
    }
    worst
}

/// The RK eight's start at stages 0, 350 and 2100, as it is and perturbed by uniform
/// numbers of ±0.15 in every entry (state, then input): `(k, x_k, u_k)`.
#[allow(clippy::type_complexity)]
fn rk_test_points<M, const NS: usize, const NX: usize>(
    model: &M,
    seed: u64,
) -> Vec<(usize, SVector<f64, NX>, SVector<f64, 2>)>
where
    M: PlanModel<NS>,
{
    let (xs, ws) = rk_start::<M, NS, NX>(model, &eight(0.005));
    let mut rand = lcg(seed);
    let mut points = Vec::new();
    for k in [0, 350, 2100] {
        for perturb in [0.0, 0.3] {
            let x = xs[k].map(|v| v + perturb * rand());
            let w = ws[k].map(|v| v + perturb * rand());
            points.push((k, x, w));
        }
    }
    points
}

/// Uniform numbers in [−0.5, 0.5) from a fixed seed: the perturbations of both tests,
/// reproducible.
fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut rng = dmech_lie::lcg::Lcg(seed);
    move || rng.uniform()
}

#[test]
fn rk_dynamics_jacobian_equals_generic() {
    let wip = Wip::default();
    let alg = WipAlgebraicCurrent::new(wip);
    for method in [RungeKutta::Rk1, RungeKutta::Rk2, RungeKutta::Rk4] {
        let e_dyn = rk_jacobian_error::<Wip, 5, 15>(&wip, method);
        let e_alg = rk_jacobian_error::<WipAlgebraicCurrent, 3, 11>(&alg, method);
        eprintln!("{method:?}: dynamic current {e_dyn:.3e}, algebraic current {e_alg:.3e}");
        assert!(
            e_dyn <= ROUND_OFF,
            "{method:?}, dynamic current: {e_dyn:.3e}"
        );
        assert!(
            e_alg <= ROUND_OFF,
            "{method:?}, algebraic current: {e_alg:.3e}"
        );
    }
}

/// The VI transcription's exact constraint curvature by blocks against the generic path
/// (`Dual2`/hyper-duals over the whole stage through `dynamics` and `equality`), on the
/// WIP: a nonlinear force (`tanh` friction) read by each quadrature, at the eight's start
/// and at perturbed points, with random multipliers.
#[test]
fn block_constraint_curvature_equals_generic() {
    use dmech_ocp::nlp::derivatives::generic_constraint_curvature;
    use dmech_ocp::nlp::StageProblem;
    use robots::wip::plan::{varint_plan, PlanBounds};
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let mut rand = lcg(4242);
    for q in [
        ForcingQuadrature::Left,
        ForcingQuadrature::Right,
        ForcingQuadrature::Midpoint,
    ] {
        let mut plan_q =
            varint_plan::<_, 5, 15, 7>(&wip, &p, PlanBounds::default(), Discretisation::FirstOrder);
        plan_q.stages.quadrature = q;
        for k in [0, 700, 2100] {
            for perturb in [0.0, 0.3] {
                let x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
                let w: SVector<f64, 7> = ws[k].map(|v| v + perturb * rand());
                let lam = SVector::<f64, 15>::from_fn(|_, _| 10.0 * rand());
                let nu = SVector::<f64, 5>::from_fn(|_, _| 10.0 * rand());
                let (hxx, hxw, hww) = plan_q.constraint_curvature(k, &x, &w, &lam, &nu);
                let (rxx, rxw, rww) = generic_constraint_curvature::<_, 15, 7, 5, 2, 8>(
                    &plan_q, k, &x, &w, &lam, &nu,
                );
                let scale = rxx.amax().max(rxw.amax()).max(rww.amax());
                let err = (hxx - rxx)
                    .amax()
                    .max((hxw - rxw).amax())
                    .max((hww - rww).amax());
                assert!(
                    err <= ROUND_OFF * scale,
                    "{q:?}, stage {k}, perturbation {perturb}: error {err:.3e} (scale {scale:.3e})"
                );
            }
        }
    }
}

/// The RK transcription's cost curvature (second-order passes over `(v_k, u_k)` only, the
/// problem being affine in the configuration and the previous input) against the generic
/// one over the whole stage, for both current models, with a cost scale and random
/// inequality multipliers, at the eight's start and at perturbed points.
#[test]
fn rk_cost_curvature_equals_generic() {
    use dmech_ocp::nlp::derivatives::generic_cost_curvature;
    use dmech_ocp::nlp::StageProblem;
    use robots::wip::plan::{rk_plan, PlanBounds};

    fn worst<M, const NS: usize, const NX: usize>(model: &M) -> f64
    where
        M: PlanModel<NS>,
    {
        let p = eight(0.005);
        let plan = rk_plan::<M, NS, NX>(model, &p, PlanBounds::default(), RungeKutta::Rk1);
        let mut rand = lcg(4243);
        let mut worst = 0.0f64;
        for (k, x, u) in rk_test_points::<M, NS, NX>(model, 4242) {
            let zeta = SVector::<f64, 8>::from_fn(|_, _| rand());
            let scale = 2.0 + rand();
            let (a, b, c) = plan.cost_curvature(k, &x, &u, scale, &zeta);
            let (ra, rb, rc) =
                generic_cost_curvature::<_, NX, 2, 0, 2, 8>(&plan, k, &x, &u, scale, &zeta);
            let size = ra.amax().max(rb.amax()).max(rc.amax()).max(1.0);
            let err = (a - ra).amax().max((b - rb).amax()).max((c - rc).amax());
            worst = worst.max(err / size);
        }
        worst
    }
    let wip = Wip::default();
    let e_dyn = worst::<Wip, 5, 15>(&wip);
    let e_alg = worst::<WipAlgebraicCurrent, 3, 11>(&WipAlgebraicCurrent::new(wip));
    eprintln!("dynamic current {e_dyn:.3e}, algebraic current {e_alg:.3e}");
    assert!(e_dyn <= ROUND_OFF && e_alg <= ROUND_OFF);
}

/// The largest change of the VI residual when one ignorable shape position is shifted,
/// over random stages, for each ignorable coordinate of `sys`; and the bound it is held
/// to: round-off of the momentum terms the residual is a difference of, `|p|/h`, with `p`
/// of the size of the stage vectors' entries.
fn ignorable_shift_effect<S, const NS: usize, const NX: usize, const NW: usize>(
    sys: &S,
) -> Vec<(usize, f64, f64)>
where
    S: dmech::PrincipalKinematicSystem<3, NS, 2, Param = f64>,
{
    let h = 0.005;
    let st = VarIntStages::new::<3, NS, 2>(sys, h, ForcingQuadrature::Right);
    let mut rand = lcg(4242);
    sys.ignorable_shape()
        .iter()
        .map(|&j| {
            let (mut worst, mut bound) = (0.0f64, 0.0f64);
            for _ in 0..200 {
                let x: SVector<f64, NX> = SVector::from_fn(|_, _| rand());
                let w: SVector<f64, NW> = SVector::from_fn(|_, _| rand());
                let e0 = st.equality::<f64, 3, NS, 2, NX, NW>(&x, &w);
                let mut xs = x;
                xs[3 + j] += 0.37 + rand();
                let e1 = st.equality::<f64, 3, NS, 2, NX, NW>(&xs, &w);
                worst = worst.max((e1 - e0).amax());
                let size = 1.0 + x.amax().max(xs.amax()).max(w.amax());
                bound = bound.max(64.0 * f64::EPSILON * size / h);
            }
            (j, worst, bound)
        })
        .collect()
}

/// What `ignorable_shape` declares: shifting the wheel angles leaves the residual exactly
/// as it was (nothing reads them), shifting the charges moves it by round-off only (their
/// back-EMF term changes by a total time derivative, which cancels between the two
/// momenta of a node), and the tilt, which is not declared, moves it.
#[test]
fn the_wip_residual_does_not_read_its_ignorable_shape_positions() {
    let wip = Wip::default();
    let alg = WipAlgebraicCurrent::new(wip);
    let full = ignorable_shift_effect::<_, 5, 15, 7>(&wip);
    let algebraic = ignorable_shift_effect::<_, 3, 11, 5>(&alg);
    eprintln!("dynamic current {full:?}, algebraic current {algebraic:?}");
    assert_eq!(full.iter().map(|r| r.0).collect::<Vec<_>>(), [1, 2, 3, 4]);
    assert_eq!(algebraic.iter().map(|r| r.0).collect::<Vec<_>>(), [1, 2]);
    for &(j, worst, bound) in full.iter().chain(&algebraic) {
        if j <= 2 {
            assert_eq!(worst, 0.0, "wheel angle s_{j}");
        } else {
            assert!(worst <= bound, "charge s_{j}: {worst:e} > {bound:e}");
        }
    }
    // The check can fail: the tilt is read.
    let st = VarIntStages::new::<3, 5, 2>(&wip, 0.005, ForcingQuadrature::Right);
    let (x, w) = (
        SVector::<f64, 15>::repeat(0.1),
        SVector::<f64, 7>::repeat(0.2),
    );
    let mut xs = x;
    xs[3] += 0.37;
    let moved =
        st.equality::<f64, 3, 5, 2, 15, 7>(&xs, &w) - st.equality::<f64, 3, 5, 2, 15, 7>(&x, &w);
    assert!(
        moved.amax() > 1e-3,
        "the tilt moves the residual by {:e}",
        moved.amax()
    );
}

/// The VI transcription without the ignorable positions in its state is the full one with
/// their rows and columns left out: the same values, the same derivatives and the same
/// exact curvature (by blocks), on the eight's start and at perturbed points.
#[test]
fn the_reduced_vi_state_is_the_full_one_without_the_ignorable_positions() {
    use robots::wip::plan::NX_VI;
    let wip = Wip::default();
    let p = eight(0.005);
    let (xs, ws) = varint_start::<Wip, 5, 15, 7>(&wip, &p);
    let full =
        varint_plan::<Wip, 5, 15, 7>(&wip, &p, PlanBounds::default(), Discretisation::FirstOrder);
    let reduced = varint_plan::<Wip, 5, NX_VI, 7>(
        &wip,
        &p,
        PlanBounds::default(),
        Discretisation::FirstOrder,
    );
    // x = (x, y, θ, α, φR, φL, qR, qL, v(5), u(2)): the reduced state keeps 0–3 and 8–14.
    let kept: Vec<usize> = (0..15).filter(|i| !(4..8).contains(i)).collect();
    let zeta = SVector::<f64, NC>::repeat(0.1);
    let mut rand = lcg(777);
    let mut worst = 0.0f64;
    for k in [0, 1, 700, 2100, 4234] {
        for perturb in [0.0, 0.3] {
            // The full state with the ignorable positions at zero, as the reduced one reads them.
            let mut x: SVector<f64, 15> = xs[k].map(|v| v + perturb * rand());
            x.fixed_rows_mut::<4>(4).fill(0.0);
            let w: SVector<f64, 7> = ws[k].map(|v| v + perturb * rand());
            let xr = SVector::<f64, NX_VI>::from_fn(|i, _| x[kept[i]]);
            let df = dmech_ocp::nlp::derivatives::stage_derivatives(&full, k, &x, &w, &zeta, None);
            let dr =
                dmech_ocp::nlp::derivatives::stage_derivatives(&reduced, k, &xr, &w, &zeta, None);
            let pick = |m: &SMatrix<f64, 15, 15>| {
                SMatrix::<f64, NX_VI, NX_VI>::from_fn(|i, j| m[(kept[i], kept[j])])
            };
            let rows = |v: &SVector<f64, 15>| SVector::<f64, NX_VI>::from_fn(|i, _| v[kept[i]]);
            let cols =
                |m: &SMatrix<f64, 5, 15>| SMatrix::<f64, 5, NX_VI>::from_fn(|i, j| m[(i, kept[j])]);
            let fw = SMatrix::<f64, NX_VI, 7>::from_fn(|i, j| df.fw[(kept[i], j)]);
            let cx = SMatrix::<f64, NC, NX_VI>::from_fn(|i, j| df.cx[(i, kept[j])]);
            // The dropped rows of f are the ignorable positions' own update; the dropped
            // columns of every Jacobian are zero (wheel angles) or round-off (charges).
            for (a, b) in [
                ((rows(&df.f) - dr.f).amax(), 1.0),
                ((pick(&df.fx) - dr.fx).amax(), df.fx.amax()),
                ((fw - dr.fw).amax(), df.fw.amax()),
                ((df.e - dr.e).amax(), 1.0),
                ((cols(&df.ex) - dr.ex).amax(), df.ex.amax()),
                ((df.ew - dr.ew).amax(), df.ew.amax()),
                ((cx - dr.cx).amax(), 1.0),
                ((df.cw - dr.cw).amax(), 1.0),
                ((rows(&df.gx) - dr.gx).amax(), 1.0),
                ((df.gw - dr.gw).amax(), 1.0),
                ((df.c - dr.c).amax(), 1.0),
                ((df.cost - dr.cost).abs(), 1.0),
            ] {
                worst = worst.max(a / b.max(1.0));
            }
            // The exact curvature (the cost's and the constraints' by blocks): the full
            // Hessian's rows and columns of the carried entries. The dynamics' multipliers
            // of the ignored positions' rows are zero, as at any optimum (those rows of
            // every cost-to-go vanish); random ones would move ν through `F_vᵀλ`.
            let mut lam = SVector::<f64, 15>::from_fn(|_, _| rand());
            lam.fixed_rows_mut::<4>(4).fill(0.0);
            let hf =
                dmech_ocp::nlp::derivatives::stage_derivatives(&full, k, &x, &w, &zeta, Some(&lam));
            let lam_r = rows(&lam);
            let hr = dmech_ocp::nlp::derivatives::stage_derivatives(
                &reduced,
                k,
                &xr,
                &w,
                &zeta,
                Some(&lam_r),
            );
            let hxw = SMatrix::<f64, NX_VI, 7>::from_fn(|i, j| hf.hxw[(kept[i], j)]);
            for (a, b) in [
                ((pick(&hf.hxx) - hr.hxx).amax(), hf.hxx.amax()),
                ((hxw - hr.hxw).amax(), hf.hxw.amax()),
                ((hf.hww - hr.hww).amax(), hf.hww.amax()),
            ] {
                worst = worst.max(a / b.max(1.0));
            }
            assert!(hr.hxx.amax() > 0.0, "the exact curvature is not empty");
        }
    }
    eprintln!("largest difference, relative to each block: {worst:.3e}");
    assert!(worst <= ROUND_OFF, "{worst:e}");
}
