//! IPOPT's filter: when a trial point of the line search is accepted (Wächter & Biegler,
//! "On the implementation of an interior-point filter line-search algorithm", Math.
//! Program. 106, 2006, §2.3), with IPOPT's constants under their names in that paper.
//!
//! A trial point is measured by its constraint violation `θ` and its barrier function `φ`.
//! It is acceptable if the filter (pairs `(θ, φ)` that earlier steps ruled out) does not
//! dominate it and it improves on the current point: by the Armijo condition on `φ` where
//! the step is a descent step for `φ` and `θ` is small (an "f-type" step, which leaves the
//! filter as it is), otherwise by a fraction of `θ` in either `θ` or `φ` (which adds the
//! current point to the filter).

use super::iterate::Measures;

/// `γ_θ`: the fraction of `θ` a step must remove (sufficient decrease in `θ`).
pub(super) const GAMMA_THETA: f64 = 1e-5;
/// `γ_φ`: the decrease of `φ`, in units of `θ`, that also counts as progress.
pub(super) const GAMMA_PHI: f64 = 1e-5;
/// `η_φ`: the Armijo constant of an f-type step.
pub(super) const ETA_PHI: f64 = 1e-4;
/// `s_θ`, `s_φ`, `δ`: the switching condition `α (−∇φᵀd)^{s_φ} > δ θ^{s_θ}` that decides
/// whether a step is judged by `φ` alone.
pub(super) const S_THETA: f64 = 1.1;
pub(super) const S_PHI: f64 = 2.3;
pub(super) const DELTA: f64 = 1.0;
/// `γ_α`: the safety factor of the smallest step length, below which the line search
/// gives up (IPOPT's `alpha_min_frac`).
pub(super) const ALPHA_MIN_FRAC: f64 = 0.05;
/// `θ_max = 10⁴ max(1, θ₀)`: no trial point beyond it is acceptable; `θ_min = 10⁻⁴ max(1, θ₀)`:
/// below it, descent steps are judged by `φ`.
const THETA_MAX_FACTOR: f64 = 1e4;
const THETA_MIN_FACTOR: f64 = 1e-4;
/// IPOPT's `Compare_le`: a decrease test passes within this many machine epsilons of its
/// reference value, so that a step whose predicted decrease is below the round-off of `φ`
/// (near the solution, `θ ≈ 1e-13` against `φ ≈ 5·10³`) is not rejected by noise.
const COMPARE_ULPS: f64 = 10.0;

/// The outcome of [`Filter::test`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Acceptance {
    Rejected,
    /// Accepted; `augment`: the step was judged by `θ` (an h-type step), so the current
    /// point enters the filter.
    Accepted {
        augment: bool,
    },
}

/// The filter and its bounds on `θ`.
#[derive(Clone, Debug)]
pub(super) struct Filter {
    entries: Vec<(f64, f64)>,
    theta_max: f64,
    theta_min: f64,
}

impl Filter {
    /// An empty filter for a solve that starts at violation `theta0`.
    pub(super) fn new(theta0: f64) -> Self {
        Filter {
            entries: Vec::new(),
            theta_max: THETA_MAX_FACTOR * theta0.max(1.0),
            theta_min: THETA_MIN_FACTOR * theta0.max(1.0),
        }
    }

    pub(super) fn clear(&mut self) {
        self.entries.clear();
    }

    /// Rule out the region the current point dominates (with its margins).
    pub(super) fn augment(&mut self, current: &Measures) {
        self.entries.push((
            (1.0 - GAMMA_THETA) * current.theta,
            current.barrier - GAMMA_PHI * current.theta,
        ));
    }

    /// The smallest step length the line search tries from `current` along a direction
    /// with barrier slope `dphi`.
    pub(super) fn alpha_min(&self, current: &Measures, dphi: f64) -> f64 {
        if dphi < 0.0 {
            ALPHA_MIN_FRAC
                * GAMMA_THETA
                    .min(GAMMA_PHI * current.theta / (-dphi))
                    .min(DELTA * current.theta.powf(S_THETA) / (-dphi).powf(S_PHI))
        } else {
            ALPHA_MIN_FRAC * GAMMA_THETA
        }
    }

    /// Whether `trial`, reached by the step length `alpha` from `current` along a direction
    /// of barrier slope `dphi`, is acceptable.
    pub(super) fn test(
        &self,
        current: &Measures,
        dphi: f64,
        trial: &Measures,
        alpha: f64,
    ) -> Acceptance {
        let finite = trial.theta.is_finite() && trial.barrier.is_finite();
        if !finite || trial.theta > self.theta_max {
            return Acceptance::Rejected;
        }
        let dominated = self
            .entries
            .iter()
            .any(|&(ft, fp)| trial.theta >= ft && trial.barrier >= fp);
        if dominated {
            return Acceptance::Rejected;
        }
        let le =
            |lhs: f64, rhs: f64, base: f64| lhs - rhs <= COMPARE_ULPS * f64::EPSILON * base.abs();
        let switching =
            dphi < 0.0 && alpha * (-dphi).powf(S_PHI) > DELTA * current.theta.powf(S_THETA);
        let (ok, augment) = if current.theta <= self.theta_min && switching {
            let armijo = current.barrier + ETA_PHI * alpha * dphi;
            (le(trial.barrier, armijo, current.barrier), false)
        } else {
            let theta_ok = le(
                trial.theta,
                (1.0 - GAMMA_THETA) * current.theta,
                current.theta,
            );
            let phi_ok = le(
                trial.barrier,
                current.barrier - GAMMA_PHI * current.theta,
                current.barrier,
            );
            (theta_ok || phi_ok, true)
        };
        if ok {
            Acceptance::Accepted { augment }
        } else {
            Acceptance::Rejected
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(theta: f64, barrier: f64) -> Measures {
        Measures {
            theta,
            theta_max: theta,
            objective: barrier,
            barrier,
        }
    }

    /// A point the filter holds rules out every trial that is no better in both measures.
    #[test]
    fn a_filter_entry_dominates_worse_points() {
        let mut f = Filter::new(1.0);
        let current = at(0.5, 10.0);
        f.augment(&at(0.2, 5.0));
        // Better than `current` in θ, but dominated by the entry.
        assert_eq!(
            f.test(&current, 1.0, &at(0.3, 6.0), 1.0),
            Acceptance::Rejected
        );
        // Better than the entry in θ: acceptable, by θ.
        assert_eq!(
            f.test(&current, 1.0, &at(0.1, 6.0), 1.0),
            Acceptance::Accepted { augment: true }
        );
    }

    /// Near feasibility a descent step is judged by the Armijo condition on φ and leaves
    /// the filter unchanged; a step that does not decrease φ enough is rejected even if
    /// it reduces θ.
    #[test]
    fn small_violation_descent_steps_use_armijo() {
        let f = Filter::new(1.0);
        let current = at(1e-8, 100.0);
        let dphi = -1.0;
        let armijo = 100.0 + ETA_PHI * dphi;
        assert_eq!(
            f.test(&current, dphi, &at(1e-8, armijo - 1e-9), 1.0),
            Acceptance::Accepted { augment: false }
        );
        assert_eq!(
            f.test(&current, dphi, &at(0.0, armijo + 1e-6), 1.0),
            Acceptance::Rejected
        );
    }

    /// Beyond θ_max nothing is acceptable, however low φ.
    #[test]
    fn theta_max_bounds_every_trial() {
        let f = Filter::new(2.0);
        let current = at(1.0, 0.0);
        assert_eq!(
            f.test(&current, 1.0, &at(2.1e4, -1e9), 1.0),
            Acceptance::Rejected
        );
        assert_eq!(
            f.test(&current, 1.0, &at(f64::NAN, 0.0), 1.0),
            Acceptance::Rejected
        );
    }
}
