//! Where the model fails: which operating conditions a channel's residual follows. For
//! each condition (the plant's, e.g. wheel speed near zero, sign of the wheel speed, large
//! commanded voltage, tilt above its median; and the second half of the log) the rows split
//! into two groups, and the
//! residual's normalised power `(r/σ)²` and mean `r/σ` are compared between them by a
//! Welch statistic. Residuals are autocorrelated (a model error is slow), so each group's
//! sample count is replaced by its effective count `n (1 − ρ₁)/(1 + ρ₁)` (AR(1)
//! approximation, `ρ₁` the lag-one autocorrelation of the channel's residual); the critical
//! value is that of [`super::adequacy`] shared over every comparison.

use super::adequacy::critical_z;
use super::log::MeasuredLog;
use super::noise::Residuals;
use super::Indicator;

/// One operating condition that a channel's residual follows.
#[derive(Clone, Debug)]
pub struct Condition {
    /// Index of the channel in the plant's channels.
    pub channel: usize,
    /// The condition, in words (e.g. "wheel speed near zero").
    pub condition: String,
    /// `"level"`: `(r/σ)²` differs; `"mean"`: `r/σ` differs.
    pub measure: &'static str,
    /// The measure inside and outside the condition.
    pub inside: f64,
    pub outside: f64,
    /// Welch statistic with effective sample counts.
    pub z: f64,
}

/// The second half of the log against the first: a trend in time, for every system.
pub fn trend(log: &MeasuredLog) -> Indicator {
    let n = log.len();
    Indicator {
        name: "second half of the log (trend in time)".into(),
        flags: (0..n).map(|k| Some(k >= n / 2)).collect(),
    }
}

/// Rows where a value lies above its median (`None` where the value is undefined).
pub fn above_median(name: &str, values: &[Option<f64>]) -> Option<Indicator> {
    let mut v: Vec<f64> = values.iter().flatten().copied().collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let q = v[v.len() / 2];
    Some(Indicator {
        name: name.into(),
        flags: values.iter().map(|x| x.map(|a| a > q)).collect(),
    })
}

/// Rows where the magnitude of a value lies in its lowest quarter ("near zero").
pub fn near_zero(name: &str, values: &[Option<f64>]) -> Option<Indicator> {
    let mut v: Vec<f64> = values.iter().flatten().map(|x| x.abs()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let q1 = v[v.len() / 4];
    Some(Indicator {
        name: name.into(),
        flags: values.iter().map(|x| x.map(|a| a.abs() <= q1)).collect(),
    })
}

/// Rows where a value is positive.
pub fn positive(name: &str, values: &[Option<f64>]) -> Indicator {
    Indicator {
        name: name.into(),
        flags: values.iter().map(|x| x.map(|a| a > 0.0)).collect(),
    }
}

struct Group {
    n: f64,
    sum: f64,
    sum2: f64,
}

impl Group {
    fn mean(&self) -> f64 {
        self.sum / self.n
    }
    fn var(&self) -> f64 {
        ((self.sum2 - self.sum * self.sum / self.n) / (self.n - 1.0)).max(0.0)
    }
}

/// The conditions (the plant's `ind` and a trend in time) that the residual of the given
/// channels follows, strongest first.
pub fn conditions(
    log: &MeasuredLog,
    mut ind: Vec<Indicator>,
    res: &Residuals,
    sigma: &[f64],
    channels: &[usize],
) -> Vec<Condition> {
    ind.push(trend(log));
    let critical = critical_z(2 * ind.len() * channels.len().max(1));
    let mut out = Vec::new();
    for &c in channels {
        let s = sigma[c];
        if !s.is_finite() {
            continue;
        }
        let x: Vec<Option<f64>> = (0..res.rows())
            .map(|k| {
                let r = res.get(k, c);
                r.is_finite().then(|| r / s)
            })
            .collect();
        // Lag-one autocorrelation of r/σ and of (r/σ)² (consecutive rows where both exist).
        let rho = |f: &dyn Fn(f64) -> f64| {
            let vals: Vec<f64> = x.iter().flatten().map(|v| f(*v)).collect();
            let m = vals.iter().sum::<f64>() / vals.len().max(1) as f64;
            let (mut num, mut den) = (0.0, 0.0);
            for k in 0..x.len() {
                if let Some(a) = x[k] {
                    den += (f(a) - m).powi(2);
                    if let Some(Some(b)) = x.get(k + 1) {
                        num += (f(a) - m) * (f(*b) - m);
                    }
                }
            }
            if den > 0.0 {
                (num / den).clamp(-0.99, 0.99)
            } else {
                0.0
            }
        };
        for (measure, f) in [
            ("level", &(|v: f64| v * v) as &dyn Fn(f64) -> f64),
            ("mean", &(|v: f64| v) as &dyn Fn(f64) -> f64),
        ] {
            let r1 = rho(f);
            let shrink = (1.0 - r1) / (1.0 + r1);
            for Indicator { name, flags } in &ind {
                let mut g = [
                    Group {
                        n: 0.0,
                        sum: 0.0,
                        sum2: 0.0,
                    },
                    Group {
                        n: 0.0,
                        sum: 0.0,
                        sum2: 0.0,
                    },
                ];
                for (xv, fl) in x.iter().zip(flags) {
                    if let (Some(v), Some(b)) = (xv, fl) {
                        let gi = usize::from(*b);
                        let y = f(*v);
                        g[gi].n += 1.0;
                        g[gi].sum += y;
                        g[gi].sum2 += y * y;
                    }
                }
                if g[0].n < 10.0 || g[1].n < 10.0 {
                    continue;
                }
                let se = (g[0].var() / (g[0].n * shrink) + g[1].var() / (g[1].n * shrink)).sqrt();
                if se <= 0.0 {
                    continue;
                }
                let z = (g[1].mean() - g[0].mean()) / se;
                if z.abs() > critical {
                    out.push(Condition {
                        channel: c,
                        condition: name.clone(),
                        measure,
                        inside: g[1].mean(),
                        outside: g[0].mean(),
                        z,
                    });
                }
            }
        }
    }
    out.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
    out
}
