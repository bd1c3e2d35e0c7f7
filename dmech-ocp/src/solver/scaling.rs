//! Objective scaling: the solver's absolute constants (`μ₀ = 0.1`, the tolerances, the
//! dual regularisation, the inertia-correction and SR1 thresholds) are IPOPT's, made for
//! objectives whose terms are of order one. A barrier term `μ log t` per inequality and
//! stage competes with each stage's cost: where the cost per stage is far below one, the
//! barrier dominates the early iterations, and the iterates reach a region the monotone
//! barrier rule does not leave (`docs/solver.md`, "Objective scaling": a steered
//! vehicle whose cost per stage is 6e-4 stalls at 500 iterations, and solves in 23 with
//! its cost scaled by 1/s ≈ 1.2e4).
//!
//! The rule: at the start, the mean stage cost `s = Σ_k |ℓ_k| / N`; the solver works on
//! `c ℓ` with `c = 1/s` when `0 < s < 1`, and `c = 1` when `s ≥ 1` (an objective of order
//! one or more is left alone). A start of zero cost (at rest, inputs zero) gives no scale:
//! then `s` is taken after one iteration of the unscaled problem (a probe from the same
//! start, whose step gives the inputs their first magnitude). The optimum is the same
//! point; the multipliers scale by `c`, and the solver reports them and the objective in
//! the problem's own units.

use super::Iterate;
use crate::nlp::HessianBlocks;
use crate::nlp::StageProblem;
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// `p` with its cost multiplied by `c`; everything else delegated (including the exact
/// Jacobian routes a problem overrides).
pub(super) struct ScaledCost<'a, P> {
    pub(super) p: &'a P,
    pub(super) c: f64,
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageProblem<NX, NW, NE, NF, NC> for ScaledCost<'_, P>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    crate::nlp::forward_stage_problem!(p: horizon, initial_state, dynamics, equality,
        constraints, bounds, state_equalities, terminal_equalities, affine_in_state,
        constant_cost_curvature,
        dynamics_jacobian, equality_jacobian, equality_partials, constraint_curvature);
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        self.p.cost(k, x, w) * T::from(self.c)
    }
    fn terminal_cost<T: Real>(&self, x: &SVector<T, NX>) -> T {
        self.p.terminal_cost(x) * T::from(self.c)
    }
    fn globals(&self) -> Option<crate::nlp::Globals> {
        self.p.globals().map(|mut g| {
            g.cost.iter_mut().for_each(|v| *v *= self.c);
            g
        })
    }
    /// The problem's own curvature with the cost's scale passed down (its override, if it
    /// has one, serves the scaled problem).
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        cost_scale: f64,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NW> {
        self.p.cost_curvature(k, x, w, cost_scale * self.c, zeta)
    }
}

/// The objective scale `c = max(1, 1/s)` of `p` at the point `it` (module doc), or `None`
/// if its mean stage cost `s` is zero (or not finite): no scale to read there.
pub(super) fn objective_scale<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &dyn super::oracle::StageOracle<NX, NW, NE, NF, NC>,
    it: &Iterate<NX, NW, NC>,
) -> Option<f64> {
    let n = it.w.len();
    let total: f64 = (0..n).map(|k| p.cost(k, &it.x[k], &it.w[k]).abs()).sum();
    let s = total / n.max(1) as f64;
    (s > 0.0 && s.is_finite()).then(|| (1.0 / s).max(1.0))
}

/// IPOPT's `nlp_scaling_max_gradient`: the largest objective gradient entry the solver
/// works with.
pub(super) const MAX_GRADIENT: f64 = 100.0;

/// The scale `c` lowered so that no coefficient of the globals' linear cost exceeds
/// [`MAX_GRADIENT`] after scaling (IPOPT's gradient-based rule, applied where the gradient
/// is known at no cost: a global's cost coefficient is its gradient everywhere). Why: a
/// free total time priced at 1e3 per second or more put entries of 1e4–1e13 in the
/// gradient of a few globals, and the solver crawled at steps of 1e-13 and ended at the
/// iteration limit or reported a feasible problem infeasible. `true` with the result when
/// the cap applied.
pub(super) fn capped_by_global_cost(c: f64, global_cost: &[f64]) -> (f64, bool) {
    let largest = global_cost.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if largest * c > MAX_GRADIENT {
        (MAX_GRADIENT / largest, true)
    } else {
        (c, false)
    }
}

impl<const NX: usize, const NW: usize, const NC: usize> Iterate<NX, NW, NC> {
    /// The same primal point with the equality multipliers (`λ`, `y`) times `c`, and the
    /// bound multipliers `z` times `c` when `scale_bounds`.
    pub(super) fn with_duals_scaled(mut self, c: f64, scale_bounds: bool) -> Self {
        self.lambda.iter_mut().for_each(|l| *l *= c);
        self.y.iter_mut().for_each(|y| *y *= c);
        self.globals.y.iter_mut().for_each(|y| *y *= c);
        if scale_bounds {
            self.z_lo.iter_mut().for_each(|z| *z *= c);
            self.z_hi.iter_mut().for_each(|z| *z *= c);
            let g = &mut self.globals;
            g.z_lo
                .iter_mut()
                .chain(g.z_hi.iter_mut())
                .for_each(|z| *z *= c);
        }
        self
    }
}
