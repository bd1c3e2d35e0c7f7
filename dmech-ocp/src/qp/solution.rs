//! What a QP solve returns: the solution, its status and figures, and the warm start made
//! from it (shifted by a stage for receding-horizon control).

use super::iterate::StageIterate;
use nalgebra::SVector;

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpStatus {
    /// The KKT conditions hold to the tolerance.
    Solved,
    /// The iteration limit came first; the iterate is the last one.
    MaxIterations,
    /// The hard rows cannot all hold: the multipliers are a Farkas certificate.
    PrimalInfeasible,
    /// The objective is unbounded below: the last step is a direction of descent along
    /// which every hard row stays satisfied.
    DualInfeasible,
    /// The Newton step failed (a stage's reduced Hessian not positive definite despite
    /// the regularisation, or a value not finite).
    NumericalError,
}

/// Figures of a solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QpInfo {
    /// Interior-point iterations (Newton factorisations).
    pub iterations: usize,
    /// `‖∇L‖∞` at the end.
    pub stationarity: f64,
    /// The largest violation of the dynamics and of the rows' slack equations.
    pub primal_residual: f64,
    /// The mean complementarity `μ`.
    pub complementarity: f64,
    /// The objective at the returned point (soft rows' prices included).
    pub objective: f64,
    /// Wall-clock time of the solve (s).
    pub solve_time: f64,
    /// Whether the solve started from a warm start.
    pub warm: bool,
}

/// A solution: states `x[0..=N]`, inputs `u[0..N]`, multipliers, and how it was found.
#[derive(Clone, Debug)]
pub struct QpSolution<const NX: usize, const NU: usize, const NC: usize> {
    /// How the solve ended.
    pub status: QpStatus,
    /// Its figures.
    pub info: QpInfo,
    /// The states, `x[0]` the given one.
    pub x: Vec<SVector<f64, NX>>,
    /// The inputs.
    pub u: Vec<SVector<f64, NU>>,
    /// The multipliers of the dynamics: `pi[k]` of `x_{k+1} = A_k x_k + B_k u_k + c_k`,
    /// the gradient of the optimal cost-to-go at `x_{k+1}`.
    pub pi: Vec<SVector<f64, NX>>,
    /// The rows' multipliers per stage `0 … N`, signed: `> 0` where the upper side
    /// holds the row, `< 0` where the lower side does.
    pub row_multipliers: Vec<SVector<f64, NC>>,
    /// The soft rows' violations per stage `0 … N`, `max(z − hi, lo − z, 0)` at the
    /// returned point (zero on hard rows).
    pub violations: Vec<SVector<f64, NC>>,
    pub(crate) iterate: Vec<StageIterate<NX, NU, NC>>,
}

/// A primal–dual start for [`crate::qp::QpSolver::solve_warm`]: the inputs, the
/// multipliers of dynamics and rows, the rows' slacks. The states are rolled out from
/// the new `x_0` with the new dynamics, so the start satisfies them exactly.
#[derive(Clone, Debug)]
pub struct WarmStart<const NX: usize, const NU: usize, const NC: usize> {
    pub(crate) iterate: Vec<StageIterate<NX, NU, NC>>,
}

impl<const NX: usize, const NU: usize, const NC: usize> QpSolution<NX, NU, NC> {
    /// The solution as a start for the same horizon.
    pub fn warm_start(&self) -> WarmStart<NX, NU, NC> {
        WarmStart {
            iterate: self.iterate.clone(),
        }
    }

    /// The solution as a start for the next sample of a receding horizon: stage `k + 1`
    /// becomes stage `k`, the last stage repeated (its inputs and row multipliers), the
    /// terminal stage kept.
    pub fn shifted(&self) -> WarmStart<NX, NU, NC> {
        let it = &self.iterate;
        let n = it.len() - 1;
        let mut shifted = Vec::with_capacity(n + 1);
        shifted.extend_from_slice(&it[1..n]);
        let mut last = it[n - 1].clone();
        last.x = it[n].x;
        shifted.push(last);
        shifted.push(it[n].clone());
        WarmStart { iterate: shifted }
    }
}

impl<const NX: usize, const NU: usize, const NC: usize> WarmStart<NX, NU, NC> {
    /// The horizon it was made for.
    pub fn horizon(&self) -> usize {
        self.iterate.len() - 1
    }
}
