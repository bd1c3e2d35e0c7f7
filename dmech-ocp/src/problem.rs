//! A stage-structured nonlinear program, as the interior-point solver sees it.
//!
//! ```text
//! min  Σ_{k<N} ℓ_k(x_k, w_k) + ℓ_N(x_N)
//! s.t. x_0 = x̄                                  (given)
//!      x_{k+1} = f_k(x_k, w_k)                  (dynamics, explicit)
//!      e_k(x_k, w_k) = 0                        (stage equality, NE rows)
//!      lo_k ≤ c_k(x_k, w_k) ≤ hi_k              (stage inequalities, NC rows)
//!      x_k[i] = value                           (state equalities: waypoints, end state)
//! ```
//! The stage equality must be solvable for the first `NE` components of `w` (its Jacobian
//! with respect to them is invertible): the solver eliminates them stage by stage, which
//! leaves the Riccati recursion `NU = NW − NE` free inputs per stage. For the variational
//! integrator these are the velocities `v_k`, and the matrix is the integrator's Newton
//! matrix.
//!
//! Every function is generic over the scalar: the solver takes exact derivatives with
//! dual numbers. Nothing here knows about a particular robot.

use dmech::partials::{lift_vec, seeded, split_passes};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// `x_k[index] = value` at stage `k` (`k = N` is the end state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateEquality {
    pub stage: usize,
    pub index: usize,
    pub value: f64,
}

/// The problem. `NX` state, `NW` stage decision, `NE` stage equalities, `NC` inequalities.
pub trait StageProblem<const NX: usize, const NW: usize, const NE: usize, const NC: usize>:
    Sync
{
    /// The number of stages `N` (decisions `w_0 … w_{N−1}`, states `x_0 … x_N`).
    fn horizon(&self) -> usize;
    /// `x̄ = x_0`.
    fn initial_state(&self) -> SVector<f64, NX>;
    fn dynamics<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
        -> SVector<T, NX>;
    fn equality<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
        -> SVector<T, NE>;
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T;
    /// `ℓ_N(x_N)`, a cost on the end state. Default: none.
    fn terminal_cost<T: Real>(&self, _x: &SVector<T, NX>) -> T {
        T::zero()
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NC>;
    /// `(lo, hi)` of the stage inequalities; infinite entries mean "no bound".
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>);
    /// The state equalities, any order.
    fn state_equalities(&self) -> Vec<StateEquality>;
    /// `true` if the cost and the inequalities are affine in `x` (the `xx` and `xw` blocks of
    /// their Hessian vanish), which saves the solver two of its three second-order passes.
    /// A declaration, checked by the solver at its start point (it stops with an error if
    /// those blocks are not zero there). Default `false`.
    fn affine_in_state(&self) -> bool {
        false
    }
    /// The curvature of the constraints, `(∇²_xx, ∇²_xw, ∇²_ww)` of `λᵀf + νᵀe` at
    /// `(x, w)` (the exact Hessian's part beyond the cost and the inequalities). The default
    /// differentiates [`StageProblem::dynamics`] and [`StageProblem::equality`] twice by
    /// dual numbers ([`crate::derivatives::generic_constraint_curvature`]); a problem with a
    /// cheaper exact route overrides it (e.g. [`crate::varint::VarIntStages`]).
    #[allow(clippy::type_complexity)]
    fn constraint_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        lambda: &SVector<f64, NX>,
        nu: &SVector<f64, NE>,
    ) -> (
        SMatrix<f64, NX, NX>,
        SMatrix<f64, NX, NW>,
        SMatrix<f64, NW, NW>,
    )
    where
        Self: Sized,
    {
        crate::derivatives::generic_constraint_curvature::<Self, NX, NW, NE, NC>(
            self, k, x, w, lambda, nu,
        )
    }
    /// `(f, F_x, F_w)` of the dynamics, exact. The default differentiates
    /// [`StageProblem::dynamics`] by two vector-dual passes (seeded in `x`, then in `w`); a
    /// problem with a cheaper exact route overrides it (e.g.
    /// [`crate::runge_kutta::RkStages::dynamics_jacobian`]).
    #[allow(clippy::type_complexity)]
    fn dynamics_jacobian(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>) {
        let fx = self.dynamics(k, &seeded(x), &lift_vec::<f64, NX, NW>(w));
        let fw = self.dynamics(k, &lift_vec::<f64, NW, NX>(x), &seeded(w));
        split_passes(&fx, &fw)
    }
    /// `(e, E_x, E_w)` of the stage equality, exact. The default differentiates
    /// [`StageProblem::equality`] by two vector-dual passes (seeded in `x`, then in `w`); a
    /// problem with a cheaper exact route overrides it (e.g.
    /// [`crate::varint::VarIntStages::equality_jacobian`]).
    #[allow(clippy::type_complexity)]
    fn equality_jacobian(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NE>, SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>) {
        let ex = self.equality(k, &seeded(x), &lift_vec::<f64, NX, NW>(w));
        let ew = self.equality(k, &lift_vec::<f64, NW, NX>(x), &seeded(w));
        split_passes(&ex, &ew)
    }
}
