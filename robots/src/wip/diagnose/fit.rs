//! Prediction-error fit on short windows (multiple shooting without continuity): the log is
//! cut into windows; each window's initial state `z₀` is free, the effect parameters `ϑ`
//! are shared; the weighted residuals (prediction − reading)/σ_c over every window are
//! minimised by Levenberg–Marquardt, with the window states eliminated by a Schur
//! complement. Derivatives with respect to `z₀` and `ϑ` come from one dual-number pass
//! through the window's simulation.

use super::effects::{Effect, ModelExtension};
use super::measured::{Channel, MeasuredLog};
use super::prediction::{FitScalar, Predictor, DUAL_STATE, NZ};
use crate::wip::WipParams;
use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use num_dual::DualSVec64;

/// Number of effect parameters a full fit can carry (two effects of up to two parameters).
pub const MAX_PARAMS: usize = 4;

type Z = SVector<f64, NZ>;

/// How the log is cut and weighted.
#[derive(Clone, Debug)]
pub struct FitSetup {
    /// First row of the first window (leaves room for the delayed commands before it).
    pub first_row: usize,
    /// Window length in samples.
    pub window: usize,
    /// Noise level of each channel (`∞` for channels not used).
    pub sigma: [f64; 9],
    pub threads: usize,
    pub max_iterations: usize,
}

impl FitSetup {
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

/// A candidate model: the effects switched on (none, one or two).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Candidate {
    pub effects: Vec<Effect>,
}

impl Candidate {
    pub fn none() -> Self {
        Candidate { effects: vec![] }
    }
    pub fn n_params(&self) -> usize {
        self.effects.iter().map(|e| e.n_params()).sum()
    }
    pub fn name(&self) -> String {
        if self.effects.is_empty() {
            "none".into()
        } else {
            self.effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join("+")
        }
    }
    pub fn parameter_names(&self) -> Vec<&'static str> {
        self.effects
            .iter()
            .flat_map(|e| e.parameter_names().iter().copied())
            .collect()
    }
    pub fn nominal(&self, p: &WipParams) -> Vec<f64> {
        self.effects.iter().flat_map(|e| e.nominal(p)).collect()
    }
    /// The parameters of `theta` outside their effect's physically plausible range.
    pub fn implausible(&self, theta: &[f64], p: &WipParams) -> Vec<String> {
        let mut out = Vec::new();
        let mut at = 0;
        for e in &self.effects {
            let n = e.n_params();
            if theta.len() >= at + n {
                out.extend(e.implausible(&theta[at..at + n], p));
            }
            at += n;
        }
        out
    }
    fn scale(&self, p: &WipParams) -> Vec<f64> {
        self.effects.iter().flat_map(|e| e.scale(p)).collect()
    }
    fn project(&self, theta: &mut [f64], p: &WipParams) {
        let mut i = 0;
        for e in &self.effects {
            let n = e.n_params();
            e.project(&mut theta[i..i + n], p);
            i += n;
        }
    }
    /// The extension with these parameter values.
    pub fn extension<T: FitScalar>(&self, p: &WipParams, theta: &[T]) -> ModelExtension<T> {
        let mut ext = ModelExtension::<T>::nominal(p);
        let mut i = 0;
        for e in &self.effects {
            let n = e.n_params();
            ext.set(*e, &theta[i..i + n]);
            i += n;
        }
        ext
    }
}

/// The result of fitting a candidate.
#[derive(Clone, Debug)]
pub struct Fit {
    pub candidate: Candidate,
    pub theta: Vec<f64>,
    /// Standard deviation of each parameter (from the Gauss–Newton covariance, scaled by
    /// the residual variance).
    pub std: Vec<f64>,
    pub z0: Vec<Z>,
    /// Weighted residual sum of squares and number of residuals.
    pub rss: f64,
    pub m: usize,
    pub iterations: usize,
    /// Whether the simulation of some window failed at the returned point.
    pub converged: bool,
}

/// A window's predicted readings: rows `start..start+len`.
fn predict_window<T: FitScalar>(
    pred: &Predictor<T>,
    log: &MeasuredLog,
    (start, len): (usize, usize),
    z0: SVector<T, NZ>,
) -> Option<Vec<[T; 9]>> {
    let h = log.h;
    let mut z = z0;
    let mut out = Vec::with_capacity(len);
    let mut wdot =
        pred.wheel_acceleration(&z, pred.mean_applied(&log.cmd, start.saturating_sub(1), h))?;
    for k in start..start + len {
        out.push(pred.readings(&z, pred.current_voltage(&log.cmd, k, h), wdot));
        if k + 1 < start + len {
            (z, wdot) = pred.advance(&z, &log.cmd, k, h)?;
        }
    }
    Some(out)
}

/// Reading minus prediction residual, wrapped for the heading.
fn residual(c: Channel, predicted: f64, measured: f64) -> f64 {
    let d = predicted - measured;
    if c == Channel::Theta {
        d - (d / std::f64::consts::TAU).round() * std::f64::consts::TAU
    } else {
        d
    }
}

/// Per-channel sums of squared unweighted residuals and counts, and the residuals
/// themselves (NaN where not measured), of a fitted model over its windows.
pub struct Residuals {
    /// `r[k][c]`, rows of the whole log (NaN outside windows or where not measured).
    pub r: Vec<[f64; 9]>,
}

pub struct Fitter<'a> {
    pub log: &'a MeasuredLog,
    pub params: &'a WipParams,
    pub setup: FitSetup,
    pub windows: Vec<(usize, usize)>,
}

struct WindowLin {
    a: SMatrix<f64, NZ, NZ>,
    w: DMatrix<f64>,
    v: DMatrix<f64>,
    gz: Z,
    gp: DVector<f64>,
    rss: f64,
    m: usize,
}

impl<'a> Fitter<'a> {
    pub fn new(log: &'a MeasuredLog, params: &'a WipParams, setup: FitSetup) -> Self {
        let windows = setup.windows(log.len());
        Fitter {
            log,
            params,
            setup,
            windows,
        }
    }

    /// Initial window states from the readings themselves (pose from the nearest pose
    /// sample, wheel rates from encoder differences).
    pub fn initial_states(&self) -> Vec<Z> {
        let log = self.log;
        let h = log.h;
        self.windows
            .iter()
            .map(|&(s, len)| {
                let near = |c: Channel| -> f64 {
                    (s..(s + len).min(log.len()))
                        .find_map(|k| log.value(k, c))
                        .unwrap_or(0.0)
                };
                let alpha = near(Channel::Alpha);
                let va = near(Channel::VAlpha);
                let rate = |c: Channel| -> f64 {
                    let (a, b) = (s.saturating_sub(2), (s + 2).min(log.len() - 1));
                    match (log.value(a, c), log.value(b, c)) {
                        (Some(x), Some(y)) if b > a => (y - x) / ((b - a) as f64 * h) + va,
                        _ => 0.0,
                    }
                };
                Z::from_column_slice(&[
                    near(Channel::X),
                    near(Channel::Y),
                    near(Channel::Theta),
                    alpha,
                    near(Channel::PhiRRel) + alpha,
                    near(Channel::PhiLRel) + alpha,
                    va,
                    rate(Channel::PhiRRel),
                    rate(Channel::PhiLRel),
                ])
            })
            .collect()
    }

    fn weight(&self, c: Channel) -> f64 {
        let s = self.setup.sigma[c.index()];
        if s.is_finite() && s > 0.0 && self.log.present[c.index()] {
            1.0 / s
        } else {
            0.0
        }
    }

    /// Weighted residual sum of squares and count of one window (f64 pass); `None` if the
    /// simulation fails.
    fn window_cost(
        &self,
        cand: &Candidate,
        theta: &[f64],
        win: (usize, usize),
        z0: &Z,
    ) -> Option<(f64, usize)> {
        let pred = Predictor::<f64>::new(cand.extension(self.params, theta), self.params);
        let (start, _) = win;
        let y = predict_window(&pred, self.log, win, *z0)?;
        let mut rss = 0.0;
        let mut m = 0;
        for (j, yk) in y.iter().enumerate() {
            for c in Channel::ALL {
                let wgt = self.weight(c);
                if wgt == 0.0 {
                    continue;
                }
                if let Some(meas) = self.log.value(start + j, c) {
                    let r = residual(c, yk[c.index()], meas) * wgt;
                    rss += r * r;
                    m += 1;
                }
            }
        }
        Some((rss, m))
    }

    /// The window's Gauss–Newton blocks (one dual pass with `N = 5 + n_params`
    /// directions).
    fn window_lin_n<const N: usize>(
        &self,
        cand: &Candidate,
        theta: &[f64],
        win: (usize, usize),
        z0: &Z,
    ) -> Option<WindowLin> {
        type Dn<const N: usize> = DualSVec64<N>;
        let np = cand.n_params();
        let nd = DUAL_STATE.len();
        assert!(nd + np <= N);
        let theta_d: Vec<Dn<N>> = theta
            .iter()
            .enumerate()
            .map(|(j, &t)| Dn::<N>::from(t).derivative(nd + j))
            .collect();
        let pred = Predictor::<Dn<N>>::new(cand.extension(self.params, &theta_d), self.params);
        let mut zd = z0.map(Dn::<N>::from);
        for (d, &i) in DUAL_STATE.iter().enumerate() {
            zd[i] = Dn::<N>::from(z0[i]).derivative(d);
        }
        let (start, _) = win;
        let y = predict_window(&pred, self.log, win, zd)?;
        let mut a = SMatrix::<f64, NZ, NZ>::zeros();
        let mut w = DMatrix::<f64>::zeros(NZ, np);
        let mut v = DMatrix::<f64>::zeros(np, np);
        let mut gz = Z::zeros();
        let mut gp = DVector::<f64>::zeros(np);
        let mut rss = 0.0;
        let mut m = 0;
        for (j, yk) in y.iter().enumerate() {
            for c in Channel::ALL {
                let wgt = self.weight(c);
                if wgt == 0.0 {
                    continue;
                }
                let Some(meas) = self.log.value(start + j, c) else {
                    continue;
                };
                let yc = yk[c.index()];
                let r = residual(c, yc.re, meas) * wgt;
                let g = yc
                    .eps
                    .unwrap_generic(nalgebra::Const::<N>, nalgebra::Const::<1>);
                // Row of the Jacobian: z₀ columns (dual or additive) and parameter columns.
                let mut jz = Z::zeros();
                for (d, &i) in DUAL_STATE.iter().enumerate() {
                    jz[i] = g[d] * wgt;
                }
                match c {
                    Channel::X => jz[0] += wgt,
                    Channel::Y => jz[1] += wgt,
                    Channel::PhiRRel => jz[4] += wgt,
                    Channel::PhiLRel => jz[5] += wgt,
                    _ => {}
                }
                let jp = DVector::<f64>::from_fn(np, |q, _| g[nd + q] * wgt);
                a += jz * jz.transpose();
                w += jz * jp.transpose();
                v += &jp * jp.transpose();
                gz += jz * r;
                gp += &jp * r;
                rss += r * r;
                m += 1;
            }
        }
        let finite = a
            .iter()
            .chain(w.iter())
            .chain(v.iter())
            .all(|x| x.is_finite())
            && rss.is_finite();
        finite.then_some(WindowLin {
            a,
            w,
            v,
            gz,
            gp,
            rss,
            m,
        })
    }

    fn window_lin(
        &self,
        cand: &Candidate,
        theta: &[f64],
        win: (usize, usize),
        z0: &Z,
    ) -> Option<WindowLin> {
        match cand.n_params() {
            0 => self.window_lin_n::<5>(cand, theta, win, z0),
            1 => self.window_lin_n::<6>(cand, theta, win, z0),
            2 => self.window_lin_n::<7>(cand, theta, win, z0),
            3 => self.window_lin_n::<8>(cand, theta, win, z0),
            4 => self.window_lin_n::<9>(cand, theta, win, z0),
            n if n <= SCREEN_PARAMS => {
                self.window_lin_n::<{ 5 + SCREEN_PARAMS }>(cand, theta, win, z0)
            }
            n => panic!("{n} effect parameters: more than the catalogue has"),
        }
    }

    /// Run `f` over every window, on `threads` threads.
    fn map_windows<R: Send>(&self, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
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
    pub fn cost(&self, cand: &Candidate, theta: &[f64], z0: &[Z]) -> Option<(f64, usize)> {
        let parts = self.map_windows(|wi| self.window_cost(cand, theta, self.windows[wi], &z0[wi]));
        parts
            .into_iter()
            .try_fold((0.0, 0), |(r, m), p| p.map(|(a, b)| (r + a, m + b)))
    }

    /// Levenberg–Marquardt from `(theta0, z0)`.
    /// With `abandon_above`, the fit stops early once it cannot get below that cost: after
    /// two iterations, when the cost less three times the reduction the next step
    /// promises is still above it (the candidate cannot win).
    pub fn fit(
        &self,
        cand: &Candidate,
        theta0: &[f64],
        z0: &[Z],
        abandon_above: Option<f64>,
        progress: &dyn Fn(&str),
    ) -> Fit {
        let np = cand.n_params();
        assert!(np <= MAX_PARAMS, "at most {MAX_PARAMS} effect parameters");
        let scale = DVector::from_vec(cand.scale(self.params));
        let mut theta = theta0.to_vec();
        let mut z: Vec<Z> = z0.to_vec();
        let mut lambda = 1e-3;
        let mut iterations = 0;
        let mut converged = false;
        let mut std_last = vec![f64::INFINITY; np];
        'outer: for it in 0..self.setup.max_iterations {
            iterations = it + 1;
            let lins: Option<Vec<WindowLin>> = self
                .map_windows(|wi| self.window_lin(cand, &theta, self.windows[wi], &z[wi]))
                .into_iter()
                .collect();
            let Some(lins) = lins else {
                break;
            };
            let rss: f64 = lins.iter().map(|l| l.rss).sum();
            // The covariance of the candidates' table comes from the last linearisation;
            // the chosen model's is recomputed at its final point (`final_std`).
            std_last = if np > 0 {
                parameter_std(&lins, np)
            } else {
                vec![]
            };
            progress(&format!(
                "  {:<28} it {:>2}  cost {:>12.3}  {}",
                cand.name(),
                it,
                rss,
                fmt_theta(&theta)
            ));
            loop {
                let (dz, dp) = step(&lins, np, lambda, &scale);
                let predicted = predicted_reduction(&lins, &dz, &dp);
                if let Some(bound) = abandon_above {
                    if it >= 2 && rss - 3.0 * predicted.max(0.0) > bound {
                        break 'outer;
                    }
                }
                let mut theta_new: Vec<f64> =
                    theta.iter().zip(dp.iter()).map(|(t, d)| t + d).collect();
                cand.project(&mut theta_new, self.params);
                let z_new: Vec<Z> = z.iter().zip(&dz).map(|(a, b)| a + b).collect();
                match self.cost(cand, &theta_new, &z_new) {
                    Some((rss_new, _)) if rss_new <= rss => {
                        let rel = (rss - rss_new) / rss.max(1e-300);
                        theta = theta_new;
                        z = z_new;
                        lambda = (lambda / 3.0).max(1e-9);
                        // Converged when the model promised (and the step delivered) less
                        // than a hundredth of what one parameter must pay in the
                        // information criterion.
                        if rel < 1e-9 || predicted < CONVERGED_REDUCTION {
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
        let (rss, m) = self.cost(cand, &theta, &z).unwrap_or((f64::INFINITY, 0));
        let std = std_last;
        Fit {
            candidate: cand.clone(),
            theta,
            std,
            z0: z,
            rss,
            m,
            iterations,
            converged,
        }
    }

    /// The parameters' standard deviations at the fit's own point (one more linearisation;
    /// `fit` reports those of the last iteration's, taken before its last step), with the
    /// effect's systematic floor added in quadrature ([`Effect::systematic`]).
    pub fn final_std(&self, fit: &Fit) -> Vec<f64> {
        let np = fit.candidate.n_params();
        if np == 0 {
            return vec![];
        }
        let lins: Option<Vec<WindowLin>> = self
            .map_windows(|wi| {
                self.window_lin(&fit.candidate, &fit.theta, self.windows[wi], &fit.z0[wi])
            })
            .into_iter()
            .collect();
        let stat = match lins {
            Some(l) => parameter_std(&l, np),
            None => return vec![f64::INFINITY; np],
        };
        let sys: Vec<f64> = fit
            .candidate
            .effects
            .iter()
            .flat_map(|e| e.systematic(self.params))
            .collect();
        stat.iter().zip(sys).map(|(a, b)| a.hypot(b)).collect()
    }

    /// Screen the whole catalogue with one linearisation at the nominal model (window
    /// states `z0`): for each effect, the Gauss–Newton step of its parameters with every
    /// window state re-optimised, and the reduction of the cost it predicts.
    pub fn screen(&self, z0: &[Z], rss: f64, m: usize) -> Option<Vec<Screened>> {
        let all = Candidate {
            effects: Effect::ALL.to_vec(),
        };
        let theta0 = all.nominal(self.params);
        // Windows whose linearisation is not finite (a prediction far off the data) are
        // left out of the screening; the full fits see every window.
        let lins: Vec<WindowLin> = self
            .map_windows(|wi| self.window_lin(&all, &theta0, self.windows[wi], &z0[wi]))
            .into_iter()
            .flatten()
            .collect();
        if lins.is_empty() {
            return None;
        }
        let mut out = Vec::new();
        let mut offset = 0;
        for e in Effect::ALL {
            let idx: Vec<usize> = (offset..offset + e.n_params()).collect();
            offset += e.n_params();
            let k = idx.len();
            let mut s = DMatrix::<f64>::zeros(k, k);
            let mut g = DVector::<f64>::zeros(k);
            for l in &lins {
                let w = l.w.select_columns(&idx);
                let v = l.v.select_rows(&idx).select_columns(&idx);
                s += v;
                g += l.gp.select_rows(&idx);
                if let Some(ch) = damped(&l.a, 0.0).cholesky() {
                    let mut x = DMatrix::<f64>::zeros(NZ, k);
                    for j in 0..k {
                        let col = Z::from_iterator(w.column(j).iter().copied());
                        x.set_column(j, &ch.solve(&col));
                    }
                    s -= w.transpose() * x;
                    g -= w.transpose() * ch.solve(&l.gz);
                }
            }
            let inv = s.clone().try_inverse();
            let (delta, reduction, std) = match inv {
                Some(inv) => {
                    let delta = -(&inv * &g);
                    let red = g.dot(&(&inv * &g));
                    let dof = (m as f64 - (NZ * self.windows.len() + k) as f64).max(1.0);
                    let s2 = (rss - red).max(0.0) / dof;
                    let std = (0..k).map(|i| (inv[(i, i)].max(0.0) * s2).sqrt()).collect();
                    (delta, red, std)
                }
                None => (DVector::zeros(k), 0.0, vec![f64::INFINITY; k]),
            };
            let reduction = if reduction.is_finite() {
                reduction.max(0.0)
            } else {
                0.0
            };
            let mut theta: Vec<f64> = idx
                .iter()
                .zip(delta.iter())
                .map(|(&i, d)| theta0[i] + d)
                .collect();
            e.project(&mut theta, self.params);
            out.push(Screened {
                effect: e,
                theta,
                std,
                reduction,
            });
        }
        Some(out)
    }

    /// Unweighted residuals (prediction − reading) of a fitted model, per row and channel.
    pub fn residuals(&self, fit: &Fit) -> Residuals {
        let mut r = vec![[f64::NAN; 9]; self.log.len()];
        let pred = Predictor::<f64>::new(
            fit.candidate.extension(self.params, &fit.theta),
            self.params,
        );
        for (wi, &(start, len)) in self.windows.iter().enumerate() {
            if let Some(y) = predict_window(&pred, self.log, (start, len), fit.z0[wi]) {
                for (j, yk) in y.iter().enumerate() {
                    for c in Channel::ALL {
                        if let Some(meas) = self.log.value(start + j, c) {
                            r[start + j][c.index()] = residual(c, yk[c.index()], meas);
                        }
                    }
                }
            }
        }
        Residuals { r }
    }
}

fn fmt_theta(theta: &[f64]) -> String {
    theta
        .iter()
        .map(|t| format!("{t:.5e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The fit stops when a Gauss–Newton step promises less than this reduction of the
/// weighted residual sum of squares (one parameter must pay `ln m ≈ 10` in the BIC).
pub const CONVERGED_REDUCTION: f64 = 0.05;

/// `RSS(0) − RSS(δ)` of the Gauss–Newton model for the step `δ = (Δz, Δϑ)`.
fn predicted_reduction(lins: &[WindowLin], dz: &[Z], dp: &DVector<f64>) -> f64 {
    let mut red = 0.0;
    for (l, d) in lins.iter().zip(dz) {
        let mut quad = (d.transpose() * l.a * d)[0];
        let mut lin = l.gz.dot(d);
        if !dp.is_empty() {
            quad += 2.0 * (d.transpose() * &l.w * dp)[0] + (dp.transpose() * &l.v * dp)[0];
            lin += l.gp.dot(dp);
        }
        red -= 2.0 * lin + quad;
    }
    red
}

/// What one linearisation at the nominal model predicts for an effect.
#[derive(Clone, Debug)]
pub struct Screened {
    pub effect: Effect,
    /// Parameters after one Gauss–Newton step from the nominal values.
    pub theta: Vec<f64>,
    pub std: Vec<f64>,
    /// Predicted reduction of the weighted residual sum of squares.
    pub reduction: f64,
}

/// Parameters of the whole catalogue (the screening linearisation carries them all).
pub const SCREEN_PARAMS: usize = 12;

/// Damped window block `A + λ diag(A) + ridge`.
fn damped(a: &SMatrix<f64, NZ, NZ>, lambda: f64) -> SMatrix<f64, NZ, NZ> {
    let mut d = *a;
    let top = a.diagonal().max().max(1e-300);
    for i in 0..NZ {
        d[(i, i)] += lambda * a[(i, i)] + 1e-10 * top;
    }
    d
}

/// Schur complement `Σ V − Σ Wᵀ A⁻¹ W` with damping `λ` on the window blocks.
/// Standard deviations of the parameters at a linearisation, the larger per parameter of
/// - the classical `s² S⁻¹` (`S` the Schur complement of the Gauss–Newton matrix onto the
///   parameters, `s²` the residual variance per degree of freedom): right when the
///   weighted residuals are white with a common variance;
/// - the cluster-robust sandwich `S⁻¹ (G/(G−1) Σ_w g_w g_wᵀ) S⁻¹` over the `G` windows,
///   `g_w = gp_w − W_wᵀ A_w⁻¹ gz_w` the window's score with its own state eliminated: the
///   windows are independent, but within a window the residuals are not white (encoder
///   quantisation, and the prediction model's own approximations, which shift each
///   window's preferred parameters a little). Without such correlation both agree.
fn parameter_std(lins: &[WindowLin], np: usize) -> Vec<f64> {
    let s = schur(lins, np, 0.0);
    let Some(inv) = s.try_inverse() else {
        return vec![f64::INFINITY; np];
    };
    let g = lins.len() as f64;
    let rss: f64 = lins.iter().map(|l| l.rss).sum();
    let m: usize = lins.iter().map(|l| l.m).sum();
    let dof = (m as f64 - (NZ * lins.len() + np) as f64).max(1.0);
    let s2 = rss / dof;
    let mut b = DMatrix::<f64>::zeros(np, np);
    for l in lins {
        let mut gw = l.gp.clone();
        if let Some(ch) = damped(&l.a, 0.0).cholesky() {
            gw -= l.w.transpose() * ch.solve(&l.gz);
        }
        b += &gw * gw.transpose();
    }
    let robust = &inv * b * &inv * (g / (g - 1.0).max(1.0));
    (0..np)
        .map(|i| {
            (inv[(i, i)].max(0.0) * s2)
                .max(robust[(i, i)].max(0.0))
                .sqrt()
        })
        .collect()
}

fn schur(lins: &[WindowLin], np: usize, lambda: f64) -> DMatrix<f64> {
    let mut s = DMatrix::<f64>::zeros(np, np);
    for l in lins {
        s += &l.v;
        if np > 0 {
            let ad = damped(&l.a, lambda);
            if let Some(ch) = ad.cholesky() {
                let mut x = DMatrix::<f64>::zeros(NZ, np);
                for j in 0..np {
                    let col = Z::from_iterator(l.w.column(j).iter().copied());
                    x.set_column(j, &ch.solve(&col));
                }
                s -= l.w.transpose() * x;
            }
        }
    }
    s
}

/// One damped Gauss–Newton step: `(Δz per window, Δϑ)`.
fn step(
    lins: &[WindowLin],
    np: usize,
    lambda: f64,
    scale: &DVector<f64>,
) -> (Vec<Z>, DVector<f64>) {
    let mut s = DMatrix::<f64>::zeros(np, np);
    let mut rhs = DVector::<f64>::zeros(np);
    let chols: Vec<_> = lins
        .iter()
        .map(|l| damped(&l.a, lambda).cholesky())
        .collect();
    for (l, ch) in lins.iter().zip(&chols) {
        s += &l.v;
        rhs -= &l.gp;
        if let Some(ch) = ch {
            if np > 0 {
                let mut x = DMatrix::<f64>::zeros(NZ, np);
                for j in 0..np {
                    let col = Z::from_iterator(l.w.column(j).iter().copied());
                    x.set_column(j, &ch.solve(&col));
                }
                s -= l.w.transpose() * &x;
                let agz = ch.solve(&l.gz);
                rhs += l.w.transpose() * agz;
            }
        }
    }
    // Marquardt damping on the parameters, in their own scale.
    for i in 0..np {
        let d = s[(i, i)].max(1e-12 / (scale[i] * scale[i]));
        s[(i, i)] += lambda * d;
    }
    let dp = if np > 0 {
        s.clone()
            .cholesky()
            .map(|c| c.solve(&rhs))
            .unwrap_or_else(|| DVector::zeros(np))
    } else {
        DVector::zeros(0)
    };
    let dz = lins
        .iter()
        .zip(&chols)
        .map(|(l, ch)| match ch {
            Some(ch) => {
                let mut g = l.gz;
                if np > 0 {
                    g += &l.w * &dp;
                }
                -ch.solve(&g)
            }
            None => Z::zeros(),
        })
        .collect();
    (dz, dp)
}
