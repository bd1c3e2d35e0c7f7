//! Noise levels and the error measure. A channel's noise level is estimated from first
//! differences of a residual within the prediction windows, `σ² = mean(Δr²)/2`: white noise
//! passes a difference, a model error that varies slowly over a sample step barely does.
//! The error of a model is `E = sqrt(mean_c (RMS_c/σ_c)²)` over the measured channels:
//! `E = 1` is the noise floor (docs/diagnose.md §4).

use super::log::MeasuredLog;

/// Residuals (prediction − reading) of a fitted model per row and channel, NaN outside the
/// windows or where not measured.
#[derive(Clone, Debug)]
pub struct Residuals {
    /// The residuals row after row, `n_channels` per row (in each channel's unit).
    pub r: Vec<f64>,
    /// Channels per row.
    pub n_channels: usize,
}

impl Residuals {
    /// `rows × n_channels` residuals, all NaN.
    pub fn new(rows: usize, n_channels: usize) -> Self {
        Residuals {
            r: vec![f64::NAN; rows * n_channels],
            n_channels,
        }
    }
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.r.len() / self.n_channels.max(1)
    }
    /// The residual of channel `c` at row `k` (NaN where there is none).
    pub fn get(&self, k: usize, c: usize) -> f64 {
        self.r[k * self.n_channels + c]
    }
    /// Set the residual of channel `c` at row `k`.
    pub fn set(&mut self, k: usize, c: usize, v: f64) {
        self.r[k * self.n_channels + c] = v;
    }
    /// One channel's residuals with their rows, skipping NaN.
    pub fn channel(&self, c: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..self.rows())
            .map(move |k| (k, self.get(k, c)))
            .filter(|(_, v)| !v.is_nan())
    }
}

/// Noise level of a sequence from its first differences between consecutive samples:
/// `σ² = mean(Δr²)/2` for white noise. Samples at NaN are skipped; pairs further apart
/// than `max_gap` rows are not used.
pub fn difference_noise(r: impl Iterator<Item = (usize, f64)>, max_gap: usize) -> f64 {
    let mut prev: Option<(usize, f64)> = None;
    let (mut s, mut n) = (0.0, 0usize);
    for (k, v) in r {
        if v.is_nan() {
            continue;
        }
        if let Some((kp, vp)) = prev {
            if k - kp <= max_gap {
                s += (v - vp) * (v - vp);
                n += 1;
            }
        }
        prev = Some((k, v));
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / (2.0 * n as f64)).sqrt()
    }
}

/// Noise from second differences of the readings themselves (`σ² = mean(Δ²y)/6`), used
/// only to weight the first nominal fit.
pub fn raw_noise(log: &MeasuredLog, c: usize) -> f64 {
    let pts: Vec<(usize, f64)> = (0..log.len())
        .filter_map(|k| log.value(k, c).map(|v| (k, v)))
        .collect();
    let (mut s, mut n) = (0.0, 0usize);
    for w in pts.windows(3) {
        let d = w[2].1 - 2.0 * w[1].1 + w[0].1;
        s += d * d;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / (6.0 * n as f64)).sqrt().max(1e-9)
    }
}

/// The rows between consecutive samples of a channel (a pose from a tracking system may
/// come every few rows): the smallest gap.
pub fn sample_gap(log: &MeasuredLog, c: usize) -> usize {
    let mut prev = None;
    let mut gap = usize::MAX;
    for k in 0..log.len() {
        if log.value(k, c).is_some() {
            if let Some(p) = prev {
                gap = gap.min(k - p);
            }
            prev = Some(k);
        }
    }
    if gap == usize::MAX {
        1
    } else {
        gap
    }
}

/// Per-channel noise from a fit's residuals, within windows (NaN for absent channels).
pub fn residual_noise(log: &MeasuredLog, res: &Residuals, windows: &[(usize, usize)]) -> Vec<f64> {
    let mut sigma = vec![f64::NAN; log.n_channels];
    for (c, s) in sigma.iter_mut().enumerate() {
        if !log.present[c] {
            continue;
        }
        let gap = sample_gap(log, c);
        // Differences only inside a window (the prediction restarts between windows).
        let (mut s2, mut n) = (0.0, 0.0);
        for &(start, len) in windows {
            let sd = difference_noise((start..start + len).map(|k| (k, res.get(k, c))), gap);
            let cnt = (start..start + len)
                .filter(|&k| !res.get(k, c).is_nan())
                .count() as f64;
            if sd.is_finite() && cnt > 1.0 {
                s2 += sd * sd * (cnt - 1.0);
                n += cnt - 1.0;
            }
        }
        if n > 0.0 {
            *s = (s2 / n).sqrt().max(1e-9);
        }
    }
    sigma
}

/// `RMS(r_c)/σ_c` per channel (NaN where absent), and the error
/// `sqrt(mean_c (RMS_c/σ_c)²)`.
pub fn normalised_error(res: &Residuals, sigma: &[f64]) -> (Vec<f64>, f64) {
    let mut per = vec![f64::NAN; res.n_channels];
    let (mut sum, mut n) = (0.0, 0);
    for (c, p) in per.iter_mut().enumerate() {
        let s = sigma[c];
        if !s.is_finite() {
            continue;
        }
        let (mut ss, mut cnt) = (0.0, 0usize);
        for (_, v) in res.channel(c) {
            ss += v * v;
            cnt += 1;
        }
        if cnt == 0 {
            continue;
        }
        let ratio = (ss / cnt as f64).sqrt() / s;
        *p = ratio;
        sum += ratio * ratio;
        n += 1;
    }
    (
        per,
        if n > 0 {
            (sum / n as f64).sqrt()
        } else {
            f64::NAN
        },
    )
}
