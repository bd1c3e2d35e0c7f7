//! Step lengths: the fraction-to-the-boundary rule and the trial point.

use super::*;

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
        (amax_p, amax_d)
    }

    pub(super) fn trial(
        &self,
        it: &Iterate<NX, NW, NC>,
        s: &Step<NX, NW, NC>,
        a: f64,
    ) -> Iterate<NX, NW, NC> {
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
