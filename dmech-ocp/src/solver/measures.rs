//! The residual measures of an iterate: stage values, the filter's violation `θ` and
//! barrier function `φ`, and the largest violation of a primal point.

use super::*;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// Every stage's values at `it`, built on the stage threads (each written once: a
    /// zero-filled vector first was a serial pass and the page faults of 0.9 MB per trial).
    pub(super) fn values(&self, it: &Iterate<NX, NW, NC>) -> Vec<StageValues<NX, NE, NC>> {
        par_collect(self.n, self.opts.threads, |k| {
            self.p.values(k, &it.x[k], &it.w[k])
        })
    }

    pub(super) fn measures(
        &self,
        it: &Iterate<NX, NW, NC>,
        vals: &[StageValues<NX, NE, NC>],
        mu: f64,
    ) -> Measures {
        let (mut theta, mut theta_max, mut obj) = (0.0, 0.0f64, 0.0);
        let mut logs = LogSum::default();
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
                    logs.add(it.t_lo[k][i]);
                }
                if b.has_hi[i] > 0.0 {
                    add(b.hi[i] - v.c[i] - it.t_hi[k][i]);
                    logs.add(it.t_hi[k][i]);
                }
            }
        }
        for e in &self.eqs {
            add(it.x[e.stage][e.index] - e.value);
        }
        for r in self.p.terminal_equalities(&it.x[self.n]) {
            add(r);
        }
        obj += self.p.terminal_cost(&it.x[self.n]);
        let mut barrier = obj - mu * logs.value();
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
        for r in self.p.terminal_equalities(&x[self.n]) {
            worst = worst.max(r.abs());
        }
        worst
    }
}

/// `Σ ln tᵢ` of many positive numbers by one logarithm: the product of their binary
/// mantissas (kept in `[1, 2)`, its exponent moved out after each factor, so exactly
/// rescaled) and the sum of their exponents, `ln Π mᵢ + (Σ eᵢ) ln 2`. The barrier term of
/// every trial point takes the logarithm of each slack (68,000 at the eight's finest mesh,
/// on the serial part of the line search), where a multiplication costs a fraction of a
/// logarithm. Accuracy: the product's `n` roundings of `ε/2` each against the sum's
/// rounding at the running total's magnitude; a value that is not a positive normal
/// number (zero, negative, subnormal, infinite, NaN) takes its own `ln`, so the sum is
/// `−∞` or NaN where the plain sum is.
#[derive(Clone, Copy, Debug)]
pub(super) struct LogSum {
    mantissa: f64,
    exponent: i64,
    others: f64,
}

impl Default for LogSum {
    fn default() -> Self {
        LogSum {
            mantissa: 1.0,
            exponent: 0,
            others: 0.0,
        }
    }
}

const MANTISSA_MASK: u64 = (1 << 52) - 1;
const EXPONENT_OF_ONE: u64 = 1023 << 52;

/// `(m, e)` with `x = m 2^e`, `m ∈ [1, 2)`, for a positive normal `x`.
fn split_binary(x: f64) -> (f64, i64) {
    let bits = x.to_bits();
    let e = (bits >> 52) as i64 - 1023;
    (f64::from_bits((bits & MANTISSA_MASK) | EXPONENT_OF_ONE), e)
}

impl LogSum {
    pub(super) fn add(&mut self, t: f64) {
        if t.is_normal() && t > 0.0 {
            let (m, e) = split_binary(t);
            let (p, pe) = split_binary(self.mantissa * m);
            self.mantissa = p;
            self.exponent += e + pe;
        } else {
            self.others += t.ln();
        }
    }

    pub(super) fn value(&self) -> f64 {
        self.mantissa.ln() + self.exponent as f64 * std::f64::consts::LN_2 + self.others
    }
}

#[cfg(test)]
mod tests {
    use super::LogSum;
    use dmech_lie::lcg::Lcg;

    /// Against the plain sum of logarithms, on numbers spread over the whole normal range
    /// (and many of them, as at a fine mesh). Bound: the product's relative error is at
    /// most `n ε` (one rounding of `ε/2` per factor; its logarithm's error the same), the
    /// plain sum's `n ε` times the largest running total, and `(Σ e) ln 2` one rounding of
    /// its magnitude.
    #[test]
    fn log_sum_is_the_sum_of_logarithms() {
        let mut seed = Lcg(11);
        for n in [1usize, 2, 17, 1000, 70_000] {
            let mut sum = LogSum::default();
            let (mut plain, mut largest) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = seed.uniform() + 0.5; // [0, 1)
                let t = 10f64.powf(600.0 * u - 300.0);
                sum.add(t);
                plain += t.ln();
                largest = largest.max(plain.abs());
            }
            let eps = f64::EPSILON;
            let bound = n as f64 * eps * (1.0 + largest) + 2.0 * eps * plain.abs();
            let err = (sum.value() - plain).abs();
            assert!(
                err <= bound,
                "n = {n}: |{} − {plain}| = {err:e} > {bound:e}",
                sum.value()
            );
        }
    }

    /// A value that is not a positive normal number gives what its logarithm gives.
    #[test]
    fn log_sum_of_zero_negative_and_subnormal() {
        let of = |t: &[f64]| {
            let mut s = LogSum::default();
            t.iter().for_each(|&x| s.add(x));
            s.value()
        };
        assert_eq!(of(&[2.0, 0.0, 3.0]), f64::NEG_INFINITY);
        assert!(of(&[2.0, -1.0]).is_nan());
        assert!(of(&[f64::NAN, 1.0]).is_nan());
        let tiny = f64::MIN_POSITIVE / 8.0; // subnormal
        let want = tiny.ln() + 5f64.ln();
        assert!((of(&[tiny, 5.0]) - want).abs() <= 4.0 * f64::EPSILON * want.abs());
        assert_eq!(of(&[]), 0.0);
    }
}
