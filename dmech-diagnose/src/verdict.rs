//! The verdict of `diagnose` ([`super::selection`]): the errors before and after, the
//! residual tests, the conditions the residual follows and the words of the report; and the
//! checks that the log carries information and every reported number is finite.

use super::adequacy::{channel_tests, ChannelTest};
use super::conditions::conditions;
use super::diagnosis::{DiagnoseOptions, Diagnosis};
use super::error::DiagnoseError;
use super::log::MeasuredLog;
use super::model::Catalogue;
use super::noise::{normalised_error, residual_noise};
use super::session::{Calibration, Scored, Session};
use super::Plant;

/// Errors before and after, residual tests, conditions and the verdict.
#[allow(clippy::too_many_arguments)]
pub(super) fn conclude<P: Plant>(
    ss: &Session<P>,
    log: &MeasuredLog,
    opts: &DiagnoseOptions,
    flagged: Vec<String>,
    nominal: Scored,
    base: Scored,
    chosen: Scored,
    candidates: Vec<Scored>,
    calibration: Option<Calibration>,
    sigma: Vec<f64>,
) -> Diagnosis {
    let fitter = &ss.fitter;
    let cat = fitter.catalogue();
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
    let tests_before = channel_tests(log, &res_before, &fitter.windows, &sigma_final);
    let tests_after = channel_tests(log, &res_after, &fitter.windows, &sigma_final);
    let names = |c: usize| fitter.plant.channels()[c].name.clone();
    let left = |tests: &[ChannelTest]| -> Vec<String> {
        tests
            .iter()
            .filter(|t| !t.passes())
            .map(|t| format!("{} ({})", names(t.channel), t.failures().join(", ")))
            .collect()
    };
    let (left_before, left_after) = (left(&tests_before), left(&tests_after));
    let explained = error_after <= opts.explained && left_after.is_empty();
    let indicators = fitter.plant.conditions(log);
    let followed = |res, tests: &[ChannelTest]| {
        let failing: Vec<usize> = tests
            .iter()
            .filter(|t| !t.passes())
            .map(|t| t.channel)
            .collect();
        conditions(
            log,
            indicators.clone(),
            res,
            &fitter.windows,
            &sigma_final,
            &failing,
        )
    };
    let conditions_before = followed(&res_before, &tests_before);
    let conditions = followed(&res_after, &tests_after);
    let effects = chosen.fit.candidate.effects.clone();
    let list = |v: &[String]| {
        if v.is_empty() {
            "the overall level".to_string()
        } else {
            v.join("; ")
        }
    };
    let calibrated = !chosen.fit.candidate.calibration.is_empty();
    let (cause, verdict) = if effects.is_empty() && !calibrated {
        if error_before <= opts.explained && left_before.is_empty() {
            ("none".to_string(), format!("The nominal model explains the log: its error is {error_before:.3} times the noise floor, and no effect of the catalogue improves the information criterion."))
        } else {
            ("unexplained".to_string(), format!("The nominal model's error is {error_before:.3} times the noise floor and its residual is not noise in {}; no effect of the catalogue reduces it by enough to pay for its parameters.", list(&left_before)))
        }
    } else if !explained && error_after > opts.explained {
        // A candidate is named only when it brings the log to the noise: its residual
        // passes every channel's test, or its overall error is within `explained` of the
        // floor (the residual tests then say what is still left). A partial improvement
        // that leaves structured residuals is not a cause.
        ("unexplained".to_string(), format!("The best candidate ({}) reduces the error from {error_before:.3} to {error_after:.3} times the noise floor, but its residual is not noise in {}: no effect of the catalogue explains the log.", chosen.fit.candidate.name(cat), list(&left_after)))
    } else {
        let tail = if explained {
            format!(
                "the refitted model's error is {error_after:.3} times the noise floor (explained)."
            )
        } else {
            format!("the residual is still not noise ({error_after:.3} times the noise floor; failing: {}): a further effect, outside the catalogue or weaker, remains.", list(&left_after))
        };
        let cause = effects
            .first()
            .map_or("calibration".to_string(), |&e| cat.effects[e].name.clone());
        (cause, format!("Cause: {}. The nominal model's error is {error_before:.3} times the noise floor; {tail}", chosen.fit.candidate.name(cat)))
    };
    let _ = base;
    Diagnosis {
        cause,
        effects,
        alternatives: Vec::new(),
        chosen,
        nominal,
        candidates,
        calibration,
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
        conditions_before,
        flagged,
        verdict,
        elapsed_s: ss.t0.elapsed().as_secs_f64(),
    }
}

/// The BIC difference below which two single-effect explanations are not told apart: a
/// difference of 2 is posterior odds of `e:1`, "not worth more than a bare mention"
/// (Kass and Raftery, 1995). Two effects that act alike on the log (a constant drive
/// friction and a negative voltage offset on a car that never reverses) score within it.
pub const INDISTINGUISHABLE_BIC: f64 = 2.0;

/// The single effects, each fitted alone and nameable, with their scores under the first
/// noise weights (the scores [`INDISTINGUISHABLE_BIC`] compares; a chosen candidate is
/// re-scored under its own weights later).
pub(super) fn single_scores(candidates: &[Scored], cat: &Catalogue) -> Vec<(String, f64)> {
    candidates
        .iter()
        .filter(|c| c.fitted && c.nameable())
        .filter_map(|c| match c.fit.candidate.effects[..] {
            [e] => Some((cat.effects[e].name.clone(), c.score)),
            _ => None,
        })
        .collect()
}

/// Name the alternatives of a verdict that names an effect: the single effects of
/// `singles` ([`single_scores`]) other than the cause that score within
/// [`INDISTINGUISHABLE_BIC`] of the cause's own, in `alternatives` and in the verdict.
pub(super) fn name_alternatives(d: &mut Diagnosis, singles: &[(String, f64)]) {
    let Some(&(_, own)) = singles.iter().find(|(n, _)| *n == d.cause) else {
        return;
    };
    d.alternatives = singles
        .iter()
        .filter(|(n, s)| *n != d.cause && (s - own).abs() <= INDISTINGUISHABLE_BIC)
        .map(|(n, _)| n.clone())
        .collect();
    if !d.alternatives.is_empty() {
        d.verdict.push_str(&format!(
            " The log cannot tell {} from {}: alone, each explains it as well (BIC within {INDISTINGUISHABLE_BIC}).",
            d.cause,
            d.alternatives.join(", ")
        ));
    }
}

/// A log whose readings are all constant carries no information about the model (and its
/// residual noise would be zero): a clear error instead of a score of `ln 0`.
pub(super) fn informative(log: &MeasuredLog) -> Result<(), DiagnoseError> {
    let varies = |c: usize| {
        let mut vals = (0..log.len()).filter_map(|k| log.value(k, c));
        match vals.next() {
            Some(f) => vals.any(|v| v != f),
            None => false,
        }
    };
    if (0..log.n_channels).any(varies) {
        Ok(())
    } else {
        Err(DiagnoseError::NoInformation)
    }
}

/// Every number `diagnose` reports must be finite (JSON has no NaN): candidates with a
/// non-finite score are dropped; a non-finite error, gain or chosen parameter is an error.
pub(super) fn finite_outputs(mut d: Diagnosis) -> Result<Diagnosis, DiagnoseError> {
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
    for (i, (v, s)) in d.chosen.fit.theta.iter().zip(&d.chosen.fit.std).enumerate() {
        if !v.is_finite() || !s.is_finite() {
            bad.push(format!("parameter {i} = {v} ± {s}"));
        }
    }
    if bad.is_empty() {
        Ok(d)
    } else {
        Err(DiagnoseError::NonFinite(bad.join(", ")))
    }
}
