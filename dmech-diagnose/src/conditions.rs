//! Where the model fails: which operating conditions a channel's residual follows. For
//! each condition (the plant's, e.g. wheel speed near zero, sign of the wheel speed, large
//! commanded voltage, tilt above its median; and the second half of the log) the rows split
//! into two groups, and the
//! residual's normalised power `(r/σ)²` and mean `r/σ` are compared between them by a
//! paired t statistic over the windows (`t_statistic`: per window the difference between
//! the groups, of the log level or of the mean). Residuals are autocorrelated inside a
//! window (a model error is slow) but the windows are independent, each with its own fitted
//! state. (An AR(1) effective count over the whole log, `n (1 − ρ₁)/(1 + ρ₁)`, shrank a
//! slow residual's count to a few samples and named no condition on the hidden-effect
//! tests, though the groups interleave inside each window; an unpaired cluster-robust
//! difference let the window-to-window variation of the level swamp a ratio of 14.) A
//! condition that holds for whole windows (a wheel slow through most of a window, its
//! residual large throughout) leaves little inside a window; for the level, a second test
//! over the windows correlates each window's log level with the fraction of its rows
//! inside the condition (`between_windows`). The critical value is that of
//! [`super::adequacy`] shared over every comparison (three per channel and condition),
//! moved to Student's `t` on the test's degrees of freedom; `z` is reported on the normal
//! scale, the stronger of the two tests.

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
    /// The measure's mean over the rows where the condition holds.
    pub inside: f64,
    /// The measure's mean over the rows where it does not.
    pub outside: f64,
    /// The t statistic (paired over windows, or for the level between windows, whichever is
    /// stronger) on the normal scale of the critical value.
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

#[derive(Default)]
struct Group {
    n: f64,
    sum: f64,
}

impl Group {
    fn add(&mut self, y: f64) {
        self.n += 1.0;
        self.sum += y;
    }
    fn mean(&self) -> f64 {
        self.sum / self.n
    }
}

/// Samples of each group a window needs to enter the paired comparison.
const MIN_IN_WINDOW: f64 = 3.0;

/// `mean(d) / (sd(d)/√G)` (at least three differences, not all equal).
fn t_statistic(d: &[f64]) -> Option<f64> {
    let g = d.len() as f64;
    if d.len() < 3 || d.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let m = d.iter().sum::<f64>() / g;
    let var = d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (g - 1.0);
    (var > 0.0).then(|| m / (var / g).sqrt())
}

/// Windows a between-window comparison needs.
const MIN_WINDOWS: usize = 5;

/// The level between windows: over the windows (independent, each with its own fitted
/// state), the correlation of the log of the window's level `mean((r/σ)²)` with the
/// fraction of its rows inside the condition, as Pearson's `t = r sqrt((G−2)/(1−r²))` on
/// `G − 2` degrees of freedom, with `G`. This sees a condition that holds for whole
/// windows (a wheel slow through most of a window, its residual large throughout) where
/// the paired comparison inside windows sees little.
fn between_windows(
    x: &[Option<f64>],
    flags: &[Option<bool>],
    windows: &[(usize, usize)],
) -> Option<(f64, usize)> {
    let mut pts = Vec::new();
    for &(start, len) in windows {
        let (mut level, mut inside, mut n) = (0.0, 0.0, 0.0);
        for (xv, fl) in x.iter().zip(flags).skip(start).take(len) {
            if let (Some(v), Some(b)) = (xv, fl) {
                level += v * v;
                inside += f64::from(u8::from(*b));
                n += 1.0;
            }
        }
        if n >= 2.0 * MIN_IN_WINDOW && level > 0.0 {
            pts.push((inside / n, (level / n).ln()));
        }
    }
    let g = pts.len();
    if g < MIN_WINDOWS {
        return None;
    }
    let gf = g as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), (p, q)| (a + p / gf, b + q / gf));
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (p, q) in &pts {
        sxy += (p - mx) * (q - my);
        sxx += (p - mx) * (p - mx);
        syy += (q - my) * (q - my);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        return None;
    }
    let r = (sxy / (sxx * syy).sqrt()).clamp(-1.0 + 1e-12, 1.0 - 1e-12);
    Some((r * ((gf - 2.0) / (1.0 - r * r)).sqrt(), g))
}

/// `t_ν(p) / z(p)` for the normal quantile `z`: the Cornish–Fisher expansion of Student's
/// quantile (Abramowitz & Stegun 26.7.5), `t = z + (z³ + z)/(4ν) + (5z⁵ + 16z³ + 3z)/(96ν²)`.
/// Dividing `t` by it puts the statistic on the normal scale of the critical value.
fn t_critical_ratio(z: f64, nu: usize) -> f64 {
    let nu = nu as f64;
    let t = z
        + (z.powi(3) + z) / (4.0 * nu)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * nu * nu);
    t / z
}

/// The conditions (the plant's `ind` and a trend in time) that the residual of the given
/// channels follows, strongest first.
pub fn conditions(
    log: &MeasuredLog,
    mut ind: Vec<Indicator>,
    res: &Residuals,
    windows: &[(usize, usize)],
    sigma: &[f64],
    channels: &[usize],
) -> Vec<Condition> {
    ind.push(trend(log));
    // Per channel and condition: the mean and the level paired, the level between windows.
    let critical = critical_z(3 * ind.len() * channels.len().max(1));
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
        for (measure, f) in [
            ("level", &(|v: f64| v * v) as &dyn Fn(f64) -> f64),
            ("mean", &(|v: f64| v) as &dyn Fn(f64) -> f64),
        ] {
            for Indicator { name, flags } in &ind {
                let mut g = [Group::default(), Group::default()];
                for (xv, fl) in x.iter().zip(flags) {
                    if let (Some(v), Some(b)) = (xv, fl) {
                        g[usize::from(*b)].add(f(*v));
                    }
                }
                if g[0].n < 10.0 || g[1].n < 10.0 {
                    continue;
                }
                // Paired over windows: in each window holding both groups, the difference
                // between them (of the log of the level: a slow residual's level varies
                // from window to window by factors, and the log makes that variation
                // additive and cancels it); windows are independent, each with its own
                // fitted state, so the differences are independent under the hypothesis
                // that the condition does not matter: a t statistic on G − 1 degrees of
                // freedom, whatever the correlation inside a window.
                let mut d = Vec::new();
                for &(start, len) in windows {
                    let mut w = [Group::default(), Group::default()];
                    for (xv, fl) in x.iter().zip(flags).skip(start).take(len) {
                        if let (Some(v), Some(b)) = (xv, fl) {
                            w[usize::from(*b)].add(f(*v));
                        }
                    }
                    if w[0].n < MIN_IN_WINDOW || w[1].n < MIN_IN_WINDOW {
                        continue;
                    }
                    d.push(if measure == "level" {
                        (w[1].mean() / w[0].mean()).ln()
                    } else {
                        w[1].mean() - w[0].mean()
                    });
                }
                let paired = t_statistic(&d).map(|t| t / t_critical_ratio(critical, d.len() - 1));
                let between = if measure == "level" {
                    between_windows(&x, flags, windows)
                        .map(|(t, g)| t / t_critical_ratio(critical, g - 2))
                } else {
                    None
                };
                // The stronger of the two on the normal scale.
                let Some(z) = [paired, between]
                    .into_iter()
                    .flatten()
                    .max_by(|a, b| a.abs().total_cmp(&b.abs()))
                else {
                    continue;
                };
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
