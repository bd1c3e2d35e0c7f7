//! "Is anything left?": per-channel tests of a residual against white measurement noise,
//! with the sample count in the statistics, so that a small systematic error over a long
//! log is found where a rule on the overall error alone cannot see it.
//!
//! For a channel with `n` residual samples `r_k` inside the prediction windows and noise
//! level `σ̂` from first differences (`σ̂² = mean(Δr²)/2`, [`super::noise::difference_noise`]),
//! three statistics are standard normal when the residual is white Gaussian noise:
//!
//! - mean: `z_M = mean(r)·√n/σ̂` (two-sided);
//! - level: `z_L = (mean(r²)/σ̂² − 1)·√n` (one-sided, excess). Var of `mean(r²)` is `2σ⁴/n`,
//!   of `σ̂²` is `3σ⁴/n` (the differences `Δ_k` have variance `2σ²` and lag-one covariance
//!   `−σ²`), their covariance `2σ⁴/n`; so `Var(ln ratio) = (2 + 3 − 2·2)/n = 1/n`;
//! - whiteness: the lag-one autocorrelation `ρ₁ = Σ r_k r_{k+1} / Σ r_k²` over consecutive
//!   samples within windows, `z_W = ρ₁·√n` (one-sided, positive: a model error varies slowly
//!   from sample to sample; Durbin–Watson `DW ≈ 2(1 − ρ₁)`).
//!
//! The window's fitted initial state removes part of the noise from the residual, which
//! lowers `mean(r²)` and makes `ρ₁` and `mean(r)` lean negative: each test is then
//! conservative, never liberal. The thresholds come from the normal distribution at a
//! false-alarm rate [`FALSE_ALARM`] per log, split evenly (Bonferroni) over the tests of
//! every measured channel.

use super::log::MeasuredLog;
use super::noise::{sample_gap, Residuals};

/// The probability that a log whose residual is pure white noise fails some test.
pub const FALSE_ALARM: f64 = 1e-3;

/// The three statistics of one channel.
#[derive(Clone, Copy, Debug)]
pub struct ChannelTest {
    /// Index of the channel in the plant's channels.
    pub channel: usize,
    /// Residual samples in the statistics.
    pub n: usize,
    /// Mean test `z_M = mean(r)·√n/σ̂`, two-sided: a bias left in the reading.
    pub z_mean: f64,
    /// Level test `z_L = (mean(r²)/σ̂² − 1)·√n`, one-sided: residual power above the noise
    /// floor.
    pub z_level: f64,
    /// Whiteness test `z_W = ρ₁·√n` (lag-one autocorrelation within windows), one-sided:
    /// a slowly varying model error.
    pub z_white: f64,
    /// `RMS(r)/σ̂`.
    pub ratio: f64,
    /// The critical value every `|z|` is compared with.
    pub critical: f64,
}

impl ChannelTest {
    /// Whether the residual is consistent with white noise: `|z_mean|`, `z_level` and
    /// `z_white` all at most [`ChannelTest::critical`].
    pub fn passes(&self) -> bool {
        self.z_mean.abs() <= self.critical
            && self.z_level <= self.critical
            && self.z_white <= self.critical
    }

    /// Which tests fail, in words.
    pub fn failures(&self) -> Vec<&'static str> {
        let mut f = Vec::new();
        if self.z_mean.abs() > self.critical {
            f.push("mean");
        }
        if self.z_level > self.critical {
            f.push("level");
        }
        if self.z_white > self.critical {
            f.push("whiteness");
        }
        f
    }
}

/// The standard normal quantile `Φ⁻¹(p)` for `0 < p < 1` (Acklam's rational approximation,
/// relative error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e+01,
        2.209460984245205e+02,
        -2.759285104469687e+02,
        1.383_577_518_672_69e2,
        -3.066479806614716e+01,
        2.506628277459239e+00,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e+01,
        1.615858368580409e+02,
        -1.556989798598866e+02,
        6.680131188771972e+01,
        -1.328068155288572e+01,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-03,
        -3.223964580411365e-01,
        -2.400758277161838e+00,
        -2.549732539343734e+00,
        4.374664141464968e+00,
        2.938163982698783e+00,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-03,
        3.224671290700398e-01,
        2.445134137142996e+00,
        3.754408661907416e+00,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// The critical `z` for `n_tests` tests sharing the false-alarm rate [`FALSE_ALARM`]
/// (one-sided each; the two-sided mean test uses the same value, which halves its share
/// again: conservative).
pub fn critical_z(n_tests: usize) -> f64 {
    -normal_quantile(FALSE_ALARM / n_tests.max(1) as f64)
}

/// The tests of every channel with a finite noise level `sigma[c]`. Consecutive samples
/// of a channel are pairs for the whiteness test only inside a window and at most `gap(c)`
/// rows apart (the pose channels come every few rows).
pub fn channel_tests(
    log: &MeasuredLog,
    res: &Residuals,
    windows: &[(usize, usize)],
    sigma: &[f64],
) -> Vec<ChannelTest> {
    let channels: Vec<usize> = (0..log.n_channels)
        .filter(|&c| log.present[c] && sigma[c].is_finite())
        .collect();
    let critical = critical_z(3 * channels.len());
    let mut out = Vec::new();
    for c in channels {
        let s = sigma[c];
        let gap = sample_gap(log, c);
        let (mut n, mut sum, mut sum2, mut lag) = (0usize, 0.0, 0.0, 0.0);
        for &(start, len) in windows {
            let mut prev: Option<(usize, f64)> = None;
            for k in start..start + len {
                let v = res.get(k, c);
                if !v.is_finite() {
                    continue;
                }
                n += 1;
                sum += v;
                sum2 += v * v;
                if let Some((kp, vp)) = prev {
                    if k - kp <= gap {
                        lag += v * vp;
                    }
                }
                prev = Some((k, v));
            }
        }
        if n < 2 || sum2 <= 0.0 {
            continue;
        }
        let nf = n as f64;
        let ms = sum2 / nf;
        out.push(ChannelTest {
            channel: c,
            n,
            z_mean: sum / nf * nf.sqrt() / s,
            z_level: (ms / (s * s) - 1.0) * nf.sqrt(),
            z_white: lag / sum2 * nf.sqrt(),
            ratio: ms.sqrt() / s,
            critical,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::difference_noise;
    use dmech_lie::rng::Rng;

    #[test]
    fn normal_quantile_matches_known_values() {
        // Φ⁻¹ at 0.975, 0.999 and 1e-6 (tables), to the approximation's 1.2e-9.
        assert!((normal_quantile(0.975) - 1.959963984540054).abs() < 1e-8);
        assert!((normal_quantile(0.999) - 3.090232306167814).abs() < 1e-8);
        assert!((normal_quantile(1e-6) + 4.753424308822899).abs() < 1e-7);
    }

    /// A one-channel log whose residual is `r`.
    fn log_of(r: &[f64]) -> (MeasuredLog, Residuals) {
        let mut log = MeasuredLog::empty(0.01, 1, 1);
        let mut res = Residuals::new(r.len(), 1);
        for (k, v) in r.iter().enumerate() {
            log.push_row(k as f64 * 0.01, &[0.0], &[0.0]);
            res.set(k, 0, *v);
        }
        log.channels_present_from_data();
        (log, res)
    }

    fn tests_of(r: &[f64]) -> ChannelTest {
        let (log, res) = log_of(r);
        let windows: Vec<(usize, usize)> = (0..r.len() / 50).map(|w| (w * 50, 50)).collect();
        let sigma = [difference_noise(r.iter().copied().enumerate(), 1)];
        channel_tests(&log, &res, &windows, &sigma)[0]
    }

    fn gauss(rng: &mut Rng) -> f64 {
        rng.normal()
    }

    /// White noise passes at about the stated rate; the z statistics have unit spread
    /// (the variance derivation in the module comment).
    #[test]
    fn white_noise_passes_and_statistics_are_standard() {
        let mut rng = Rng::new(7);
        let (mut fails, runs) = (0, 200);
        let mut zl = Vec::new();
        for _ in 0..runs {
            let r: Vec<f64> = (0..3000).map(|_| gauss(&mut rng)).collect();
            let t = tests_of(&r);
            if !t.passes() {
                fails += 1;
            }
            zl.push(t.z_level);
        }
        // 200 runs at a 1e-3 false-alarm rate: P(≥ 3 failures) ≈ 1e-3.
        assert!(fails <= 2, "{fails} of {runs} white-noise runs failed");
        let mean = zl.iter().sum::<f64>() / runs as f64;
        let var = zl.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / (runs - 1) as f64;
        // The sample variance of 200 unit normals lies in [0.7, 1.35] with probability > 0.999.
        assert!((0.7..1.35).contains(&var), "Var(z_level) = {var}");
    }

    /// The case: a residual 1.2 × its noise from a slow error over 3000 samples.
    #[test]
    fn a_twenty_percent_slow_excess_is_found() {
        let mut rng = Rng::new(11);
        // A sinusoid of 1 s period, amplitude giving RMS² = 0.44 σ² (1.2² − 1).
        let a = (2.0f64 * 0.44).sqrt();
        let r: Vec<f64> = (0..3000)
            .map(|k| gauss(&mut rng) + a * (k as f64 * 0.01 * std::f64::consts::TAU).sin())
            .collect();
        let t = tests_of(&r);
        assert!(!t.passes(), "{t:?}");
        assert!(t.failures().contains(&"level"), "{t:?}");
    }
}
