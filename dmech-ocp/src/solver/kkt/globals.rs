//! Global variables in the interior point ([`crate::nlp::Globals`]): `p` with simple
//! bounds (a barrier on `p − lo` and `hi − p` directly, no slacks), linear equalities
//! `aᵀp = b` (multipliers `y_g`) and a linear cost `cᵀp`. Stage `k` reads `p[support(k)]`
//! through the last `per_stage` entries `θ_k` of its decision, kept equal to them.
//!
//! The Newton step: each stage condensed as without globals, plus its coupling to `θ_k`
//! (`δw = w0 + W_x δx + W_u δu + W_θ δθ`, the stage equality eliminating `δv` for `δθ`
//! too); the Riccati recursion augmented by the globals' columns
//! ([`crate::solver::kkt::global_riccati`]), whose reduced system in `δp`,
//! ```text
//! [Ψ₀ + Σ_g + δ_w I   Aᵀ] [δp ]   [−(ψ₀ + c − μ/(p − lo) + μ/(hi − p))]
//! [A                  0 ] [y_g⁺] = [−(A p − b)                         ]
//! ```
//! is solved densely, its inertia checked (`n_g` positive, one negative per equality)
//! together with the stages' `H_uu`; then the forward pass and the recovery with
//! `δθ_k = δp[support(k)]`. The dual infeasibility of `p` is
//! `c + Σ_k S_kᵀ ∇_θ L_k + Aᵀy_g − z_lo + z_hi`.

use super::*;
use crate::nlp::Globals;
use crate::solver::kkt::global_riccati::{global_forward, global_sweep, GlobalSchur, LqCoupling};
use crate::solver::kkt::riccati::LqSolution;
use crate::solver::kkt::{Correction, KktBackend};
use nalgebra::{DMatrix, DVector};

/// The globals' own terms, which the Riccati path adds to its reduced system: a diagonal
/// (barrier curvature and shift), a gradient, and equalities `A_g δp = r_g`.
#[derive(Clone, Debug, Default)]
pub(crate) struct GlobalTerms {
    /// The diagonal.
    pub(crate) diag: Vec<f64>,
    /// The gradient.
    pub(crate) grad: Vec<f64>,
    /// The equalities' rows `A_g`.
    pub(crate) eq_a: Vec<Vec<f64>>,
    /// Their right-hand sides `r_g`.
    pub(crate) eq_rhs: Vec<f64>,
}

/// The globals' part of an iterate: `p`, the multipliers of its lower and upper bounds
/// (zero where there is none) and of its equalities.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GlobalIterate {
    /// The globals `p`.
    pub p: Vec<f64>,
    /// Their lower bounds' multipliers.
    pub z_lo: Vec<f64>,
    /// Their upper bounds' multipliers.
    pub z_hi: Vec<f64>,
    /// Their equalities' multipliers.
    pub y: Vec<f64>,
}

/// The globals' part of a Newton step: `δp`, `δz`, and the equalities' new multipliers.
#[derive(Clone, Debug, Default)]
pub(in crate::solver) struct GlobalStep {
    pub(in crate::solver) dp: Vec<f64>,
    pub(in crate::solver) dz_lo: Vec<f64>,
    pub(in crate::solver) dz_hi: Vec<f64>,
    pub(in crate::solver) y: Vec<f64>,
}

/// A stage's coupling to its globals, and how its decision moves with them (`W_θ`, the
/// first `per_stage` columns).
pub(in crate::solver) type StageCoupling<const NX: usize, const NW: usize, const NF: usize> =
    (LqCoupling<NX, NF, NW>, SMatrix<f64, NW, NW>);

/// What the solver keeps of the problem's globals.
#[derive(Clone, Debug)]
pub(in crate::solver) struct GlobalSpec {
    pub(in crate::solver) g: Globals,
    pub(in crate::solver) has_lo: Vec<bool>,
    pub(in crate::solver) has_hi: Vec<bool>,
}

impl GlobalSpec {
    pub(in crate::solver) fn new(g: Globals) -> Self {
        GlobalSpec {
            has_lo: g.lo.iter().map(|v| v.is_finite()).collect(),
            has_hi: g.hi.iter().map(|v| v.is_finite()).collect(),
            g,
        }
    }

    /// The same globals with their cost multiplied by `c` (objective scaling).
    pub(in crate::solver) fn with_cost_scaled(mut self, c: f64) -> Self {
        self.g.cost.iter_mut().for_each(|v| *v *= c);
        self
    }

    fn residuals(&self, p: &[f64]) -> impl Iterator<Item = f64> + '_ {
        let p = p.to_vec();
        self.g
            .equalities
            .iter()
            .map(move |e| e.a.iter().zip(&p).map(|(a, v)| a * v).sum::<f64>() - e.b)
    }

    /// `Σ|aᵀp − b|` and its largest term.
    pub(in crate::solver) fn violation(&self, p: &[f64]) -> (f64, f64) {
        self.residuals(p)
            .fold((0.0, 0.0f64), |(s, m), r| (s + r.abs(), m.max(r.abs())))
    }

    pub(in crate::solver) fn cost(&self, p: &[f64]) -> f64 {
        self.g.cost.iter().zip(p).map(|(c, v)| c * v).sum()
    }

    /// `−μ Σ ln` of the bounds' gaps.
    pub(in crate::solver) fn log_barrier(&self, p: &[f64], mu: f64) -> f64 {
        let mut logs = 0.0;
        for j in 0..p.len() {
            if self.has_lo[j] {
                logs += (p[j] - self.g.lo[j]).ln();
            }
            if self.has_hi[j] {
                logs += (self.g.hi[j] - p[j]).ln();
            }
        }
        -mu * logs
    }

    /// The largest `|t z − μ|` over the bounds.
    /// `Σ zⱼ tⱼ` over the globals' bounds.
    pub(in crate::solver) fn duality_gap(&self, gi: &GlobalIterate) -> f64 {
        let mut gap = 0.0;
        for j in 0..gi.p.len() {
            if self.has_lo[j] {
                gap += (gi.p[j] - self.g.lo[j]) * gi.z_lo[j];
            }
            if self.has_hi[j] {
                gap += (self.g.hi[j] - gi.p[j]) * gi.z_hi[j];
            }
        }
        gap
    }

    pub(in crate::solver) fn complementarity(&self, gi: &GlobalIterate, mu: f64) -> f64 {
        let mut c = 0.0f64;
        for j in 0..gi.p.len() {
            if self.has_lo[j] {
                c = c.max(((gi.p[j] - self.g.lo[j]) * gi.z_lo[j] - mu).abs());
            }
            if self.has_hi[j] {
                c = c.max(((self.g.hi[j] - gi.p[j]) * gi.z_hi[j] - mu).abs());
            }
        }
        c
    }

    /// The globals' part of a start: `p` (the given one, or the problem's) pushed into its
    /// bounds by IPOPT's rule, unit bound multipliers, zero equality multipliers.
    pub(in crate::solver) fn start(&self, p: Option<&[f64]>) -> GlobalIterate {
        let g = &self.g;
        let p = (0..g.len())
            .map(|j| {
                let v = p.map_or(g.start[j], |p| p[j]);
                let gap = g.hi[j] - g.lo[j];
                let push = |b: f64| (1e-2 * b.abs().max(1.0)).min(1e-2 * gap);
                let mut v = v;
                if self.has_lo[j] {
                    v = v.max(g.lo[j] + push(g.lo[j]));
                }
                if self.has_hi[j] {
                    v = v.min(g.hi[j] - push(g.hi[j]));
                }
                v
            })
            .collect();
        let unit = |has: &Vec<bool>| has.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect();
        GlobalIterate {
            p,
            z_lo: unit(&self.has_lo),
            z_hi: unit(&self.has_hi),
            y: vec![0.0; g.equalities.len()],
        }
    }
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The last `per_stage` entries of every `w_k` set to the globals they copy.
    pub(in crate::solver) fn sync_globals(&self, it: &mut Iterate<NX, NW, NC>) {
        let Some(gs) = &self.globals else { return };
        let t0 = NW - gs.g.per_stage;
        for (k, w) in it.w.iter_mut().enumerate() {
            for (i, &j) in gs.g.support_of(k).iter().enumerate() {
                w[t0 + i] = it.globals.p[j];
            }
        }
    }

    /// The gradient of the Lagrangian in `p`: `c + Σ_k S_kᵀ ∇_θ L_k + Aᵀy − z_lo + z_hi`,
    /// with `∇_w L_k = ∇ℓ + F_wᵀλ + C_wᵀζ + E_wᵀν` from the derivatives at `it`.
    pub(in crate::solver) fn global_gradient(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
    ) -> DVector<f64> {
        let Some(gs) = &self.globals else {
            return DVector::zeros(0);
        };
        let gi = &it.globals;
        let t0 = NW - gs.g.per_stage;
        let mut g = DVector::from_column_slice(&gs.g.cost);
        for (k, d) in ders.iter().enumerate() {
            let zeta = it.z_hi[k] - it.z_lo[k];
            let mut gw = d.gw + d.fw.transpose() * it.lambda[k] + d.cw.transpose() * zeta;
            if let Some(nu) = d.nu {
                gw += d.ew.transpose() * nu;
            }
            for (i, &j) in gs.g.support_of(k).iter().enumerate() {
                g[j] += gw[t0 + i];
            }
        }
        for (e, y) in gs.g.equalities.iter().zip(&gi.y) {
            for j in 0..g.len() {
                g[j] += e.a[j] * y;
            }
        }
        for j in 0..g.len() {
            g[j] += gi.z_hi[j] - gi.z_lo[j];
        }
        g
    }

    /// Stage `k`'s coupling to its globals from its derivatives `d` and its condensing
    /// `el` (the same Hessian and gradient as [`Solver::condense`]).
    #[allow(clippy::too_many_arguments)]
    fn coupling(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        curvature: StageCurvature<'_, NX, NW, NE>,
        mu: f64,
        el: &Elimination<NX, NW, NF>,
        nt: usize,
    ) -> Result<StageCoupling<NX, NW, NF>, Failure> {
        // The state blocks are the condensing's; only the decision blocks are used here.
        let (mut hxx, mut gx) = (SMatrix::zeros(), SVector::zeros());
        let (hxw, hww, gw) = self.stage_hessian_into(k, it, d, curvature, mu, (&mut hxx, &mut gx));
        let t0 = NW - nt;
        let mut wt = SMatrix::<f64, NW, NW>::zeros();
        for i in 0..nt {
            wt[(t0 + i, i)] = 1.0;
        }
        if NE > 0 {
            let ev: SMatrix<f64, NE, NE> = d.ew.fixed_columns::<NE>(0).into_owned();
            let lu = Lu::new(&ev).ok_or(Failure::SingularStageEquality { stage: k })?;
            let mut et = SMatrix::<f64, NE, NW>::zeros();
            for i in 0..nt {
                et.set_column(i, &(-d.ew.column(t0 + i)));
            }
            wt.fixed_rows_mut::<NE>(0).copy_from(&lu.solve_columns(&et));
        }
        let hww_wt = hww * wt;
        let cp = LqCoupling {
            s_xt: hxw * wt + el.wx.transpose() * hww_wt,
            s_ut: el.wu.transpose() * hww_wt,
            r_tt: wt.transpose() * hww_wt,
            q_t: wt.transpose() * (gw + hww * el.w0),
            b_t: d.fw * wt,
        };
        Ok((cp, wt))
    }

    /// Every stage's coupling, in parallel, into `out`.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::solver) fn couplings(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        (constants, qn): (&ConstantsTable<NX, NW, NC>, &[QuasiNewton<NX, NW, NE>]),
        elim: &[Elimination<NX, NW, NF>],
        mu: f64,
        out: &mut Vec<StageCoupling<NX, NW, NF>>,
    ) -> Result<(), Failure> {
        let nt = self.globals.as_ref().map_or(0, |g| g.g.per_stage);
        out.resize_with(self.n, || (LqCoupling::zeros(), SMatrix::zeros()));
        let failed = std::sync::Mutex::new(None::<Failure>);
        par_update(out, self.opts.threads, |k, slot| {
            let curvature = self.stage_curvature(k, constants, qn);
            match self.coupling(k, it, &ders[k], curvature, mu, &elim[k], nt) {
                Ok(c) => *slot = c,
                Err(e) => *failed.lock().unwrap_or_else(|p| p.into_inner()) = Some(e),
            }
        });
        match failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// The globals' own terms of the Newton system at `gi`: the barrier curvature plus the
    /// shift `delta` on the diagonal, the gradient `c − μ/(p − lo) + μ/(hi − p)`, the
    /// equalities `A δp = −(A p − b)`.
    pub(in crate::solver) fn global_terms(
        &self,
        gi: &GlobalIterate,
        mu: f64,
        delta: f64,
    ) -> GlobalTerms {
        let Some(gs) = &self.globals else {
            return GlobalTerms::default();
        };
        let ng = gs.g.len();
        let (mut diag, mut grad) = (vec![delta; ng], gs.g.cost.clone());
        for j in 0..ng {
            if gs.has_lo[j] {
                let t = gi.p[j] - gs.g.lo[j];
                diag[j] += gi.z_lo[j] / t;
                grad[j] -= mu / t;
            }
            if gs.has_hi[j] {
                let t = gs.g.hi[j] - gi.p[j];
                diag[j] += gi.z_hi[j] / t;
                grad[j] += mu / t;
            }
        }
        GlobalTerms {
            diag,
            grad,
            eq_a: gs.g.equalities.iter().map(|e| e.a.clone()).collect(),
            eq_rhs: gs.residuals(&gi.p).map(|r| -r).collect(),
        }
    }

    /// The reduced system of the globals (module doc) with primal shift `delta`: `δp` and
    /// the equalities' new multipliers, or `None` if its inertia is wrong.
    fn reduced_global_step(
        &self,
        schur: &GlobalSchur<NX, NF>,
        gi: &GlobalIterate,
        mu: f64,
        delta: f64,
    ) -> Option<(DVector<f64>, Vec<f64>)> {
        let gs = self.globals.as_ref()?;
        let (ng, ne) = (gs.g.len(), gs.g.equalities.len());
        let terms = self.global_terms(gi, mu, delta);
        let mut kkt = DMatrix::<f64>::zeros(ng + ne, ng + ne);
        let mut rhs = DVector::<f64>::zeros(ng + ne);
        kkt.view_mut((0, 0), (ng, ng)).copy_from(&schur.psi);
        for j in 0..ng {
            kkt[(j, j)] += terms.diag[j];
            rhs[j] = -(schur.psi_vec[j] + terms.grad[j]);
        }
        for (i, (a, r)) in terms.eq_a.iter().zip(&terms.eq_rhs).enumerate() {
            for j in 0..ng {
                kkt[(ng + i, j)] = a[j];
                kkt[(j, ng + i)] = a[j];
            }
            rhs[ng + i] = *r;
        }
        // Inertia: n_g positive and n_e negative eigenvalues, none near zero.
        let eig = kkt.clone().symmetric_eigen().eigenvalues;
        let scale = eig.amax().max(1.0);
        let tiny = 1e3 * f64::EPSILON * scale * (ng + ne) as f64;
        let positive = eig.iter().filter(|&&v| v > tiny).count();
        let negative = eig.iter().filter(|&&v| v < -tiny).count();
        if positive != ng || negative != ne {
            return None;
        }
        let sol = kkt.lu().solve(&rhs)?;
        let dp = sol.rows(0, ng).into_owned();
        let y = sol.rows(ng, ne).iter().copied().collect();
        Some((dp, y))
    }

    fn schur(
        &self,
        sweep: &BackwardSweep<NX, NF>,
        lq: &[LqStage<NX, NF>],
        couplings: &[StageCoupling<NX, NW, NF>],
    ) -> Option<GlobalSchur<NX, NF>> {
        let gs = self.globals.as_ref()?;
        let cps: Vec<LqCoupling<NX, NF, NW>> = couplings.iter().map(|c| c.0.clone()).collect();
        let support = |k: usize| gs.g.support_of(k);
        global_sweep(sweep, lq, &cps, &support, gs.g.len(), &SVector::zeros()).ok()
    }

    /// The step from the sweeps and `δp`: the forward pass, the stages' recovery with
    /// `W_θ δθ_k` added to their decisions, the bound multipliers of the globals.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::solver) fn global_recover(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        terminal: &TerminalDerivatives<NX>,
        lq: &[LqStage<NX, NF>],
        elim: &[Elimination<NX, NW, NF>],
        couplings: &[StageCoupling<NX, NW, NF>],
        sweep: &BackwardSweep<NX, NF>,
        solved: (GlobalSchur<NX, NF>, DVector<f64>, Vec<f64>),
        mu: f64,
        dc: f64,
    ) -> Step<NX, NW, NC> {
        let (schur, dp, y) = solved;
        let gs = self.globals.as_ref().expect("a problem with globals");
        let support = |k: usize| gs.g.support_of(k);
        let cps: Vec<LqCoupling<NX, NF, NW>> = couplings.iter().map(|c| c.0.clone()).collect();
        let sol = global_forward(sweep, &schur, lq, &cps, &support, &SVector::zeros(), &dp);
        self.recover_with_globals(it, ders, terminal, elim, couplings, sol, &dp, y, mu, dc)
    }

    /// The step from the LQ solution and the globals' step `δp`, `y_g`: the stages'
    /// recovery with `W_θ δθ_k` added to their decisions, the globals' bound multipliers.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::solver) fn recover_with_globals(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        terminal: &TerminalDerivatives<NX>,
        elim: &[Elimination<NX, NW, NF>],
        couplings: &[StageCoupling<NX, NW, NF>],
        sol: LqSolution<NX, NF>,
        dp: &DVector<f64>,
        y: Vec<f64>,
        mu: f64,
        dc: f64,
    ) -> Step<NX, NW, NC> {
        let Some(gs) = self.globals.as_ref() else {
            return self.recover(it, ders, terminal, elim, sol, mu, dc, None);
        };
        let support = |k: usize| gs.g.support_of(k);
        let dw_globals: Vec<SVector<f64, NW>> = (0..self.n)
            .map(|k| {
                let mut theta = SVector::<f64, NW>::zeros();
                for (i, &j) in support(k).iter().enumerate() {
                    theta[i] = dp[j];
                }
                couplings[k].1 * theta
            })
            .collect();
        let mut step = self.recover(it, ders, terminal, elim, sol, mu, dc, Some(&dw_globals));
        let gi = &it.globals;
        let (mut dz_lo, mut dz_hi) = (vec![0.0; dp.len()], vec![0.0; dp.len()]);
        for j in 0..dp.len() {
            if gs.has_lo[j] {
                let t = gi.p[j] - gs.g.lo[j];
                dz_lo[j] = mu / t - gi.z_lo[j] - gi.z_lo[j] / t * dp[j];
            }
            if gs.has_hi[j] {
                let t = gs.g.hi[j] - gi.p[j];
                dz_hi[j] = mu / t - gi.z_hi[j] + gi.z_hi[j] / t * dp[j];
            }
        }
        step.globals = GlobalStep {
            dp: dp.iter().copied().collect(),
            dz_lo,
            dz_hi,
            y,
        };
        step
    }
}

/// The Riccati recursion augmented by the globals' columns (module documentation): the
/// stages condensed and swept as without globals, their couplings to the globals, the
/// Schur complement in `δp` solved densely with its inertia checked.
pub(in crate::solver) struct RiccatiWithGlobals;

impl<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    KktBackend<NX, NW, NE, NF, NC> for RiccatiWithGlobals
{
    fn condense_and_solve(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
        correction: Option<Correction<'_, NX, NW, NE, NC>>,
        tm: &mut Timings,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure> {
        let (swept, t_sweep) = s.condense_workspace(it, ws, mu, dc, delta, correction)?;
        // The couplings read no residual: a correction's are the iteration's (with the
        // corrected `w0`).
        let Workspace {
            ders,
            elim,
            qn,
            constants,
            couplings,
            ..
        } = ws;
        s.couplings(it, ders, (constants, qn), elim, mu, couplings)?;
        tm.riccati += t_sweep;
        let t = Instant::now();
        let step = swept
            .ok()
            .and_then(|()| self.step(s, it, ws, mu, dc, delta));
        tm.riccati += t.elapsed().as_secs_f64();
        Ok(step)
    }

    fn solve_again(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
        tm: &mut Timings,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure> {
        let t = Instant::now();
        ws.sweep.reshift(delta);
        let swept = ws.sweep.sweep_all(&ws.lq);
        let step = swept
            .ok()
            .and_then(|()| self.step(s, it, ws, mu, dc, delta));
        tm.riccati += t.elapsed().as_secs_f64();
        Ok(step)
    }
}

impl RiccatiWithGlobals {
    /// From a completed backward sweep: the globals' Schur complement and reduced step at
    /// shift `delta` (`None` if its inertia is wrong), then the forward pass and recovery.
    fn step<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
    ) -> Option<Step<NX, NW, NC>> {
        let schur = s.schur(&ws.sweep, &ws.lq, &ws.couplings)?;
        let (dp, y) = s.reduced_global_step(&schur, &it.globals, mu, delta)?;
        Some(s.global_recover(
            it,
            &ws.ders,
            &ws.terminal,
            &ws.lq,
            &ws.elim,
            &ws.couplings,
            &ws.sweep,
            (schur, dp, y),
            mu,
            dc,
        ))
    }
}
