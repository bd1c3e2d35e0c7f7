//! Where the model fails: which operating conditions a channel's residual follows. For
//! each condition (wheel speed near zero, sign of the wheel speed, large commanded voltage,
//! second half of the log, tilt above its median) the rows split into two groups, and the
//! residual's normalised power `(r/σ)²` and mean `r/σ` are compared between them by a
//! Welch statistic. Residuals are autocorrelated (a model error is slow), so each group's
//! sample count is replaced by its effective count `n (1 − ρ₁)/(1 + ρ₁)` (AR(1)
//! approximation, `ρ₁` the lag-one autocorrelation of the channel's residual); the critical
//! value is that of [`super::adequacy`] shared over every comparison.

use super::adequacy::critical_z;
use super::fit::Residuals;
use super::measured::{Channel, MeasuredLog};

/// One operating condition that a channel's residual follows.
#[derive(Clone, Debug)]
pub struct Condition {
    pub channel: Channel,
    /// The condition, in words (e.g. "wheel speed near zero").
    pub condition: &'static str,
    /// `"level"`: `(r/σ)²` differs; `"mean"`: `r/σ` differs.
    pub measure: &'static str,
    /// The measure inside and outside the condition.
    pub inside: f64,
    pub outside: f64,
    /// Welch statistic with effective sample counts.
    pub z: f64,
}

/// The per-row condition indicators (`None` where undefined).
fn indicators(log: &MeasuredLog) -> Vec<(&'static str, Vec<Option<bool>>)> {
    let n = log.len();
    let mut out = Vec::new();
    // Mean wheel speed relative to the body, from the wheel-angle readings (central
    // differences over two rows).
    let wheel = |k: usize| -> Option<f64> {
        let a = [Channel::PhiRRel, Channel::PhiLRel];
        let (mut s, mut m) = (0.0, 0);
        for c in a {
            if k >= 1 && k + 1 < n {
                if let (Some(y1), Some(y0)) = (log.value(k + 1, c), log.value(k - 1, c)) {
                    s += (y1 - y0) / (2.0 * log.h);
                    m += 1;
                }
            }
        }
        (m > 0).then(|| s / m as f64)
    };
    let w: Vec<Option<f64>> = (0..n).map(wheel).collect();
    let median = |v: &mut Vec<f64>| -> Option<f64> {
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 2])
    };
    let mut aw: Vec<f64> = w.iter().flatten().map(|x| x.abs()).collect();
    if median(&mut aw).is_some() {
        // "Near zero": the slowest quarter of the rows.
        let q1 = aw[aw.len() / 4];
        out.push((
            "wheel speed near zero (slowest quarter)",
            w.iter().map(|x| x.map(|v| v.abs() <= q1)).collect(),
        ));
        out.push((
            "wheel speed positive",
            w.iter().map(|x| x.map(|v| v > 0.0)).collect(),
        ));
    }
    let mut au: Vec<f64> = log.cmd.iter().map(|u| 0.5 * (u[0] + u[1]).abs()).collect();
    if let Some(q) = median(&mut au) {
        out.push((
            "commanded voltage above its median",
            log.cmd
                .iter()
                .map(|u| Some(0.5 * (u[0] + u[1]).abs() > q))
                .collect(),
        ));
    }
    out.push((
        "second half of the log (trend in time)",
        (0..n).map(|k| Some(k >= n / 2)).collect(),
    ));
    let mut tilt: Vec<f64> = (0..n)
        .filter_map(|k| log.value(k, Channel::Alpha))
        .collect();
    if let Some(q) = median(&mut tilt) {
        out.push((
            "tilt above its median",
            (0..n)
                .map(|k| log.value(k, Channel::Alpha).map(|a| a > q))
                .collect(),
        ));
    }
    out
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

/// The conditions that the residual of the given channels follows, strongest first.
pub fn conditions(
    log: &MeasuredLog,
    res: &Residuals,
    sigma: &[f64; 9],
    channels: &[Channel],
) -> Vec<Condition> {
    let ind = indicators(log);
    let critical = critical_z(2 * ind.len() * channels.len().max(1));
    let mut out = Vec::new();
    for &c in channels {
        let i = c.index();
        let s = sigma[i];
        if !s.is_finite() {
            continue;
        }
        let x: Vec<Option<f64>> = res
            .r
            .iter()
            .map(|r| r[i].is_finite().then(|| r[i] / s))
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
            for (name, flags) in &ind {
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
                        condition: name,
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
