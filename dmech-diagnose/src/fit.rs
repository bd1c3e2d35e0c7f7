//! Prediction-error fit on short windows (multiple shooting without continuity): the log is
//! cut into windows; each window's initial state `z₀` is free, the candidate's free
//! coordinates `β` are shared; the weighted residuals (prediction − reading)/σ_c over every
//! window are minimised by Levenberg–Marquardt, with the window states eliminated by a Schur
//! complement. Derivatives with respect to `z₀` and `β` come from one dual-number pass
//! through the window's simulation.

use super::log::MeasuredLog;
use super::model::{from_internal, to_internal, Candidate, Catalogue, Direction};
use super::noise::Residuals;
use super::normal_equations::{damped, WindowLin};
use super::normal_equations::{
    direction_scale, param_std, parameter_cov, predicted_reduction, step,
};
use super::window_memo::WindowMemo;
use super::Plant;
use nalgebra::{DMatrix, DVector};

mod window_pass;

/// How the log is cut and weighted.
#[derive(Clone, Debug)]
pub struct FitSetup {
    /// First row of the first window (leaves room for the delayed commands before it).
    pub first_row: usize,
    /// Window length in samples.
    pub window: usize,
    /// Noise level of each channel (`∞` for channels not used).
    pub sigma: Vec<f64>,
    /// Threads the windows are spread over (at least one is used).
    pub threads: usize,
    /// Levenberg–Marquardt iterations of [`Fitter::fit`] before it stops unconverged.
    pub max_iterations: usize,
}

impl FitSetup {
    /// Consecutive windows `(start, len)` from `first_row`; a last piece shorter than half
    /// a window is left out.
    pub fn windows(&self, n_rows: usize) -> Vec<(usize, usize)> {
        let mut w = Vec::new();
        let mut start = self.first_row;
        while start + self.window / 2 < n_rows {
            let len = self.window.min(n_rows - start);
            w.push((start, len));
            start += len;
        }
        w
    }
}

/// The result of fitting a candidate.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The candidate fitted (what it frees).
    pub candidate: Candidate,
    /// Every parameter of the catalogue (the free ones fitted, the others at their
    /// reference values).
    pub theta: Vec<f64>,
    /// Standard deviation of every parameter the candidate frees (0 for the others), with
    /// its systematic floor.
    pub std: Vec<f64>,
    /// Covariance of the free coordinates `β`.
    pub cov: DMatrix<f64>,
    /// Per free coordinate, the design effect of the window clustering (robust over
    /// classical variance, at least 1; `normal_equations::parameter_cov`).
    pub design: Vec<f64>,
    /// The fitted initial state of each window, in the order of [`Fitter::windows`]
    /// (empty for a candidate only screened).
    pub z0: Vec<Vec<f64>>,
    /// Weighted residual sum of squares and number of residuals.
    pub rss: f64,
    /// Number of weighted residuals: the readings inside the windows of channels with a
    /// finite noise level.
    pub m: usize,
    /// Levenberg–Marquardt iterations (linearisations) taken, continuations included; 0 for
    /// a candidate only screened.
    pub iterations: usize,
    /// The last accepted step promised less than [`CONVERGED_REDUCTION`] in the criterion
    /// or lowered the RSS by less than a relative 10⁻⁹, or no damping up to 10⁸ found a
    /// descent; `false` when the iteration cap, an abandonment or a failed linearisation
    /// ended the fit.
    pub converged: bool,
    /// Stopped early because it could not beat the bound it was given.
    pub abandoned: bool,
}

impl Fit {
    /// The values of the candidate's effect parameters, in order.
    pub fn effect_values(&self, cat: &Catalogue) -> Vec<f64> {
        self.candidate
            .effect_params(cat)
            .iter()
            .map(|&p| self.theta[p])
            .collect()
    }
    /// The standard deviations of the candidate's effect parameters, in the order of
    /// [`Fit::effect_values`].
    pub fn effect_std(&self, cat: &Catalogue) -> Vec<f64> {
        self.candidate
            .effect_params(cat)
            .iter()
            .map(|&p| self.std[p])
            .collect()
    }
}

/// The fit stops when a Gauss–Newton step promises less than this reduction of the
/// criterion `m ln(RSS/m)` (one parameter must pay `ln m ≈ 10` in the BIC). A reduction
/// `ΔRSS` of the weighted residual sum of squares changes the criterion by
/// `m ΔRSS / RSS`: with weights at the noise (`RSS ≈ m`) the two are the same; on a log the
/// model is far from (`RSS ≫ m`) a step of the same worth is larger in RSS.
pub const CONVERGED_REDUCTION: f64 = 0.05;

/// A fit is abandoned when its cost less this many times the reduction its next step
/// promises stays above the bound it was given ([`cannot_win`]): a linearisation's
/// promise misjudges a nonlinear descent, by less than this factor on the catalogues'
/// effects (none of the recovery matrix's true effects is abandoned).
pub const ABANDON_MARGIN: f64 = 3.0;

/// Whether a fit at cost `rss`, whose next step promises the reduction `promised`, cannot
/// get below `bound`: `rss − ABANDON_MARGIN · promised > bound` ([`Fitter::fit`]'s
/// abandonment, and the screen's before a fit starts).
pub fn cannot_win(rss: f64, promised: f64, bound: f64) -> bool {
    rss - ABANDON_MARGIN * promised.max(0.0) > bound
}

/// The most dual directions a linearisation carries (window state and free coordinates).
pub const MAX_DIRECTIONS: usize = 40;

/// The prediction-error fit of a plant to a log: the windows, their weights, and the
/// reference parameters; fits a candidate by Levenberg–Marquardt with the window states
/// eliminated by a Schur complement, screens effects, and gives residuals.
pub struct Fitter<'a, P: Plant> {
    /// The system whose model is fitted.
    pub plant: &'a P,
    /// The measured log.
    pub log: &'a MeasuredLog,
    /// How the log is cut and weighted.
    pub setup: FitSetup,
    /// The prediction windows `(first row, rows)`.
    pub windows: Vec<(usize, usize)>,
    /// Reference values of every parameter (the nominal model, or a calibrated one).
    pub reference: Vec<f64>,
    /// State components carried by dual directions (the others are additive).
    dual_states: Vec<usize>,
    /// Window results shared between parameter vectors that predict a window alike
    /// (only for a scan: [`Fitter::with_window_memo`]).
    memo: Option<WindowMemo>,
}

impl<'a, P: Plant> Fitter<'a, P> {
    /// The same fit over the windows `pick` (indices into `self.windows`) only.
    pub fn on_windows(&self, pick: &[usize]) -> Self {
        Fitter {
            plant: self.plant,
            log: self.log,
            setup: self.setup.clone(),
            windows: pick.iter().map(|&w| self.windows[w]).collect(),
            reference: self.reference.clone(),
            dual_states: self.dual_states.clone(),
            memo: None,
        }
    }

    /// The same fit keeping its windows' costs and states-only linearisations for reuse
    /// under parameters the plant's [`Plant::window_key`] does not tell apart: for a scan
    /// that runs the same states-only iterations under many values of one parameter. The
    /// results are those without it, bit for bit.
    pub fn with_window_memo(mut self) -> Self {
        self.memo = Some(WindowMemo::new(self.windows.len()));
        self
    }

    /// A fit over the windows [`FitSetup::windows`] of the log, with the catalogue's nominal
    /// values as the reference.
    pub fn new(plant: &'a P, log: &'a MeasuredLog, setup: FitSetup) -> Self {
        let windows = setup.windows(log.len());
        let additive: Vec<usize> = plant.additive().iter().map(|&(s, _)| s).collect();
        let dual_states = (0..plant.state_dim())
            .filter(|s| !additive.contains(s))
            .collect();
        Fitter {
            plant,
            log,
            setup,
            windows,
            reference: plant.catalogue().nominal(),
            dual_states,
            memo: None,
        }
    }

    /// The plant's catalogue.
    pub fn catalogue(&self) -> &Catalogue {
        self.plant.catalogue()
    }

    /// Initial window states from the readings themselves.
    pub fn initial_states(&self) -> Vec<Vec<f64>> {
        self.windows
            .iter()
            .map(|&(s, len)| self.plant.initial_state(self.log, s, len))
            .collect()
    }

    fn weight(&self, c: usize) -> f64 {
        let s = self.setup.sigma[c];
        if s.is_finite() && s > 0.0 && self.log.present[c] {
            1.0 / s
        } else {
            0.0
        }
    }

    /// Run `f` over every window, on `threads` threads.
    pub(crate) fn map_windows<R: Send>(&self, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
        let n = self.windows.len();
        let threads = self.setup.threads.max(1).min(n.max(1));
        let chunk = n.div_ceil(threads);
        let f = &f;
        std::thread::scope(|sc| {
            let handles: Vec<_> = (0..threads)
                .map(|t| {
                    sc.spawn(move || {
                        (t * chunk..((t + 1) * chunk).min(n))
                            .map(f)
                            .collect::<Vec<R>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().expect("a fit thread panicked"))
                .collect()
        })
    }

    /// Total weighted cost; `None` if some window's simulation fails.
    pub fn cost(&self, theta: &[f64], z0: &[Vec<f64>]) -> Option<(f64, usize)> {
        let parts = self.map_windows(|wi| {
            let win = self.windows[wi];
            let compute = || self.window_cost(theta, win, &z0[wi]);
            match &self.memo {
                Some(memo) => {
                    let key = self.plant.window_key(self.log, win.0, win.1, theta);
                    memo.cost(wi, &key, &z0[wi], compute)
                }
                None => compute(),
            }
        });
        parts
            .into_iter()
            .try_fold((0.0, 0), |(r, m), p| p.map(|(a, b)| (r + a, m + b)))
    }

    /// Linearise every window (`None` if one fails).
    pub(crate) fn linearise(
        &self,
        theta: &[f64],
        dirs: &[Direction],
        z0: &[Vec<f64>],
    ) -> Option<Vec<WindowLin>> {
        let cat = self.catalogue();
        let x = to_internal(cat, theta);
        // The parameters `window_lin` predicts with (`x` mapped back as it maps it).
        let used: Vec<f64> = cat
            .params
            .iter()
            .zip(&x)
            .map(|(s, &v)| s.from_internal(v))
            .collect();
        self.map_windows(|wi| {
            let win = self.windows[wi];
            let compute = || self.window_lin(&x, dirs, win, &z0[wi]);
            match &self.memo {
                Some(memo) if dirs.is_empty() => {
                    let key = self.plant.window_key(self.log, win.0, win.1, &used);
                    memo.lin(wi, &key, &z0[wi], compute)
                }
                _ => compute(),
            }
        })
        .into_iter()
        .collect()
    }

    /// Levenberg–Marquardt from `(theta0, z0)`, freeing the candidate's directions.
    /// With `abandon_above`, the fit stops early once it cannot get below that cost: after
    /// two iterations, when the cost less [`ABANDON_MARGIN`] times the reduction the next
    /// step promises is still above it ([`cannot_win`]; a caller may apply the same test
    /// before the first iteration to the screen's promise, [`Fitter::screen`]).
    /// Sooner, a slow descent is cut short: abandoned after one iteration, a voltage gain
    /// on `regbot_01` stopped at E 1.221 where its fit goes on to 1.126 and leads.
    pub fn fit(
        &self,
        cand: &Candidate,
        theta0: &[f64],
        z0: &[Vec<f64>],
        abandon_above: Option<f64>,
        progress: &dyn Fn(&str),
    ) -> Fit {
        let cap = self.setup.max_iterations;
        self.fit_capped(cand, theta0, z0, abandon_above, progress, cap)
    }

    /// [`Fitter::fit`] with at most `max_iterations` iterations.
    pub fn fit_capped(
        &self,
        cand: &Candidate,
        theta0: &[f64],
        z0: &[Vec<f64>],
        abandon_above: Option<f64>,
        progress: &dyn Fn(&str),
        max_iterations: usize,
    ) -> Fit {
        let cat = self.catalogue();
        let dirs = cand.directions(cat);
        let k = dirs.len();
        assert!(
            self.dual_states.len() + k <= MAX_DIRECTIONS,
            "{k} free coordinates: more than a linearisation carries"
        );
        let scale = DVector::from_iterator(k, dirs.iter().map(|d| direction_scale(cat, d)));
        let mut theta = from_internal(cat, &to_internal(cat, theta0));
        let mut z: Vec<Vec<f64>> = z0.to_vec();
        let mut lambda = 1e-3;
        let (mut iterations, mut converged, mut abandoned) = (0, false, false);
        let mut cov = DMatrix::from_element(k, k, f64::INFINITY);
        let mut design = vec![f64::INFINITY; k];
        'outer: for it in 0..max_iterations {
            iterations = it + 1;
            let Some(lins) = self.linearise(&theta, &dirs, &z) else {
                break;
            };
            let rss: f64 = lins.iter().map(|l| l.rss).sum();
            // The covariance of the candidates' table comes from the last linearisation;
            // the chosen model's is recomputed at its final point (`final_std`).
            (cov, design) = parameter_cov(&lins, k);
            progress(&format!(
                "  {:<28} it {:>2}  cost {:>12.3}",
                cand.name(cat),
                it,
                rss
            ));
            loop {
                let (dz, dp) = step(&lins, k, lambda, &scale);
                let predicted = predicted_reduction(&lins, &dz, &dp);
                if let Some(bound) = abandon_above {
                    if it >= 2 && cannot_win(rss, predicted, bound) {
                        abandoned = true;
                        break 'outer;
                    }
                }
                let mut x = to_internal(cat, &theta);
                for (q, d) in dirs.iter().enumerate() {
                    for &(j, b) in d {
                        x[j] += b * dp[q];
                    }
                }
                let theta_new = from_internal(cat, &x);
                let z_new: Vec<Vec<f64>> = z
                    .iter()
                    .zip(&dz)
                    .map(|(a, b)| a.iter().zip(b.iter()).map(|(p, q)| p + q).collect())
                    .collect();
                match self.cost(&theta_new, &z_new) {
                    Some((rss_new, _)) if rss_new <= rss => {
                        let rel = (rss - rss_new) / rss.max(1e-300);
                        theta = theta_new;
                        z = z_new;
                        lambda = (lambda / 3.0).max(1e-9);
                        // Converged when the model promised (and the step delivered) less
                        // than a hundredth of what one parameter must pay in the
                        // information criterion.
                        let worth = predicted * lins.iter().map(|l| l.m).sum::<usize>() as f64
                            / rss.max(1e-300);
                        if rel < 1e-9 || worth < CONVERGED_REDUCTION {
                            converged = true;
                            break 'outer;
                        }
                        break;
                    }
                    _ => {
                        lambda *= 4.0;
                        if lambda > 1e8 {
                            converged = true; // no descent left at this point
                            break 'outer;
                        }
                    }
                }
            }
        }
        let (rss, m) = self.cost(&theta, &z).unwrap_or((f64::INFINITY, 0));
        let std = param_std(cat, &dirs, &theta, &cov, self.log.h);
        Fit {
            candidate: cand.clone(),
            theta,
            std,
            cov,
            design,
            z0: z,
            rss,
            m,
            iterations,
            converged,
            abandoned,
        }
    }

    /// The covariance and standard deviations at the fit's own point (one more
    /// linearisation; `fit` reports those of its last iteration, taken before its last
    /// step), with each parameter's systematic floor added in quadrature.
    pub fn final_std(&self, fit: &mut Fit) {
        let cat = self.catalogue();
        let dirs = fit.candidate.directions(cat);
        if dirs.is_empty() {
            return;
        }
        (fit.cov, fit.design) = match self.linearise(&fit.theta, &dirs, &fit.z0) {
            Some(l) => parameter_cov(&l, dirs.len()),
            None => (
                DMatrix::from_element(dirs.len(), dirs.len(), f64::INFINITY),
                vec![f64::INFINITY; dirs.len()],
            ),
        };
        fit.std = param_std(cat, &dirs, &fit.theta, &fit.cov, self.log.h);
    }

    /// Screen effects with one linearisation at `theta` (window states `z0`): for each
    /// effect, the Gauss–Newton step of its parameters with every window state
    /// re-optimised, and the reduction of the cost it predicts.
    pub fn screen(
        &self,
        effects: &[usize],
        theta: &[f64],
        z0: &[Vec<f64>],
        rss: f64,
        m: usize,
    ) -> Option<Vec<Screened>> {
        let cat = self.catalogue();
        let all = Candidate::of(effects.to_vec());
        let dirs = all.directions(cat);
        // Windows whose linearisation is not finite (a prediction far off the data) are
        // left out of the screening; the full fits see every window.
        let x = to_internal(cat, theta);
        let lins: Vec<WindowLin> = self
            .map_windows(|wi| self.window_lin(&x, &dirs, self.windows[wi], &z0[wi]))
            .into_iter()
            .flatten()
            .collect();
        if lins.is_empty() {
            return None;
        }
        let nz = self.plant.state_dim();
        let mut out = Vec::new();
        let mut offset = 0;
        for &e in effects {
            let np = cat.effects[e].params.len();
            let idx: Vec<usize> = (offset..offset + np).collect();
            offset += np;
            let mut s = DMatrix::<f64>::zeros(np, np);
            let mut g = DVector::<f64>::zeros(np);
            for l in &lins {
                let w = l.w.select_columns(&idx);
                s += l.v.select_rows(&idx).select_columns(&idx);
                g += l.gp.select_rows(&idx);
                if let Some(ch) = damped(&l.a, 0.0).cholesky() {
                    let x = ch.solve(&w);
                    s -= w.transpose() * x;
                    g -= w.transpose() * ch.solve(&l.gz);
                }
            }
            let (delta, reduction, std) = match s.clone().try_inverse() {
                Some(inv) => {
                    let delta = -(&inv * &g);
                    let red = g.dot(&(&inv * &g));
                    let dof = (m as f64 - (nz * self.windows.len() + np) as f64).max(1.0);
                    let s2 = (rss - red).max(0.0) / dof;
                    let std = (0..np)
                        .map(|i| (inv[(i, i)].max(0.0) * s2).sqrt())
                        .collect();
                    (delta, red, std)
                }
                None => (DVector::zeros(np), 0.0, vec![f64::INFINITY; np]),
            };
            let reduction = if reduction.is_finite() {
                reduction.max(0.0)
            } else {
                0.0
            };
            let mut x2 = x.clone();
            for (q, &p) in cat.effects[e].params.iter().enumerate() {
                x2[p] += delta[q];
            }
            let theta2 = from_internal(cat, &x2);
            out.push(Screened {
                effect: e,
                theta: cat.effects[e].params.iter().map(|&p| theta2[p]).collect(),
                std,
                reduction,
            });
        }
        Some(out)
    }

    /// Unweighted residuals (prediction − reading) of a fitted model, per row and channel.
    pub fn residuals(&self, fit: &Fit) -> Residuals {
        self.residuals_at(&fit.theta, &fit.z0)
    }

    /// Unweighted residuals (prediction − reading) at parameters `theta` and window states
    /// `z0`, per row and channel; NaN outside the windows, where not measured, and
    /// throughout a window whose prediction fails.
    pub fn residuals_at(&self, theta: &[f64], z0: &[Vec<f64>]) -> Residuals {
        let nc = self.log.n_channels;
        let mut res = Residuals::new(self.log.len(), nc);
        let chans = self.plant.channels();
        let parts = self.map_windows(|wi| {
            let (start, len) = self.windows[wi];
            self.predict(start, len, &z0[wi], theta)
        });
        for (&(start, len), y) in self.windows.iter().zip(parts) {
            let Some(y) = y else { continue };
            for j in 0..len {
                for (c, spec) in chans.iter().enumerate() {
                    if let Some(meas) = self.log.value(start + j, c) {
                        res.set(start + j, c, spec.residual(y[j * nc + c], meas));
                    }
                }
            }
        }
        res
    }
}

/// What one linearisation predicts for an effect.
#[derive(Clone, Debug)]
pub struct Screened {
    /// Index of the effect in the catalogue.
    pub effect: usize,
    /// Parameters after one Gauss–Newton step.
    pub theta: Vec<f64>,
    /// Classical standard deviations of those parameters from the linearisation (`∞` when
    /// the reduced normal matrix is singular).
    pub std: Vec<f64>,
    /// Predicted reduction of the weighted residual sum of squares.
    pub reduction: f64,
}

impl Screened {
    /// Whether the linearisation sees nothing of the effect: its reduced normal matrix is
    /// singular, as where the prediction does not move with the parameters at their start
    /// (a time threshold with no events below it, a static friction of zero). Its
    /// predicted reduction of zero then says nothing of its fit.
    pub fn unseen(&self) -> bool {
        self.std.iter().any(|s| !s.is_finite())
    }
}
