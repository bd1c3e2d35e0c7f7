//! The fits `diagnose` decides with ([`super::selection`]): a candidate fitted (continued
//! while it leads, its outlying windows restarted), scored by the criterion and judged
//! plausible and determined; the re-weighting after a choice; the calibration, and the
//! chosen effects refitted together with it.

use super::error::DiagnoseError;
use super::fit::{Fit, Fitter, Screened};
use super::grid_scan::GridChoice;
use super::identify::DETERMINED;
use super::identify::{identify, Identifiability};
use super::log::MeasuredLog;
use super::model::{Candidate, Catalogue};
use super::noise::{normalised_error, residual_noise};
use super::Plant;
use std::time::Instant;

/// An effect whose every parameter lies within this many standard deviations of its
/// nominal value is absent, not found: naming it would credit it with what the longer fit
/// of its candidate bought (a null effect adds nothing to the model).
const ABSENT_SIGMAS: f64 = 3.0;

/// Rounds of `max_iterations` more that a leading fit still descending may take.
const CONTINUATIONS: usize = 3;

/// Rounds of outlying-window restarts a leading fit may take.
pub(super) const RESTARTS: usize = 2;

/// One fitted candidate with its score and error.
#[derive(Clone, Debug)]
pub struct Scored {
    /// The fit (for a candidate only screened, its one Gauss–Newton step from the base).
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
    /// [`DETERMINED`] of the parameter's plausible range, or an effect at its null value
    /// (`ABSENT_SIGMAS`). Such a candidate is not named either (its effect is confounded
    /// with others, invisible in this log, or absent).
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
/// their plausible range, and the effects whose every parameter lies within
/// [`ABSENT_SIGMAS`] standard deviations of its nominal value (where the effect is absent:
/// the log determines that it is not there), in words.
fn undetermined(cat: &Catalogue, fit: &Fit) -> Vec<String> {
    let mut out: Vec<String> = fit
        .candidate
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
        .collect();
    for &e in &fit.candidate.effects {
        let params = &cat.effects[e].params;
        let at_null =
            |p: usize| (fit.theta[p] - cat.params[p].nominal).abs() <= ABSENT_SIGMAS * fit.std[p];
        if !params.is_empty() && params.iter().all(|&p| at_null(p)) {
            let values: Vec<String> = params
                .iter()
                .map(|&p| {
                    let s = &cat.params[p];
                    format!("{} = {:.4e} ± {:.1e}", s.name, fit.theta[p], fit.std[p])
                })
                .collect();
            out.push(format!(
                "{} absent ({} within {ABSENT_SIGMAS}σ of the values without it)",
                cat.effects[e].name,
                values.join(", ")
            ));
        }
    }
    out
}

/// What the calibration found.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// Which combinations of the calibrated parameters the log determines, at the nominal
    /// fit.
    pub identifiability: Identifiability,
    /// The calibrated model (no effect), fitted along the determined combinations.
    pub fit: Scored,
}

fn bic(fit: &Fit, k: usize) -> f64 {
    let m = fit.m.max(1) as f64;
    m * (fit.rss / m).ln() + k as f64 * m.ln()
}

/// Everything `diagnose` decides with, for one weighting of the residuals.
pub(super) struct Session<'a, P: Plant> {
    pub(super) fitter: Fitter<'a, P>,
    pub(super) progress: &'a dyn Fn(&str),
    pub(super) t0: Instant,
    /// Residuals in the criterion (the nominal fit's count).
    pub(super) m_res: f64,
    /// Free coordinates of the calibration that effect candidates are built on (their
    /// parameters count in the criterion even while held at the calibrated values).
    pub(super) base_free: usize,
    /// What each scanned parameter's scan chose ([`Session::grid_start`]).
    pub(super) grid_chosen: std::sync::Mutex<Vec<GridChoice>>,
}

impl<P: Plant> Session<'_, P> {
    pub(super) fn score(&self, fit: Fit, fitted: bool) -> Scored {
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

    /// Whether `with`, which adds effects to `without` (fitted under the same weights),
    /// pays for them: the likelihood-ratio statistic of the nested fits,
    /// `Λ = m ln(RSS_without / RSS_with)` over the `m` weighted residuals, divided by the
    /// design effect `δ` of the window clustering (the mean over the added coordinates of
    /// the robust over the classical variance, [`Fit::design`]; Rao & Scott's first-order
    /// correction: residuals correlated within a window make `Λ` about `δ` times what
    /// white ones would), must exceed the information criterion's price `k ln m` of the
    /// `k` added parameters. With white residuals (`δ = 1`) this is the criterion itself.
    pub(super) fn pays(&self, with: &Scored, without: &Scored) -> bool {
        self.gain_statistic(with, without)
            .is_some_and(|(lr, price)| lr > price)
    }

    /// `(Λ/δ, k ln m)` of [`Session::pays`]; `None` when `with` adds nothing.
    pub(super) fn gain_statistic(&self, with: &Scored, without: &Scored) -> Option<(f64, f64)> {
        let cat = self.fitter.catalogue();
        let mut coord = 0;
        let mut added = Vec::new();
        for &e in &with.fit.candidate.effects {
            let n = cat.effects[e].params.len();
            if !without.fit.candidate.effects.contains(&e) {
                added.extend(coord..coord + n);
            }
            coord += n;
        }
        if added.is_empty() {
            return None;
        }
        let m = with.fit.m.max(1) as f64;
        let lr = m * (without.fit.rss / with.fit.rss).ln();
        let delta = added
            .iter()
            .map(|&q| with.fit.design.get(q).copied().unwrap_or(1.0))
            .sum::<f64>()
            / added.len() as f64;
        Some((lr / delta.max(1.0), added.len() as f64 * m.ln()))
    }

    /// One candidate's progress line; one that may not be named says why (a better score
    /// passed over is otherwise a puzzle in the log).
    pub(super) fn say(&self, name: &str, s: &Scored) {
        let why_not = s.implausible.iter().map(|r| format!("implausible: {r}"));
        let why_not = why_not.chain(s.undetermined.iter().map(|r| format!("undetermined: {r}")));
        let why_not: Vec<String> = why_not.collect();
        let not_named = if why_not.is_empty() {
            String::new()
        } else {
            format!("  (not nameable: {})", why_not.join("; "))
        };
        (self.progress)(&format!(
            "  {:<28} error {:>8.3}  score {:>14.1}  {} iterations  ({:.1} s){not_named}",
            name,
            s.error,
            s.score,
            s.fit.iterations,
            self.t0.elapsed().as_secs_f64()
        ));
    }

    /// The cost above which a fit of `cand` cannot beat `best`: `best` plus what the
    /// candidate's parameters cost in the criterion, and a margin.
    pub(super) fn abandon_bound(&self, cand: &Candidate, best: f64) -> f64 {
        let m = self.m_res;
        let cat = self.fitter.catalogue();
        best * (1.0 + cand.n_free(cat) as f64 * m.ln() / m) + 50.0
    }

    /// Fit a candidate from `theta0`, `z0`; abandoned early when it cannot beat `best`
    /// plus what its parameters cost.
    pub(super) fn fit(
        &self,
        cand: Candidate,
        theta0: &[f64],
        z0: &[Vec<f64>],
        best: Option<f64>,
    ) -> Scored {
        let cat = self.fitter.catalogue();
        let bound = best.map(|b| self.abandon_bound(&cand, b));
        let (theta0, z0, scanned) = self.grid_start(&cand, theta0, z0);
        let f = self.fit_leading(&cand, &theta0, &z0, bound, best, RESTARTS);
        let f = self.cross_sampled_edges(&cand, f, &scanned, bound, best);
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
    pub(super) fn fit_leading(
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
    pub(super) fn reweigh(
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

/// After a calibration, the chosen effects and the calibrated combinations refitted
/// together (the calibration was made without the effects). An effect whose parameters
/// become undetermined or implausible there is confounded with the calibration: it is
/// dropped (its parameters back at their nominal values) and the rest refitted. If the
/// rest's joint refit fails by the calibration's parameters alone, the rest is fitted on
/// the base (the calibration as it was) and kept if nameable.
pub(super) fn joint_refit<P: Plant>(
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
            if effects.len() == chosen.fit.candidate.effects.len() {
                return chosen;
            }
            // The rest is not confounded: it stays on the base, without the dropped. It
            // starts from its own earlier fit where there is one (the chosen's window
            // states carry the dropped effect, and an unstable plant's prediction from
            // them may lead the fit astray).
            let mut key = effects.clone();
            key.sort_unstable();
            let earlier = candidates
                .iter()
                .filter(|s| s.fitted && s.fit.candidate.calibration.is_empty())
                .filter(|s| {
                    let mut e = s.fit.candidate.effects.clone();
                    e.sort_unstable();
                    e == key
                })
                .min_by(|a, b| a.score.total_cmp(&b.score));
            let (theta0, z0) = match earlier {
                Some(s) => (s.fit.theta.clone(), s.fit.z0.clone()),
                None => (theta.clone(), chosen.fit.z0.clone()),
            };
            let rest = ss.fit(Candidate::of(effects), &theta0, &z0, None);
            candidates.push(rest.clone());
            return if rest.nameable() { rest } else { base.clone() };
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

/// The models a choice is measured against: the nominal model, and the base the effects
/// are built on (the calibrated model after a calibration, else the nominal one).
#[derive(Clone)]
pub(super) struct References {
    pub nominal: Scored,
    pub base: Scored,
    pub calibrated: bool,
}

impl References {
    /// Re-weigh after a choice: `chosen`, the nominal model and (after a calibration) the
    /// calibrated base model are refitted under the new weights.
    pub(super) fn reweigh<P: Plant>(
        &mut self,
        ss: &mut Session<P>,
        log: &MeasuredLog,
        chosen: &mut Scored,
    ) {
        if self.calibrated {
            ss.reweigh(log, chosen, &mut [&mut self.nominal, &mut self.base]);
        } else if ss.reweigh(log, chosen, &mut [&mut self.nominal]) {
            self.base = self.nominal.clone();
        }
    }
}

/// The calibration: identifiability at the nominal fit, then a fit along the determined
/// combinations.
pub(super) fn calibrate<P: Plant>(
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
pub(super) fn screened_only<P: Plant>(
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
        design: vec![1.0; k],
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
