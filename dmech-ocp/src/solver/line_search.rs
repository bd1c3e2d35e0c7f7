//! The line search: the fraction-to-the-boundary rule, trial points, IPOPT's filter
//! line search with second-order corrections (its acceptance test in `filter.rs`).

use super::filter::Acceptance;
use super::*;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The largest steps `(α_p, α_d)` in `(0, 1]` that keep the slacks and the bound
    /// multipliers a fraction `τ` away from zero.
    pub(super) fn max_step(
        &self,
        it: &Iterate<NX, NW, NC>,
        step: &Step<NX, NW, NC>,
        tau: f64,
    ) -> (f64, f64) {
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
        if let Some(gs) = &self.globals {
            let (gi, gd) = (&it.globals, &step.globals);
            for j in 0..gi.p.len() {
                if gs.has_lo[j] {
                    if gd.dp[j] < 0.0 {
                        amax_p = amax_p.min(-tau * (gi.p[j] - gs.g.lo[j]) / gd.dp[j]);
                    }
                    if gd.dz_lo[j] < 0.0 {
                        amax_d = amax_d.min(-tau * gi.z_lo[j] / gd.dz_lo[j]);
                    }
                }
                if gs.has_hi[j] {
                    if gd.dp[j] > 0.0 {
                        amax_p = amax_p.min(tau * (gs.g.hi[j] - gi.p[j]) / gd.dp[j]);
                    }
                    if gd.dz_hi[j] < 0.0 {
                        amax_d = amax_d.min(-tau * gi.z_hi[j] / gd.dz_hi[j]);
                    }
                }
            }
        }
        (amax_p, amax_d)
    }

    pub(super) fn trial(
        &self,
        it: &Iterate<NX, NW, NC>,
        s: &Step<NX, NW, NC>,
        a: f64,
    ) -> Iterate<NX, NW, NC> {
        let n = self.n;
        let mut trial = Iterate {
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
            globals: it.globals.clone(),
        };
        if self.globals.is_some() {
            let (g, gd) = (&mut trial.globals, &s.globals);
            for (p, dp) in g.p.iter_mut().zip(&gd.dp) {
                *p += dp * a;
            }
            for (y0, y1) in g.y.iter_mut().zip(&gd.y) {
                *y0 += (y1 - *y0) * a;
            }
            // The decisions' copies of the globals exactly equal to them.
            self.sync_globals(&mut trial);
        }
        trial
    }
}

/// `τ_min`: the fraction to the boundary is `τ = max(τ_min, 1 − μ)`.
const TAU_MIN: f64 = 0.99;
/// The step length is halved between trials.
const BACKTRACK: f64 = 0.5;
/// A primal step below this, relative to the iterate, at a feasible point is taken whole
/// without a line search (IPOPT's tiny-step rule).
const TINY_STEP: f64 = 1e-9;
/// Second-order corrections: at most `p_max` per line search, each kept only while it
/// cuts the violation to `κ_soc` of the last.
const SOC_MAX: usize = 4;
const KAPPA_SOC: f64 = 0.99;

/// A trial point with its stage values and measures.
pub(super) type Trial<const NX: usize, const NW: usize, const NE: usize, const NC: usize> =
    (Iterate<NX, NW, NC>, Vec<StageValues<NX, NE, NC>>, Measures);

/// The outcome of a line search: the accepted trial point, if any, the primal and dual
/// step lengths, the largest primal step the boundary allowed, and the trials taken.
pub(super) struct LineSearch<const NX: usize, const NW: usize, const NE: usize, const NC: usize> {
    pub(super) accepted: Option<Trial<NX, NW, NE, NC>>,
    pub(super) alpha: f64,
    pub(super) alpha_dual: f64,
    pub(super) alpha_max: f64,
    pub(super) trials: usize,
}

impl<const NX: usize, const NW: usize, const NE: usize, const NC: usize>
    LineSearch<NX, NW, NE, NC>
{
    /// Before the first iteration (the iteration table's first row).
    pub(super) fn none() -> Self {
        LineSearch {
            accepted: None,
            alpha: 0.0,
            alpha_dual: 0.0,
            alpha_max: 0.0,
            trials: 0,
        }
    }
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// IPOPT's filter line search along `step` from `it` (measures `m`): backtracking from
    /// the largest step the boundary allows, with second-order corrections after a
    /// rejected full step that raised the violation (which replace `step` when one is
    /// accepted). The filter is augmented by an accepted h-type step.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn line_search(
        &self,
        it: &Iterate<NX, NW, NC>,
        m: &Measures,
        step: &mut Step<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        filter: &mut Filter,
        mu: f64,
        dc: f64,
        delta: f64,
        tm: &mut Timings,
    ) -> LineSearch<NX, NW, NE, NC> {
        let n = self.n;
        let tau = (1.0 - mu).max(TAU_MIN);
        let (amax_p, mut amax_d) = self.max_step(it, step, tau);
        let t2 = Instant::now();
        let dphi = self.barrier_slope(it, step, ws, mu);
        let alpha_min = filter.alpha_min(m, dphi);
        let mut alpha = amax_p;
        let mut trials = 0;
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
        let tiny = rel_step < TINY_STEP && m.theta_max <= self.opts.constr_viol_tol;
        let accepted = loop {
            let trial = self.trial(it, step, alpha);
            let tv = self.values(&trial);
            let tmz = self.measures(&trial, &tv, mu);
            if tiny {
                break Some((trial, tv, tmz));
            }
            trials += 1;
            if let Acceptance::Accepted { augment } = filter.test(m, dphi, &tmz, alpha) {
                if augment {
                    filter.augment(m);
                }
                break Some((trial, tv, tmz));
            }
            // Second-order correction (IPOPT's): the full step was rejected and made the
            // constraint violation worse, the mark of the constraints' curvature (Maratos
            // effect). Re-solve the same KKT system with the residuals `α c(x) + c(x + α d)`
            // and try the corrected step, up to `p_max` times while it reduces the violation.
            if trials == 1 && tmz.theta >= m.theta {
                let (mut soc_trial, mut soc_vals, mut soc_alpha) = (trial, tv, alpha);
                let mut theta_trial = tmz.theta;
                let mut found = None;
                for _ in 0..SOC_MAX {
                    let t_soc = Instant::now();
                    let correction = (&soc_vals[..], &soc_trial, soc_alpha);
                    let sstep = self.second_order_correction(it, ws, correction, mu, dc, delta);
                    let Some(sstep) = sstep else {
                        break;
                    };
                    tm.kkt += t_soc.elapsed().as_secs_f64();
                    let (ap, ad) = self.max_step(it, &sstep, tau);
                    let ct = self.trial(it, &sstep, ap);
                    let cv = self.values(&ct);
                    let cm = self.measures(&ct, &cv, mu);
                    tm.second_order_corrections += 1;
                    if let Acceptance::Accepted { augment } = filter.test(m, dphi, &cm, alpha) {
                        found = Some((ct, cv, cm, sstep, ap, ad, augment));
                        break;
                    }
                    let theta_soc_old = theta_trial;
                    theta_trial = cm.theta;
                    if theta_trial > KAPPA_SOC * theta_soc_old {
                        break;
                    }
                    (soc_trial, soc_vals, soc_alpha) = (ct, cv, ap);
                }
                if let Some((ct, cv, cm, sstep, ap, ad, augment)) = found {
                    if augment {
                        filter.augment(m);
                    }
                    *step = sstep;
                    amax_d = ad;
                    alpha = ap;
                    break Some((ct, cv, cm));
                }
            }
            alpha *= BACKTRACK;
            if alpha < alpha_min {
                break None;
            }
        };
        tm.line_search += t2.elapsed().as_secs_f64();
        LineSearch {
            accepted,
            alpha,
            alpha_dual: amax_d,
            alpha_max: amax_p,
            trials,
        }
    }

    /// The directional derivative `∇φᵀd` of the barrier function along the step.
    fn barrier_slope(
        &self,
        it: &Iterate<NX, NW, NC>,
        step: &Step<NX, NW, NC>,
        ws: &Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
    ) -> f64 {
        let mut dphi = 0.0;
        for k in 0..self.n {
            let d = &ws.ders[k];
            dphi += d.gx.dot(&step.dx[k]) + d.gw.dot(&step.dw[k]);
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
        if let Some(gs) = &self.globals {
            let (gi, gd) = (&it.globals, &step.globals);
            for j in 0..gi.p.len() {
                dphi += gs.g.cost[j] * gd.dp[j];
                if gs.has_lo[j] {
                    dphi -= mu * gd.dp[j] / (gi.p[j] - gs.g.lo[j]);
                }
                if gs.has_hi[j] {
                    dphi += mu * gd.dp[j] / (gs.g.hi[j] - gi.p[j]);
                }
            }
        }
        dphi
    }
}
