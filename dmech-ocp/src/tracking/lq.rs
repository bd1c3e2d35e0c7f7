//! The finite-horizon LQ tracker along a linearised plan: the Riccati recursion's gains
//! `K_k` and its cost-to-go `P_k` (the terminal cost of [`super::Mpc`]'s horizons).

use super::{LinearisedPlan, TrackingError};
use dmech_lie::linalg::Lu;
use nalgebra::SMatrix;

/// The tracking cost `Σ_{k<N} (δx_kᵀ Q δx_k + δu_kᵀ R δu_k) + δx_Nᵀ Q_N δx_N` on the
/// deviations from the plan.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackingWeights<const NX: usize, const NF: usize> {
    /// `Q`, every stage's state weight.
    pub state: SMatrix<f64, NX, NX>,
    /// `Q_N`, the last stage's.
    pub terminal: SMatrix<f64, NX, NX>,
    /// `R`, the input weight.
    pub input: SMatrix<f64, NF, NF>,
}

/// The LQ design along a plan: gains `K_k` (`k < N`) and cost-to-go `P_k` (`k ≤ N`,
/// `P_N = Q_N`): the optimal cost from stage `k` of the unconstrained problem is
/// `δx_kᵀ P_k δx_k`.
#[derive(Clone, Debug)]
pub struct LqDesign<const NX: usize, const NF: usize> {
    /// `K_k`: the law `δu_k = −K_k δx_k`.
    pub gains: Vec<SMatrix<f64, NF, NX>>,
    /// `P_k`.
    pub cost_to_go: Vec<SMatrix<f64, NX, NX>>,
}

/// The Riccati recursion along a linearised plan (module documentation of
/// [`crate::tracking`]), with its cost-to-go.
pub fn lq_design<const NX: usize, const NF: usize>(
    plan: &LinearisedPlan<NX, NF>,
    weights: &TrackingWeights<NX, NF>,
) -> Result<LqDesign<NX, NF>, TrackingError> {
    let (q, r) = (&weights.state, &weights.input);
    let n = plan.a.len();
    let mut p = weights.terminal;
    let mut gains = vec![SMatrix::<f64, NF, NX>::zeros(); n];
    let mut cost_to_go = vec![p; n + 1];
    for k in (0..n).rev() {
        let (a, b) = (&plan.a[k], &plan.b[k]);
        let bp = b.transpose() * p;
        let lu = Lu::new(&(r + bp * b)).ok_or(TrackingError::SingularRiccati { stage: k })?;
        let kk = lu.solve_columns(&(bp * a));
        p = q + a.transpose() * p * (a - b * kk);
        // Symmetrise against round-off over a long horizon.
        p = (p + p.transpose()) * 0.5;
        gains[k] = kk;
        cost_to_go[k] = p;
    }
    Ok(LqDesign { gains, cost_to_go })
}

/// The finite-horizon LQ gains `K_k` along a linearised plan, state weight `q` at every
/// stage and `q_end` at the last, input weight `r` ([`lq_design`]'s gains).
pub fn lq_gains<const NX: usize, const NF: usize>(
    plan: &LinearisedPlan<NX, NF>,
    q: &SMatrix<f64, NX, NX>,
    q_end: &SMatrix<f64, NX, NX>,
    r: &SMatrix<f64, NF, NF>,
) -> Result<Vec<SMatrix<f64, NF, NX>>, TrackingError> {
    let weights = TrackingWeights {
        state: *q,
        terminal: *q_end,
        input: *r,
    };
    Ok(lq_design(plan, &weights)?.gains)
}
