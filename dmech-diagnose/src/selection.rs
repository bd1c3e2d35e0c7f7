//! Which effect explains the log: optionally calibrate the system's own parameters first
//! (the combinations the log determines, [`super::identify`]); then every effect of the
//! catalogue is screened and fitted, scored by the Bayesian information criterion (a
//! parameter must pay `ln m` in `m ln(RSS/m)`), the best is kept if it beats the base model;
//! if the residual is still above the noise, effects are added one at a time (forward
//! selection: every remaining effect with the chosen ones, the best by the criterion kept)
//! up to [`DiagnoseOptions::max_effects`] (docs/diagnose.md §5). How one candidate is
//! fitted and scored is [`super::session`]; the verdict, [`super::verdict`].

pub use super::diagnosis::{DiagnoseOptions, Diagnosis};
pub use super::error::DiagnoseError;
use super::fit::{cannot_win, FitSetup, Fitter, Screened};
use super::log::MeasuredLog;
use super::model::Candidate;
use super::noise::{normalised_error, raw_noise, residual_noise};
use super::session::{calibrate, joint_refit, screened_only, References, Scored, Session};
use super::verdict::{conclude, finite_outputs, informative, name_alternatives, single_scores};
use super::Plant;
use std::time::Instant;

/// The window length in samples and the first window's row.
fn layout<P: Plant>(
    plant: &P,
    log: &MeasuredLog,
    opts: &DiagnoseOptions,
) -> Result<(usize, usize), DiagnoseError> {
    let h = log.h;
    let window = (opts.window_s / h).round();
    // Fewer samples than this cannot separate an effect's response from the noise (and a
    // silent clamp would change the answer behind the user's back).
    const MIN_WINDOW: usize = 10;
    if window.is_nan() || window < MIN_WINDOW as f64 {
        return Err(DiagnoseError::WindowTooShort {
            window_s: opts.window_s,
            samples: window,
            h,
            min: MIN_WINDOW,
        });
    }
    let window = window as usize;
    let first_row = plant.history(h).min(log.len() / 4);
    if log.len() < first_row + window {
        return Err(DiagnoseError::LogTooShort {
            rows: log.len(),
            need: first_row + window,
            window_s: opts.window_s,
        });
    }
    Ok((window, first_row))
}

/// Resolve effect or parameter names against the catalogue.
fn indices(
    names: &[String],
    known: &[&str],
    what: &'static str,
) -> Result<Vec<usize>, DiagnoseError> {
    names
        .iter()
        .map(|n| {
            known
                .iter()
                .position(|k| k == n)
                .ok_or_else(|| DiagnoseError::Unknown {
                    what,
                    name: n.clone(),
                    known: known.join(", "),
                })
        })
        .collect()
}

/// Diagnose a log against a plant's model.
pub fn diagnose<P: Plant>(
    plant: &P,
    log: &MeasuredLog,
    opts: &DiagnoseOptions,
    progress: &dyn Fn(&str),
) -> Result<Diagnosis, DiagnoseError> {
    let t0 = Instant::now();
    let cat = plant.catalogue();
    let (owned, flagged) = cleaned(plant, log, progress)?;
    let log = &owned;
    let effect_names: Vec<&str> = cat.effects.iter().map(|e| e.name.as_str()).collect();
    let excluded = indices(&opts.exclude, &effect_names, "effect")?;
    let cal_names: Vec<&str> = cat
        .calibration
        .iter()
        .map(|&p| cat.params[p].name.as_str())
        .collect();
    let calibrated: Vec<usize> = indices(&opts.calibrate, &cal_names, "parameter to calibrate")?
        .into_iter()
        .map(|i| cat.calibration[i])
        .collect();
    let (window, first_row) = layout(plant, log, opts)?;
    let sigma0: Vec<f64> = (0..log.n_channels)
        .map(|c| {
            if log.present[c] {
                raw_noise(log, c)
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let setup = FitSetup {
        first_row,
        window,
        sigma: sigma0,
        threads: opts.threads,
        max_iterations: opts.max_iterations,
    };
    let fitter = Fitter::new(plant, log, setup);
    progress(&format!(
        "diagnose: {} rows, h = {} s, {} windows of {} s, {} threads",
        log.len(),
        log.h,
        fitter.windows.len(),
        window as f64 * log.h,
        opts.threads
    ));
    let mut ss = Session {
        fitter,
        progress,
        t0,
        m_res: 1.0,
        base_free: 0,
        grid_chosen: Default::default(),
    };
    let nominal_theta = cat.nominal();
    let z_init = ss.fitter.initial_states();
    // The first fit only sets the noise levels: a few iterations suffice.
    ss.fitter.setup.max_iterations = opts.max_iterations.min(5);
    progress("  first fit of the nominal model (sets the noise levels)");
    let first = ss
        .fitter
        .fit(&Candidate::none(), &nominal_theta, &z_init, None, progress);
    ss.fitter.setup.max_iterations = opts.max_iterations;
    let sigma = residual_noise(log, &ss.fitter.residuals(&first), &ss.fitter.windows);
    ss.fitter.setup.sigma = sigma
        .iter()
        .map(|&s| if s.is_nan() { f64::INFINITY } else { s })
        .collect();
    progress("  nominal model under the noise weights");
    let f = ss.fitter.fit(
        &Candidate::none(),
        &nominal_theta,
        &first.z0,
        None,
        progress,
    );
    let nominal = ss.score(f, true);
    ss.m_res = nominal.fit.m.max(1) as f64;
    ss.say("none", &nominal);

    // Calibration of the system's own parameters, before effects are judged.
    let calibration = if calibrated.is_empty() {
        None
    } else {
        Some(calibrate(&ss, &calibrated, &nominal)?)
    };
    // A calibration that ends outside the physical ranges has taken up what a missing
    // effect does: the effects are judged on the nominal model instead (the joint refit
    // at the end frees the calibration again).
    let judged_on = calibration.as_ref().filter(|c| c.fit.nameable());
    ss.base_free = judged_on.map_or(0, |c| c.fit.fit.candidate.calibration.len());
    let base = judged_on.map_or_else(|| nominal.clone(), |c| c.fit.clone());
    if calibration.is_some() && judged_on.is_none() {
        progress(
            "  the calibration leaves the physical ranges: effects judged on the nominal model",
        );
    }
    let mut candidates = vec![nominal.clone()];
    if let Some(c) = &calibration {
        candidates.push(c.fit.clone());
    }

    // A reading hypothesis on a channel the log does not carry has nothing to fit.
    let open: Vec<usize> = (0..cat.effects.len())
        .filter(|&e| !excluded.contains(&e) && !cat.is_calibration_effect(e, &calibrated))
        .filter(|&e| cat.effects[e].reading.is_none_or(|c| log.present[c]))
        .collect();
    single_effects(&ss, &open, &base, opts, &mut candidates)?;
    let singles = single_scores(&candidates, cat);
    // A single effect is named only if it pays over the base model (`Session::pays`).
    let unpaid: Vec<String> = candidates
        .iter()
        .filter(|c| c.fitted && c.nameable() && c.fit.candidate.effects.len() == 1)
        .filter(|c| c.score < base.score && !ss.pays(c, &base))
        .map(|c| unpaid_line(&ss, c, &base))
        .collect();
    for line in &unpaid {
        progress(line);
    }
    let mut chosen = candidates
        .iter()
        .filter(|c| c.fitted && c.nameable())
        .filter(|c| c.fit.candidate.effects.is_empty() || ss.pays(c, &base))
        .filter(|c| c.fit.candidate.effects.len() <= 1)
        .filter(|c| {
            calibration.is_none()
                || !c.fit.candidate.effects.is_empty()
                || !c.fit.candidate.calibration.is_empty()
        })
        .min_by(|a, b| a.score.total_cmp(&b.score))
        // None may be nameable: every effect left open undetermined or implausible, and a
        // calibration whose own parameters leave their physical ranges. The base model the
        // effects are judged on stands, and the verdict says what is left.
        .map_or_else(|| base.clone(), Scored::clone);
    let is_base = |c: &Scored| c.fit.candidate.effects.is_empty();
    let mut refs = References {
        nominal,
        base,
        calibrated: calibration.is_some(),
    };
    if !is_base(&chosen) {
        refs.reweigh(&mut ss, log, &mut chosen);
        add_effects(
            &mut ss,
            log,
            &open,
            opts,
            &mut chosen,
            &mut refs,
            &mut candidates,
        );
    }
    // After a calibration, the chosen effects and the calibrated combinations are refitted
    // together: the calibration was made without them.
    if let (Some(c), false) = (&calibration, is_base(&chosen)) {
        chosen = joint_refit(&ss, c, chosen, &refs.base, &mut candidates);
    }
    for c in candidates.iter_mut() {
        if c.fit.candidate == refs.nominal.fit.candidate {
            *c = refs.nominal.clone();
        } else if c.fit.candidate == refs.base.fit.candidate {
            *c = refs.base.clone();
        } else if c.fit.candidate == chosen.fit.candidate {
            *c = chosen.clone();
        }
    }
    candidates.sort_by(|a, b| a.score.total_cmp(&b.score));
    // A refit under new weights can move the chosen parameters out of their range.
    if !chosen.nameable() {
        progress(&format!(
            "  {} ends outside its physical range or undetermined ({}): not named",
            chosen.fit.candidate.name(cat),
            chosen
                .implausible
                .iter()
                .chain(&chosen.undetermined)
                .cloned()
                .collect::<Vec<_>>()
                .join("; ")
        ));
        chosen = refs.base.clone();
    }
    ss.fitter.final_std(&mut chosen.fit);
    if let Some(c) = candidates
        .iter_mut()
        .find(|c| c.fit.candidate == chosen.fit.candidate)
    {
        c.fit.std = chosen.fit.std.clone();
    }
    let mut d = conclude(
        &ss,
        log,
        opts,
        flagged,
        refs.nominal,
        refs.base,
        chosen,
        candidates,
        calibration,
        sigma,
    );
    name_alternatives(&mut d, &singles);
    finite_outputs(d)
}

/// The log without readings far outside their channel's range, without copied channels
/// and without channels derived from others ([`Plant::derived_channels`]), and those
/// dropped, in words (each also a warning line).
fn cleaned<P: Plant>(
    plant: &P,
    log: &MeasuredLog,
    progress: &dyn Fn(&str),
) -> Result<(MeasuredLog, Vec<String>), DiagnoseError> {
    let mut owned = log.clone();
    let mut flagged = owned
        .drop_out_of_range(plant.channels(), plant.inputs())
        .map_err(DiagnoseError::Log)?;
    // A log without information is one error, not a list of "copies" first: constant
    // columns all equal each other.
    informative(&owned)?;
    for (copy, original) in owned.duplicated_channels() {
        flagged.push(format!(
            "column '{}' equals '{}' in every row: a copy, not a second measurement; set aside",
            plant.channels()[copy].name,
            plant.channels()[original].name
        ));
        owned.drop_channel(copy);
    }
    for (derived, why) in plant.derived_channels(&owned) {
        flagged.push(format!(
            "column '{}' {why}: not a second measurement; set aside",
            plant.channels()[derived].name
        ));
        owned.drop_channel(derived);
    }
    for f in &flagged {
        progress(&format!("diagnose: warning: {f}"));
    }
    Ok((owned, flagged))
}

/// Screen the effects `open` with one linearisation at the base model, and those it
/// cannot see by their scan where they have one (the order of the fits, and the predicted
/// reductions in the progress output); fit the most promising `max_full_fits` to
/// convergence (all by default: a linearisation misjudges the nonlinear effects), each
/// under the bound of the best nameable fit so far, and none whose predicted reduction
/// cannot reach that bound by [`ABANDON_MARGIN`](super::fit::ABANDON_MARGIN) times over.
fn single_effects<P: Plant>(
    ss: &Session<P>,
    open: &[usize],
    base: &Scored,
    opts: &DiagnoseOptions,
    candidates: &mut Vec<Scored>,
) -> Result<(), DiagnoseError> {
    let cat = ss.fitter.catalogue();
    let m = base.fit.m.max(1) as f64;
    let screened = ss
        .fitter
        .screen(
            open,
            &base.fit.theta,
            &base.fit.z0,
            base.fit.rss,
            base.fit.m,
        )
        .ok_or(DiagnoseError::NotSimulable)?;
    // An effect the linearisation cannot see is screened by the scan of its jumping
    // parameter, where it has one (`Session::scan_screen`): its predicted reduction is
    // then that of its best grid value. With `seen`, whether a reduction was predicted.
    let screened: Vec<(Screened, bool)> = screened
        .into_iter()
        .map(|sc| {
            if !sc.unseen() {
                return (sc, true);
            }
            match ss.scan_screen(&Candidate::of(vec![sc.effect]), base) {
                Some(reduction) => (Screened { reduction, ..sc }, true),
                None => (sc, false),
            }
        })
        .collect();
    let mut order: Vec<&(Screened, bool)> = screened.iter().collect();
    let net = |s: &Screened| screened_net(cat, s, m);
    // By predicted gain, the effects nothing predicts last: a fit that cannot beat the
    // best so far is abandoned early, and the unseen ones are the dearest (a hybrid
    // friction law), fitted without a bound they may run to the iteration cap far from
    // any minimum.
    order.sort_by(|(a, a_seen), (b, b_seen)| {
        b_seen.cmp(a_seen).then_with(|| net(b).total_cmp(&net(a)))
    });
    // A reading hypothesis is linear in its parameter (an offset exactly, a scale given
    // the states), so the screen's Gauss–Newton step from the base model predicts its fit:
    // one whose predicted reduction does not pay for its parameter is not fitted.
    let pays = |sc: &Screened| net(sc) > 0.0;
    let mut best_rss = base.fit.rss;
    for (rank, (sc, seen)) in order.into_iter().enumerate() {
        let said = if !seen {
            "unseen by the linearisation at its start: fitted last".to_string()
        } else {
            let by = if sc.unseen() { ", by its scan" } else { "" };
            format!(
                "predicted reduction {:>12.1}  (a parameter costs {:.1}{by})",
                sc.reduction,
                m.ln()
            )
        };
        (ss.progress)(&format!(
            "  screen {:<24} {said}",
            cat.effects[sc.effect].name
        ));
        let cand = Candidate::of(vec![sc.effect]);
        // The first step's test of `Fitter::fit`'s abandonment, on the screen's promise.
        let hopeless = *seen
            && cannot_win(
                base.fit.rss,
                sc.reduction,
                ss.abandon_bound(&cand, best_rss),
            );
        let worth_fitting = rank < opts.max_full_fits && (!is_reading(cat, sc.effect) || pays(sc));
        if worth_fitting && hopeless {
            (ss.progress)("    not fitted: its predicted reduction cannot beat the best fit");
        }
        if worth_fitting && !hopeless {
            let start = cand.start_from(cat, &base.fit.theta);
            let s = ss.fit(cand, &start, &base.fit.z0, Some(best_rss));
            best_rss = bound_after(best_rss, &s);
            candidates.push(s);
        } else {
            candidates.push(screened_only(ss, cand, sc, base));
        }
    }
    Ok(())
}

/// `open` ordered by the score of each effect's own single-effect fit in `candidates`,
/// lowest first (those without one last, in `open`'s order). The effect strongest alone is
/// the likeliest to lead beside the current choice, and the sooner the leading fit is in,
/// the sooner the others are abandoned ([`bound_after`]). The order decides no choice:
/// every contender that may be named is fitted until it cannot beat the best nameable
/// fit.
fn strongest_alone_first(open: &[usize], candidates: &[Scored]) -> Vec<usize> {
    let alone = |e: usize| {
        candidates
            .iter()
            .filter(|c| c.fit.candidate.effects == [e])
            .map(|c| c.score)
            .fold(f64::INFINITY, f64::min)
    };
    let mut order: Vec<(f64, usize)> = open.iter().map(|&e| (alone(e), e)).collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    order.into_iter().map(|(_, e)| e).collect()
}

/// The bound a later fit is abandoned above (`Fitter::fit`): the lowest cost of the fits
/// that may be named. A fit that may not (a parameter outside its physical range, or
/// undetermined) is never chosen, so its cost must not stop a fit that may: an effect
/// whose fit ends above it is still the cause if nothing nameable beats it.
fn bound_after(bound: f64, s: &Scored) -> f64 {
    if s.nameable() {
        bound.min(s.fit.rss)
    } else {
        bound
    }
}

/// The progress line of a candidate that the criterion prefers but whose gain over
/// `without` does not pay once the window clustering is accounted for.
fn unpaid_line<P: Plant>(ss: &Session<P>, c: &Scored, without: &Scored) -> String {
    let cat = ss.fitter.catalogue();
    let (lr, price) = ss.gain_statistic(c, without).unwrap_or((0.0, 0.0));
    format!(
        "  {} not named: its gain over {} does not pay (Λ/δ = {lr:.1} ≤ {price:.1})",
        c.fit.candidate.name(cat),
        without.fit.candidate.name(cat)
    )
}

/// A screened effect's predicted reduction of `m ln RSS` less the criterion's price of its
/// parameters (`k ln m`): positive if its fit can pay for them.
fn screened_net(cat: &super::model::Catalogue, s: &Screened, m: f64) -> f64 {
    s.reduction - cat.effects[s.effect].params.len() as f64 * m.ln()
}

/// Whether effect `e` is a generic reading hypothesis (`super::readings`).
fn is_reading(cat: &super::model::Catalogue, e: usize) -> bool {
    cat.effects[e].reading.is_some()
}

/// The reading hypotheses of `open` (not in `current`) whose screened reduction at
/// `current` does not pay for their parameters: not fitted in this round of the forward
/// selection (as in [`single_effects`]; they are linear in their parameters, so the
/// screen predicts their fit). Progress lines say which.
fn unpaid_readings<P: Plant>(ss: &Session<P>, open: &[usize], current: &Scored) -> Vec<usize> {
    let cat = ss.fitter.catalogue();
    let readings: Vec<usize> = open
        .iter()
        .copied()
        .filter(|&e| is_reading(cat, e) && !current.fit.candidate.effects.contains(&e))
        .collect();
    if readings.is_empty() {
        return Vec::new();
    }
    let m = current.fit.m.max(1) as f64;
    let Some(screened) = ss.fitter.screen(
        &readings,
        &current.fit.theta,
        &current.fit.z0,
        current.fit.rss,
        current.fit.m,
    ) else {
        return Vec::new();
    };
    let skip: Vec<usize> = screened
        .iter()
        .filter(|s| screened_net(cat, s, m) <= 0.0)
        .map(|s| s.effect)
        .collect();
    if !skip.is_empty() {
        (ss.progress)(&format!(
            "  screen: {} of {} reading hypotheses cannot pay for their parameters here: not fitted",
            skip.len(),
            readings.len()
        ));
    }
    skip
}

/// Forward selection: while the chosen effects leave the error above
/// [`DiagnoseOptions::explained`] and fewer than `max_effects` are chosen, every remaining
/// effect of `open` is fitted together with them. The contenders that beat the current
/// choice by the criterion and may be named are taken in the criterion's order: each is
/// re-weighed, and kept if it lowers the error the verdict reports (each model against the
/// noise re-estimated from its own residuals, [`reported_error`]); otherwise the weights go
/// back and the next is tried. The additions exist to bring that error down (the loop runs
/// while it is above `explained`), and the criterion compares the contenders under the
/// current model's weights, which the re-weighing after a choice moves: an addition that
/// raises the reported error has not paid for itself in the measure the verdict uses
/// (docs/diagnose.md §5).
fn add_effects<P: Plant>(
    ss: &mut Session<P>,
    log: &MeasuredLog,
    open: &[usize],
    opts: &DiagnoseOptions,
    chosen: &mut Scored,
    refs: &mut References,
    candidates: &mut Vec<Scored>,
) {
    let plant = ss.fitter.plant;
    let cat = plant.catalogue();
    while chosen.fit.candidate.effects.len() < opts.max_effects && chosen.error > opts.explained {
        (ss.progress)(&format!(
            "  {} leaves the error at {:.3} times the noise: adding another effect",
            chosen.fit.candidate.name(cat),
            chosen.error
        ));
        let current = chosen.clone();
        let mut best_rss = current.fit.rss;
        let mut contenders: Vec<Scored> = Vec::new();
        let skip = unpaid_readings(ss, open, &current);
        for e in strongest_alone_first(open, candidates) {
            if current.fit.candidate.effects.contains(&e) || skip.contains(&e) {
                continue;
            }
            let mut effects = current.fit.candidate.effects.clone();
            effects.push(e);
            let cand = Candidate::of(effects);
            let start = cand.start_from(cat, &current.fit.theta);
            let s = ss.fit(cand, &start, &current.fit.z0, Some(best_rss));
            best_rss = bound_after(best_rss, &s);
            if s.score < current.score && s.nameable() {
                if ss.pays(&s, &current) {
                    contenders.push(s.clone());
                } else {
                    (ss.progress)(&unpaid_line(ss, &s, &current));
                }
            }
            candidates.push(s);
        }
        contenders.sort_by(|a, b| a.score.total_cmp(&b.score));
        let before = reported_error(ss, log, &current);
        let mut added = false;
        for mut trial in contenders {
            let (sigma, saved) = (ss.fitter.setup.sigma.clone(), refs.clone());
            refs.reweigh(ss, log, &mut trial);
            let after = reported_error(ss, log, &trial);
            if after < before && trial.nameable() {
                *chosen = trial;
                added = true;
                break;
            }
            (ss.progress)(&format!(
                "  {} leaves the reported error at {after:.3} against {before:.3} without it{}: not added",
                trial.fit.candidate.name(cat),
                if trial.nameable() { "" } else { " (or is not nameable after re-weighing)" }
            ));
            ss.fitter.setup.sigma = sigma;
            *refs = saved;
        }
        if !added {
            break;
        }
    }
}

/// The error the verdict reports for a model ([`super::verdict`]): its residuals against
/// the noise re-estimated from them.
fn reported_error<P: Plant>(ss: &Session<P>, log: &MeasuredLog, s: &Scored) -> f64 {
    let res = ss.fitter.residuals(&s.fit);
    let sigma = residual_noise(log, &res, &ss.fitter.windows);
    normalised_error(&res, &sigma).1
}
