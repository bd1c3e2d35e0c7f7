//! The residual measures of an iterate: stage values, the filter's violation `θ` and
//! barrier function `φ`, and the largest violation of a primal point.

use super::*;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NU: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NU, NC>
{
    pub(super) fn values(&self, it: &Iterate<NX, NW, NC>) -> Vec<StageValues<NX, NE, NC>> {
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
            self.p.values(k, &it.x[k], &it.w[k])
        });
        out
    }

    pub(super) fn measures(
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
        obj += self.p.terminal_cost(&it.x[self.n]);
        let mut barrier = obj - mu * logs;
        if let Some(gs) = &self.globals {
            let (sum, max) = gs.violation(&it.globals.p);
            theta += sum;
            theta_max = theta_max.max(max);
            let c = gs.cost(&it.globals.p);
            obj += c;
            barrier += c + gs.log_barrier(&it.globals.p, mu);
        }
        Measures {
            theta,
            theta_max,
            objective: obj,
            barrier,
        }
    }

    /// The largest violation of any constraint at a primal point (slacks not used).
    pub fn max_violation(&self, x: &[SVector<f64, NX>], w: &[SVector<f64, NW>]) -> f64 {
        let mut worst = 0.0f64;
        for k in 0..self.n {
            let v = self.p.values(k, &x[k], &w[k]);
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
}
