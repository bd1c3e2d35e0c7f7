//! A primal–dual interior-point method for [`StageProblem`]s whose Newton systems are
//! solved by a Riccati recursion over the stages (the FATROP/HPIPM family).
//!
//! Per iteration (`Solver::run`): stage derivatives in parallel (`derivative_pass.rs`);
//! the KKT error (`kkt_error.rs`); the Newton step (`kkt.rs`): the stage equality eliminated for its `NE` dependent
//! decisions, inequality slacks and multipliers condensed into the stage Hessian
//! (`Cᵀ Σ C`), state and terminal equalities as dual-regularised rows (a quadratic term
//! `‖G δx + c‖²/(2δ_c)` and the multiplier update `y⁺ = y + (G δx + c)/δ_c`), one backward
//! and one forward Riccati sweep (`riccati.rs`), inertia correction by a primal shift when
//! a stage's `H_uu` is not positive definite (`inertia.rs`); IPOPT's filter line search
//! with the fraction-to-the-boundary rule and second-order corrections
//! (`line_search.rs`, `filter.rs`). The barrier parameter follows IPOPT's monotone rule.
//! Algorithm and options: `docs/solver.md`.

// Stage loops index several per-stage arrays (derivatives, iterate, step) in step.
#![allow(clippy::needless_range_loop)]

use crate::nlp::derivatives::{
    ConstantsTable, Precomputed, StageConstants, StageDerivatives, StageValues, TerminalDerivatives,
};
use crate::nlp::HessianBlocks;
use crate::nlp::{StageProblem, StateEquality};
use crate::solver::kkt::riccati::{BackwardSweep, LqSolution, LqStage, RiccatiError};
use dmech_lie::linalg::Lu;
use nalgebra::{SMatrix, SVector};
use std::io::Write as _;
use std::time::Instant;

mod derivative_pass;
mod filter;
mod huge_pages;
mod inertia;
mod iterate;
mod iteration_table;
mod kkt;
mod kkt_error;
mod line_search;
mod measures;
mod options;
mod oracle;
mod parallel;
mod quasi_newton;
mod recovery;
mod restoration;
mod scaling;
mod start;
mod worker_pool;

pub use derivative_pass::reuse_workspaces;
use derivative_pass::Workspace;
use filter::Filter;
use inertia::InertiaCorrection;
use iterate::{Bounds, Elimination, Measures, Step};
pub use iterate::{Iterate, SolveResult};
pub use kkt::globals::GlobalIterate;
use kkt::globals::GlobalSpec;
/// The Riccati recursion, for the `state_size` benchmark only.
#[cfg(feature = "bench")]
#[doc(hidden)]
pub use kkt::riccati;
use kkt_error::{KktError, StageAux};
use line_search::LineSearch;
pub use options::{
    Curvature, Failure, IpOptions, IterationObserver, IterationReport, KktMethod, Status, Timings,
};
pub use parallel::STAGE_THREAD_STACK;
use parallel::{par_collect, par_fill, par_update, par_zip, par_zip3, PAR_CHUNK};
use quasi_newton::QuasiNewton;
use restoration::Restored;

/// IPOPT's monotone barrier rule: once the barrier problem's error is at most `κ_ε μ`,
/// `μ ← max(tol/10, min(κ_μ μ, μ^θ_μ))`.
const KAPPA_EPSILON: f64 = 10.0;
const KAPPA_MU: f64 = 0.2;
const THETA_MU: f64 = 1.5;

/// `κ_Σ`: a bound multiplier is kept within `[μ/(κ_Σ t), κ_Σ μ/t]` after its step.
const KAPPA_SIGMA: f64 = 1e10;

/// Iterates beyond this magnitude are reported as diverging.
const DIVERGING_ITERATES: f64 = 1e12;

/// Far from feasibility (a violation above this), a failed line search or a stalled
/// violation calls for feasibility restoration (`restoration.rs`); closer, the solver takes
/// a short step instead.
const INFEASIBLE_VIOLATION: f64 = 1e-2;
/// The stall test: no new low of the largest violation (by 1 %) for this many iterations.
const STALL_ITERATIONS: usize = 30;
const STALL_FACTOR: f64 = 0.99;

/// Whether the largest violation has stopped falling far from feasibility: above
/// `INFEASIBLE_VIOLATION` at each of the last `STALL_ITERATIONS` iterations, and no new low
/// (by `1 − STALL_FACTOR`) among them. A low, not the value a window ago, and every
/// iteration far, so that a violation that oscillates on its way down (the midpoint
/// zigzag's continuation phase swings between 1e-3 and 6e-2) is not taken for a stall.
struct StallWatch {
    best: f64,
    since: usize,
    far: usize,
}

impl StallWatch {
    fn new() -> Self {
        StallWatch {
            best: f64::INFINITY,
            since: 0,
            far: 0,
        }
    }

    fn stalled(&mut self, theta_max: f64) -> bool {
        if theta_max < STALL_FACTOR * self.best {
            self.best = theta_max;
            self.since = 0;
        } else {
            self.since += 1;
        }
        self.far = if theta_max > INFEASIBLE_VIOLATION {
            self.far + 1
        } else {
            0
        };
        self.far >= STALL_ITERATIONS && self.since >= STALL_ITERATIONS
    }
}

/// Line-search trials (the first one included) after which the quasi-Newton curvature is
/// reset: a step cut by 2⁵. At 4 (a cut by 2³) the midpoint VI's resets themselves kept
/// its barrier subproblem cycling (docs/solver.md).
const QN_RESET_BACKTRACKS: usize = 6;

/// Steps taken without line-search acceptance, at most, per solve, and their length as
/// a fraction of the largest step to the boundary.
const MAX_FORCED_STEPS: usize = 20;
const FORCED_STEP_FRACTION: f64 = 0.125;

/// What a run of the loop is.
enum Mode<'f, const NX: usize, const NW: usize, const NC: usize> {
    /// The problem itself, restored (`restoration.rs`) when it cannot go on far from
    /// feasibility.
    Main,
    /// A restoration problem, which stops as soon as `done` holds at an iterate, and whose
    /// objective follows the barrier parameter (`follow(μ)`: `true` if it changed).
    Restoration {
        done: &'f dyn Fn(&Iterate<NX, NW, NC>, &Measures) -> bool,
        follow: &'f dyn Fn(f64) -> bool,
    },
}

/// The solver of one problem. It holds the problem as a trait object (`StageOracle`,
/// `oracle.rs`), so that its code is compiled once per set of sizes, not once per problem
/// type.
pub struct Solver<
    'a,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
> {
    p: &'a dyn oracle::StageOracle<NX, NW, NE, NF, NC>,
    /// The problems derived from `p` (scaled, restoration); `None` for a restoration
    /// problem's own solver, which derives none.
    derived: Option<&'a dyn oracle::DerivedProblems<NX, NW, NE, NF, NC>>,
    n: usize,
    opts: IpOptions,
    bounds: Vec<Bounds<NC>>,
    eqs: Vec<StateEquality>,
    eqs_at: Vec<Vec<usize>>,
    /// The number of terminal equalities ([`StageProblem::terminal_equalities`]): their
    /// multipliers follow the state equalities' in `Iterate::y`.
    terminal_rows: usize,
    /// The problem's global variables, if any (`globals.rs`).
    globals: Option<GlobalSpec>,
    /// The sparse KKT matrix's symbolic factorisation, once the sparse path needs it.
    #[cfg(feature = "sparse-ldlt")]
    sparse: std::sync::OnceLock<Result<crate::solver::kkt::sparse_ldlt::SparseKkt, Failure>>,
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The solver of `p`. Panics if the sizes do not fit (`NF` must be `NW − NE`, less the
    /// globals' copies per stage) or the problem's globals are inconsistent: programming
    /// errors of the problem's definition, reported with both sides.
    pub fn new<P: StageProblem<NX, NW, NE, NF, NC>>(p: &'a P, opts: IpOptions) -> Self {
        Self::of_oracle(p, Some(p), opts)
    }

    /// [`Solver::new`] once the problem's type is erased.
    fn of_oracle(
        p: &'a dyn oracle::StageOracle<NX, NW, NE, NF, NC>,
        derived: Option<&'a dyn oracle::DerivedProblems<NX, NW, NE, NF, NC>>,
        opts: IpOptions,
    ) -> Self {
        let n = p.horizon();
        let globals = p.globals().map(|g| {
            if let Err(e) = g.check(n, NW) {
                panic!("{e}");
            }
            GlobalSpec::new(g)
        });
        let nt = globals.as_ref().map_or(0, |g| g.g.per_stage);
        assert_eq!(
            NE + NF + nt,
            NW,
            "NF must be NW − NE − (globals per stage {nt})"
        );
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
        let terminal_rows = p.terminal_equalities(&p.initial_state()).len();
        Solver {
            p,
            derived,
            n,
            opts,
            bounds,
            eqs,
            eqs_at,
            terminal_rows,
            globals,
            #[cfg(feature = "sparse-ldlt")]
            sparse: Default::default(),
        }
    }
    /// Solve from `start`. A problem whose cost per stage at the start is below one is
    /// solved with its cost scaled up (`scaling.rs`); the result is in the problem's units.
    pub fn solve(&self, start: Iterate<NX, NW, NC>) -> SolveResult<NX, NW, NC> {
        let c = self
            .opts
            .objective_scale
            .or_else(|| scaling::objective_scale(self.p, &start))
            .or_else(|| {
                let probe = self.variant(
                    self.p,
                    self.globals.clone(),
                    IpOptions {
                        max_iter: 1,
                        verbose: false,
                        observer: None,
                        time_limit: f64::INFINITY,
                        ..self.opts.clone()
                    },
                );
                scaling::objective_scale(self.p, &probe.run(start.clone()).iterate)
            })
            .unwrap_or(1.0);
        let global_cost = self.globals.as_ref().map_or(&[][..], |g| &g.g.cost[..]);
        let (c, capped) = scaling::capped_by_global_cost(c, global_cost);
        if c == 1.0 {
            return self.run(start);
        }
        if self.opts.verbose {
            let why = if capped {
                format!(
                    "the globals' cost gradient at most {}",
                    scaling::MAX_GRADIENT
                )
            } else {
                format!(
                    "mean stage cost {:.3e} at the start or after one step",
                    1.0 / c
                )
            };
            let _ = writeln!(std::io::stderr(), "objective scaled by {c:.3e} ({why})");
        }
        let scaled = self
            .derived
            .expect("a restoration problem is run, not solved")
            .scaled(c);
        let globals = self.globals.clone().map(|g| g.with_cost_scaled(c));
        let inner = self.variant(&*scaled, globals, self.opts.clone());
        // A cold start (no equality multipliers) has the initial bound multipliers 1 of
        // `initial_iterate`, IPOPT's initial value for the problem the solver works on;
        // a warm start's multipliers are in the problem's units and are scaled with it.
        let warm = start.lambda.iter().any(|l| l.amax() > 0.0) || start.y.iter().any(|&y| y != 0.0);
        let r = inner.run(start.with_duals_scaled(c, warm));
        SolveResult {
            iterate: r.iterate.with_duals_scaled(1.0 / c, true),
            objective: r.objective / c,
            duality_gap: r.duality_gap / c,
            ..r
        }
    }

    /// This solver on `p` (the problem itself or its scaled cost: the same stages, bounds
    /// and state equalities), with `globals` and `opts`.
    fn variant<'b>(
        &'b self,
        p: &'b dyn oracle::StageOracle<NX, NW, NE, NF, NC>,
        globals: Option<GlobalSpec>,
        opts: IpOptions,
    ) -> Solver<'b, NX, NW, NE, NF, NC> {
        Solver {
            p,
            derived: self.derived,
            n: self.n,
            opts,
            bounds: self.bounds.clone(),
            eqs: self.eqs.clone(),
            eqs_at: self.eqs_at.clone(),
            terminal_rows: self.terminal_rows,
            globals,
            #[cfg(feature = "sparse-ldlt")]
            sparse: Default::default(),
        }
    }

    /// The number of equality multipliers in `Iterate::y`: the state equalities', then the
    /// terminal equalities'.
    fn equality_multipliers(&self) -> usize {
        self.eqs.len() + self.terminal_rows
    }

    /// The terminal equalities' multipliers in `y` (empty if `y` has none).
    fn terminal_multipliers<'y>(&self, y: &'y [f64]) -> &'y [f64] {
        y.get(self.eqs.len()..).unwrap_or(&[])
    }

    /// The interior-point loop on the problem as given, with feasibility restoration.
    fn run(&self, start: Iterate<NX, NW, NC>) -> SolveResult<NX, NW, NC> {
        self.run_with(start, Mode::Main).0
    }

    /// The interior-point loop. In [`Mode::Restoration`] it also reports whether it stopped
    /// because the restoration had succeeded.
    fn run_with(
        &self,
        start: Iterate<NX, NW, NC>,
        mode: Mode<'_, NX, NW, NC>,
    ) -> (SolveResult<NX, NW, NC>, bool) {
        let t_start = Instant::now();
        let o = &self.opts;
        let mut tm = Timings::default();
        let mut it = start;
        let mut mu = o.mu_init;
        let mut vals = self.values(&it);
        let mut m = self.measures(&it, &vals, mu);
        let mut filter = Filter::new(m.theta);
        let mut inertia = InertiaCorrection::default();
        let mut stall = StallWatch::new();
        let mut ws = Workspace::new(self.n, o.curvature == Curvature::Sr1, o.threads);
        let mut last = LineSearch::none();
        // The shift of the step that led to the current iterate (IPOPT's `lg(rg)` column).
        let mut last_shift = 0.0;
        let mut forced_steps = 0usize;
        let mut iter = 0;
        let mut restored = false;
        let mut restore = false;
        self.print_header();
        if let Some(failure) = self.check_affine_declaration(&it) {
            return (
                self.finish(Status::Failed(failure), it, 0, tm, t_start),
                false,
            );
        }
        match self.stage_constants(&it) {
            Ok(constants) => ws.constants = constants,
            Err(failure) => {
                return (
                    self.finish(Status::Failed(failure), it, 0, tm, t_start),
                    false,
                )
            }
        }
        let status = loop {
            if !m.objective.is_finite()
                || !m.theta.is_finite()
                || it.x.iter().any(|x| x.amax() > DIVERGING_ITERATES)
            {
                break Status::Diverged;
            }
            if let Mode::Restoration { done, follow } = mode {
                if iter > 0 && done(&it, &m) {
                    restored = true;
                    break Status::Solved;
                }
                if follow(mu) {
                    filter.clear();
                    vals = self.values(&it);
                    m = self.measures(&it, &vals, mu);
                }
            }
            // No acceptable step far from feasibility, or a violation that has stopped
            // falling there: restoration decides whether a feasible point is near.
            if std::mem::take(&mut restore) || stall.stalled(m.theta_max) {
                match self.restoration(&mode, &mut it, &mut iter, &mut tm, mu, t_start) {
                    Some(status) => break status,
                    None => {
                        (vals, m) =
                            self.restart_after_restoration(&it, &mut ws, &mut filter, &m, mu);
                        stall = StallWatch::new();
                    }
                }
            }
            self.derivative_pass(&it, &vals, &mut ws, &mut tm);
            let kkt = self.kkt_error(&it, &ws.terminal, &ws.ders, ws.aux.iter().map(|a| a.kkt));
            let compl0 = self.complementarity(&it, 0.0, kkt.s_d);
            self.print_row(iter, &m, &kkt, mu, last_shift, &last, t_start);
            if kkt.dual <= o.tol && compl0 <= o.tol && kkt.primal <= o.constr_viol_tol {
                break Status::Solved;
            }
            if iter >= o.max_iter {
                break Status::MaxIterations;
            }
            if t_start.elapsed().as_secs_f64() > o.time_limit {
                break Status::TimeLimit;
            }
            if o.final_barrier.is_some_and(|fb| mu <= fb)
                && self.barrier_error(&it, mu, &kkt) <= KAPPA_EPSILON * mu
            {
                break Status::Solved;
            }
            if self.update_barrier(&it, &mut mu, &kkt) {
                filter.clear();
            }
            vals.iter_mut()
                .zip(ws.aux.iter())
                .for_each(|(v, a)| *v = a.vals);
            m = self.measures(&it, &vals, mu);
            // The state equalities' regularisation follows the barrier parameter: loose
            // while far from the solution (steps that respect the other constraints),
            // tight near it (fast convergence of their multipliers).
            let dc = (o.delta_c * (mu / o.mu_init).powi(2)).max(o.delta_c_min);

            let (mut step, delta) =
                match self.newton_step(&it, &mut ws, &mut inertia, mu, dc, &mut tm) {
                    Ok(s) => s,
                    Err(failure) => break Status::Failed(failure),
                };
            last_shift = delta;
            last = self.line_search(
                &it,
                &m,
                &mut step,
                &mut ws,
                &mut filter,
                mu,
                dc,
                delta,
                &mut tm,
            );
            if last.accepted.is_none() {
                if m.theta_max > INFEASIBLE_VIOLATION && matches!(mode, Mode::Main) {
                    restore = true;
                    continue;
                }
                if forced_steps < MAX_FORCED_STEPS {
                    // Near feasibility (or inside a restoration): forget the quasi-Newton
                    // curvature (a secant model gone bad gives steps the barrier function
                    // does not accept), take a short step anyway and restart the filter.
                    // Bounded in number, so a problem without an acceptable step still ends.
                    ws.reset_quasi_newton();
                    filter.clear();
                    forced_steps += 1;
                    last.alpha = last.alpha_max * FORCED_STEP_FRACTION;
                    let trial = self.trial(&it, &step, last.alpha);
                    let tv = self.values(&trial);
                    let tmz = self.measures(&trial, &tv, mu);
                    last.accepted = Some((trial, tv, tmz));
                }
            }
            // A step accepted only after cutting it by 2⁵ or more says the secant model
            // predicts badly: start it over from the exact cost curvature (docs/solver.md).
            if last.accepted.is_some() && last.trials >= QN_RESET_BACKTRACKS {
                ws.reset_quasi_newton();
            }
            let Some((trial, tv, tmz)) = last.accepted.take() else {
                break Status::Failed(Failure::LineSearch {
                    violation: m.theta_max,
                });
            };
            it = self.dual_step(&it, trial, &step, last.alpha_dual, mu);
            vals = tv;
            m = tmz;
            iter += 1;
        };
        ws.retire();
        (self.finish(status, it, iter, tm, t_start), restored)
    }

    /// Restoration from `it` in [`Mode::Main`]: `None` when it made progress (`it` is then
    /// the restored iterate), else the status the solve ends with (`it` the last iterate).
    /// Inside a restoration (which does not restore itself) a stalled violation means the
    /// hard constraints cannot be met: infeasible.
    fn restoration(
        &self,
        mode: &Mode<'_, NX, NW, NC>,
        it: &mut Iterate<NX, NW, NC>,
        iter: &mut usize,
        tm: &mut Timings,
        mu: f64,
        t_start: Instant,
    ) -> Option<Status> {
        let vals = self.values(it);
        let m = self.measures(it, &vals, mu);
        if !matches!(mode, Mode::Main) {
            return Some(Status::Infeasible {
                violation: m.theta_max,
            });
        }
        let t = Instant::now();
        let secs_left = self.opts.time_limit - t_start.elapsed().as_secs_f64();
        let limits = (self.opts.max_iter - *iter, secs_left);
        let (outcome, iterations) = self.restore(it, &m, mu, limits, tm.restorations > 0);
        tm.restorations += 1;
        tm.restoration += t.elapsed().as_secs_f64();
        *iter += iterations;
        match outcome {
            Restored::Progress(r) => {
                *it = r;
                None
            }
            Restored::Stop(status, r) => {
                *it = r;
                Some(status)
            }
        }
    }

    /// Go on from a restored iterate: its measures, the point restoration began at
    /// (measures `entry`) added to the filter, the SR1 curvature forgotten.
    fn restart_after_restoration(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        filter: &mut Filter,
        entry: &Measures,
        mu: f64,
    ) -> (Vec<StageValues<NX, NE, NC>>, Measures) {
        filter.augment(entry);
        ws.reset_quasi_newton();
        let vals = self.values(it);
        let m = self.measures(it, &vals, mu);
        (vals, m)
    }

    /// The KKT error of the barrier problem at `μ` (IPOPT's `E_μ`).
    fn barrier_error(&self, it: &Iterate<NX, NW, NC>, mu: f64, kkt: &KktError) -> f64 {
        kkt.dual
            .max(kkt.primal)
            .max(self.complementarity(it, mu, kkt.s_d))
    }

    /// IPOPT's monotone barrier rule: decrease `μ` while the barrier problem at `μ` is
    /// solved to `κ_ε μ`, not below `tol/10` nor below the final barrier (if any).
    /// `true` if `μ` changed (the filter is then reset).
    fn update_barrier(&self, it: &Iterate<NX, NW, NC>, mu: &mut f64, kkt: &KktError) -> bool {
        let floor = (self.opts.tol / 10.0).max(self.opts.final_barrier.unwrap_or(0.0));
        let mut changed = false;
        while *mu > floor && self.barrier_error(it, *mu, kkt) <= KAPPA_EPSILON * *mu {
            *mu = floor.max((KAPPA_MU * *mu).min(mu.powf(THETA_MU)));
            changed = true;
        }
        changed
    }

    /// The accepted trial point with the dual step of length `alpha_dual`, each bound
    /// multiplier kept within `κ_Σ` of `μ/t`.
    fn dual_step(
        &self,
        it: &Iterate<NX, NW, NC>,
        mut trial: Iterate<NX, NW, NC>,
        step: &Step<NX, NW, NC>,
        alpha_dual: f64,
        mu: f64,
    ) -> Iterate<NX, NW, NC> {
        for k in 0..self.n {
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    let z = it.z_lo[k][i] + alpha_dual * step.dz_lo[k][i];
                    let t = trial.t_lo[k][i];
                    trial.z_lo[k][i] = z.clamp(mu / (KAPPA_SIGMA * t), KAPPA_SIGMA * mu / t);
                }
                if b.has_hi[i] > 0.0 {
                    let z = it.z_hi[k][i] + alpha_dual * step.dz_hi[k][i];
                    let t = trial.t_hi[k][i];
                    trial.z_hi[k][i] = z.clamp(mu / (KAPPA_SIGMA * t), KAPPA_SIGMA * mu / t);
                }
            }
        }
        if let Some(gs) = &self.globals {
            let (g, gd) = (&mut trial.globals, &step.globals);
            for j in 0..g.p.len() {
                if gs.has_lo[j] {
                    let t = g.p[j] - gs.g.lo[j];
                    let z = it.globals.z_lo[j] + alpha_dual * gd.dz_lo[j];
                    g.z_lo[j] = z.clamp(mu / (KAPPA_SIGMA * t), KAPPA_SIGMA * mu / t);
                }
                if gs.has_hi[j] {
                    let t = gs.g.hi[j] - g.p[j];
                    let z = it.globals.z_hi[j] + alpha_dual * gd.dz_hi[j];
                    g.z_hi[j] = z.clamp(mu / (KAPPA_SIGMA * t), KAPPA_SIGMA * mu / t);
                }
            }
        }
        trial
    }
}
