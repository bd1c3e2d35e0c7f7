//! The iterate and the result of a solve, and the per-iteration working data: the
//! eliminated stage equality, the bounds, the Newton step, the residual measures.

use super::kkt::globals::{GlobalIterate, GlobalStep};
use super::{Status, Timings};
use nalgebra::{SMatrix, SVector};

/// The primal–dual iterate.
#[derive(Clone, Debug)]
pub struct Iterate<const NX: usize, const NW: usize, const NC: usize> {
    /// The states `x_0 … x_N`.
    pub x: Vec<SVector<f64, NX>>,
    /// The decisions `w_0 … w_{N−1}`.
    pub w: Vec<SVector<f64, NW>>,
    /// `lambda[k]`: multiplier of `x_{k+1} = f_k(x_k, w_k)`.
    pub lambda: Vec<SVector<f64, NX>>,
    /// The slacks `c_k − lo_k` of the lower bounds.
    pub t_lo: Vec<SVector<f64, NC>>,
    /// The slacks `hi_k − c_k` of the upper bounds.
    pub t_hi: Vec<SVector<f64, NC>>,
    /// The lower bounds' multipliers.
    pub z_lo: Vec<SVector<f64, NC>>,
    /// The upper bounds' multipliers.
    pub z_hi: Vec<SVector<f64, NC>>,
    /// The state equalities' multipliers, in the problem's order, then the terminal
    /// equalities' ([`crate::nlp::StageProblem::terminal_equalities`]).
    pub y: Vec<f64>,
    /// The global variables and their multipliers (empty without globals).
    pub globals: GlobalIterate,
}

/// The result of a solve.
#[derive(Clone, Debug)]
pub struct SolveResult<const NX: usize, const NW: usize, const NC: usize> {
    /// How the solve ended.
    pub status: Status,
    /// The last iterate (the optimum when solved).
    pub iterate: Iterate<NX, NW, NC>,
    /// Iterations taken, restoration's included.
    pub iterations: usize,
    /// The objective at the returned point, in the problem's units.
    pub objective: f64,
    /// Largest constraint violation (dynamics, stage equalities, inequalities, state
    /// equalities), recomputed at the returned point.
    pub max_violation: f64,
    /// `Σ zᵢ tᵢ` over every bound at the returned point: the barrier problem's duality gap,
    /// `m μ` on its central path. For a convex problem the objective lies at most this far
    /// above the optimum; near a local optimum that satisfies the second-order conditions,
    /// the same holds to first order. In the problem's units.
    pub duality_gap: f64,
    /// Where the time went.
    pub timings: Timings,
}

/// How a stage's decision step follows from the condensed one: `δw = w0 + wx δx + wu δu`.
#[derive(Clone, Debug)]
pub(super) struct Elimination<const NX: usize, const NW: usize, const NF: usize> {
    pub(super) w0: SVector<f64, NW>,
    pub(super) wx: SMatrix<f64, NW, NX>,
    pub(super) wu: SMatrix<f64, NW, NF>,
}

impl<const NX: usize, const NW: usize, const NF: usize> Elimination<NX, NW, NF> {
    pub(super) fn zeros() -> Self {
        Elimination {
            w0: SVector::zeros(),
            wx: SMatrix::zeros(),
            wu: SMatrix::zeros(),
        }
    }
}

#[derive(Clone)]
pub(super) struct Bounds<const NC: usize> {
    pub(super) lo: SVector<f64, NC>,
    pub(super) hi: SVector<f64, NC>,
    pub(super) has_lo: SVector<f64, NC>,
    pub(super) has_hi: SVector<f64, NC>,
}

/// The step of the primal–dual iterate.
pub(super) struct Step<const NX: usize, const NW: usize, const NC: usize> {
    pub(super) dx: Vec<SVector<f64, NX>>,
    pub(super) dw: Vec<SVector<f64, NW>>,
    pub(super) lambda: Vec<SVector<f64, NX>>,
    pub(super) dt_lo: Vec<SVector<f64, NC>>,
    pub(super) dt_hi: Vec<SVector<f64, NC>>,
    pub(super) dz_lo: Vec<SVector<f64, NC>>,
    pub(super) dz_hi: Vec<SVector<f64, NC>>,
    pub(super) y: Vec<f64>,
    pub(super) globals: GlobalStep,
}

/// Residual measures at an iterate.
#[derive(Clone, Copy, Debug)]
pub(super) struct Measures {
    pub(super) theta: f64,     // Σ |constraint residual| (filter)
    pub(super) theta_max: f64, // max |constraint residual|
    pub(super) objective: f64,
    pub(super) barrier: f64, // objective − μ Σ ln t
}
