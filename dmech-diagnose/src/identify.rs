//! Which combinations of the system's own parameters a log determines. At a fitted model,
//! the Fisher information of the parameters' logarithms (the Schur complement of the
//! Gauss–Newton matrix with the window states eliminated, divided by the residual variance
//! per degree of freedom) is decomposed, `F = V Λ Vᵀ`. Along an eigenvector `v` the log
//! determines `Σ_j v_j ln θ_j`, the logarithm of the product `Π θ_j^{v_j}`, to a relative
//! standard deviation `1/√λ`. A combination is *determined* when that is at most
//! [`DETERMINED`]; the others are left at the parameter file's values.
//!
//! A combination is named by its exponents, normalised so that the largest is one and
//! rounded; exponents below a tenth of the largest are left out of the name (not of the
//! direction), e.g. `m_b^1.00·l^0.98·I_byy^-0.21`.

use super::fit::Fitter;
use super::model::Direction;
use super::normal_equations::schur;
use super::Plant;
use nalgebra::{DMatrix, SymmetricEigen};

/// A combination is determined when the log fixes it to this relative standard deviation.
pub const DETERMINED: f64 = 0.1;

/// One eigen-direction of the information.
#[derive(Clone, Debug)]
pub struct Combination {
    /// Unit vector over the calibrated parameters, in `ln θ`.
    pub weights: Vec<f64>,
    /// Relative standard deviation of the product `Π θ_j^{w_j}` (`1/√λ`).
    pub std: f64,
    /// `std` at most [`DETERMINED`]: the calibration frees this combination.
    pub determined: bool,
    /// The product's exponents in words, e.g. `m_b^1.00·l^0.98` ([`combination_name`]).
    pub name: String,
}

/// The identifiability of a set of parameters at a fitted model.
#[derive(Clone, Debug)]
pub struct Identifiability {
    /// Indices of the parameters (into the catalogue).
    pub params: Vec<usize>,
    /// Best determined first.
    pub combinations: Vec<Combination>,
}

impl Identifiability {
    /// The determined combinations as free directions of a fit (in `ln θ`).
    pub fn directions(&self) -> Vec<Direction> {
        self.combinations
            .iter()
            .filter(|c| c.determined)
            .map(|c| {
                self.params
                    .iter()
                    .zip(&c.weights)
                    .filter(|(_, w)| w.abs() > 1e-12)
                    .map(|(&p, &w)| (p, w))
                    .collect()
            })
            .collect()
    }
}

/// Name a combination by its exponents (largest one; below a tenth left out).
pub fn combination_name(names: &[&str], weights: &[f64]) -> String {
    let top = weights.iter().fold(0.0f64, |m, w| m.max(w.abs()));
    if top == 0.0 {
        return "1".into();
    }
    // The sign of an eigenvector is arbitrary: make the largest exponent positive.
    let sign = weights
        .iter()
        .find(|w| w.abs() == top)
        .map_or(1.0, |w| w.signum());
    let parts: Vec<String> = names
        .iter()
        .zip(weights)
        .filter(|(_, w)| w.abs() >= 0.1 * top)
        .map(|(n, w)| format!("{n}^{:.2}", sign * w / top))
        .collect();
    parts.join("·")
}

/// The identifiability of `params` (catalogue indices, fitted in `ln θ`) at the model
/// `theta` with window states `z0`; `None` if the model cannot be linearised there.
pub fn identify<P: Plant>(
    fitter: &Fitter<P>,
    params: &[usize],
    theta: &[f64],
    z0: &[Vec<f64>],
) -> Option<Identifiability> {
    let cat = fitter.catalogue();
    let dirs: Vec<Direction> = params.iter().map(|&p| vec![(p, 1.0)]).collect();
    let lins = fitter.linearise(theta, &dirs, z0)?;
    let k = params.len();
    let info = schur(&lins, k);
    let rss: f64 = lins.iter().map(|l| l.rss).sum();
    let m: usize = lins.iter().map(|l| l.m).sum();
    let nz = fitter.plant.state_dim();
    let dof = (m as f64 - (nz * lins.len() + k) as f64).max(1.0);
    let info: DMatrix<f64> = (&info + info.transpose()) * (0.5 * dof / rss.max(1e-300));
    let eig = SymmetricEigen::new(info);
    let names: Vec<&str> = params
        .iter()
        .map(|&p| cat.params[p].name.as_str())
        .collect();
    let mut combinations: Vec<Combination> = (0..k)
        .map(|i| {
            let lambda = eig.eigenvalues[i];
            let weights: Vec<f64> = eig.eigenvectors.column(i).iter().copied().collect();
            let std = if lambda > 0.0 {
                lambda.sqrt().recip()
            } else {
                f64::INFINITY
            };
            Combination {
                name: combination_name(&names, &weights),
                weights,
                std,
                determined: std <= DETERMINED,
            }
        })
        .collect();
    combinations.sort_by(|a, b| a.std.total_cmp(&b.std));
    Some(Identifiability {
        params: params.to_vec(),
        combinations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_normalise_to_the_largest_exponent_and_drop_small_ones() {
        let n = combination_name(&["m_b", "l", "r"], &[-0.7, -0.69, 0.05]);
        assert_eq!(n, "m_b^1.00·l^0.99");
        let n = combination_name(&["a", "b"], &[0.6, -0.8]);
        assert_eq!(n, "a^-0.75·b^1.00");
    }
}
