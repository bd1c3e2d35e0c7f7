//! The primal–dual interior point for [`StageQp`]s: Mehrotra's predictor–corrector, its
//! Newton systems by the Riccati recursion of `newton.rs`, cold or warm started.

use super::certificates::{dual_infeasible, primal_infeasible};
use super::iterate::{residuals, Measures, Side, StageIterate, StageResidual, StageSides, SIGN};
use super::newton::{factor, newton_residual, solve, StageFactor, Target};
use super::problem::StageQp;
use super::settings::QpSettings;
use super::solution::{QpInfo, QpSolution, QpStatus, WarmStart};
use nalgebra::SVector;
use std::time::Instant;

/// The solver with its workspace: one per thread, reused from solve to solve (its buffers
/// grow to the longest horizon seen and are not freed).
#[derive(Clone, Debug)]
pub struct QpSolver<const NX: usize, const NU: usize, const NC: usize> {
    settings: QpSettings,
    sides: Vec<StageSides<NC>>,
    it: Vec<StageIterate<NX, NU, NC>>,
    res: Vec<StageResidual<NX, NU, NC>>,
    fac: Vec<StageFactor<NX, NU, NC>>,
    dir: Vec<StageIterate<NX, NU, NC>>,
    affine: Vec<StageIterate<NX, NU, NC>>,
    /// The Newton system's residual at `dir` and the refinement's correction.
    refine_res: Vec<StageResidual<NX, NU, NC>>,
    correction: Vec<StageIterate<NX, NU, NC>>,
}

/// The problem's scales for the termination test: `dual` the largest gradient entry or
/// soft price, `primal` the largest finite bound, dynamics offset or initial state
/// entry, each at least 1.
struct Scales {
    dual: f64,
    primal: f64,
}

impl<const NX: usize, const NU: usize, const NC: usize> QpSolver<NX, NU, NC> {
    /// A solver with `settings`.
    pub fn new(settings: QpSettings) -> Self {
        QpSolver {
            settings,
            sides: Vec::new(),
            it: Vec::new(),
            res: Vec::new(),
            fac: Vec::new(),
            dir: Vec::new(),
            affine: Vec::new(),
            refine_res: Vec::new(),
            correction: Vec::new(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &QpSettings {
        &self.settings
    }

    /// Solve `qp` from a cold start: inputs zero, the states rolled out, slacks and
    /// multipliers centred at [`QpSettings::start_mu`] (`start_slacks`).
    pub fn solve(&mut self, qp: &StageQp<NX, NU, NC>) -> QpSolution<NX, NU, NC> {
        let start = Instant::now();
        self.prepare(qp);
        for ik in self.it.iter_mut() {
            *ik = StageIterate::zeros();
        }
        self.start_slacks(qp, 1.0, false);
        self.run(qp, start, false)
    }

    /// Solve `qp` from `warm` (e.g. the previous sample's [`QpSolution::shifted`]): its
    /// inputs and multipliers, the states rolled out from `qp`'s `x_0`, the slacks those
    /// states give; slacks and multipliers raised to at least
    /// [`QpSettings::warm_floor`]. A start of another horizon is ignored (a cold start).
    pub fn solve_warm(
        &mut self,
        qp: &StageQp<NX, NU, NC>,
        warm: &WarmStart<NX, NU, NC>,
    ) -> QpSolution<NX, NU, NC> {
        if warm.horizon() != qp.horizon() {
            return self.solve(qp);
        }
        let start = Instant::now();
        self.prepare(qp);
        self.it.clone_from_slice(&warm.iterate);
        self.start_slacks(qp, self.settings.warm_floor, true);
        self.run(qp, start, true)
    }

    /// The workspace sized for `qp` and its rows' sides.
    fn prepare(&mut self, qp: &StageQp<NX, NU, NC>) {
        let n = qp.horizon() + 1;
        self.sides.clear();
        self.sides
            .extend((0..n).map(|k| StageSides::of(qp.rows(k))));
        self.it.resize(n, StageIterate::zeros());
        self.res.resize(n, StageResidual::zeros());
        self.fac.resize(n, StageFactor::zeros());
        self.dir.resize(n, StageIterate::zeros());
        self.affine.resize(n, StageIterate::zeros());
        self.refine_res.resize(n, StageResidual::zeros());
        self.correction.resize(n, StageIterate::zeros());
    }

    /// The states rolled out from the inputs, then each present side's slack, violation
    /// and multipliers. Cold, centred at `μ_0 = start_mu`: a hard side's slack is the
    /// row's distance to its bound raised to 1 and its multiplier `μ_0/t`; a soft side
    /// splits its price between `λ` and `ν` (`r_s = 0`), its violation is the rollout's
    /// plus `μ_0/ν` and its slack at least `μ_0/λ`. Warm (`floor` = [`QpSettings::warm_floor`]):
    /// the start's multipliers and violations raised to `floor`, the slacks the rows'
    /// distances (violation included) raised to `floor`.
    fn start_slacks(&mut self, qp: &StageQp<NX, NU, NC>, floor: f64, warm: bool) {
        let n = qp.horizon();
        let mu0 = self.settings.start_mu;
        self.it[0].x = *qp.x0();
        for k in 0..n {
            let st = &qp.stages()[k];
            self.it[k + 1].x = st.a * self.it[k].x + st.b * self.it[k].u + st.c;
        }
        self.it[n].u = SVector::zeros();
        self.it[n].pi = SVector::zeros();
        for k in 0..=n {
            let rows = qp.rows(k);
            let ik = &mut self.it[k];
            let mut z = rows.d * ik.x;
            if k < n {
                z += rows.e * ik.u;
            }
            let sd = &self.sides[k];
            for j in 0..2 {
                for i in 0..NC {
                    let gap = sd.b[j][i] - SIGN[j] * z[i];
                    let (t, lam, s, nu) = match (sd.side[j][i], warm) {
                        (Side::Absent, _) => (1.0, 0.0, 0.0, 0.0),
                        (Side::Hard, false) => {
                            let t = gap.max(1.0);
                            (t, mu0 / t, 0.0, 0.0)
                        }
                        (Side::Soft { l1, l2 }, false) => centred_soft_side(gap, l1, l2, mu0),
                        (Side::Hard, true) => (gap.max(floor), ik.lam[j][i].max(floor), 0.0, 0.0),
                        (Side::Soft { .. }, true) => {
                            let s = ik.s[j][i].max(floor);
                            let (lam, nu) = (ik.lam[j][i].max(floor), ik.nu[j][i].max(floor));
                            ((gap + s).max(floor), lam, s, nu)
                        }
                    };
                    ik.t[j][i] = t;
                    ik.lam[j][i] = lam;
                    ik.s[j][i] = s;
                    ik.nu[j][i] = nu;
                }
            }
        }
    }

    fn scales(&self, qp: &StageQp<NX, NU, NC>) -> Scales {
        let mut dual = qp.terminal().q_vec.amax();
        let mut primal = qp.x0().amax();
        for st in qp.stages() {
            dual = dual.max(st.q_vec.amax()).max(st.r_vec.amax());
            primal = primal.max(st.c.amax());
        }
        for sd in &self.sides {
            for j in 0..2 {
                for i in 0..NC {
                    match sd.side[j][i] {
                        Side::Absent => continue,
                        Side::Soft { l1, .. } => dual = dual.max(l1),
                        Side::Hard => {}
                    }
                    primal = primal.max(sd.b[j][i].abs());
                }
            }
        }
        Scales {
            dual: dual.max(1.0),
            primal: primal.max(1.0),
        }
    }

    /// The predictor–corrector iterations from the start in `self.it`.
    fn run(
        &mut self,
        qp: &StageQp<NX, NU, NC>,
        start: Instant,
        warm: bool,
    ) -> QpSolution<NX, NU, NC> {
        let scales = self.scales(qp);
        let tol = self.settings.tol;
        let pairs: usize = self.sides.iter().map(StageSides::pairs).sum();
        let mut iterations = 0;
        // Every stop comes before a step: the residuals at the top of the last pass are
        // those of the returned iterate.
        let (status, m) = loop {
            let m = residuals(qp, &self.sides, &self.it, &mut self.res);
            if !(m.stationarity.is_finite() && m.primal.is_finite() && m.mu.is_finite()) {
                break (QpStatus::NumericalError, m);
            }
            if converged(&m, &scales, pairs, tol) {
                break (QpStatus::Solved, m);
            }
            if iterations == self.settings.max_iter {
                break (self.diagnose(qp, QpStatus::MaxIterations), m);
            }
            if self.hard_multiplier_max() > 1e8 * scales.dual
                && primal_infeasible(qp, &self.sides, &self.it, self.settings.certificate_tol)
            {
                break (QpStatus::PrimalInfeasible, m);
            }
            iterations += 1;
            if factor(
                qp,
                &self.sides,
                &self.it,
                self.settings.regularisation,
                &mut self.fac,
            )
            .is_err()
            {
                break (QpStatus::NumericalError, m);
            }
            let (it, res, sides) = (&self.it, &self.res, &self.sides);
            solve(
                qp,
                sides,
                it,
                res,
                &mut self.fac,
                &Target::Affine,
                &mut self.affine,
            );
            let alpha_aff = max_step(it, &self.affine);
            let sigma_mu = match pairs {
                0 => 0.0,
                _ => {
                    let mu_aff = complementarity(it, &self.affine, alpha_aff) / pairs as f64;
                    (mu_aff / m.mu).powi(3) * m.mu
                }
            };
            let target = Target::Corrector {
                affine: &self.affine,
                sigma_mu,
            };
            solve(qp, sides, it, res, &mut self.fac, &target, &mut self.dir);
            self.refine(qp, 0.1 * tol * scales.dual);
            // τ → 1 as μ → 0 (IPOPT's rule): near the solution a step of 0.995 would cap
            // the reduction of μ at 200 per iteration.
            let tau = self.settings.step_fraction.max(1.0 - m.mu);
            let alpha = (tau * max_step(&self.it, &self.dir)).min(1.0);
            let (y_norm, dy_norm) = primal_norms(&self.it, &self.dir);
            if dy_norm > 1e8 * y_norm.max(scales.primal)
                && dual_infeasible(qp, &self.sides, &self.dir, self.settings.certificate_tol)
            {
                break (QpStatus::DualInfeasible, m);
            }
            if alpha.is_nan() || alpha <= 1e-12 {
                break (self.diagnose(qp, QpStatus::NumericalError), m);
            }
            for (ik, dk) in self.it.iter_mut().zip(&self.dir) {
                ik.step(alpha, dk);
            }
        };
        self.solution(qp, status, m, iterations, start, warm)
    }

    /// Iterative refinement of `dir`: near the solution the barrier weights `λ/t` of the
    /// active sides reach `λ²/μ`, and the Riccati recursion's rounding grows with them;
    /// while the Newton system's residual at `dir` exceeds `threshold`, solve for it and
    /// correct (at most twice).
    fn refine(&mut self, qp: &StageQp<NX, NU, NC>, threshold: f64) {
        for _ in 0..2 {
            if newton_residual(qp, &self.dir, &self.res, &mut self.refine_res) <= threshold {
                return;
            }
            let (it, sides) = (&self.it, &self.sides);
            let target = Target::Refinement;
            solve(
                qp,
                sides,
                it,
                &self.refine_res,
                &mut self.fac,
                &target,
                &mut self.correction,
            );
            for (dk, ck) in self.dir.iter_mut().zip(&self.correction) {
                dk.step(1.0, ck);
            }
        }
    }

    /// What a stop without convergence means: a certificate of infeasibility if the
    /// iterate or the last direction is one, otherwise `status`.
    fn diagnose(&self, qp: &StageQp<NX, NU, NC>, status: QpStatus) -> QpStatus {
        let tol = self.settings.certificate_tol;
        if primal_infeasible(qp, &self.sides, &self.it, tol) {
            QpStatus::PrimalInfeasible
        } else if dual_infeasible(qp, &self.sides, &self.dir, tol) {
            QpStatus::DualInfeasible
        } else {
            status
        }
    }

    /// The largest multiplier of a hard side.
    fn hard_multiplier_max(&self) -> f64 {
        let mut m: f64 = 0.0;
        for (sd, ik) in self.sides.iter().zip(&self.it) {
            for j in 0..2 {
                for i in 0..NC {
                    if sd.side[j][i] == Side::Hard {
                        m = m.max(ik.lam[j][i]);
                    }
                }
            }
        }
        m
    }

    fn solution(
        &self,
        qp: &StageQp<NX, NU, NC>,
        status: QpStatus,
        m: Measures,
        iterations: usize,
        start: Instant,
        warm: bool,
    ) -> QpSolution<NX, NU, NC> {
        let n = qp.horizon();
        let x: Vec<_> = self.it.iter().map(|ik| ik.x).collect();
        let u: Vec<_> = self.it[..n].iter().map(|ik| ik.u).collect();
        QpSolution {
            status,
            info: QpInfo {
                iterations,
                stationarity: m.stationarity,
                primal_residual: m.primal,
                complementarity: m.mu,
                objective: qp.objective(&x, &u),
                solve_time: start.elapsed().as_secs_f64(),
                warm,
            },
            pi: self.it[..n].iter().map(|ik| ik.pi).collect(),
            row_multipliers: self.it.iter().map(|ik| ik.lam[0] - ik.lam[1]).collect(),
            violations: (0..=n)
                .map(|k| {
                    let (rows, ik) = (qp.rows(k), &self.it[k]);
                    let mut z = rows.d * ik.x;
                    if k < n {
                        z += rows.e * ik.u;
                    }
                    SVector::from_fn(|i, _| match rows.soft[i] {
                        Some(_) => (z[i] - rows.hi[i]).max(rows.lo[i] - z[i]).max(0.0),
                        None => 0.0,
                    })
                })
                .collect(),
            x,
            u,
            iterate: self.it.clone(),
        }
    }
}

/// A soft side's start at the complementarity `μ`, its slack equation `t − s = g` (`g`
/// the row's distance to its bound, negative where the rollout violates it) and its
/// stationarity `λ + ν = l1 + l2 s` all holding: `t λ = s ν = μ` make that
/// `h(s) = μ/(s + g) + μ/s − l1 − l2 s = 0`, decreasing and convex on
/// `s > max(0, −g)`. With `l2 = 0` its root is that of
/// `l1 s² + (l1 g − 2μ) s − μ g = 0`, in closed form; otherwise that closed form at the
/// price `p = l1 + l2 s₁` of a first root `s₁`, then Newton steps (from the left of
/// the root, where they rise to it monotonically; guarded to stay in the domain).
/// Returns `(t, λ, s, ν)`.
fn centred_soft_side(g: f64, l1: f64, l2: f64, mu: f64) -> (f64, f64, f64, f64) {
    // The positive root of p s² + (p g − 2μ) s − μ g = 0, without cancellation.
    let root = |p: f64| {
        let b = p * g - 2.0 * mu;
        let sq = (p * g).hypot(2.0 * mu);
        match b <= 0.0 {
            true => (sq - b) / (2.0 * p),
            false => 2.0 * mu * g / (b + sq),
        }
    };
    let lower = (-g).max(0.0);
    // A price at least that of the violation the rollout has (l2 alone: one unit of it).
    let p1 = match l1 + l2 * lower {
        p if p > 0.0 => p,
        _ => l2,
    };
    let mut s = root(p1);
    if l2 > 0.0 {
        s = root(l1 + l2 * s);
        for _ in 0..3 {
            let h = mu / (s + g) + mu / s - l1 - l2 * s;
            let dh = -mu / ((s + g) * (s + g)) - mu / (s * s) - l2;
            s = (s - h / dh).max(0.5 * (s + lower));
        }
    }
    let t = s + g;
    (t, mu / t, s, mu / s)
}

/// Stationarity and primal residual within `tol` of their scales, and the duality gap
/// `pairs · μ` within `tol` of the objective (at least 1).
fn converged(m: &Measures, scales: &Scales, pairs: usize, tol: f64) -> bool {
    m.stationarity <= tol * scales.dual
        && m.primal <= tol * scales.primal
        && pairs as f64 * m.mu <= tol * m.objective.abs().max(1.0)
}

/// The largest `α ≤ 1` that keeps every side's `t, λ, s, ν` nonnegative along `d`. No
/// branch on the sides' kinds: an absent side's direction is zero, and so is a hard
/// side's `Δs, Δν` (`newton::solve`).
fn max_step<const NX: usize, const NU: usize, const NC: usize>(
    it: &[StageIterate<NX, NU, NC>],
    d: &[StageIterate<NX, NU, NC>],
) -> f64 {
    let mut alpha: f64 = 1.0;
    for (ik, dk) in it.iter().zip(d) {
        for j in 0..2 {
            for (v, dv) in [
                (&ik.t[j], &dk.t[j]),
                (&ik.lam[j], &dk.lam[j]),
                (&ik.s[j], &dk.s[j]),
                (&ik.nu[j], &dk.nu[j]),
            ] {
                for i in 0..NC {
                    if dv[i] < 0.0 {
                        alpha = alpha.min(-v[i] / dv[i]);
                    }
                }
            }
        }
    }
    alpha
}

/// `Σ (t + αΔt)(λ + αΔλ) + Σ (s + αΔs)(ν + αΔν)` over the sides (an absent side's
/// `λ` and its direction are zero, a hard side's `s, ν` too).
fn complementarity<const NX: usize, const NU: usize, const NC: usize>(
    it: &[StageIterate<NX, NU, NC>],
    d: &[StageIterate<NX, NU, NC>],
    alpha: f64,
) -> f64 {
    let mut sum = 0.0;
    for (ik, dk) in it.iter().zip(d) {
        for j in 0..2 {
            let t = ik.t[j] + dk.t[j] * alpha;
            let lam = ik.lam[j] + dk.lam[j] * alpha;
            let s = ik.s[j] + dk.s[j] * alpha;
            let nu = ik.nu[j] + dk.nu[j] * alpha;
            sum += t.dot(&lam) + s.dot(&nu);
        }
    }
    sum
}

/// `‖(x, u)‖∞` of the iterate and of the direction.
fn primal_norms<const NX: usize, const NU: usize, const NC: usize>(
    it: &[StageIterate<NX, NU, NC>],
    d: &[StageIterate<NX, NU, NC>],
) -> (f64, f64) {
    let norm = |v: &[StageIterate<NX, NU, NC>]| {
        v.iter()
            .map(|s| s.x.amax().max(s.u.amax()))
            .fold(0.0, f64::max)
    };
    (norm(it), norm(d))
}
