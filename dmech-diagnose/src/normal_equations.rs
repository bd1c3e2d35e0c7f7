//! The windows' Gauss–Newton normal equations ([`super::fit`]): each window contributes a
//! block for its own initial state coupled to the free coordinates only; a step eliminates
//! the windows (the Schur complement onto the free coordinates), solves for them and
//! back-substitutes; the covariance of the free coordinates and the parameters'
//! standard deviations come from the same blocks.

use super::model::{Catalogue, Direction};
use nalgebra::{DMatrix, DVector};

/// A window's Gauss–Newton blocks: `A = J_zᵀJ_z`, `W = J_zᵀJ_β`, `V = J_βᵀJ_β`, the
/// gradients `J_zᵀr`, `J_βᵀr`, and the window's weighted RSS and count.
#[derive(Clone)]
pub(crate) struct WindowLin {
    pub a: DMatrix<f64>,
    pub w: DMatrix<f64>,
    pub v: DMatrix<f64>,
    pub gz: DVector<f64>,
    pub gp: DVector<f64>,
    pub rss: f64,
    pub m: usize,
}

/// A direction's typical size in internal coordinates: its parameters' scales, combined.
pub(super) fn direction_scale(cat: &Catalogue, d: &Direction) -> f64 {
    let s: f64 = d
        .iter()
        .map(|&(j, b)| (cat.params[j].scale / b.abs().max(1e-300)).powi(-2))
        .sum();
    s.powf(-0.5)
}

/// Standard deviation of every parameter (0 where not free) from the covariance of the
/// free coordinates, with the systematic floor in quadrature: `Cov x = B Cov β Bᵀ`, and
/// `σ_θ = θ σ_x` for a parameter fitted in `ln θ`; a sampled time threshold has the floor
/// `h/√12` of the sample step `h` as well.
pub(super) fn param_std(
    cat: &Catalogue,
    dirs: &[Direction],
    theta: &[f64],
    cov: &DMatrix<f64>,
    h: f64,
) -> Vec<f64> {
    let mut var = vec![0.0; cat.params.len()];
    let mut free = vec![false; cat.params.len()];
    for (p, dp) in dirs.iter().enumerate() {
        for (q, dq) in dirs.iter().enumerate() {
            for &(i, bi) in dp {
                for &(j, bj) in dq {
                    if i == j {
                        var[i] += bi * bj * cov[(p, q)];
                    }
                }
            }
        }
        for &(i, _) in dp {
            free[i] = true;
        }
    }
    cat.params
        .iter()
        .enumerate()
        .map(|(i, s)| {
            if !free[i] {
                return 0.0;
            }
            let sx = var[i].max(0.0).sqrt();
            let st = if s.log { theta[i] * sx } else { sx };
            let quantum = if s.sampled_time {
                h / 12f64.sqrt()
            } else {
                0.0
            };
            if st.is_finite() {
                st.hypot(s.systematic).hypot(quantum)
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// `RSS(0) − RSS(δ)` of the Gauss–Newton model for the step `δ = (Δz, Δβ)`.
pub(super) fn predicted_reduction(
    lins: &[WindowLin],
    dz: &[DVector<f64>],
    dp: &DVector<f64>,
) -> f64 {
    let mut red = 0.0;
    for (l, d) in lins.iter().zip(dz) {
        let mut quad = d.dot(&(&l.a * d));
        let mut lin = l.gz.dot(d);
        if !dp.is_empty() {
            quad += 2.0 * d.dot(&(&l.w * dp)) + dp.dot(&(&l.v * dp));
            lin += l.gp.dot(dp);
        }
        red -= 2.0 * lin + quad;
    }
    red
}

/// Damped window block `A + λ diag(A) + ridge` (the ridge keeps directions that no reading
/// sees, such as an unmeasured position, from making it singular).
pub(crate) fn damped(a: &DMatrix<f64>, lambda: f64) -> DMatrix<f64> {
    let mut d = a.clone();
    let top = a.diagonal().max().max(1e-300);
    for i in 0..a.nrows() {
        d[(i, i)] += lambda * a[(i, i)] + 1e-10 * top;
    }
    d
}

/// Covariance of the free coordinates at a linearisation, per entry the larger (on the
/// diagonal) of
/// - the classical `s² S⁻¹` (`S` the Schur complement of the Gauss–Newton matrix onto the
///   free coordinates, `s²` the residual variance per degree of freedom): right when the
///   weighted residuals are white with a common variance;
/// - the cluster-robust sandwich `S⁻¹ (G/(G−1) Σ_w g_w g_wᵀ) S⁻¹` over the `G` windows,
///   `g_w = gp_w − W_wᵀ A_w⁻¹ gz_w` the window's score with its own state eliminated: the
///   windows are independent, but within a window the residuals are not white (sensor
///   quantisation, and the prediction model's own approximations, which shift each
///   window's preferred parameters a little). Without such correlation both agree.
///
/// The matrix returned is the one of the two whose trace (in units of each classical
/// variance) is larger, so that it stays a covariance. Beside it, per free coordinate, the
/// design effect of the window clustering: the robust variance over the classical one, at
/// least 1. Within-window correlation of the residuals inflates a likelihood-ratio
/// statistic by about this factor (Rao & Scott's first-order correction divides by their
/// mean); with white residuals it is 1. Both infinite where the information is singular.
pub(crate) fn parameter_cov(lins: &[WindowLin], k: usize) -> (DMatrix<f64>, Vec<f64>) {
    if k == 0 {
        return (DMatrix::zeros(0, 0), Vec::new());
    }
    let s = schur(lins, k);
    let Some(inv) = s.try_inverse() else {
        return (
            DMatrix::from_element(k, k, f64::INFINITY),
            vec![f64::INFINITY; k],
        );
    };
    let g = lins.len() as f64;
    let rss: f64 = lins.iter().map(|l| l.rss).sum();
    let m: usize = lins.iter().map(|l| l.m).sum();
    let nz = lins.first().map_or(0, |l| l.a.nrows());
    let dof = (m as f64 - (nz * lins.len() + k) as f64).max(1.0);
    let classical = &inv * (rss / dof);
    let mut b = DMatrix::<f64>::zeros(k, k);
    for l in lins {
        let mut gw = l.gp.clone();
        if let Some(ch) = damped(&l.a, 0.0).cholesky() {
            gw -= l.w.transpose() * ch.solve(&l.gz);
        }
        b += &gw * gw.transpose();
    }
    let robust = &inv * b * &inv * (g / (g - 1.0).max(1.0));
    let design = (0..k)
        .map(|i| {
            let c = classical[(i, i)];
            if c > 0.0 && robust[(i, i)].is_finite() {
                (robust[(i, i)] / c).max(1.0)
            } else {
                f64::INFINITY
            }
        })
        .collect();
    (larger_of(&classical, &robust), design)
}

/// Per coordinate the larger variance of the two covariances; correlations from the matrix
/// that gives it.
fn larger_of(classical: &DMatrix<f64>, robust: &DMatrix<f64>) -> DMatrix<f64> {
    let k = classical.nrows();
    let mut out = classical.clone();
    for i in 0..k {
        for j in 0..k {
            let (ci, cj) = (classical[(i, i)].max(0.0), classical[(j, j)].max(0.0));
            let (ri, rj) = (robust[(i, i)].max(0.0), robust[(j, j)].max(0.0));
            let (si, sj) = (ci.max(ri).sqrt(), cj.max(rj).sqrt());
            let corr = if ri > ci {
                robust[(i, j)] / (ri * rj).sqrt().max(1e-300)
            } else {
                classical[(i, j)] / (ci * cj).sqrt().max(1e-300)
            };
            out[(i, j)] = if i == j { si * si } else { corr * si * sj };
        }
    }
    out
}

/// Schur complement `Σ V − Σ Wᵀ A⁻¹ W` of the Gauss–Newton matrix onto the free
/// coordinates (the Fisher information of `β` under unit-variance weighted residuals).
pub(crate) fn schur(lins: &[WindowLin], k: usize) -> DMatrix<f64> {
    let mut s = DMatrix::<f64>::zeros(k, k);
    for l in lins {
        s += &l.v;
        if k > 0 {
            if let Some(ch) = damped(&l.a, 0.0).cholesky() {
                let x = ch.solve(&l.w);
                s -= l.w.transpose() * x;
            }
        }
    }
    s
}

/// One damped Gauss–Newton step: `(Δz per window, Δβ)`.
pub(super) fn step(
    lins: &[WindowLin],
    k: usize,
    lambda: f64,
    scale: &DVector<f64>,
) -> (Vec<DVector<f64>>, DVector<f64>) {
    let mut s = DMatrix::<f64>::zeros(k, k);
    let mut rhs = DVector::<f64>::zeros(k);
    let chols: Vec<_> = lins
        .iter()
        .map(|l| damped(&l.a, lambda).cholesky())
        .collect();
    for (l, ch) in lins.iter().zip(&chols) {
        s += &l.v;
        rhs -= &l.gp;
        if let Some(ch) = ch {
            if k > 0 {
                let x = ch.solve(&l.w);
                s -= l.w.transpose() * &x;
                rhs += l.w.transpose() * ch.solve(&l.gz);
            }
        }
    }
    // Marquardt damping on the free coordinates, in their own scale.
    for i in 0..k {
        let d = s[(i, i)].max(1e-12 / (scale[i] * scale[i]));
        s[(i, i)] += lambda * d;
    }
    let dp = if k > 0 {
        s.clone()
            .cholesky()
            .map(|c| c.solve(&rhs))
            .unwrap_or_else(|| DVector::zeros(k))
    } else {
        DVector::zeros(0)
    };
    let dz = lins
        .iter()
        .zip(&chols)
        .map(|(l, ch)| match ch {
            Some(ch) => {
                let mut g = l.gz.clone();
                if k > 0 {
                    g += &l.w * &dp;
                }
                -ch.solve(&g)
            }
            None => DVector::zeros(l.a.nrows()),
        })
        .collect();
    (dz, dp)
}
