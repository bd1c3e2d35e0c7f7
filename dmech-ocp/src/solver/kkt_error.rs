//! The KKT error: each stage's part, computed in the derivative pass while the stage's
//! derivatives are in cache, summed in stage order with IPOPT's dual scaling `s_d`, and the
//! complementarity.

use super::*;

/// One stage's part of the KKT error: its dual and primal errors, `Σ|ν|` (if the stage
/// equality's multiplier estimate exists) and `Σ|λ| + Σz`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct StageKkt {
    pub(super) dual: f64,
    pub(super) primal: f64,
    pub(super) nu_sum: Option<f64>,
    pub(super) others: f64,
}

/// What the derivative pass leaves per stage besides the derivatives.
#[derive(Clone, Copy, Debug)]
pub(super) struct StageAux<const NX: usize, const NE: usize, const NC: usize> {
    pub(super) kkt: StageKkt,
    pub(super) vals: StageValues<NX, NE, NC>,
}

impl<const NX: usize, const NE: usize, const NC: usize> StageAux<NX, NE, NC> {
    pub(super) fn zeros() -> Self {
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
pub(super) struct KktError {
    pub(super) dual: f64,
    pub(super) primal: f64,
    pub(super) s_d: f64,
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// Stage `k`'s part of the KKT error at the iterate, from its derivatives `d` (with
    /// `d.nu` set): computed in the derivative pass, while `d` is still in cache.
    pub(super) fn kkt_stage(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
    ) -> StageKkt {
        let zeta = it.z_hi[k] - it.z_lo[k];
        let lam = &it.lambda[k];
        let mut gx = d.gx + d.fx.tr_mul(lam) + d.cx.tr_mul(&zeta);
        if k > 0 {
            gx -= it.lambda[k - 1]; // x_k's part in the dynamics row of stage k − 1
        }
        let mut gw = d.gw + d.fw.tr_mul(lam) + d.cw.tr_mul(&zeta);
        let nu_sum = d.nu.map(|nu| {
            gx += d.ex.tr_mul(&nu);
            gw += d.ew.tr_mul(&nu);
            nu.abs().sum()
        });
        // A state equality fixes one component: its multiplier estimate zeroes that
        // component of the gradient (the iterate's y carries the round-off of the
        // regularised update, amplified by 1/δ_c).
        for &j in &self.eqs_at[k] {
            gx[self.eqs[j].index] = 0.0;
        }
        // The globals' copies are not free per stage: their gradient is summed over the
        // stages into the globals' own (`globals.rs`).
        let nt = self.globals.as_ref().map_or(0, |g| g.g.per_stage);
        let gw_own = if nt == 0 {
            gw.amax()
        } else {
            gw.rows(0, NW - nt).amax()
        };
        let dual = if k > 0 { gx.amax() } else { 0.0 }.max(gw_own);
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
    pub(super) fn kkt_error(
        &self,
        it: &Iterate<NX, NW, NC>,
        terminal: &TerminalDerivatives<NX>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
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
        // x_N's gradient: the terminal cost's and its part in the dynamics row of stage N − 1.
        let mut gx_n = terminal.gx;
        if n > 0 {
            gx_n -= it.lambda[n - 1];
        }
        for &j in &self.eqs_at[n] {
            gx_n[self.eqs[j].index] = 0.0;
        }
        let gx_n = self.without_terminal_rows(gx_n, terminal);
        dual = dual.max(gx_n.amax());
        for e in &self.eqs {
            primal = primal.max((it.x[e.stage][e.index] - e.value).abs());
        }
        for r in &terminal.equalities {
            primal = primal.max(r.abs());
        }
        for y in &it.y {
            mult_sum += y.abs();
            mult_cnt += 1.0;
        }
        let mut global_dual = 0.0f64;
        if let Some(gs) = &self.globals {
            let gi = &it.globals;
            global_dual = self.global_gradient(it, ders).amax();
            primal = primal.max(gs.violation(&gi.p).1);
            let m = gi.y.iter().chain(&gi.z_lo).chain(&gi.z_hi);
            mult_sum += m.clone().map(|v| v.abs()).sum::<f64>();
            mult_cnt += m.count() as f64;
        }
        dual = dual.max(global_dual);
        let s_max = 100.0;
        let s_d = (mult_sum / mult_cnt.max(1.0)).max(s_max) / s_max;
        KktError {
            dual: dual / s_d,
            primal,
            s_d,
        }
    }

    /// `g` less its least-squares combination of the terminal equalities' gradients, those
    /// restricted, as `g` is, to the components no state equality at `x_N` fixes: the
    /// dual residual at `x_N` with the best multipliers of those rows (what zeroing a
    /// component does for a state equality's unit row; the iterate's `y` carries the
    /// regularised update's round-off amplified by `1/δ_c`).
    fn without_terminal_rows(
        &self,
        mut g: SVector<f64, NX>,
        terminal: &TerminalDerivatives<NX>,
    ) -> SVector<f64, NX> {
        let m = terminal.equality_gradients.len();
        if m == 0 {
            return g;
        }
        let fixed = |a: &SVector<f64, NX>| {
            let mut a = *a;
            for &j in &self.eqs_at[self.n] {
                a[self.eqs[j].index] = 0.0;
            }
            a
        };
        let rows: Vec<SVector<f64, NX>> = terminal.equality_gradients.iter().map(fixed).collect();
        let a = nalgebra::DMatrix::from_fn(NX, m, |i, j| rows[j][i]);
        let b = nalgebra::DVector::from_column_slice(g.as_slice());
        // `min ‖A c − g‖` by the SVD (rank-safe: a row that vanishes or repeats is no
        // obstacle); `g − A c` is the part of `g` no combination of the rows explains.
        if let Ok(c) = a.clone().svd(true, true).solve(&b, 1e-12) {
            let fit = a * c;
            for i in 0..NX {
                g[i] -= fit[i];
            }
        }
        g
    }

    /// The largest `|t z − μ|` over all bounded sides, scaled by `s_d`.
    /// `Σ zᵢ tᵢ` over every bound, the stages' and the globals': the duality gap of the
    /// barrier problem (`m μ` at a point on its central path).
    pub(super) fn duality_gap(&self, it: &Iterate<NX, NW, NC>) -> f64 {
        let mut gap = 0.0;
        for k in 0..self.n {
            let b = &self.bounds[k];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    gap += it.t_lo[k][i] * it.z_lo[k][i];
                }
                if b.has_hi[i] > 0.0 {
                    gap += it.t_hi[k][i] * it.z_hi[k][i];
                }
            }
        }
        if let Some(gs) = &self.globals {
            gap += gs.duality_gap(&it.globals);
        }
        gap
    }

    pub(super) fn complementarity(&self, it: &Iterate<NX, NW, NC>, mu: f64, s_d: f64) -> f64 {
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
        if let Some(gs) = &self.globals {
            compl = compl.max(gs.complementarity(&it.globals, mu));
        }
        compl / s_d
    }
}
