//! Starting points: a cold start from primal values, a warm start from a previous solution.

use super::*;

/// A warm start keeps the previous bound multipliers, floored at this fraction of `μ₀/t`
/// (positive, and on the scale of the previous barrier's complementarity `z t = μ_prev`
/// when that was `μ₀/10` or more). Raising them onto the new barrier's central path
/// (`z = μ₀/t`, the rule before) changes the dual residual by up to `(μ₀ − μ_prev)/t` at
/// every nearly active bound, which the next steps had to undo: measured on the friction
/// continuation's second phase (iterations, floor 1 → 1e-2): eight 65 → 58, zigzag
/// 40 → 38, eight at h = 1.25 ms 96 → 86, eight RK4 75 → 67, zigzag RK1 55 → 57, zigzag
/// RK2 algebraic 39 → 40 (`docs/solver.md`, "Starts").
const WARM_MULT_FLOOR: f64 = 1e-2;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
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
            y: vec![0.0; self.equality_multipliers()],
            globals: self
                .globals
                .as_ref()
                .map_or_else(GlobalIterate::default, |g| g.start(None)),
            x,
            w,
        };
        self.sync_globals(&mut it);
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
    /// `WARM_MULT_FLOOR · μ₀/t`. Equality multipliers beyond this problem's are dropped,
    /// missing ones start at zero.
    pub fn warm_iterate(&self, prev: Iterate<NX, NW, NC>) -> Iterate<NX, NW, NC> {
        let mut it = prev;
        it.x[0] = self.p.initial_state();
        it.y.resize(self.equality_multipliers(), 0.0);
        let mu = self.opts.mu_init;
        if let Some(gs) = &self.globals {
            // Globals from the previous solution if it has them (kept, with their
            // multipliers floored as the stages' below), else the problem's start.
            let prev = std::mem::take(&mut it.globals);
            let mut g = gs.start((prev.p.len() == gs.g.len()).then_some(&prev.p[..]));
            if prev.p.len() == gs.g.len() && prev.y.len() == g.y.len() {
                g.y = prev.y;
                for j in 0..g.p.len() {
                    if gs.has_lo[j] {
                        let t = g.p[j] - gs.g.lo[j];
                        g.z_lo[j] = prev.z_lo[j].max(WARM_MULT_FLOOR * mu / t);
                    }
                    if gs.has_hi[j] {
                        let t = gs.g.hi[j] - g.p[j];
                        g.z_hi[j] = prev.z_hi[j].max(WARM_MULT_FLOOR * mu / t);
                    }
                }
            } else {
                // No globals before (a fixed-timing start): their bound multipliers on this
                // barrier's central path.
                for j in 0..g.p.len() {
                    if gs.has_lo[j] {
                        g.z_lo[j] = mu / (g.p[j] - gs.g.lo[j]);
                    }
                    if gs.has_hi[j] {
                        g.z_hi[j] = mu / (gs.g.hi[j] - g.p[j]);
                    }
                }
            }
            it.globals = g;
            self.sync_globals(&mut it);
        }
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
}
