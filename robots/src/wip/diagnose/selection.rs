//! Which effect explains the log: every candidate of the catalogue is fitted, scored by the
//! Bayesian information criterion (a parameter must pay `ln m` in `m ln(RSS/m)`), the best
//! is kept if it beats the nominal model; if the residual is still above the noise, pairs
//! with the best are tried. The error measure and the verdict are defined here.

use super::adequacy::{channel_tests, ChannelTest};
use super::effects::Effect;
use super::fit::{Candidate, Fit, FitSetup, Fitter, Residuals};
use super::measured::{Channel, MeasuredLog};
use crate::wip::WipParams;
use std::time::Instant;

/// Options of `diagnose`.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Window length (s) of the prediction-error fit.
    pub window_s: f64,
    pub threads: usize,
    pub max_iterations: usize,
    /// A model "explains" the log when its error is at most this (1 = the noise floor).
    pub explained: f64,
    /// Try pairs of effects when the best single effect leaves the error above `explained`.
    pub pairs: bool,
    /// At most this many single effects are fitted to convergence after screening.
    pub max_full_fits: usize,
    /// Effects of the catalogue left out (to test what the tool says about an effect it
    /// does not know).
    pub exclude: Vec<Effect>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            window_s: 0.5,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
            max_iterations: 15,
            explained: 1.2,
            pairs: true,
            max_full_fits: Effect::ALL.len(),
            exclude: Vec::new(),
        }
    }
}

/// One fitted candidate with its score and error.
#[derive(Clone, Debug)]
pub struct Scored {
    pub fit: Fit,
    /// BIC: `m ln(RSS/m) + k ln m` (lower is better).
    pub score: f64,
    /// The normalised error of the fitted model.
    pub error: f64,
    /// Fitted to convergence (`false`: only screened, one linearised step).
    pub fitted: bool,
    /// Parameters outside their physical range ([`Effect::plausible`]); such a candidate
    /// is never named.
    pub implausible: Vec<String>,
}

/// The outcome of `diagnose`.
pub struct Diagnosis {
    /// `"none"`, `"unexplained"`, or an effect name (the stronger one if two effects are
    /// found; `effects` lists both).
    pub cause: String,
    pub effects: Vec<Effect>,
    pub chosen: Scored,
    pub nominal: Scored,
    /// Every candidate tried, best (lowest score) first.
    pub candidates: Vec<Scored>,
    /// Noise level per channel used as fit weights (from the nominal model's residuals).
    pub sigma: [f64; 9],
    /// Noise level per channel from the chosen model's residuals: the error's yardstick
    /// (NaN where the channel is absent).
    pub sigma_final: [f64; 9],
    pub error_before: f64,
    pub error_after: f64,
    pub gain: f64,
    /// Per channel `RMS(r_c)/σ_c` before and after (NaN where absent).
    pub channel_before: [f64; 9],
    pub channel_after: [f64; 9],
    pub residuals_before: Residuals,
    pub residuals_after: Residuals,
    pub windows: Vec<(usize, usize)>,
    /// "Is anything left" per channel, for the nominal model and the chosen one
    /// ([`super::adequacy`]).
    pub tests_before: Vec<ChannelTest>,
    pub tests_after: Vec<ChannelTest>,
    /// The operating conditions that the chosen model's residual follows, in the channels
    /// that fail their tests ([`super::conditions`]).
    pub conditions: Vec<super::conditions::Condition>,
    /// Readings dropped as far outside their channel's range (row, channel, value).
    pub flagged: Vec<String>,
    /// A one-paragraph verdict for the report.
    pub verdict: String,
    pub elapsed_s: f64,
}

/// Noise level of a sequence from its first differences between consecutive samples:
/// `σ² = mean(Δr²)/2` for white noise; a model error that varies slowly over a sample
/// step barely enters. Samples at NaN are skipped; pairs further apart than `max_gap`
/// rows are not used.
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
fn raw_noise(log: &MeasuredLog, c: Channel) -> f64 {
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

/// The pose channels come every few rows: the largest gap between samples of a channel.
fn sample_gap(log: &MeasuredLog, c: Channel) -> usize {
    let ks: Vec<usize> = (0..log.len())
        .filter(|&k| log.value(k, c).is_some())
        .collect();
    ks.windows(2).map(|w| w[1] - w[0]).min().unwrap_or(1)
}

/// Per-channel noise from a fit's residuals, within windows.
fn residual_noise(log: &MeasuredLog, res: &Residuals, windows: &[(usize, usize)]) -> [f64; 9] {
    let mut sigma = [f64::NAN; 9];
    for c in Channel::ALL {
        if !log.present[c.index()] {
            continue;
        }
        let gap = sample_gap(log, c);
        // Differences only inside a window (the prediction restarts between windows).
        let mut s2 = 0.0;
        let mut n = 0.0;
        for &(start, len) in windows {
            let sd = difference_noise((start..start + len).map(|k| (k, res.r[k][c.index()])), gap);
            let cnt = (start..start + len)
                .filter(|&k| !res.r[k][c.index()].is_nan())
                .count() as f64;
            if sd.is_finite() && cnt > 1.0 {
                s2 += sd * sd * (cnt - 1.0);
                n += cnt - 1.0;
            }
        }
        if n > 0.0 {
            sigma[c.index()] = (s2 / n).sqrt().max(1e-9);
        }
    }
    sigma
}

/// `RMS(r_c)/σ_c` per channel, and the overall error `sqrt(mean_c (RMS_c/σ_c)²)`.
pub fn normalised_error(res: &Residuals, sigma: &[f64; 9]) -> ([f64; 9], f64) {
    let mut per = [f64::NAN; 9];
    let (mut sum, mut n) = (0.0, 0);
    for c in Channel::ALL {
        let s = sigma[c.index()];
        if !s.is_finite() {
            continue;
        }
        let vals: Vec<f64> = res
            .r
            .iter()
            .map(|r| r[c.index()])
            .filter(|v| !v.is_nan())
            .collect();
        if vals.is_empty() {
            continue;
        }
        let rms = (vals.iter().map(|v| v * v).sum::<f64>() / vals.len() as f64).sqrt();
        per[c.index()] = rms / s;
        sum += (rms / s).powi(2);
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

fn bic(fit: &Fit) -> f64 {
    let m = fit.m.max(1) as f64;
    m * (fit.rss / m).ln() + fit.candidate.n_params() as f64 * m.ln()
}

/// Diagnose a log against the model with parameters `params`.
pub fn diagnose(
    log: &MeasuredLog,
    params: &WipParams,
    opts: &DiagnoseOptions,
    progress: &dyn Fn(&str),
) -> Result<Diagnosis, String> {
    let t0 = Instant::now();
    let mut owned = log.clone();
    let flagged = owned.drop_out_of_range()?;
    for f in &flagged {
        progress(&format!("diagnose: warning: {f}"));
    }
    let log = &owned;
    owned_log_informative(log)?;
    let h = log.h;
    let window = (opts.window_s / h).round();
    // Fewer samples than this cannot separate an effect's response from the noise (and a
    // silent clamp would change the answer behind the user's back).
    const MIN_WINDOW: f64 = 10.0;
    if window.is_nan() || window < MIN_WINDOW {
        return Err(format!(
            "a window of {} s is {window} samples of {h} s; it needs at least {MIN_WINDOW} \
             samples (--window ≥ {} s)",
            opts.window_s,
            MIN_WINDOW * h
        ));
    }
    let window = window as usize;
    // Room for the delayed commands before the first window (delays up to 50 ms).
    let first_row = ((0.05 / h).ceil() as usize + 2).min(log.len() / 4);
    if log.len() < first_row + window {
        return Err(format!(
            "the log is too short: {} rows, need at least {} ({} s windows)",
            log.len(),
            first_row + window,
            opts.window_s
        ));
    }
    let mut sigma0 = [f64::INFINITY; 9];
    for c in Channel::ALL {
        if log.present[c.index()] {
            sigma0[c.index()] = raw_noise(log, c);
        }
    }
    let setup = FitSetup {
        first_row,
        window,
        sigma: sigma0,
        threads: opts.threads,
        max_iterations: opts.max_iterations,
    };
    let mut fitter = Fitter::new(log, params, setup);
    progress(&format!(
        "diagnose: {} rows, h = {} s, {} windows of {} s, {} threads",
        log.len(),
        h,
        fitter.windows.len(),
        window as f64 * h,
        opts.threads
    ));
    let quiet = |_: &str| {};
    let none = Candidate::none();
    let z_init = fitter.initial_states();
    // The first fit only sets the noise levels: a few iterations suffice.
    fitter.setup.max_iterations = opts.max_iterations.min(5);
    progress("  first fit of the nominal model (sets the noise levels)");
    let first = fitter.fit(&none, &[], &z_init, None, progress);
    fitter.setup.max_iterations = opts.max_iterations;
    // The noise floor of each channel, from the nominal fit's residuals; weights from here on.
    let sigma = residual_noise(log, &fitter.residuals(&first), &fitter.windows);
    fitter.setup.sigma = sigma.map(|s| if s.is_nan() { f64::INFINITY } else { s });
    progress("  nominal model under the noise weights");
    let nominal_fit = fitter.fit(&none, &[], &first.z0, None, progress);
    let z_nom = nominal_fit.z0.clone();
    // Scores and errors under the fitter's current weights.
    let score_of = |fit: Fit, fitter: &Fitter| {
        let (_, error) = normalised_error(&fitter.residuals(&fit), &fitter.setup.sigma);
        Scored {
            implausible: fit.candidate.implausible(&fit.theta, params),
            score: bic(&fit),
            fit,
            error,
            fitted: true,
        }
    };
    let nominal = score_of(nominal_fit, &fitter);
    progress(&format!(
        "  {:<28} error {:>8.3}  score {:>14.1}  ({:.1} s)",
        "none",
        nominal.error,
        nominal.score,
        t0.elapsed().as_secs_f64()
    ));

    // A candidate whose cost cannot fall below the best so far (plus what its parameters
    // cost in the criterion) is abandoned early.
    let best_rss = std::cell::Cell::new(nominal.fit.rss);
    let m_res = nominal.fit.m.max(1) as f64;
    let fit_candidate =
        |fitter: &Fitter, cand: Candidate, start: &[f64], z0: &[nalgebra::SVector<f64, 9>]| {
            let bound = best_rss.get() * (1.0 + cand.n_params() as f64 * m_res.ln() / m_res) + 50.0;
            let f = fitter.fit(&cand, start, z0, Some(bound), &quiet);
            if f.rss < best_rss.get() {
                best_rss.set(f.rss);
            }
            let s = score_of(f, fitter);
            progress(&format!(
                "  {:<28} error {:>8.3}  score {:>14.1}  {} iterations  ({:.1} s)",
                cand.name(),
                s.error,
                s.score,
                s.fit.iterations,
                t0.elapsed().as_secs_f64()
            ));
            s
        };
    let mut candidates = vec![nominal.clone()];
    // Screen the catalogue with one linearisation (the order of the fits, and the predicted
    // reductions in the progress output); fit the `opts.max_full_fits` most promising to
    // convergence (all of them by default: a linearisation misjudges the nonlinear effects,
    // dead zone and delay, and a full fit costs a fraction of a second).
    let m = nominal.fit.m.max(1) as f64;
    let screened = fitter
        .screen(&nominal.fit.z0, nominal.fit.rss, nominal.fit.m)
        .ok_or("the nominal model cannot be simulated over the log (the linearisation failed)")?;
    let mut order: Vec<&super::fit::Screened> = screened
        .iter()
        .filter(|s| !opts.exclude.contains(&s.effect))
        .collect();
    order.sort_by(|a, b| {
        let net = |s: &super::fit::Screened| s.reduction - s.effect.n_params() as f64 * m.ln();
        net(b).total_cmp(&net(a))
    });
    for (rank, sc) in order.iter().enumerate() {
        progress(&format!(
            "  screen {:<24} predicted reduction {:>12.1}  (a parameter costs {:.1})",
            sc.effect.name(),
            sc.reduction,
            m.ln()
        ));
        let cand = Candidate {
            effects: vec![sc.effect],
        };
        if rank < opts.max_full_fits {
            let start = cand.nominal(params);
            candidates.push(fit_candidate(&fitter, cand, &start, &z_nom));
        } else {
            let rss = (nominal.fit.rss - sc.reduction).max(0.0);
            let fit = Fit {
                candidate: cand,
                theta: sc.theta.clone(),
                std: sc.std.clone(),
                z0: vec![],
                rss,
                m: nominal.fit.m,
                iterations: 0,
                converged: false,
            };
            candidates.push(Scored {
                implausible: fit.candidate.implausible(&fit.theta, params),
                score: bic(&fit),
                error: nominal.error * (rss / nominal.fit.rss.max(1e-300)).sqrt(),
                fit,
                fitted: false,
            });
        }
    }
    let best_single = candidates
        .iter()
        .filter(|c| c.fitted && c.implausible.is_empty())
        .min_by(|a, b| a.score.total_cmp(&b.score))
        .expect("at least the nominal")
        .clone();
    let mut chosen = best_single.clone();
    let mut nominal = nominal;
    let mut sigma_used = sigma;
    // The weights came from the nominal model's residuals, which a strong effect inflates.
    // Re-estimate the noise from the chosen model's residuals; if it moved by more than
    // 10 % in some channel, refit the chosen and the nominal model with it (so that the
    // decisions below compare errors against the noise, not against the nominal misfit).
    let reweigh = |fitter: &mut Fitter,
                   chosen: &mut Scored,
                   nominal: &mut Scored,
                   sigma_used: &mut [f64; 9]| {
        let fresh = residual_noise(log, &fitter.residuals(&chosen.fit), &fitter.windows);
        let moved = Channel::ALL.iter().any(|c| {
            let (a, b) = (sigma_used[c.index()], fresh[c.index()]);
            a.is_finite() && b.is_finite() && (a / b - 1.0).abs() > 0.1
        });
        if !moved || chosen.fit.candidate.effects.is_empty() {
            return;
        }
        progress(&format!(
            "  noise re-estimated from the residuals of {}; refitting it and the nominal model",
            chosen.fit.candidate.name()
        ));
        *sigma_used = fresh;
        fitter.setup.sigma = fresh.map(|s| if s.is_nan() { f64::INFINITY } else { s });
        let f = fitter.fit(
            &chosen.fit.candidate,
            &chosen.fit.theta,
            &chosen.fit.z0,
            None,
            &quiet,
        );
        *chosen = score_of(f, fitter);
        let f = fitter.fit(&none, &[], &nominal.fit.z0, None, &quiet);
        *nominal = score_of(f, fitter);
    };
    reweigh(&mut fitter, &mut chosen, &mut nominal, &mut sigma_used);
    if opts.pairs && !chosen.fit.candidate.effects.is_empty() && chosen.error > opts.explained {
        progress(&format!(
            "  {} leaves the error at {:.3} times the noise: trying pairs",
            chosen.fit.candidate.name(),
            chosen.error
        ));
        let single = chosen.clone();
        let e1 = single.fit.candidate.effects[0];
        best_rss.set(single.fit.rss);
        for e in Effect::ALL {
            if e == e1 || opts.exclude.contains(&e) {
                continue;
            }
            let cand = Candidate {
                effects: vec![e1, e],
            };
            let mut start = single.fit.theta.clone();
            start.extend(e.nominal(params));
            let s = fit_candidate(&fitter, cand, &start, &single.fit.z0);
            if s.score < chosen.score && s.implausible.is_empty() {
                chosen = s.clone();
            }
            candidates.push(s);
        }
        if chosen.fit.candidate.effects.len() > 1 {
            reweigh(&mut fitter, &mut chosen, &mut nominal, &mut sigma_used);
        }
        // The single effect under the same weights as the pairs, for the table.
        candidates.retain(|c| c.fit.candidate.effects != single.fit.candidate.effects);
        candidates.push(single);
    } else if let Some(c) = candidates
        .iter_mut()
        .find(|c| c.fit.candidate.effects == chosen.fit.candidate.effects)
    {
        *c = chosen.clone();
    }
    if let Some(c) = candidates
        .iter_mut()
        .find(|c| c.fit.candidate.effects.is_empty())
    {
        *c = nominal.clone();
    }
    candidates.sort_by(|a, b| a.score.total_cmp(&b.score));
    // A refit under new weights can move the chosen parameters out of their range.
    if !chosen.implausible.is_empty() {
        progress(&format!(
            "  {} ends outside its physical range ({}): not named",
            chosen.fit.candidate.name(),
            chosen.implausible.join("; ")
        ));
        chosen = nominal.clone();
    }
    chosen.fit.std = fitter.final_std(&chosen.fit);
    if let Some(c) = candidates
        .iter_mut()
        .find(|c| c.fit.candidate.effects == chosen.fit.candidate.effects)
    {
        c.fit.std = chosen.fit.std.clone();
    }
    let sigma_final = residual_noise(log, &fitter.residuals(&chosen.fit), &fitter.windows);
    // Error before and after, against the noise seen in the chosen model's residuals.
    let res_before = fitter.residuals(&nominal.fit);
    let res_after = fitter.residuals(&chosen.fit);
    let (channel_before, error_before) = normalised_error(&res_before, &sigma_final);
    let (channel_after, error_after) = normalised_error(&res_after, &sigma_final);
    // A log the nominal model already explains to the noise has nothing to gain.
    let gain = if error_before > 0.0 {
        1.0 - error_after / error_before
    } else {
        0.0
    };
    let effects = chosen.fit.candidate.effects.clone();
    let tests_before = channel_tests(log, &res_before, &fitter.windows, &sigma_final);
    let tests_after = channel_tests(log, &res_after, &fitter.windows, &sigma_final);
    let left = |tests: &[ChannelTest]| -> Vec<String> {
        tests
            .iter()
            .filter(|t| !t.passes())
            .map(|t| format!("{} ({})", t.channel.name(), t.failures().join(", ")))
            .collect()
    };
    let (left_before, left_after) = (left(&tests_before), left(&tests_after));
    let explained = error_after <= opts.explained && left_after.is_empty();
    let failing: Vec<Channel> = tests_after
        .iter()
        .filter(|t| !t.passes())
        .map(|t| t.channel)
        .collect();
    let conditions = super::conditions::conditions(log, &res_after, &sigma_final, &failing);
    let (cause, verdict) = if effects.is_empty() {
        if error_before <= opts.explained && left_before.is_empty() {
            (
                "none".to_string(),
                format!(
                    "The nominal model explains the log: its error is {error_before:.3} times the noise floor, and no effect of the catalogue improves the information criterion."
                ),
            )
        } else {
            (
                "unexplained".to_string(),
                format!(
                    "The nominal model's error is {error_before:.3} times the noise floor and its residual is not noise in {}; no effect of the catalogue reduces it by enough to pay for its parameters.",
                    if left_before.is_empty() { "the overall level".to_string() } else { left_before.join("; ") }
                ),
            )
        }
    } else if !explained && error_after > opts.explained {
        // A candidate is named only when it brings the log to the noise: its residual
        // passes every channel's test, or its overall error is within `explained` of the
        // floor (the residual tests then say what is still left). A partial improvement
        // that leaves structured residuals is not a cause.
        (
            "unexplained".to_string(),
            format!(
                "The best candidate ({}) reduces the error from {error_before:.3} to {error_after:.3} times the noise floor, but its residual is not noise in {}: no effect of the catalogue explains the log.",
                chosen.fit.candidate.name(),
                if left_after.is_empty() { "the overall level".to_string() } else { left_after.join("; ") }
            ),
        )
    } else {
        let names = chosen.fit.candidate.name();
        let tail = if explained {
            format!(
                "the refitted model's error is {error_after:.3} times the noise floor (explained)."
            )
        } else {
            format!("the residual is still not noise ({error_after:.3} times the noise floor; failing: {}): a further effect, outside the catalogue or weaker, remains.", if left_after.is_empty() { "the overall level".to_string() } else { left_after.join("; ") })
        };
        (
            effects[0].name().to_string(),
            format!(
                "Cause: {names}. The nominal model's error is {error_before:.3} times the noise floor; {tail}"
            ),
        )
    };
    let d = Diagnosis {
        cause,
        effects,
        chosen,
        nominal,
        candidates,
        sigma,
        sigma_final,
        error_before,
        error_after,
        gain,
        channel_before,
        channel_after,
        residuals_before: res_before,
        residuals_after: res_after,
        windows: fitter.windows.clone(),
        tests_before,
        tests_after,
        conditions,
        flagged,
        verdict,
        elapsed_s: t0.elapsed().as_secs_f64(),
    };
    finite_outputs(d)
}

/// A log whose readings and commands are all constant carries no information about the
/// model (and its residual noise would be zero): a clear error instead of a score of
/// `ln 0`.
fn owned_log_informative(log: &MeasuredLog) -> Result<(), String> {
    let varies = |c: Channel| {
        let mut vals = (0..log.len()).filter_map(|k| log.value(k, c));
        match vals.next() {
            Some(f) => vals.any(|v| v != f),
            None => false,
        }
    };
    let readings = Channel::ALL.into_iter().any(varies);
    if !readings {
        return Err(
            "the log carries no information: every reading is constant (nothing to compare the model with)"
                .into(),
        );
    }
    Ok(())
}

/// Every number `diagnose` reports must be finite (JSON has no NaN): candidates with a
/// non-finite score are dropped; a non-finite error, gain or chosen parameter is an error.
fn finite_outputs(mut d: Diagnosis) -> Result<Diagnosis, String> {
    d.candidates.retain(|c| {
        c.score.is_finite()
            && c.error.is_finite()
            && c.fit.theta.iter().chain(&c.fit.std).all(|v| v.is_finite())
    });
    let mut bad = Vec::new();
    for (name, v) in [
        ("error_before", d.error_before),
        ("error_after", d.error_after),
        ("gain", d.gain),
        ("chosen score", d.chosen.score),
    ] {
        if !v.is_finite() {
            bad.push(format!("{name} = {v}"));
        }
    }
    let names = d.chosen.fit.candidate.parameter_names();
    for values in [&d.chosen.fit.theta, &d.chosen.fit.std] {
        for (n, v) in names.iter().zip(values) {
            if !v.is_finite() {
                bad.push(format!("{n} = {v}"));
            }
        }
    }
    if bad.is_empty() {
        Ok(d)
    } else {
        Err(format!(
            "the fit gave non-finite results ({}): the log does not determine the model",
            bad.join(", ")
        ))
    }
}
