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

/// Options of the solver.
#[derive(Clone, Debug)]
pub struct IpOptions {
    /// Convergence tolerance on the scaled KKT error (IPOPT's `tol`).
    pub tol: f64,
    /// Largest allowed constraint violation at convergence.
    pub constr_viol_tol: f64,
    pub max_iter: usize,
    pub mu_init: f64,
    /// Dual regularisation of the state equalities at `μ = mu_init`; it shrinks like `μ²`
    /// down to `delta_c_min`.
    pub delta_c: f64,
    pub delta_c_min: f64,
    /// Worker threads for the stage derivatives and the line search.
    pub threads: usize,
    /// Print an iteration table on stderr.
    pub verbose: bool,
    /// Include the curvature of the dynamics and stage equalities in the Hessian
    /// (exact Newton; expensive with nested duals). Otherwise a Gauss–Newton-type
    /// Hessian: cost and inequality curvature only.
    pub exact_hessian: bool,
    /// Partitioned SR1 approximation of the dynamics' and stage equalities' curvature
    /// (used when `exact_hessian` is off).
    pub quasi_newton: bool,
    /// The SR1 update `B += r rᵀ/(sᵀr)` of a stage is skipped when `|sᵀr| ≤ sr1_skip ‖s‖‖r‖`.
    /// The update's norm is `‖r‖²/|sᵀr|`, at most `‖r‖/(sr1_skip ‖s‖)`: this bounds how far
    /// one stage's curvature may leap past what the secant observed. One stage's leap
    /// into negative curvature forces the inertia shift on all stages, so the bound is
    /// tight (1e-2, not the textbook 1e-8: measurements in `docs/ocp.md`).
    pub sr1_skip: f64,
    /// Wall-clock limit in seconds (reported as `MaxIterations`).
    pub time_limit: f64,
}

impl IpOptions {
    /// The barrier parameter to restart with from a nearby solution.
    pub fn warm_mu_init(&self) -> f64 {
        (self.mu_init * 1e-2).max(self.tol)
    }
}

impl Default for IpOptions {
    fn default() -> Self {
        IpOptions {
            tol: 1e-6,
            constr_viol_tol: 1e-8,
            max_iter: 500,
            mu_init: 0.1,
            delta_c: 1e-5,
            delta_c_min: 1e-10,
            threads: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
                .min(8),
            verbose: false,
            exact_hessian: false,
            quasi_newton: true,
            sr1_skip: 1e-2,
            time_limit: f64::INFINITY,
        }
    }
}

/// How a solve ended. Callers can tell these apart; only `Solved` carries an optimum.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    Solved,
    /// The constraint violation stopped decreasing far from zero: no feasible point near.
    Infeasible {
        violation: f64,
    },
    MaxIterations,
    /// Non-finite values or iterates growing without bound.
    Diverged,
    /// The line search or the inertia correction gave up.
    Failed(String),
}

impl Status {
    pub fn code(&self) -> &'static str {
        match self {
            Status::Solved => "solved",
            Status::Infeasible { .. } => "infeasible",
            Status::MaxIterations => "max_iterations",
            Status::Diverged => "diverged",
            Status::Failed(_) => "failed",
        }
    }
}

/// Where the time went.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    pub derivatives: f64,
    /// All of the KKT solve; of it, the Riccati recursions (`riccati`, one per inertia
    /// correction trial, counted in `factorizations`).
    pub kkt: f64,
    pub riccati: f64,
    pub factorizations: usize,
    /// Second-order correction steps tried.
    pub second_order_corrections: usize,
    pub line_search: f64,
    pub total: f64,
}

/// The primal–dual iterate.
#[derive(Clone, Debug)]
pub struct Iterate<const NX: usize, const NW: usize, const NC: usize> {
    pub x: Vec<SVector<f64, NX>>,
    pub w: Vec<SVector<f64, NW>>,
    /// `lambda[k]`: multiplier of `x_{k+1} = f_k(x_k, w_k)`.
    pub lambda: Vec<SVector<f64, NX>>,
    pub t_lo: Vec<SVector<f64, NC>>,
    pub t_hi: Vec<SVector<f64, NC>>,
    pub z_lo: Vec<SVector<f64, NC>>,
    pub z_hi: Vec<SVector<f64, NC>>,
    pub y: Vec<f64>,
}

/// The result of a solve.
#[derive(Clone, Debug)]
pub struct SolveResult<const NX: usize, const NW: usize, const NC: usize> {
    pub status: Status,
    pub iterate: Iterate<NX, NW, NC>,
    pub iterations: usize,
    pub objective: f64,
    /// Largest constraint violation (dynamics, stage equalities, inequalities, state
    /// equalities), recomputed at the returned point.
    pub max_violation: f64,
    pub timings: Timings,
}

/// Split `0..n` over `threads` workers and fill `out[k] = f(k)`.
fn par_fill<R: Send, F: Fn(usize) -> R + Sync>(out: &mut [R], threads: usize, f: F) {
    par_update(out, threads, |k, slot| *slot = f(k));
}

/// Stages per work item of the parallel loops: small enough that two threads finish
/// together (stage costs differ, e.g. where the friction saturates), large enough that
/// taking an item costs nothing against its work.
const PAR_CHUNK: usize = 32;

/// `f(k, &mut items[k])` for every `k`, on `threads` scoped threads.
fn par_update<R: Send, F: Fn(usize, &mut R) + Sync>(items: &mut [R], threads: usize, f: F) {
    let mut none: Vec<()> = vec![(); items.len()];
    par_zip(items, &mut none, threads, |k, a, _| f(k, a));
}

/// `f(k, &mut a[k], &mut b[k])` for every `k`, on `threads` scoped threads (see
/// [`par_zip3`]).
fn par_zip<A: Send, B: Send, F: Fn(usize, &mut A, &mut B) + Sync>(
    a: &mut [A],
    b: &mut [B],
    threads: usize,
    f: F,
) {
    let mut none: Vec<()> = vec![(); a.len()];
    par_zip3(a, b, &mut none, threads, |k, x, y, _| f(k, x, y));
}

/// `f(k, &mut a[k], &mut b[k], &mut c[k])` for every `k`, on `threads` scoped threads:
/// per-stage arrays filled in one pass, so that a stage's data is still in cache for the
/// later ones. Threads take chunks of [`PAR_CHUNK`] stages from a shared queue.
fn par_zip3<A: Send, B: Send, C: Send, F: Fn(usize, &mut A, &mut B, &mut C) + Sync>(
    a: &mut [A],
    b: &mut [B],
    c: &mut [C],
    threads: usize,
    f: F,
) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.len(), c.len());
    let chunks = a
        .chunks_mut(PAR_CHUNK)
        .zip(b.chunks_mut(PAR_CHUNK))
        .zip(c.chunks_mut(PAR_CHUNK))
        .enumerate();
    let queue = std::sync::Mutex::new(chunks);
    let work = || loop {
        let next = queue.lock().unwrap_or_else(|p| p.into_inner()).next();
        let Some((ci, ((pa, pb), pc))) = next else {
            break;
        };
        for (j, ((sa, sb), sc)) in pa
            .iter_mut()
            .zip(pb.iter_mut())
            .zip(pc.iter_mut())
            .enumerate()
        {
            f(ci * PAR_CHUNK + j, sa, sb, sc);
        }
    };
    if threads <= 1 {
        work();
        return;
    }
    std::thread::scope(|sc| {
        for _ in 0..threads {
            sc.spawn(work);
        }
    });
}

/// Partitioned SR1 approximation of one stage's constraint curvature
/// `∇²(λᵀf + νᵀe)`, updated from the exact Jacobians at consecutive iterates.
#[derive(Clone, Debug)]
struct QuasiNewton<const NX: usize, const NW: usize, const NE: usize> {
    bxx: SMatrix<f64, NX, NX>,
    bxw: SMatrix<f64, NX, NW>,
    bww: SMatrix<f64, NW, NW>,
    x: SVector<f64, NX>,
    w: SVector<f64, NW>,
    fx: SMatrix<f64, NX, NX>,
    fw: SMatrix<f64, NX, NW>,
    ex: SMatrix<f64, NE, NX>,
    ew: SMatrix<f64, NE, NW>,
    valid: bool,
}

impl<const NX: usize, const NW: usize, const NE: usize> QuasiNewton<NX, NW, NE> {
    fn new() -> Self {
        QuasiNewton {
            bxx: SMatrix::zeros(),
            bxw: SMatrix::zeros(),
            bww: SMatrix::zeros(),
            x: SVector::zeros(),
            w: SVector::zeros(),
            fx: SMatrix::zeros(),
            fw: SMatrix::zeros(),
            ex: SMatrix::zeros(),
            ew: SMatrix::zeros(),
            valid: false,
        }
    }

    fn reset(&mut self) {
        self.bxx.fill(0.0);
        self.bxw.fill(0.0);
        self.bww.fill(0.0);
    }

    /// SR1 update with the multipliers of the new iterate, then remember the new point.
    /// Skipped when `|sᵀr| ≤ skip ‖s‖‖r‖` ([`IpOptions::sr1_skip`]).
    #[allow(clippy::too_many_arguments)]
    fn update<const NC: usize>(
        &mut self,
        skip: f64,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        lam: &SVector<f64, NX>,
        nu: &SVector<f64, NE>,
    ) {
        if self.valid {
            let (sx, sw) = (x - self.x, w - self.w);
            let yx = (d.fx - self.fx).transpose() * lam + (d.ex - self.ex).transpose() * nu;
            let yw = (d.fw - self.fw).transpose() * lam + (d.ew - self.ew).transpose() * nu;
            let rx = yx - (self.bxx * sx + self.bxw * sw);
            let rw = yw - (self.bxw.transpose() * sx + self.bww * sw);
            let den = sx.dot(&rx) + sw.dot(&rw);
            let ns = (sx.norm_squared() + sw.norm_squared()).sqrt();
            let nr = (rx.norm_squared() + rw.norm_squared()).sqrt();
            if den.abs() > skip * ns * nr && ns > 0.0 {
                self.bxx += rx * rx.transpose() / den;
                self.bxw += rx * rw.transpose() / den;
                self.bww += rw * rw.transpose() / den;
            }
        }
        self.x = *x;
        self.w = *w;
        self.fx = d.fx;
        self.fw = d.fw;
        self.ex = d.ex;
        self.ew = d.ew;
        self.valid = true;
    }
}

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

/// How a stage's decision step follows from the condensed one: `δw = w0 + wx δx + wu δu`.
#[derive(Clone, Debug)]
struct Elimination<const NX: usize, const NW: usize, const NU: usize> {
    w0: SVector<f64, NW>,
    wx: SMatrix<f64, NW, NX>,
    wu: SMatrix<f64, NW, NU>,
}

impl<const NX: usize, const NW: usize, const NU: usize> Elimination<NX, NW, NU> {
    fn zeros() -> Self {
        Elimination {
            w0: SVector::zeros(),
            wx: SMatrix::zeros(),
            wu: SMatrix::zeros(),
        }
    }
}

struct Bounds<const NC: usize> {
    lo: SVector<f64, NC>,
    hi: SVector<f64, NC>,
    has_lo: SVector<f64, NC>,
    has_hi: SVector<f64, NC>,
}

/// The step of the primal–dual iterate.
struct Step<const NX: usize, const NW: usize, const NC: usize> {
    dx: Vec<SVector<f64, NX>>,
    dw: Vec<SVector<f64, NW>>,
    lambda: Vec<SVector<f64, NX>>,
    dt_lo: Vec<SVector<f64, NC>>,
    dt_hi: Vec<SVector<f64, NC>>,
    dz_lo: Vec<SVector<f64, NC>>,
    dz_hi: Vec<SVector<f64, NC>>,
    y: Vec<f64>,
}

/// Residual measures at an iterate.
#[derive(Clone, Copy, Debug)]
struct Measures {
    theta: f64,     // Σ |constraint residual| (filter)
    theta_max: f64, // max |constraint residual|
    objective: f64,
    barrier: f64, // objective − μ Σ ln t
}

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

    /// Condense stage `k`: eliminate the dependent decisions and the inequality slacks,
    /// into the solver's buffers `lq`, `el` (written in place: returning the 5 kB pair and
    /// moving it there was part of the memmove share, see `condense_and_sweep`).
    #[allow(clippy::too_many_arguments)]
    fn condense(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        qn: Option<&QuasiNewton<NX, NW, NE>>,
        mu: f64,
        dc: f64,
        lq: &mut LqStage<NX, NU>,
        el: &mut Elimination<NX, NW, NU>,
    ) -> Result<(), String> {
        let b = &self.bounds[k];
        // Inequalities: Σ and the barrier gradient term.
        let mut sigma = SVector::<f64, NC>::zeros();
        let mut bc = SVector::<f64, NC>::zeros();
        for i in 0..NC {
            if b.has_lo[i] > 0.0 {
                let s = it.z_lo[k][i] / it.t_lo[k][i];
                let r = d.c[i] - b.lo[i] - it.t_lo[k][i];
                sigma[i] += s;
                bc[i] -= mu / it.t_lo[k][i] - s * r;
            }
            if b.has_hi[i] > 0.0 {
                let s = it.z_hi[k][i] / it.t_hi[k][i];
                let r = b.hi[i] - d.c[i] - it.t_hi[k][i];
                sigma[i] += s;
                bc[i] += mu / it.t_hi[k][i] - s * r;
            }
        }
        let cx_s = SMatrix::<f64, NX, NC>::from_fn(|i, j| d.cx[(j, i)] * sigma[j]);
        let cw_s = SMatrix::<f64, NW, NC>::from_fn(|i, j| d.cw[(j, i)] * sigma[j]);
        let (mut hxx0, mut hxw0, mut hww0) = (d.hxx, d.hxw, d.hww);
        if let Some(q) = qn {
            hxx0 += q.bxx;
            hxw0 += q.bxw;
            hww0 += q.bww;
        }
        let hxx = hxx0 + cx_s * d.cx;
        let hxw = hxw0 + cx_s * d.cw;
        let hww = hww0 + cw_s * d.cw;
        let gx = d.gx + d.cx.transpose() * bc;
        let gw = d.gw + d.cw.transpose() * bc;

        // δw = w0 + wx δx + wu δu, with δv from the linearised stage equality.
        let Elimination { w0, wx, wu } = el;
        wx.fill(0.0);
        wu.fill(0.0);
        w0.fill(0.0);
        for i in 0..NU {
            wu[(NE + i, i)] = 1.0;
        }
        if NE > 0 {
            let ev: SMatrix<f64, NE, NE> = d.ew.fixed_columns::<NE>(0).into_owned();
            let eu: SMatrix<f64, NE, NU> = d.ew.fixed_columns::<NU>(NE).into_owned();
            let lu = Lu::new(&ev).ok_or_else(|| {
                format!("stage {k}: the stage equality is singular in its dependent decisions")
            })?;
            let dx = lu.solve_columns(&(-d.ex));
            let du = lu.solve_columns(&(-eu));
            let d0 = lu.solve(&(-d.e));
            wx.fixed_rows_mut::<NE>(0).copy_from(&dx);
            wu.fixed_rows_mut::<NE>(0).copy_from(&du);
            w0.fixed_rows_mut::<NE>(0).copy_from(&d0);
        }
        let (w0, wx, wu) = (&*w0, &*wx, &*wu);
        // Rows `NE..` of `wx` and `w0` are zero (the free inputs do not depend on δx): the
        // products with them take only their first `NE` rows (the skipped terms were exact
        // zeros, and the kept ones are summed in the same order).
        let dx = wx.fixed_rows::<NE>(0);
        let d0 = w0.fixed_rows::<NE>(0);
        let hww_v = hww.fixed_columns::<NE>(0);
        let hww_wx = hww_v * dx;
        let hww_wu = hww * wu;
        let hww_w0 = hww_v * d0;
        let hxw_wx = hxw.fixed_columns::<NE>(0) * dx;
        let dx_t = dx.transpose();
        lq.q_mat = hxx + hxw_wx + hxw_wx.transpose() + dx_t * hww_wx.fixed_rows::<NE>(0);
        lq.s_mat = hxw * wu + dx_t * hww_wu.fixed_rows::<NE>(0);
        lq.r_mat = wu.transpose() * hww_wu;
        lq.q = gx
            + dx_t * gw.fixed_rows::<NE>(0)
            + hxw.fixed_columns::<NE>(0) * d0
            + dx_t * hww_w0.fixed_rows::<NE>(0);
        lq.r = wu.transpose() * (gw + hww_w0);
        self.add_state_equalities(k, it, dc, &mut lq.q_mat, &mut lq.q);
        let fw_v = d.fw.fixed_columns::<NE>(0);
        lq.a = d.fx + fw_v * dx;
        lq.b = d.fw * wu;
        lq.c = d.f + fw_v * d0 - it.x[k + 1];
        Ok(())
    }

    /// The quadratic terms of the state equalities at stage `k`.
    fn add_state_equalities(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        dc: f64,
        q_mat: &mut SMatrix<f64, NX, NX>,
        q: &mut SVector<f64, NX>,
    ) {
        for &j in &self.eqs_at[k] {
            let e = &self.eqs[j];
            q_mat[(e.index, e.index)] += 1.0 / dc;
            q[e.index] += it.y[j] + (it.x[k][e.index] - e.value) / dc;
        }
    }
}

/// One stage's part of the KKT error: its dual and primal errors, `Σ|ν|` (if the stage
/// equality's multiplier estimate exists) and `Σ|λ| + Σz`.
#[derive(Clone, Copy, Debug, Default)]
struct StageKkt {
    dual: f64,
    primal: f64,
    nu_sum: Option<f64>,
    others: f64,
}

/// What the derivative pass leaves per stage besides the derivatives.
#[derive(Clone, Copy, Debug)]
struct StageAux<const NX: usize, const NE: usize, const NC: usize> {
    kkt: StageKkt,
    vals: StageValues<NX, NE, NC>,
}

impl<const NX: usize, const NE: usize, const NC: usize> StageAux<NX, NE, NC> {
    fn zeros() -> Self {
        StageAux {
            kkt: StageKkt::default(),
            vals: StageValues {
                f: SVector::zeros(),
                e: SVector::zeros(),
                cost: 0.0,
                c: SVector::zeros(),
            },
        }
    }
}

/// KKT errors at an iterate: the scaled dual infeasibility, the largest constraint
/// violation, and IPOPT's dual scaling `s_d` (for the complementarity).
#[derive(Clone, Copy, Debug)]
struct KktError {
    dual: f64,
    primal: f64,
    s_d: f64,
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
    /// Stage `k`'s part of the KKT error at the iterate, from its derivatives `d` (with
    /// `d.nu` set): computed in the derivative pass, while `d` is still in cache.
    fn kkt_stage(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
    ) -> StageKkt {
        let zeta = it.z_hi[k] - it.z_lo[k];
        let lam = &it.lambda[k];
        let mut gx = d.gx + d.fx.transpose() * lam + d.cx.transpose() * zeta;
        if k > 0 {
            gx -= it.lambda[k - 1]; // x_k's part in the dynamics row of stage k − 1
        }
        let mut gw = d.gw + d.fw.transpose() * lam + d.cw.transpose() * zeta;
        let nu_sum = d.nu.map(|nu| {
            gx += d.ex.transpose() * nu;
            gw += d.ew.transpose() * nu;
            nu.abs().sum()
        });
        // A state equality fixes one component: its multiplier estimate zeroes that
        // component of the gradient (the iterate's y carries the round-off of the
        // regularised update, amplified by 1/δ_c).
        for &j in &self.eqs_at[k] {
            gx[self.eqs[j].index] = 0.0;
        }
        let dual = if k > 0 { gx.amax() } else { 0.0 }.max(gw.amax());
        let mut primal = (d.f - it.x[k + 1]).amax().max(d.e.amax());
        let b = &self.bounds[k];
        for i in 0..NC {
            if b.has_lo[i] > 0.0 {
                primal = primal.max((d.c[i] - b.lo[i] - it.t_lo[k][i]).abs());
            }
            if b.has_hi[i] > 0.0 {
                primal = primal.max((b.hi[i] - d.c[i] - it.t_hi[k][i]).abs());
            }
        }
        let others = lam.abs().sum() + it.z_lo[k].sum() + it.z_hi[k].sum();
        StageKkt {
            dual,
            primal,
            nu_sum,
            others,
        }
    }

    /// Dual and primal errors at the current iterate (independent of μ), from the stages'
    /// parts ([`Solver::kkt_stage`]) summed in stage order.
    fn kkt_error(
        &self,
        it: &Iterate<NX, NW, NC>,
        per_stage: impl Iterator<Item = StageKkt>,
    ) -> KktError {
        let n = self.n;
        let mut dual = 0.0f64;
        let mut mult_sum = 0.0;
        let mut mult_cnt = 0.0;
        let mut primal = 0.0f64;
        for StageKkt {
            dual: d_k,
            primal: p_k,
            nu_sum,
            others,
        } in per_stage
        {
            if let Some(v) = nu_sum {
                mult_sum += v;
                mult_cnt += NE as f64;
            }
            dual = dual.max(d_k);
            mult_sum += others;
            mult_cnt += (NX + 2 * NC) as f64;
            primal = primal.max(p_k);
        }
        // x_N's gradient: its part in the dynamics row of stage N − 1.
        let mut gx_n = if n > 0 {
            -it.lambda[n - 1]
        } else {
            SVector::zeros()
        };
        for &j in &self.eqs_at[n] {
            gx_n[self.eqs[j].index] = 0.0;
        }
        dual = dual.max(gx_n.amax());
        for (j, e) in self.eqs.iter().enumerate() {
            primal = primal.max((it.x[e.stage][e.index] - e.value).abs());
            mult_sum += it.y[j].abs();
            mult_cnt += 1.0;
        }
        let s_max = 100.0;
        let s_d = (mult_sum / mult_cnt.max(1.0)).max(s_max) / s_max;
        KktError {
            dual: dual / s_d,
            primal,
            s_d,
        }
    }

    /// The largest `|t z − μ|` over all bounded sides, scaled by `s_d`.
    fn complementarity(&self, it: &Iterate<NX, NW, NC>, mu: f64, s_d: f64) -> f64 {
        let mut compl = 0.0f64;
        for k in 0..self.n {
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    compl = compl.max((it.t_lo[k][i] * it.z_lo[k][i] - mu).abs());
                }
                if b.has_hi[i] > 0.0 {
                    compl = compl.max((it.t_hi[k][i] * it.z_hi[k][i] - mu).abs());
                }
            }
        }
        compl / s_d
    }

    /// Solve from `start`.
    pub fn solve(&self, start: Iterate<NX, NW, NC>) -> SolveResult<NX, NW, NC> {
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

    /// The largest steps `(α_p, α_d)` in `(0, 1]` that keep the slacks and the bound
    /// multipliers a fraction `τ` away from zero.
    fn max_step(&self, it: &Iterate<NX, NW, NC>, step: &Step<NX, NW, NC>, tau: f64) -> (f64, f64) {
        let mut amax_p: f64 = 1.0;
        let mut amax_d: f64 = 1.0;
        for k in 0..self.n {
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    if step.dt_lo[k][i] < 0.0 {
                        amax_p = amax_p.min(-tau * it.t_lo[k][i] / step.dt_lo[k][i]);
                    }
                    if step.dz_lo[k][i] < 0.0 {
                        amax_d = amax_d.min(-tau * it.z_lo[k][i] / step.dz_lo[k][i]);
                    }
                }
                if b.has_hi[i] > 0.0 {
                    if step.dt_hi[k][i] < 0.0 {
                        amax_p = amax_p.min(-tau * it.t_hi[k][i] / step.dt_hi[k][i]);
                    }
                    if step.dz_hi[k][i] < 0.0 {
                        amax_d = amax_d.min(-tau * it.z_hi[k][i] / step.dz_hi[k][i]);
                    }
                }
            }
        }
        (amax_p, amax_d)
    }

    /// Every stage condensed by `stage(k)` into `lq[k]`, `elim[k]`, with the Riccati
    /// backward sweep (primal shift 0) run behind the condensing: chunks of stages are
    /// condensed from the last one down, in parallel, and one thread sweeps each chunk as
    /// soon as it and every later one are done (condensing a chunk itself when the next one
    /// is not). The serial sweep so overlaps the parallel condensing instead of following
    /// it; every stage sees the same operations in the same order as
    /// condense-then-[`solve_lq`], so the result is bitwise the same.
    ///
    /// `Err` is the condensing error of the first stage that fails; `Ok` carries the sweep's
    /// outcome (a stage whose `H_uu` is not positive definite stops it; the condensing
    /// still completes, for the caller's inertia correction) and the seconds spent in it.
    #[allow(clippy::type_complexity)]
    fn condense_and_sweep<F>(
        &self,
        lq: &mut [LqStage<NX, NU>],
        elim: &mut [Elimination<NX, NW, NU>],
        sweep: &mut BackwardSweep<NX, NU>,
        stage: F,
    ) -> Result<(Result<(), RiccatiError>, f64), String>
    where
        F: Fn(usize, &mut LqStage<NX, NU>, &mut Elimination<NX, NW, NU>) -> Result<(), String>
            + Sync,
    {
        let failed = std::sync::Mutex::new(None::<(usize, String)>);
        let condense_chunk =
            |ci: usize, pl: &mut [LqStage<NX, NU>], pe: &mut [Elimination<NX, NW, NU>]| {
                let mut ok = true;
                for (j, (l, e)) in pl.iter_mut().zip(pe.iter_mut()).enumerate() {
                    let k = ci * PAR_CHUNK + j;
                    if let Err(msg) = stage(k, l, e) {
                        ok = false;
                        let mut f = failed.lock().unwrap_or_else(|p| p.into_inner());
                        if f.as_ref().is_none_or(|(j, _)| k < *j) {
                            *f = Some((k, msg));
                        }
                    }
                }
                ok
            };
        let mut sweep_result = Ok(());
        let mut sweep_time = 0.0;
        // Sweep one condensed chunk (all of its stages, last first).
        let mut sweep_chunk =
            |ci: usize, stages: &[LqStage<NX, NU>], result: &mut Result<(), RiccatiError>| {
                if result.is_err() {
                    return;
                }
                let t = Instant::now();
                for (j, st) in stages.iter().enumerate().rev() {
                    if let Err(e) = sweep.step(ci * PAR_CHUNK + j, st) {
                        *result = Err(e);
                        break;
                    }
                }
                sweep_time += t.elapsed().as_secs_f64();
            };
        let n_chunks = lq.len().div_ceil(PAR_CHUNK);
        let chunks = lq
            .chunks_mut(PAR_CHUNK)
            .zip(elim.chunks_mut(PAR_CHUNK))
            .enumerate()
            .rev();
        if self.opts.threads <= 1 {
            // Each chunk swept right after it is condensed (still in cache), until one fails.
            let mut sweeping = true;
            for (ci, (pl, pe)) in chunks {
                sweeping &= condense_chunk(ci, pl, pe);
                if sweeping {
                    sweep_chunk(ci, pl, &mut sweep_result);
                }
            }
        } else {
            let queue = std::sync::Mutex::new(chunks);
            let take = || queue.lock().unwrap_or_else(|p| p.into_inner()).next();
            // Condensed chunks travel to the sweeping thread by channel; `None` marks a
            // chunk whose condensing failed.
            let (tx, rx) = std::sync::mpsc::channel::<(usize, Option<&[LqStage<NX, NU>]>)>();
            std::thread::scope(|sc| {
                for _ in 1..self.opts.threads {
                    let tx = tx.clone();
                    let (take, condense_chunk) = (&take, &condense_chunk);
                    sc.spawn(move || {
                        while let Some((ci, (pl, pe))) = take() {
                            let ok = condense_chunk(ci, pl, pe);
                            let pl: &[LqStage<NX, NU>] = pl;
                            if tx.send((ci, ok.then_some(pl))).is_err() {
                                break;
                            }
                        }
                    });
                }
                drop(tx);
                // This thread: sweep the next chunk when it is ready, otherwise condense
                // one (the queue hands them out last first, so usually the next one).
                let mut ready: Vec<Option<Option<&[LqStage<NX, NU>]>>> = vec![None; n_chunks];
                let mut next = n_chunks;
                // A chunk that failed to condense stops the sweep (its error is reported).
                let mut sweeping = true;
                while next > 0 {
                    if let Some(chunk) = ready[next - 1].take() {
                        match chunk {
                            Some(stages) if sweeping => {
                                sweep_chunk(next - 1, stages, &mut sweep_result)
                            }
                            _ => sweeping = false,
                        }
                        next -= 1;
                    } else if let Ok((ci, chunk)) = rx.try_recv() {
                        ready[ci] = Some(chunk);
                    } else if let Some((ci, (pl, pe))) = take() {
                        let ok = condense_chunk(ci, pl, pe);
                        let pl: &[LqStage<NX, NU>] = pl;
                        ready[ci] = Some(ok.then_some(pl));
                    } else {
                        match rx.recv() {
                            Ok((ci, chunk)) => ready[ci] = Some(chunk),
                            Err(_) => break,
                        }
                    }
                }
            });
        }
        match failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some((_, msg)) => Err(msg),
            None => Ok((sweep_result, sweep_time)),
        }
    }

    /// The second-order correction step: the KKT system of the iterate (same curvature,
    /// same inertia shift `delta`) with the residuals of the dynamics and the stage
    /// equalities replaced by `α r(x) + r(x_trial)`, condensed into the iteration's buffers
    /// `lq`, `elim` (its own step is already recovered from them). `None` if it cannot be
    /// solved.
    #[allow(clippy::too_many_arguments)]
    fn second_order_correction(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        qn: &[QuasiNewton<NX, NW, NE>],
        trial_vals: &[StageValues<NX, NE, NC>],
        trial: &Iterate<NX, NW, NC>,
        alpha: f64,
        mu: f64,
        dc: f64,
        delta: f64,
        lq: &mut [LqStage<NX, NU>],
        elim: &mut [Elimination<NX, NW, NU>],
    ) -> Option<Step<NX, NW, NC>> {
        let n = self.n;
        let (mut q_n, mut q_vec_n) = (SMatrix::zeros(), SVector::zeros());
        self.add_state_equalities(n, it, dc, &mut q_n, &mut q_vec_n);
        let mut sweep = BackwardSweep::new(n, &q_n, &q_vec_n, delta);
        let (swept, _) = self
            .condense_and_sweep(lq, elim, &mut sweep, |k, l, e| {
                let mut d = ders[k].clone();
                let r = (d.f - it.x[k + 1]) * alpha + (trial_vals[k].f - trial.x[k + 1]);
                d.f = it.x[k + 1] + r;
                d.e = d.e * alpha + trial_vals[k].e;
                self.condense(k, it, &d, qn.get(k), mu, dc, l, e)
            })
            .ok()?;
        swept.ok()?;
        let sol = sweep.forward(lq, &SVector::zeros());
        Some(self.recover(it, ders, elim, sol, mu, dc))
    }

    /// If the problem declares its cost and inequalities affine in the state, check it at
    /// the first, middle and last stage of the start (with unit inequality multipliers).
    fn check_affine_declaration(&self, it: &Iterate<NX, NW, NC>) -> Option<String> {
        if !self.p.affine_in_state() || self.n == 0 {
            return None;
        }
        let ones = SVector::<f64, NC>::repeat(1.0);
        for k in [0, self.n / 2, self.n - 1] {
            let (hxx, hxw) =
                crate::derivatives::state_curvature(self.p, k, &it.x[k], &it.w[k], &ones);
            let worst = hxx.amax().max(hxw.amax());
            if worst != 0.0 {
                return Some(format!(
                    "the problem declares its cost and inequalities affine in the state, but at \
                     stage {k} their state Hessian has an entry {worst:.3e}"
                ));
            }
        }
        None
    }

    fn finish(
        &self,
        status: Status,
        it: Iterate<NX, NW, NC>,
        iterations: usize,
        mut tm: Timings,
        t_start: Instant,
    ) -> SolveResult<NX, NW, NC> {
        tm.total = t_start.elapsed().as_secs_f64();
        let objective = (0..self.n)
            .map(|k| self.p.cost(k, &it.x[k], &it.w[k]))
            .sum();
        let max_violation = self.max_violation(&it.x, &it.w);
        SolveResult {
            status,
            iterate: it,
            iterations,
            objective,
            max_violation,
            timings: tm,
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn recover(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        elim: &[Elimination<NX, NW, NU>],
        sol: LqSolution<NX, NU>,
        mu: f64,
        dc: f64,
    ) -> Step<NX, NW, NC> {
        let LqSolution {
            x: dx,
            u: du,
            lambda,
        } = sol;
        let n = self.n;
        // Per stage (δw, δt_lo, δt_hi, δz_lo, δz_hi), in parallel.
        type StageStep<const NW: usize, const NC: usize> =
            (SVector<f64, NW>, [SVector<f64, NC>; 4]);
        let mut per_stage: Vec<StageStep<NW, NC>> =
            vec![(SVector::zeros(), [SVector::zeros(); 4]); n];
        par_update(
            &mut per_stage,
            self.opts.threads,
            |k, (dwk, [dt_lo, dt_hi, dz_lo, dz_hi])| {
                let c = &elim[k];
                *dwk = c.w0 + c.wx * dx[k] + c.wu * du[k];
                let d = &ders[k];
                let cd = d.cx * dx[k] + d.cw * *dwk;
                let b = &self.bounds[k];
                for i in 0..NC {
                    if b.has_lo[i] > 0.0 {
                        let r = d.c[i] - b.lo[i] - it.t_lo[k][i];
                        dt_lo[i] = cd[i] + r;
                        dz_lo[i] = mu / it.t_lo[k][i]
                            - it.z_lo[k][i]
                            - it.z_lo[k][i] / it.t_lo[k][i] * dt_lo[i];
                    }
                    if b.has_hi[i] > 0.0 {
                        let r = b.hi[i] - d.c[i] - it.t_hi[k][i];
                        dt_hi[i] = r - cd[i];
                        dz_hi[i] = mu / it.t_hi[k][i]
                            - it.z_hi[k][i]
                            - it.z_hi[k][i] / it.t_hi[k][i] * dt_hi[i];
                    }
                }
            },
        );
        let dw = per_stage.iter().map(|s| s.0).collect();
        let dt_lo = per_stage.iter().map(|s| s.1[0]).collect();
        let dt_hi = per_stage.iter().map(|s| s.1[1]).collect();
        let dz_lo = per_stage.iter().map(|s| s.1[2]).collect();
        let dz_hi = per_stage.iter().map(|s| s.1[3]).collect();
        let y = self
            .eqs
            .iter()
            .enumerate()
            .map(|(j, e)| it.y[j] + (dx[e.stage][e.index] + it.x[e.stage][e.index] - e.value) / dc)
            .collect();
        Step {
            dx,
            dw,
            lambda,
            dt_lo,
            dt_hi,
            dz_lo,
            dz_hi,
            y,
        }
    }

    fn trial(&self, it: &Iterate<NX, NW, NC>, s: &Step<NX, NW, NC>, a: f64) -> Iterate<NX, NW, NC> {
        let n = self.n;
        Iterate {
            x: (0..=n).map(|k| it.x[k] + s.dx[k] * a).collect(),
            w: (0..n).map(|k| it.w[k] + s.dw[k] * a).collect(),
            lambda: (0..n)
                .map(|k| it.lambda[k] + (s.lambda[k] - it.lambda[k]) * a)
                .collect(),
            t_lo: (0..n).map(|k| it.t_lo[k] + s.dt_lo[k] * a).collect(),
            t_hi: (0..n).map(|k| it.t_hi[k] + s.dt_hi[k] * a).collect(),
            z_lo: it.z_lo.clone(),
            z_hi: it.z_hi.clone(),
            y: it
                .y
                .iter()
                .zip(&s.y)
                .map(|(y0, y1)| y0 + (y1 - y0) * a)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Der = StageDerivatives<3, 2, 1, 1>;

    /// A deterministic pseudo-random matrix with entries in [−0.5, 0.5).
    fn mat<const R: usize, const C: usize>(seed: &mut u64) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| crate::test_rng::uniform(seed))
    }

    /// Two stage Jacobians, points and multipliers with `cos∠(s, y) = cos` (y the
    /// multiplier-weighted change of the Jacobians, `B = 0` before, so `r = y`).
    fn secant_pair(cos: f64) -> (QuasiNewton<3, 2, 1>, Der, SVector<f64, 3>, SVector<f64, 3>) {
        let mut seed = 7u64;
        let (mut d0, mut d1) = (Der::zeros(), Der::zeros());
        (d0.fx, d0.fw, d0.ex, d0.ew) = (
            mat(&mut seed),
            mat(&mut seed),
            mat(&mut seed),
            mat(&mut seed),
        );
        (d1.fx, d1.fw, d1.ex, d1.ew) = (d0.fx, d0.fw, d0.ex, d0.ew);
        // Only f_x changes, by M: y = (Mᵀλ, 0) and sᵀy = (M s_x)ᵀλ. λ is built from the
        // unit vector along M s_x and one orthogonal to it, at the requested angle.
        let m: SMatrix<f64, 3, 3> = mat(&mut seed);
        d1.fx += m;
        let (x0, w0) = (mat::<3, 1>(&mut seed), mat::<2, 1>(&mut seed));
        let x1 = x0 + mat::<3, 1>(&mut seed);
        let sx = x1 - x0;
        let a = (m * sx).normalize();
        let o = {
            let t = mat::<3, 1>(&mut seed);
            (t - a * a.dot(&t)).normalize()
        };
        // sᵀy = (M s_x)ᵀλ and ‖y‖ = ‖Mᵀλ‖: pick λ's angle to M s_x by bisection on cos.
        let cos_of = |phi: f64| {
            let lam = a * phi.cos() + o * phi.sin();
            sx.dot(&(m.transpose() * lam)) / (sx.norm() * (m.transpose() * lam).norm())
        };
        assert!(cos_of(0.0) > cos && cos_of(std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if cos_of(mid) > cos {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let lam = a * lo.cos() + o * lo.sin();
        let mut q = QuasiNewton::<3, 2, 1>::new();
        q.update(1e-8, &x0, &w0, &d0, &lam, &SVector::zeros());
        (q, d1, x1, lam)
    }

    /// An applied SR1 update satisfies the secant equation `B⁺ s = y`.
    #[test]
    fn sr1_update_satisfies_the_secant_equation() {
        let (mut q, d1, x1, lam) = secant_pair(0.05);
        let w1 = q.w;
        let (sx, y) = (x1 - q.x, (d1.fx - q.fx).transpose() * lam);
        q.update(1e-2, &x1, &w1, &d1, &lam, &SVector::zeros());
        let bs = q.bxx * sx; // s_w = 0
        let err = (bs - y).amax().max((q.bxw.transpose() * sx).amax());
        // One rank-one product and one division: round-off of a few ε; bound ≈ 500 ε.
        assert!(err < 1e-13 * y.amax().max(1.0), "B s − y = {err:e}");
    }

    /// Below the skip threshold the update is skipped; above it, it is applied.
    #[test]
    fn sr1_update_skipped_below_threshold() {
        for (cos, skip, applied) in [(5e-3, 1e-2, false), (5e-3, 1e-8, true), (2e-2, 1e-2, true)] {
            let (mut q, d1, x1, lam) = secant_pair(cos);
            let w1 = q.w;
            q.update(skip, &x1, &w1, &d1, &lam, &SVector::zeros());
            assert_eq!(q.bxx.amax() > 0.0, applied, "cos {cos}, threshold {skip}");
        }
    }
}
