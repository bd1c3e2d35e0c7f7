//! A primal–dual interior-point method for [`StageProblem`]s whose Newton systems are
//! solved by a Riccati recursion over the stages (the FATROP/HPIPM family).
//!
//! Per iteration: stage derivatives (in parallel), the stage equality eliminated for its
//! `NE` dependent decisions, inequality slacks and multipliers condensed into the stage
//! Hessian (`Cᵀ Σ C`), state equalities as dual-regularised rows (a quadratic term
//! `‖G δx + c‖²/(2δ_c)` and the multiplier update `y⁺ = y + (G δx + c)/δ_c`), then one
//! backward and one forward Riccati sweep, inertia correction by a primal shift when a
//! stage's `H_uu` is not positive definite, and IPOPT's filter line search with the
//! fraction-to-the-boundary rule. The barrier parameter follows IPOPT's monotone rule.
//! Algorithm and options: `docs/ocp.md`.

// Stage loops index several per-stage arrays (derivatives, iterate, step) in step.
#![allow(clippy::needless_range_loop)]

use crate::derivatives::{stage_derivatives_into, stage_values, StageDerivatives, StageValues};
use crate::problem::{StageProblem, StateEquality};
use crate::riccati::{solve_lq, BackwardSweep, LqSolution, LqStage, RiccatiError};
use dmech::linalg::Lu;
use nalgebra::{SMatrix, SVector};
use std::io::Write as _;
use std::time::Instant;

mod iterate;
mod kkt;
mod line_search;
mod options;
mod parallel;
mod quasi_newton;
mod recovery;
mod scaling;

use iterate::{Bounds, Elimination, Measures, Step};
pub use iterate::{Iterate, SolveResult};
use kkt::{KktError, StageAux};
pub use options::{IpOptions, Status, Timings};
use parallel::{par_fill, par_update, par_zip, par_zip3, PAR_CHUNK};
use quasi_newton::QuasiNewton;

/// A warm start keeps the previous bound multipliers, floored at this fraction of `μ₀/t`
/// (positive, and on the scale of the previous barrier's complementarity `z t = μ_prev`
/// when that was `μ₀/10` or more). Raising them onto the new barrier's central path
/// (`z = μ₀/t`, the rule before) changes the dual residual by up to `(μ₀ − μ_prev)/t` at
/// every nearly active bound, which the next steps had to undo: measured on the friction
/// continuation's second phase (iterations, floor 1 → 1e-2): eight 65 → 58, zigzag
/// 40 → 38, eight at h = 1.25 ms 96 → 86, eight RK4 75 → 67, zigzag RK1 55 → 57, zigzag
/// RK2 algebraic 39 → 40 (`docs/ocp.md`).
const WARM_MULT_FLOOR: f64 = 1e-2;

/// A violation that stalls above this is reported as infeasibility.
const INFEASIBLE_VIOLATION: f64 = 1e-2;

/// Line-search trials (the first one included) after which the quasi-Newton curvature is
/// reset.
const QN_RESET_BACKTRACKS: usize = 4;

/// Steps taken without line-search acceptance, at most, per solve.
const MAX_FORCED_STEPS: usize = 20;

pub struct Solver<
    'a,
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NU: usize,
    const NC: usize,
> {
    p: &'a P,
    n: usize,
    opts: IpOptions,
    bounds: Vec<Bounds<NC>>,
    eqs: Vec<StateEquality>,
    eqs_at: Vec<Vec<usize>>,
}

impl<
        'a,
        P,
        const NX: usize,
        const NW: usize,
        const NE: usize,
        const NU: usize,
        const NC: usize,
    > Solver<'a, P, NX, NW, NE, NU, NC>
where
    P: StageProblem<NX, NW, NE, NC>,
{
    pub fn new(p: &'a P, opts: IpOptions) -> Self {
        assert_eq!(NE + NU, NW, "NU must be NW − NE");
        let n = p.horizon();
        let bounds = (0..n)
            .map(|k| {
                let (lo, hi) = p.bounds(k);
                Bounds {
                    lo,
                    hi,
                    has_lo: lo.map(|v| if v.is_finite() { 1.0 } else { 0.0 }),
                    has_hi: hi.map(|v| if v.is_finite() { 1.0 } else { 0.0 }),
                }
            })
            .collect();
        let eqs = p.state_equalities();
        let mut eqs_at = vec![Vec::new(); n + 1];
        for (j, e) in eqs.iter().enumerate() {
            assert!(e.stage <= n && e.index < NX, "state equality out of range");
            eqs_at[e.stage].push(j);
        }
        Solver {
            p,
            n,
            opts,
            bounds,
            eqs,
            eqs_at,
        }
    }

    /// An iterate from primal values: slacks pushed into the interior, unit bound
    /// multipliers, zero equality multipliers.
    pub fn initial_iterate(
        &self,
        x: Vec<SVector<f64, NX>>,
        w: Vec<SVector<f64, NW>>,
    ) -> Iterate<NX, NW, NC> {
        assert_eq!(x.len(), self.n + 1);
        assert_eq!(w.len(), self.n);
        let mut x = x;
        x[0] = self.p.initial_state();
        let mut it = Iterate {
            lambda: vec![SVector::zeros(); self.n],
            t_lo: vec![SVector::repeat(1.0); self.n],
            t_hi: vec![SVector::repeat(1.0); self.n],
            z_lo: vec![SVector::zeros(); self.n],
            z_hi: vec![SVector::zeros(); self.n],
            y: vec![0.0; self.eqs.len()],
            x,
            w,
        };
        for k in 0..self.n {
            let c = self.p.constraints(k, &it.x[k], &it.w[k]);
            let b = &self.bounds[k];
            for i in 0..NC {
                let gap = if b.has_lo[i] > 0.0 && b.has_hi[i] > 0.0 {
                    b.hi[i] - b.lo[i]
                } else {
                    f64::INFINITY
                };
                if b.has_lo[i] > 0.0 {
                    let push = (1e-2 * b.lo[i].abs().max(1.0)).min(1e-2 * gap);
                    it.t_lo[k][i] = (c[i] - b.lo[i]).max(push);
                    it.z_lo[k][i] = 1.0;
                }
                if b.has_hi[i] > 0.0 {
                    let push = (1e-2 * b.hi[i].abs().max(1.0)).min(1e-2 * gap);
                    it.t_hi[k][i] = (b.hi[i] - c[i]).max(push);
                    it.z_hi[k][i] = 1.0;
                }
            }
        }
        it
    }

    /// A warm start from a previous solution (of this or a nearby problem): primal values
    /// and multipliers kept, slacks recomputed from the constraints at this problem and
    /// pushed at least `μ₀` into the interior, bound multipliers kept but not below
    /// [`WARM_MULT_FLOOR`]` · μ₀/t`.
    pub fn warm_iterate(&self, prev: Iterate<NX, NW, NC>) -> Iterate<NX, NW, NC> {
        let mut it = prev;
        it.x[0] = self.p.initial_state();
        let mu = self.opts.mu_init;
        for k in 0..self.n {
            let c = self.p.constraints(k, &it.x[k], &it.w[k]);
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    it.t_lo[k][i] = (c[i] - b.lo[i]).max(mu);
                    it.z_lo[k][i] = it.z_lo[k][i].max(WARM_MULT_FLOOR * mu / it.t_lo[k][i]);
                }
                if b.has_hi[i] > 0.0 {
                    it.t_hi[k][i] = (b.hi[i] - c[i]).max(mu);
                    it.z_hi[k][i] = it.z_hi[k][i].max(WARM_MULT_FLOOR * mu / it.t_hi[k][i]);
                }
            }
        }
        it
    }

    fn values(&self, it: &Iterate<NX, NW, NC>) -> Vec<StageValues<NX, NE, NC>> {
        let mut out = vec![
            StageValues {
                f: SVector::zeros(),
                e: SVector::zeros(),
                cost: 0.0,
                c: SVector::zeros(),
            };
            self.n
        ];
        par_fill(&mut out, self.opts.threads, |k| {
            stage_values(self.p, k, &it.x[k], &it.w[k])
        });
        out
    }

    fn measures(
        &self,
        it: &Iterate<NX, NW, NC>,
        vals: &[StageValues<NX, NE, NC>],
        mu: f64,
    ) -> Measures {
        let (mut theta, mut theta_max, mut obj, mut logs) = (0.0, 0.0f64, 0.0, 0.0);
        let mut add = |r: f64| {
            theta += r.abs();
            theta_max = theta_max.max(r.abs());
        };
        for k in 0..self.n {
            let v = &vals[k];
            obj += v.cost;
            for i in 0..NX {
                add(v.f[i] - it.x[k + 1][i]);
            }
            for i in 0..NE {
                add(v.e[i]);
            }
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    add(v.c[i] - b.lo[i] - it.t_lo[k][i]);
                    logs += it.t_lo[k][i].ln();
                }
                if b.has_hi[i] > 0.0 {
                    add(b.hi[i] - v.c[i] - it.t_hi[k][i]);
                    logs += it.t_hi[k][i].ln();
                }
            }
        }
        for e in &self.eqs {
            add(it.x[e.stage][e.index] - e.value);
        }
        Measures {
            theta,
            theta_max,
            objective: obj,
            barrier: obj - mu * logs,
        }
    }

    /// The largest violation of any constraint at a primal point (slacks not used).
    pub fn max_violation(&self, x: &[SVector<f64, NX>], w: &[SVector<f64, NW>]) -> f64 {
        let mut worst = 0.0f64;
        for k in 0..self.n {
            let v = stage_values(self.p, k, &x[k], &w[k]);
            worst = worst.max((v.f - x[k + 1]).amax()).max(v.e.amax());
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    worst = worst.max(b.lo[i] - v.c[i]);
                }
                if b.has_hi[i] > 0.0 {
                    worst = worst.max(v.c[i] - b.hi[i]);
                }
            }
        }
        for e in &self.eqs {
            worst = worst.max((x[e.stage][e.index] - e.value).abs());
        }
        worst
    }

    /// Solve from `start`. A problem whose cost per stage at the start is below one is
    /// solved with its cost scaled up (`scaling.rs`); the result is in the problem's units.
    pub fn solve(&self, start: Iterate<NX, NW, NC>) -> SolveResult<NX, NW, NC> {
        let c = scaling::objective_scale(self.p, &start)
            .or_else(|| {
                let probe = self.with_options(IpOptions {
                    max_iter: 1,
                    verbose: false,
                    time_limit: f64::INFINITY,
                    ..self.opts.clone()
                });
                scaling::objective_scale(self.p, &probe.run(start.clone()).iterate)
            })
            .unwrap_or(1.0);
        if c == 1.0 {
            return self.run(start);
        }
        if self.opts.verbose {
            let _ = writeln!(
                std::io::stderr(),
                "objective scaled by {c:.3e} (mean stage cost {:.3e} at the start or after one step)",
                1.0 / c
            );
        }
        let scaled = scaling::ScaledCost { p: self.p, c };
        let inner: Solver<_, NX, NW, NE, NU, NC> = Solver {
            p: &scaled,
            n: self.n,
            opts: self.opts.clone(),
            bounds: self.bounds.clone(),
            eqs: self.eqs.clone(),
            eqs_at: self.eqs_at.clone(),
        };
        // A cold start (no equality multipliers) has the initial bound multipliers 1 of
        // `initial_iterate`, IPOPT's initial value for the problem the solver works on;
        // a warm start's multipliers are in the problem's units and are scaled with it.
        let warm = start.lambda.iter().any(|l| l.amax() > 0.0) || start.y.iter().any(|&y| y != 0.0);
        let r = inner.run(start.with_duals_scaled(c, warm));
        SolveResult {
            iterate: r.iterate.with_duals_scaled(1.0 / c, true),
            objective: r.objective / c,
            ..r
        }
    }

    /// The same solver with other options.
    fn with_options(&self, opts: IpOptions) -> Self {
        Solver {
            p: self.p,
            n: self.n,
            opts,
            bounds: self.bounds.clone(),
            eqs: self.eqs.clone(),
            eqs_at: self.eqs_at.clone(),
        }
    }

    /// The interior-point loop on the problem as given.
    fn run(&self, start: Iterate<NX, NW, NC>) -> SolveResult<NX, NW, NC> {
        let t_start = Instant::now();
        let n = self.n;
        let o = &self.opts;
        let mut tm = Timings::default();
        let mut it = start;
        let mut mu = o.mu_init;
        let mut filter: Vec<(f64, f64)> = Vec::new();
        let mut delta_last = 0.0f64;
        let mut vals = self.values(&it);
        let mut m = self.measures(&it, &vals, mu);
        let theta_max_f = 1e4 * m.theta.max(1.0);
        let theta_min_f = 1e-4 * m.theta.max(1.0);
        let mut theta_hist: Vec<f64> = Vec::new();
        let status;
        let mut iter = 0;
        let (mut alpha_p, mut alpha_d) = (0.0, 0.0);
        if o.verbose {
            // Best-effort: a closed or full stderr must not abort the solve (eprintln! panics).
            let _ = writeln!(
                std::io::stderr(),
                "{:>4} {:>14} {:>9} {:>9} {:>6} {:>9} {:>9} {:>9} {:>3} {:>7}",
                "iter",
                "objective",
                "inf_pr",
                "inf_du",
                "lg(mu)",
                "lg(rg)",
                "alpha_du",
                "alpha_pr",
                "ls",
                "time"
            );
        }
        if let Some(msg) = self.check_affine_declaration(&it) {
            return self.finish(Status::Failed(msg), it, 0, tm, t_start);
        }
        let mut ders = vec![StageDerivatives::<NX, NW, NE, NC>::zeros(); n];
        // The condensed stages and their eliminations, overwritten every iteration.
        let mut lq = vec![LqStage::<NX, NU>::zeros(); n];
        let mut elim = vec![Elimination::<NX, NW, NU>::zeros(); n];
        let mut aux = vec![StageAux::<NX, NE, NC>::zeros(); n];
        let mut qn = vec![QuasiNewton::<NX, NW, NE>::new(); if o.quasi_newton { n } else { 0 }];
        let mut ls_count = 0;
        let mut forced_steps = 0usize;
        loop {
            if !m.objective.is_finite() || !m.theta.is_finite() {
                status = Status::Diverged;
                break;
            }
            if it.x.iter().any(|x| x.amax() > 1e12) {
                status = Status::Diverged;
                break;
            }
            // Derivatives.
            let t0 = Instant::now();
            let derivatives = |k: usize, d: &mut StageDerivatives<NX, NW, NE, NC>| {
                let zeta = it.z_hi[k] - it.z_lo[k];
                let lam = &it.lambda[k];
                stage_derivatives_into(
                    d,
                    self.p,
                    k,
                    &it.x[k],
                    &it.w[k],
                    &zeta,
                    o.exact_hessian.then_some(lam),
                );
                d.nu = d.equality_multiplier(lam, &zeta);
            };
            // With each stage's derivatives, while they are in cache: its SR1 update, its
            // part of the KKT error and its values (reading the 36 MB of derivatives again
            // for these was 5–7 % of a plan).
            let finish =
                |k: usize, d: &StageDerivatives<NX, NW, NE, NC>, a: &mut StageAux<NX, NE, NC>| {
                    a.kkt = self.kkt_stage(k, &it, d);
                    a.vals = StageValues {
                        f: d.f,
                        e: d.e,
                        cost: d.cost,
                        c: d.c,
                    };
                };
            if o.quasi_newton {
                par_zip3(&mut ders, &mut qn, &mut aux, o.threads, |k, d, q, a| {
                    derivatives(k, d);
                    let nu = d.nu.unwrap_or_else(SVector::zeros);
                    q.update(o.sr1_skip, &it.x[k], &it.w[k], d, &it.lambda[k], &nu);
                    finish(k, d, a);
                });
            } else {
                par_zip(&mut ders, &mut aux, o.threads, |k, d, a| {
                    derivatives(k, d);
                    finish(k, d, a);
                });
            }
            tm.derivatives += t0.elapsed().as_secs_f64();

            let KktError { dual, primal, s_d } = self.kkt_error(&it, aux.iter().map(|a| a.kkt));
            let compl0 = self.complementarity(&it, 0.0, s_d);
            if o.verbose {
                let _ = writeln!(
                    std::io::stderr(),
                    "{:>4} {:>14.7e} {:>9.2e} {:>9.2e} {:>6.1} {:>9} {:>9.2e} {:>9.2e} {:>3} {:>6.2}s",
                    iter,
                    m.objective,
                    primal,
                    dual,
                    mu.log10(),
                    if delta_last > 0.0 { format!("{:.1}", delta_last.log10()) } else { "-".into() },
                    alpha_d,
                    alpha_p,
                    ls_count,
                    t_start.elapsed().as_secs_f64()
                );
            }
            if dual <= o.tol && compl0 <= o.tol && primal <= o.constr_viol_tol {
                status = Status::Solved;
                break;
            }
            if iter >= o.max_iter || t_start.elapsed().as_secs_f64() > o.time_limit {
                status = Status::MaxIterations;
                break;
            }
            // Infeasibility: the violation has not dropped by 1% over 100 iterations while
            // still far from zero (no restoration phase: this is the stationary point of
            // the violation that the regularised equalities lead to).
            theta_hist.push(m.theta_max);
            if theta_hist.len() > 100 {
                let old = theta_hist[theta_hist.len() - 101];
                if m.theta_max > INFEASIBLE_VIOLATION && m.theta_max > 0.99 * old {
                    status = Status::Infeasible {
                        violation: m.theta_max,
                    };
                    break;
                }
            }
            // Barrier update (IPOPT's monotone rule).
            loop {
                let e_mu = dual.max(primal).max(self.complementarity(&it, mu, s_d));
                if e_mu <= 10.0 * mu && mu > o.tol / 10.0 {
                    mu = (o.tol / 10.0).max((0.2 * mu).min(mu.powf(1.5)));
                    filter.clear();
                } else {
                    break;
                }
            }
            vals.iter_mut()
                .zip(aux.iter())
                .for_each(|(v, a)| *v = a.vals);
            m = self.measures(&it, &vals, mu);
            // The state equalities' regularisation follows the barrier parameter: loose
            // while far from the solution (steps that respect the other constraints),
            // tight near it (fast convergence of their multipliers).
            let dc = (o.delta_c * (mu / o.mu_init).powi(2)).max(o.delta_c_min);

            // KKT solve.
            let t1 = Instant::now();
            let (mut q_n, mut q_vec_n) = (SMatrix::zeros(), SVector::zeros());
            self.add_state_equalities(n, &it, dc, &mut q_n, &mut q_vec_n);
            // The first factorisation (no shift) runs behind the condensing; the inertia
            // correction's retries sweep the condensed stages again with a shift.
            let mut sweep = BackwardSweep::new(n, &q_n, &q_vec_n, 0.0);
            let first = match self.condense_and_sweep(&mut lq, &mut elim, &mut sweep, |k, l, e| {
                self.condense(k, &it, &ders[k], qn.get(k), mu, dc, l, e)
            }) {
                Ok((r, t_sweep)) => {
                    tm.riccati += t_sweep;
                    r.map(|()| sweep.forward(&lq, &SVector::zeros()))
                }
                Err(e) => return self.finish(Status::Failed(e), it, iter, tm, t_start),
            };
            let mut delta = 0.0;
            let mut attempt = Some(first);
            let sol = loop {
                tm.factorizations += 1;
                let r = match attempt.take() {
                    Some(r) => r,
                    None => {
                        let t_r = Instant::now();
                        let r = solve_lq(&lq, &q_n, &q_vec_n, &SVector::zeros(), delta);
                        tm.riccati += t_r.elapsed().as_secs_f64();
                        r
                    }
                };
                match r {
                    Ok(s) => break Some(s),
                    Err(_) => {
                        delta = if delta == 0.0 {
                            if delta_last == 0.0 {
                                1e-4
                            } else {
                                (delta_last / 3.0).max(1e-20)
                            }
                        } else if delta_last == 0.0 {
                            delta * 100.0
                        } else {
                            delta * 8.0
                        };
                        if delta > 1e40 {
                            break None;
                        }
                    }
                }
            };
            let Some(sol) = sol else {
                return self.finish(
                    Status::Failed("inertia correction failed".into()),
                    it,
                    iter,
                    tm,
                    t_start,
                );
            };
            if delta > 0.0 {
                delta_last = delta;
            }
            let mut step = self.recover(&it, &ders, &elim, sol, mu, dc);
            tm.kkt += t1.elapsed().as_secs_f64();

            // Fraction to the boundary.
            let tau = (1.0 - mu).max(0.99);
            let (amax_p, mut amax_d) = self.max_step(&it, &step, tau);

            // Filter line search.
            let t2 = Instant::now();
            let mut dphi = 0.0;
            for k in 0..n {
                dphi += ders[k].gx.dot(&step.dx[k]) + ders[k].gw.dot(&step.dw[k]);
                let b = &self.bounds[k];
                for i in 0..NC {
                    if b.has_lo[i] > 0.0 {
                        dphi -= mu * step.dt_lo[k][i] / it.t_lo[k][i];
                    }
                    if b.has_hi[i] > 0.0 {
                        dphi -= mu * step.dt_hi[k][i] / it.t_hi[k][i];
                    }
                }
            }
            let (gth, gph, eta, s_th, s_ph, dl): (f64, f64, f64, f64, f64, f64) =
                (1e-5, 1e-5, 1e-4, 1.1, 2.3, 1.0);
            let alpha_min = if dphi < 0.0 {
                0.05 * gth
                    .min(gph * m.theta / (-dphi))
                    .min(dl * m.theta.powf(s_th) / (-dphi).powf(s_ph))
            } else {
                0.05 * gth
            };
            let mut alpha = amax_p;
            ls_count = 0;
            // IPOPT's tiny-step rule: a primal step at round-off level is taken whole
            // (its dual part may still be large), without the line search.
            let rel_step = (0..n)
                .map(|k| {
                    let a = step.dx[k + 1]
                        .zip_map(&it.x[k + 1], |d, x| d.abs() / (1.0 + x.abs()))
                        .amax();
                    let b = step.dw[k]
                        .zip_map(&it.w[k], |d, x| d.abs() / (1.0 + x.abs()))
                        .amax();
                    a.max(b)
                })
                .fold(0.0f64, f64::max);
            let tiny = rel_step < 1e-9 && m.theta_max <= o.constr_viol_tol;
            let accepted = loop {
                if tiny {
                    let trial = self.trial(&it, &step, alpha);
                    let tv = self.values(&trial);
                    let tmz = self.measures(&trial, &tv, mu);
                    break Some((trial, tv, tmz));
                }
                ls_count += 1;
                let trial = self.trial(&it, &step, alpha);
                let tv = self.values(&trial);
                let tmz = self.measures(&trial, &tv, mu);
                // IPOPT's acceptance test of a trial point (filter, switching condition,
                // Armijo on the barrier function); `alpha` is the step along `step`.
                let acceptable = |tmz: &Measures, alpha: f64| {
                    let ok_val = tmz.theta.is_finite()
                        && tmz.barrier.is_finite()
                        && tmz.theta <= theta_max_f;
                    let in_filter = filter
                        .iter()
                        .any(|&(ft, fp)| tmz.theta >= ft && tmz.barrier >= fp);
                    if !ok_val || in_filter {
                        return (false, false);
                    }
                    let switching =
                        dphi < 0.0 && alpha * (-dphi).powf(s_ph) > dl * m.theta.powf(s_th);
                    // IPOPT's `Compare_le`: a decrease test passes within 10 ulps of the
                    // reference, so that steps whose predicted decrease is below the
                    // round-off of φ (near the solution, θ ≈ 1e-13) are not rejected by
                    // noise.
                    let le = |lhs: f64, rhs: f64, base: f64| {
                        lhs - rhs <= 10.0 * f64::EPSILON * base.abs()
                    };
                    if m.theta <= theta_min_f && switching {
                        (
                            le(tmz.barrier, m.barrier + eta * alpha * dphi, m.barrier),
                            false,
                        )
                    } else {
                        (
                            le(tmz.theta, (1.0 - gth) * m.theta, m.theta)
                                || le(tmz.barrier, m.barrier - gph * m.theta, m.barrier),
                            true,
                        )
                    }
                };
                let (accept, augment) = acceptable(&tmz, alpha);
                if accept {
                    if augment {
                        filter.push(((1.0 - gth) * m.theta, m.barrier - gph * m.theta));
                    }
                    break Some((trial, tv, tmz));
                }
                // Second-order correction (IPOPT's): the full step was rejected and made
                // the constraint violation worse, the mark of the constraints' curvature
                // (Maratos effect). Re-solve the same KKT system with the residuals
                // `α c(x) + c(x + α d)` and try the corrected step, up to 4 times while it
                // reduces the violation by 1 %.
                if ls_count == 1 && tmz.theta >= m.theta {
                    let (mut soc_trial, mut soc_vals, mut soc_alpha) = (trial, tv, alpha);
                    let mut theta_trial = tmz.theta;
                    let mut found = None;
                    for _ in 0..4 {
                        let t_soc = Instant::now();
                        let Some(sstep) = self.second_order_correction(
                            &it, &ders, &qn, &soc_vals, &soc_trial, soc_alpha, mu, dc, delta,
                            &mut lq, &mut elim,
                        ) else {
                            break;
                        };
                        tm.kkt += t_soc.elapsed().as_secs_f64();
                        let (ap, ad) = self.max_step(&it, &sstep, tau);
                        let ct = self.trial(&it, &sstep, ap);
                        let cv = self.values(&ct);
                        let cm = self.measures(&ct, &cv, mu);
                        let (ok, aug) = acceptable(&cm, alpha);
                        tm.second_order_corrections += 1;
                        if ok {
                            found = Some((ct, cv, cm, sstep, ap, ad, aug));
                            break;
                        }
                        let theta_soc_old = theta_trial;
                        theta_trial = cm.theta;
                        if theta_trial > 0.99 * theta_soc_old {
                            break;
                        }
                        (soc_trial, soc_vals, soc_alpha) = (ct, cv, ap);
                    }
                    if let Some((ct, cv, cm, sstep, ap, ad, aug)) = found {
                        if aug {
                            filter.push(((1.0 - gth) * m.theta, m.barrier - gph * m.theta));
                        }
                        step = sstep;
                        amax_d = ad;
                        alpha = ap;
                        break Some((ct, cv, cm));
                    }
                }
                alpha *= 0.5;
                if alpha < alpha_min {
                    break None;
                }
            };
            tm.line_search += t2.elapsed().as_secs_f64();
            let accepted = match accepted {
                Some(a) => Some(a),
                None if forced_steps < MAX_FORCED_STEPS => {
                    // No restoration phase: forget the quasi-Newton curvature (a secant
                    // model gone bad gives steps the barrier function does not accept),
                    // take a short step anyway and restart the filter. Bounded in number,
                    // so a problem without an acceptable step still ends.
                    for q in qn.iter_mut() {
                        q.reset();
                    }
                    filter.clear();
                    forced_steps += 1;
                    let a = amax_p * 0.125;
                    let trial = self.trial(&it, &step, a);
                    let tv = self.values(&trial);
                    let tmz = self.measures(&trial, &tv, mu);
                    alpha = a;
                    Some((trial, tv, tmz))
                }
                None => None,
            };
            // A step accepted only after cutting it by 2³ or more says the secant model
            // predicts badly: start it over from the exact cost curvature. (Measured on the
            // eight: without it, runs of hundreds of steps cut 2⁷–2⁸ each; docs/ocp.md.)
            if accepted.is_some() && ls_count >= QN_RESET_BACKTRACKS {
                for q in qn.iter_mut() {
                    q.reset();
                }
            }
            let Some((mut trial, tv, tmz)) = accepted else {
                status = if m.theta_max > INFEASIBLE_VIOLATION {
                    Status::Infeasible {
                        violation: m.theta_max,
                    }
                } else {
                    Status::Failed(format!(
                        "line search: no acceptable step (constraint violation {:.2e})",
                        m.theta_max
                    ))
                };
                break;
            };
            // Dual step with its own step length, kept within κ_Σ of μ/t.
            for k in 0..n {
                let b = &self.bounds[k];
                for i in 0..NC {
                    if b.has_lo[i] > 0.0 {
                        let z = it.z_lo[k][i] + amax_d * step.dz_lo[k][i];
                        let t = trial.t_lo[k][i];
                        trial.z_lo[k][i] = z.clamp(mu / (1e10 * t), 1e10 * mu / t);
                    }
                    if b.has_hi[i] > 0.0 {
                        let z = it.z_hi[k][i] + amax_d * step.dz_hi[k][i];
                        let t = trial.t_hi[k][i];
                        trial.z_hi[k][i] = z.clamp(mu / (1e10 * t), 1e10 * mu / t);
                    }
                }
            }
            alpha_p = alpha;
            alpha_d = amax_d;
            it = trial;
            vals = tv;
            m = tmz;
            iter += 1;
        }
        self.finish(status, it, iter, tm, t_start)
    }
}
