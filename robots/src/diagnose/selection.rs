//! Which effect explains the log: optionally calibrate the system's own parameters first
//! (the combinations the log determines, [`super::identify`]); then every effect of the
//! catalogue is screened and fitted, scored by the Bayesian information criterion (a
//! parameter must pay `ln m` in `m ln(RSS/m)`), the best is kept if it beats the base model;
//! if the residual is still above the noise, effects are added one at a time (forward
//! selection: every remaining effect with the chosen ones, the best by the criterion kept)
//! up to [`DiagnoseOptions::max_effects`]. The verdict is
//! defined here (docs/diagnose.md §5).

use super::adequacy::{channel_tests, ChannelTest};
use super::conditions::Condition;
use super::fit::{Fit, FitSetup, Fitter, Screened};
use super::identify::DETERMINED;
use super::identify::{identify, Identifiability};
use super::log::MeasuredLog;
use super::model::{Candidate, Catalogue};
use super::noise::{normalised_error, raw_noise, residual_noise, Residuals};
use super::Plant;
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
    /// The most effects named together: while the chosen ones leave the error above
    /// `explained`, another is added if it pays for its parameters (1: single effects only).
    pub max_effects: usize,
    /// At most this many single effects are fitted to convergence after screening.
    pub max_full_fits: usize,
    /// Effects of the catalogue left out, by name (to test what the tool says about an
    /// effect it does not know).
    pub exclude: Vec<String>,
    /// The system's own parameters to calibrate before effects are judged, by name (empty:
    /// no calibration).
    pub calibrate: Vec<String>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            window_s: 0.5,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
            max_iterations: 15,
            explained: 1.2,
            max_effects: 2,
            max_full_fits: usize::MAX,
            exclude: Vec::new(),
            calibrate: Vec::new(),
        }
    }
}

/// Rounds of `max_iterations` more that a leading fit still descending may take.
const CONTINUATIONS: usize = 3;

/// Rounds of outlying-window restarts a leading fit may take.
const RESTARTS: usize = 2;

/// Why a log cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A reading or command that cannot be used (names the row and column).
    #[error("{0}")]
    Log(String),
    #[error("a window of {window_s} s is {samples} samples of {h} s; it needs at least {min} samples (--window ≥ {} s)", *min as f64 * h)]
    WindowTooShort {
        window_s: f64,
        samples: f64,
        h: f64,
        min: usize,
    },
    #[error("the log is too short: {rows} rows, need at least {need} ({window_s} s windows)")]
    LogTooShort {
        rows: usize,
        need: usize,
        window_s: f64,
    },
    #[error("the log carries no information: every reading is constant (nothing to compare the model with)")]
    NoInformation,
    #[error("the nominal model cannot be simulated over the log (the linearisation failed)")]
    NotSimulable,
    #[error("unknown {what} '{name}' (known: {known})")]
    Unknown {
        what: &'static str,
        name: String,
        known: String,
    },
    #[error("the fit gave non-finite results ({0}): the log does not determine the model")]
    NonFinite(String),
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
    /// Parameters outside their physical range; such a candidate is never named.
    pub implausible: Vec<String>,
    /// Effect parameters the log does not determine: a standard deviation above
    /// [`DETERMINED`] of the parameter's plausible range. Such a candidate is not named
    /// either (its effect is confounded with others, or invisible in this log).
    pub undetermined: Vec<String>,
}

impl Scored {
    /// Whether the candidate may be named: every parameter plausible and determined.
    pub fn nameable(&self) -> bool {
        self.implausible.is_empty() && self.undetermined.is_empty()
    }
}

/// Whether a parameter's standard deviation is at most [`DETERMINED`] of its plausible
/// range `(lo, hi)` (false when it is NaN). A scale parameter, whose range spans a decade
/// or more (a Stribeck speed from 5 mm/s to 20 rad/s), is judged on the log scale: its
/// relative deviation `sd/|value|` against `ln(hi/lo)`; knowing such a speed within 40 %
/// determines it, though 40 % of 6 rad/s is a tenth of the range's width.
fn determined(value: f64, sd: f64, (lo, hi): (f64, f64)) -> bool {
    if lo > 0.0 && hi >= 10.0 * lo {
        sd <= DETERMINED * (hi / lo).ln() * value.abs()
    } else {
        sd <= DETERMINED * (hi - lo)
    }
}

/// The effect parameters of a fit whose standard deviation exceeds [`DETERMINED`] of
/// their plausible range, in words.
fn undetermined(cat: &Catalogue, fit: &Fit) -> Vec<String> {
    fit.candidate
        .effect_params(cat)
        .into_iter()
        .filter(|&p| !determined(fit.theta[p], fit.std[p], cat.params[p].plausible))
        .map(|p| {
            let s = &cat.params[p];
            format!(
                "{} = {:.4e} ± {:.1e} (range {:.3e}–{:.3e})",
                s.name, fit.theta[p], fit.std[p], s.plausible.0, s.plausible.1
            )
        })
        .collect()
}

/// What the calibration found.
#[derive(Clone, Debug)]
pub struct Calibration {
    pub identifiability: Identifiability,
    /// The calibrated model (no effect), fitted along the determined combinations.
    pub fit: Scored,
}

/// The outcome of `diagnose`.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// `"none"`, `"calibration"` (the system's own parameters, calibrated, explain the
    /// log), `"unexplained"`, or an effect name (the stronger one if two effects are
    /// found; `effects` lists both).
    pub cause: String,
    /// Indices of the named effects in the plant's catalogue.
    pub effects: Vec<usize>,
    pub chosen: Scored,
    pub nominal: Scored,
    /// Every candidate tried, best (lowest score) first.
    pub candidates: Vec<Scored>,
    pub calibration: Option<Calibration>,
    /// Noise level per channel used as first fit weights (from the nominal residuals).
    pub sigma: Vec<f64>,
    /// Noise level per channel from the chosen model's residuals: the error's yardstick
    /// (NaN where the channel is absent).
    pub sigma_final: Vec<f64>,
    pub error_before: f64,
    pub error_after: f64,
    pub gain: f64,
    /// Per channel `RMS(r_c)/σ_c` before and after (NaN where absent).
    pub channel_before: Vec<f64>,
    pub channel_after: Vec<f64>,
    pub residuals_before: Residuals,
    pub residuals_after: Residuals,
    pub windows: Vec<(usize, usize)>,
    /// "Is anything left" per channel, for the nominal model and the chosen one.
    pub tests_before: Vec<ChannelTest>,
    pub tests_after: Vec<ChannelTest>,
    /// The operating conditions that the chosen model's residual follows, in the channels
    /// that fail their tests.
    pub conditions: Vec<Condition>,
    /// Readings dropped as far outside their channel's range, and copied channels set
    /// aside, in words.
    pub flagged: Vec<String>,
    /// A one-paragraph verdict for the report.
    pub verdict: String,
    pub elapsed_s: f64,
}

fn bic(fit: &Fit, k: usize) -> f64 {
    let m = fit.m.max(1) as f64;
    m * (fit.rss / m).ln() + k as f64 * m.ln()
}

/// Everything `diagnose` decides with, for one weighting of the residuals.
struct Session<'a, P: Plant> {
    fitter: Fitter<'a, P>,
    progress: &'a dyn Fn(&str),
    t0: Instant,
    /// Residuals in the criterion (the nominal fit's count).
    m_res: f64,
    /// Free coordinates of the calibration that effect candidates are built on (their
    /// parameters count in the criterion even while held at the calibrated values).
    base_free: usize,
}

impl<P: Plant> Session<'_, P> {
    fn score(&self, fit: Fit, fitted: bool) -> Scored {
        let cat = self.fitter.catalogue();
        let (_, error) = normalised_error(&self.fitter.residuals(&fit), &self.fitter.setup.sigma);
        let c = &fit.candidate;
        let on_base = c.calibration.is_empty() && !c.effects.is_empty();
        let k = c.n_free(cat) + if on_base { self.base_free } else { 0 };
        Scored {
            implausible: fit.candidate.implausible(cat, &fit.theta),
            undetermined: undetermined(cat, &fit),
            score: bic(&fit, k),
            fit,
            error,
            fitted,
        }
    }

    fn say(&self, name: &str, s: &Scored) {
        (self.progress)(&format!(
            "  {:<28} error {:>8.3}  score {:>14.1}  {} iterations  ({:.1} s)",
            name,
            s.error,
            s.score,
            s.fit.iterations,
            self.t0.elapsed().as_secs_f64()
        ));
    }

    /// Fit a candidate from `theta0`, `z0`; abandoned early when it cannot beat `best`
    /// plus what its parameters cost.
    fn fit(&self, cand: Candidate, theta0: &[f64], z0: &[Vec<f64>], best: Option<f64>) -> Scored {
        let cat = self.fitter.catalogue();
        let m = self.m_res;
        let bound = best.map(|b| b * (1.0 + cand.n_free(cat) as f64 * m.ln() / m) + 50.0);
        let f = self.fit_leading(&cand, theta0, z0, bound, best, RESTARTS);
        let s = self.score(f, true);
        self.say(&cand.name(cat), &s);
        s
    }

    /// `Fitter::fit`, continued while the fit is still descending when its iterations run
    /// out and leads (`rss` below `best`, or no `best`), up to [`CONTINUATIONS`] rounds:
    /// comparing a leading fit unconverged with candidates built on it would credit them
    /// with its unfinished descent (a hybrid law's secant derivatives make its descent
    /// linear, not quadratic). A leading fit's outlying windows are then restarted
    /// ([`Fitter::restart_outliers`]) and the fit continued, up to `restarts` times (none
    /// for the reference models refitted to new weights: their windows are outliers where
    /// the data excite what they lack, not where a mode went wrong).
    fn fit_leading(
        &self,
        cand: &Candidate,
        theta0: &[f64],
        z0: &[Vec<f64>],
        bound: Option<f64>,
        best: Option<f64>,
        restarts: usize,
    ) -> Fit {
        let leads = |f: &Fit| !f.abandoned && best.is_none_or(|b| f.rss < b);
        let continued = |f: Fit, z: &[Vec<f64>]| -> Fit {
            let mut more = self.fitter.fit(cand, &f.theta, z, None, &|_| {});
            if more.rss > f.rss {
                return f;
            }
            more.iterations += f.iterations;
            more
        };
        let mut f = self.fitter.fit(cand, theta0, z0, bound, &|_| {});
        for round in 0..=restarts {
            for _ in 0..CONTINUATIONS {
                if f.converged || !leads(&f) {
                    break;
                }
                let (before, z) = (f.rss, f.z0.clone());
                f = continued(f, &z);
                if f.rss >= before {
                    break;
                }
            }
            if round == restarts || !leads(&f) {
                break;
            }
            let mut z = f.z0.clone();
            let n = self.fitter.restart_outliers(&f.theta, &mut z);
            if n == 0 {
                break;
            }
            f = continued(f, &z);
        }
        f
    }

    /// The noise re-estimated from `chosen`'s residuals; if it moved by more than 10 % in
    /// some channel, the weights change and `chosen` and `base` are refitted with them
    /// (so that the decisions compare errors against the noise, not against the nominal
    /// misfit). Returns whether the weights changed.
    fn reweigh(
        &mut self,
        log: &MeasuredLog,
        chosen: &mut Scored,
        base: &mut [&mut Scored],
    ) -> bool {
        let fresh = residual_noise(
            log,
            &self.fitter.residuals(&chosen.fit),
            &self.fitter.windows,
        );
        let used = &self.fitter.setup.sigma;
        let moved = (0..fresh.len()).any(|c| {
            let (a, b) = (used[c], fresh[c]);
            a.is_finite() && b.is_finite() && (a / b - 1.0).abs() > 0.1
        });
        if !moved {
            return false;
        }
        let cat = self.fitter.catalogue();
        (self.progress)(&format!(
            "  noise re-estimated from the residuals of {}; refitting",
            chosen.fit.candidate.name(cat)
        ));
        self.fitter.setup.sigma = fresh
            .iter()
            .map(|&s| if s.is_nan() { f64::INFINITY } else { s })
            .collect();
        let f = self.fit_leading(
            &chosen.fit.candidate,
            &chosen.fit.theta,
            &chosen.fit.z0,
            None,
            None,
            RESTARTS,
        );
        *chosen = self.score(f, true);
        for b in base.iter_mut() {
            let f = self.fit_leading(&b.fit.candidate, &b.fit.theta, &b.fit.z0, None, None, 0);
            **b = self.score(f, true);
        }
        true
    }
}

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
    for f in &flagged {
        progress(&format!("diagnose: warning: {f}"));
    }
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
    let mut nominal = ss.score(f, true);
    ss.m_res = nominal.fit.m.max(1) as f64;
    ss.say("none", &nominal);

    // Calibration of the system's own parameters, before effects are judged.
    let calibration = if calibrated.is_empty() {
        None
    } else {
        Some(calibrate(&ss, &calibrated, &nominal)?)
    };
    ss.base_free = calibration
        .as_ref()
        .map_or(0, |c| c.fit.fit.candidate.calibration.len());
    let mut base = calibration
        .as_ref()
        .map_or_else(|| nominal.clone(), |c| c.fit.clone());
    let mut candidates = vec![nominal.clone()];
    if let Some(c) = &calibration {
        candidates.push(c.fit.clone());
    }

    // Screen the catalogue with one linearisation at the base model (the order of the
    // fits, and the predicted reductions in the progress output); fit the most promising
    // `max_full_fits` to convergence (all by default: a linearisation misjudges the
    // nonlinear effects, and a full fit costs a fraction of a second on a short log).
    let open: Vec<usize> = (0..cat.effects.len())
        .filter(|&e| !excluded.contains(&e) && !cat.is_calibration_effect(e, &calibrated))
        .collect();
    let m = base.fit.m.max(1) as f64;
    let screened = ss
        .fitter
        .screen(
            &open,
            &base.fit.theta,
            &base.fit.z0,
            base.fit.rss,
            base.fit.m,
        )
        .ok_or(DiagnoseError::NotSimulable)?;
    let mut order: Vec<&Screened> = screened.iter().collect();
    let net = |s: &Screened| s.reduction - cat.effects[s.effect].params.len() as f64 * m.ln();
    order.sort_by(|a, b| net(b).total_cmp(&net(a)));
    let mut best_rss = base.fit.rss;
    for (rank, sc) in order.iter().enumerate() {
        progress(&format!(
            "  screen {:<24} predicted reduction {:>12.1}  (a parameter costs {:.1})",
            cat.effects[sc.effect].name,
            sc.reduction,
            m.ln()
        ));
        let cand = Candidate::of(vec![sc.effect]);
        if rank < opts.max_full_fits {
            let start = cand.start_from(cat, &base.fit.theta);
            let s = ss.fit(cand, &start, &base.fit.z0, Some(best_rss));
            best_rss = best_rss.min(s.fit.rss);
            candidates.push(s);
        } else {
            candidates.push(screened_only(&ss, cand, sc, &base));
        }
    }
    let mut chosen = candidates
        .iter()
        .filter(|c| c.fitted && c.nameable())
        .filter(|c| c.fit.candidate.effects.len() <= 1)
        .filter(|c| {
            calibration.is_none()
                || !c.fit.candidate.effects.is_empty()
                || !c.fit.candidate.calibration.is_empty()
        })
        .min_by(|a, b| a.score.total_cmp(&b.score))
        .expect("at least the base model")
        .clone();
    let is_base = |c: &Scored| c.fit.candidate.effects.is_empty();
    if !is_base(&chosen) {
        reweigh_all(
            &mut ss,
            log,
            &mut chosen,
            &mut nominal,
            &mut base,
            calibration.is_some(),
        );
    }
    while !is_base(&chosen)
        && chosen.fit.candidate.effects.len() < opts.max_effects
        && chosen.error > opts.explained
    {
        progress(&format!(
            "  {} leaves the error at {:.3} times the noise: adding another effect",
            chosen.fit.candidate.name(cat),
            chosen.error
        ));
        let current = chosen.clone();
        let mut best_rss = current.fit.rss;
        for &e in &open {
            if current.fit.candidate.effects.contains(&e) {
                continue;
            }
            let mut effects = current.fit.candidate.effects.clone();
            effects.push(e);
            let cand = Candidate::of(effects);
            let start = cand.start_from(cat, &current.fit.theta);
            let s = ss.fit(cand, &start, &current.fit.z0, Some(best_rss));
            best_rss = best_rss.min(s.fit.rss);
            if s.score < chosen.score && s.nameable() {
                chosen = s.clone();
            }
            candidates.push(s);
        }
        if chosen.fit.candidate == current.fit.candidate {
            break;
        }
        reweigh_all(
            &mut ss,
            log,
            &mut chosen,
            &mut nominal,
            &mut base,
            calibration.is_some(),
        );
    }
    // After a calibration, the chosen effects and the calibrated combinations are refitted
    // together: the calibration was made without them.
    if let (Some(c), false) = (&calibration, is_base(&chosen)) {
        chosen = joint_refit(&ss, c, chosen, &base, &mut candidates);
    }
    for c in candidates.iter_mut() {
        if c.fit.candidate == nominal.fit.candidate {
            *c = nominal.clone();
        } else if c.fit.candidate == base.fit.candidate {
            *c = base.clone();
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
        chosen = base.clone();
    }
    ss.fitter.final_std(&mut chosen.fit);
    if let Some(c) = candidates
        .iter_mut()
        .find(|c| c.fit.candidate == chosen.fit.candidate)
    {
        c.fit.std = chosen.fit.std.clone();
    }
    let d = conclude(
        &ss,
        log,
        opts,
        flagged,
        nominal,
        base,
        chosen,
        candidates,
        calibration,
        sigma,
    );
    finite_outputs(d)
}

/// After a calibration, the chosen effects and the calibrated combinations refitted
/// together (the calibration was made without the effects). An effect whose parameters
/// become undetermined or implausible there is confounded with the calibration: it is
/// dropped (its parameters back at their nominal values) and the rest refitted.
fn joint_refit<P: Plant>(
    ss: &Session<P>,
    c: &Calibration,
    chosen: Scored,
    base: &Scored,
    candidates: &mut Vec<Scored>,
) -> Scored {
    let cat = ss.fitter.catalogue();
    let mut effects = chosen.fit.candidate.effects.clone();
    let mut theta = chosen.fit.theta.clone();
    while !effects.is_empty() {
        let cand = Candidate {
            effects: effects.clone(),
            calibration: c.identifiability.directions(),
        };
        (ss.progress)(&format!(
            "  refitting {} with the calibration free",
            Candidate::of(effects.clone()).name(cat)
        ));
        let joint = ss.fit(cand, &theta, &chosen.fit.z0, None);
        candidates.push(joint.clone());
        if joint.nameable() {
            return joint;
        }
        let bad: Vec<usize> = effects
            .iter()
            .copied()
            .filter(|&e| {
                cat.effects[e].params.iter().any(|&p| {
                    let (value, s) = (joint.fit.theta[p], &cat.params[p]);
                    !determined(value, joint.fit.std[p], s.plausible) || !s.is_plausible(value)
                })
            })
            .collect();
        if bad.is_empty() {
            return chosen;
        }
        (ss.progress)(&format!(
            "  {} confounded with the calibration: dropped",
            bad.iter()
                .map(|&e| cat.effects[e].name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        for &e in &bad {
            for &p in &cat.effects[e].params {
                theta[p] = cat.params[p].nominal;
            }
        }
        effects.retain(|e| !bad.contains(e));
    }
    base.clone()
}

/// Re-weigh after a choice: `chosen`, the nominal model and (after a calibration) the
/// calibrated base model are refitted under the new weights.
fn reweigh_all<P: Plant>(
    ss: &mut Session<P>,
    log: &MeasuredLog,
    chosen: &mut Scored,
    nominal: &mut Scored,
    base: &mut Scored,
    calibrated: bool,
) {
    if calibrated {
        ss.reweigh(log, chosen, &mut [nominal, base]);
    } else if ss.reweigh(log, chosen, &mut [nominal]) {
        *base = nominal.clone();
    }
}

/// The calibration: identifiability at the nominal fit, then a fit along the determined
/// combinations.
fn calibrate<P: Plant>(
    ss: &Session<P>,
    params: &[usize],
    nominal: &Scored,
) -> Result<Calibration, DiagnoseError> {
    let ident = identify(&ss.fitter, params, &nominal.fit.theta, &nominal.fit.z0)
        .ok_or(DiagnoseError::NotSimulable)?;
    for c in &ident.combinations {
        (ss.progress)(&format!(
            "  combination {:<40} relative std {:>9.2e}  {}",
            c.name,
            c.std,
            if c.determined {
                "determined"
            } else {
                "left at the file's value"
            }
        ));
    }
    let cand = Candidate {
        effects: vec![],
        calibration: ident.directions(),
    };
    let fit = ss.fit(cand, &nominal.fit.theta, &nominal.fit.z0, None);
    Ok(Calibration {
        identifiability: ident,
        fit,
    })
}

/// A candidate only screened (one linearised step from the base model).
fn screened_only<P: Plant>(
    ss: &Session<P>,
    cand: Candidate,
    sc: &Screened,
    base: &Scored,
) -> Scored {
    let cat = ss.fitter.catalogue();
    let mut theta = base.fit.theta.clone();
    let mut std = vec![0.0; theta.len()];
    for (q, &p) in cat.effects[sc.effect].params.iter().enumerate() {
        theta[p] = sc.theta[q];
        std[p] = sc.std[q];
    }
    let rss = (base.fit.rss - sc.reduction).max(0.0);
    let k = cand.n_free(cat) + ss.base_free;
    let fit = Fit {
        cov: nalgebra::DMatrix::zeros(k, k),
        candidate: cand,
        theta,
        std,
        z0: vec![],
        rss,
        m: base.fit.m,
        iterations: 0,
        converged: false,
        abandoned: false,
    };
    Scored {
        implausible: fit.candidate.implausible(cat, &fit.theta),
        undetermined: undetermined(cat, &fit),
        score: bic(&fit, k),
        error: base.error * (rss / base.fit.rss.max(1e-300)).sqrt(),
        fit,
        fitted: false,
    }
}

/// Errors before and after, residual tests, conditions and the verdict.
#[allow(clippy::too_many_arguments)]
fn conclude<P: Plant>(
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
    let failing: Vec<usize> = tests_after
        .iter()
        .filter(|t| !t.passes())
        .map(|t| t.channel)
        .collect();
    let conditions = super::conditions::conditions(
        log,
        fitter.plant.conditions(log),
        &res_after,
        &fitter.windows,
        &sigma_final,
        &failing,
    );
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
        flagged,
        verdict,
        elapsed_s: ss.t0.elapsed().as_secs_f64(),
    }
}

/// A log whose readings are all constant carries no information about the model (and its
/// residual noise would be zero): a clear error instead of a score of `ln 0`.
fn informative(log: &MeasuredLog) -> Result<(), DiagnoseError> {
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
fn finite_outputs(mut d: Diagnosis) -> Result<Diagnosis, DiagnoseError> {
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
