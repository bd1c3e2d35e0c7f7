//! A stage-structured nonlinear program, as the interior-point solver sees it.
//!
//! ```text
//! min  Σ_{k<N} ℓ_k(x_k, w_k) + ℓ_N(x_N)
//! s.t. x_0 = x̄                                  (given)
//!      x_{k+1} = f_k(x_k, w_k)                  (dynamics, explicit)
//!      e_k(x_k, w_k) = 0                        (stage equality, NE rows)
//!      lo_k ≤ c_k(x_k, w_k) ≤ hi_k              (stage inequalities, NC rows)
//!      x_k[i] = value                           (state equalities: waypoints, end state)
//!      r(x_N) = 0                               (terminal equalities, nonlinear)
//! ```
//! The stage equality must be solvable for the first `NE` components of `w` (its Jacobian
//! with respect to them is invertible): the solver eliminates them stage by stage, which
//! leaves the Riccati recursion `NU = NW − NE` free inputs per stage. For the variational
//! integrator these are the velocities `v_k`, and the matrix is the integrator's Newton
//! matrix.
//!
//! Every function is generic over the scalar: the solver takes exact derivatives with
//! dual numbers. Nothing here knows about a particular robot.
//!
//! **Global variables** ([`Globals`], default none) couple every stage: a vector `p`
//! (e.g. the step ratios of the segments of a plan with free timing) with bounds, linear
//! equalities and a linear cost. A stage reads the globals it depends on through the last
//! `per_stage` entries of its decision `w_k`, which the solver keeps equal to
//! `p[support(k)]`: the stage functions keep their signature, and their derivatives in
//! those entries are the derivatives in `p` (`docs/solver.md`, "Global variables and the two KKT paths").

use dmech_lie::dual::{lift_vec, seeded, split_passes};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

pub mod derivatives;

/// The [`StageProblem`] methods named, forwarded to the problem in field `$p` (inside an
/// `impl StageProblem<NX, NW, NE, NF, NC>` of a wrapper that changes only the others).
macro_rules! forward_stage_problem {
    ($p:ident: $($method:ident),* $(,)?) => {
        $( $crate::nlp::forward_stage_problem!(@one $p $method); )*
    };
    (@one $p:ident horizon) => {
        fn horizon(&self) -> usize {
            self.$p.horizon()
        }
    };
    (@one $p:ident initial_state) => {
        fn initial_state(&self) -> SVector<f64, NX> {
            self.$p.initial_state()
        }
    };
    (@one $p:ident dynamics) => {
        fn dynamics<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
            -> SVector<T, NX> {
            self.$p.dynamics(k, x, w)
        }
    };
    (@one $p:ident equality) => {
        fn equality<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
            -> SVector<T, NE> {
            self.$p.equality(k, x, w)
        }
    };
    (@one $p:ident constraints) => {
        fn constraints<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
            -> SVector<T, NC> {
            self.$p.constraints(k, x, w)
        }
    };
    (@one $p:ident bounds) => {
        fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
            self.$p.bounds(k)
        }
    };
    (@one $p:ident state_equalities) => {
        fn state_equalities(&self) -> Vec<$crate::nlp::StateEquality> {
            self.$p.state_equalities()
        }
    };
    (@one $p:ident terminal_equalities) => {
        fn terminal_equalities<T: Real>(&self, x: &SVector<T, NX>) -> Vec<T> {
            self.$p.terminal_equalities(x)
        }
    };
    (@one $p:ident affine_in_state) => {
        fn affine_in_state(&self) -> bool {
            self.$p.affine_in_state()
        }
    };
    (@one $p:ident constant_cost_curvature) => {
        fn constant_cost_curvature(&self) -> bool {
            self.$p.constant_cost_curvature()
        }
    };
    (@one $p:ident dynamics_jacobian) => {
        fn dynamics_jacobian(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>)
            -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>) {
            self.$p.dynamics_jacobian(k, x, w)
        }
    };
    (@one $p:ident equality_jacobian) => {
        fn equality_jacobian(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>)
            -> (SVector<f64, NE>, SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>) {
            self.$p.equality_jacobian(k, x, w)
        }
    };
    (@one $p:ident equality_partials) => {
        fn equality_partials(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>)
            -> (SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>) {
            self.$p.equality_partials(k, x, w)
        }
    };
    (@one $p:ident constraint_curvature) => {
        fn constraint_curvature(
            &self,
            k: usize,
            x: &SVector<f64, NX>,
            w: &SVector<f64, NW>,
            lambda: &SVector<f64, NX>,
            nu: &SVector<f64, NE>,
        ) -> $crate::nlp::HessianBlocks<NX, NW> {
            self.$p.constraint_curvature(k, x, w, lambda, nu)
        }
    };
}
pub(crate) use forward_stage_problem;

/// The blocks `(∇²_xx, ∇²_xw, ∇²_ww)` of a stage's Hessian (of a scalar function of
/// `(x, w)`).
pub type HessianBlocks<const NX: usize, const NW: usize> = (
    SMatrix<f64, NX, NX>,
    SMatrix<f64, NX, NW>,
    SMatrix<f64, NW, NW>,
);

/// `x_k[index] = value` at stage `k` (`k = N` is the end state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateEquality {
    /// The stage `k`.
    pub stage: usize,
    /// The state entry.
    pub index: usize,
    /// Its value.
    pub value: f64,
}

/// `aᵀp = b` on the global variables.
#[derive(Clone, Debug, PartialEq)]
pub struct GlobalEquality {
    /// `a`, one coefficient per global.
    pub a: Vec<f64>,
    /// `b`.
    pub b: f64,
}

/// The global variables of a problem: `p` with `lo ≤ p ≤ hi` (infinite: no bound), linear
/// equalities, the cost `cᵀp` added to the stage costs, and the globals each stage reads.
#[derive(Clone, Debug, PartialEq)]
pub struct Globals {
    /// The start value of `p` (its length is the number of globals).
    pub start: Vec<f64>,
    /// The lower bounds.
    pub lo: Vec<f64>,
    /// The upper bounds.
    pub hi: Vec<f64>,
    /// The linear equalities.
    pub equalities: Vec<GlobalEquality>,
    /// `c` of the linear cost `cᵀp`.
    pub cost: Vec<f64>,
    /// How many globals each stage reads: the last `per_stage` entries of `w_k`.
    pub per_stage: usize,
    /// `support[k · per_stage + i]`: the global that entry `NW − per_stage + i` of `w_k`
    /// copies (an index may repeat).
    pub support: Vec<usize>,
}

impl Globals {
    /// The number of globals.
    pub fn len(&self) -> usize {
        self.start.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.start.is_empty()
    }
    /// The globals stage `k` reads, in the order of its decision's last entries.
    pub fn support_of(&self, k: usize) -> &[usize] {
        &self.support[k * self.per_stage..(k + 1) * self.per_stage]
    }
    /// `Err` naming the first inconsistency with a horizon of `n` stages and decisions of
    /// size `nw`.
    pub fn check(&self, n: usize, nw: usize) -> Result<(), GlobalsError> {
        let g = self.len();
        if self.lo.len() != g || self.hi.len() != g || self.cost.len() != g {
            return Err(GlobalsError::Lengths {
                start: g,
                lo: self.lo.len(),
                hi: self.hi.len(),
                cost: self.cost.len(),
            });
        }
        if self.per_stage > nw || self.support.len() != n * self.per_stage {
            return Err(GlobalsError::Support {
                per_stage: self.per_stage,
                nw,
                support: self.support.len(),
                stages: n,
            });
        }
        if let Some(&j) = self.support.iter().find(|&&j| j >= g) {
            return Err(GlobalsError::UnknownGlobal {
                index: j,
                globals: g,
            });
        }
        if let Some(e) = self.equalities.iter().find(|e| e.a.len() != g) {
            return Err(GlobalsError::Equality {
                coefficients: e.a.len(),
                globals: g,
            });
        }
        if let Some(j) =
            (0..g).find(|&j| !(self.lo[j] <= self.start[j] && self.start[j] <= self.hi[j]))
        {
            return Err(GlobalsError::StartOutside {
                index: j,
                start: self.start[j],
                lo: self.lo[j],
                hi: self.hi[j],
            });
        }
        Ok(())
    }
}

/// An inconsistency of a problem's [`Globals`] ([`Globals::check`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GlobalsError {
    /// `start`, `lo`, `hi` and `cost` differ in length.
    #[error(
        "globals: start, lo, hi and cost must have the same length ({start}, {lo}, {hi}, {cost})"
    )]
    Lengths {
        /// `start`'s length.
        start: usize,
        /// `lo`'s length.
        lo: usize,
        /// `hi`'s length.
        hi: usize,
        /// `cost`'s length.
        cost: usize,
    },
    /// The per-stage copies do not fit the decisions, or the support the horizon.
    #[error("globals: {per_stage} per stage of {nw} decisions, support of {support} for {stages} stages")]
    Support {
        /// Globals read per stage.
        per_stage: usize,
        /// The decision size.
        nw: usize,
        /// The support's length.
        support: usize,
        /// The horizon.
        stages: usize,
    },
    /// The support names a global that does not exist.
    #[error("globals: support names global {index} of {globals}")]
    UnknownGlobal {
        /// The named global.
        index: usize,
        /// The number of globals.
        globals: usize,
    },
    /// An equality with a wrong number of coefficients.
    #[error("globals: an equality has {coefficients} coefficients for {globals} globals")]
    Equality {
        /// Its coefficients.
        coefficients: usize,
        /// The number of globals.
        globals: usize,
    },
    /// A start value outside its bounds.
    #[error("globals: start {start} of global {index} is outside [{lo}, {hi}]")]
    StartOutside {
        /// The global.
        index: usize,
        /// Its start value.
        start: f64,
        /// Its lower bound.
        lo: f64,
        /// Its upper bound.
        hi: f64,
    },
}

/// The problem. `NX` state, `NW` stage decision, `NE` stage equalities, `NF = NW − NE`
/// free decisions (less the globals' copies per stage, if any), `NC` inequalities.
pub trait StageProblem<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>: Sync
{
    /// The number of stages `N` (decisions `w_0 … w_{N−1}`, states `x_0 … x_N`).
    fn horizon(&self) -> usize;
    /// `x̄ = x_0`.
    fn initial_state(&self) -> SVector<f64, NX>;
    /// `x_{k+1} = f_k(x_k, w_k)`.
    fn dynamics<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
        -> SVector<T, NX>;
    /// The stage equality `e_k(x_k, w_k) = 0`, solvable for the first `NE` entries of `w`.
    fn equality<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>)
        -> SVector<T, NE>;
    /// The running cost `ℓ_k(x_k, w_k)`.
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T;
    /// `ℓ_N(x_N)`, a cost on the end state. Default: none.
    fn terminal_cost<T: Real>(&self, _x: &SVector<T, NX>) -> T {
        T::zero()
    }
    /// The stage inequalities `c_k(x_k, w_k)`, bounded by [`StageProblem::bounds`].
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
    /// Nonlinear equalities on the end state, `r(x_N) = 0`: conditions no single state
    /// component says, such as the discrete Legendre transform at the last node of a
    /// midpoint plan that ends at rest (`crate::transcription::variational`). The same
    /// number of rows at every `x`. The solver treats them as it treats the state
    /// equalities (dual-regularised rows of the last stage, multipliers after the state
    /// equalities' in [`crate::solver::Iterate::y`]), with their exact curvature. Default:
    /// none.
    fn terminal_equalities<T: Real>(&self, _x: &SVector<T, NX>) -> Vec<T> {
        Vec::new()
    }
    /// `true` if the cost and the inequalities are affine in `x` (the `xx` and `xw` blocks of
    /// their Hessian vanish), which saves the solver two of its three second-order passes.
    /// A declaration, checked by the solver at its start point (it stops with an error if
    /// those blocks are not zero there). Default `false`.
    fn affine_in_state(&self) -> bool {
        false
    }
    /// `true` if the cost is quadratic and the inequalities affine in `(x, w)`: the
    /// curvature of `s ℓ_k + ζᵀc_k` ([`StageProblem::cost_curvature`]) is then the same at
    /// every point and for every `ζ`, and the solver computes it once per stage instead of
    /// once per iteration. A declaration, checked by the solver at its start (it stops with
    /// an error if the curvature at a second point and multiplier differs). Default `false`.
    fn constant_cost_curvature(&self) -> bool {
        false
    }
    /// The curvature of the cost and the inequalities, `(∇²_xx, ∇²_xw, ∇²_ww)` of
    /// `s ℓ_k + ζᵀc_k` at `(x, w)` (`s = cost_scale`: a wrapper that scales the cost passes
    /// its scale down, so that the problem's own override serves it). The default
    /// differentiates [`StageProblem::cost`] and [`StageProblem::constraints`] twice by dual
    /// numbers over the whole stage ([`crate::nlp::derivatives::generic_cost_curvature`]; only
    /// the `ww` block when [`StageProblem::affine_in_state`]); a problem that knows which
    /// part of the state they are curved in overrides it (e.g.
    /// [`crate::transcription::RkTranscription`]).
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        cost_scale: f64,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NW>
    where
        Self: Sized,
    {
        crate::nlp::derivatives::generic_cost_curvature(self, k, x, w, cost_scale, zeta)
    }
    /// The curvature of the constraints, `(∇²_xx, ∇²_xw, ∇²_ww)` of `λᵀf + νᵀe` at
    /// `(x, w)` (the exact Hessian's part beyond the cost and the inequalities). The default
    /// differentiates [`StageProblem::dynamics`] and [`StageProblem::equality`] twice by
    /// dual numbers ([`crate::nlp::derivatives::generic_constraint_curvature`]); a problem with a
    /// cheaper exact route overrides it (e.g. [`crate::transcription::variational::stages::VarIntStages`]).
    fn constraint_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        lambda: &SVector<f64, NX>,
        nu: &SVector<f64, NE>,
    ) -> HessianBlocks<NX, NW>
    where
        Self: Sized,
    {
        crate::nlp::derivatives::generic_constraint_curvature(self, k, x, w, lambda, nu)
    }
    /// The global variables, if the problem has any (default: none, the pure stage
    /// structure). The last `per_stage` entries of every `w_k` are then the globals' copies
    /// (module documentation).
    fn globals(&self) -> Option<Globals> {
        None
    }
    /// `(f, F_x, F_w)` of the dynamics, exact. The default differentiates
    /// [`StageProblem::dynamics`] by two vector-dual passes (seeded in `x`, then in `w`); a
    /// problem with a cheaper exact route overrides it (e.g.
    /// [`crate::transcription::runge_kutta::stages::RkStages::dynamics_jacobian`]).
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
    /// [`crate::transcription::variational::stages::VarIntStages::equality_jacobian`]).
    #[allow(clippy::type_complexity)]
    fn equality_jacobian(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NE>, SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>)
    where
        Self: Sized,
    {
        crate::nlp::derivatives::generic_equality_jacobian(self, k, x, w)
    }
    /// `(E_x, E_w)` alone, for a caller that has the value already (the solver measured
    /// `e` at this point in its line search). The default drops the value of
    /// [`StageProblem::equality_jacobian`]; a problem whose value is a pass of its own
    /// (e.g. [`crate::transcription::variational::stages::VarIntStages::first_order_equality_partials`]) overrides it.
    #[allow(clippy::type_complexity)]
    fn equality_partials(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>)
    where
        Self: Sized,
    {
        let (_, ex, ew) = self.equality_jacobian(k, x, w);
        (ex, ew)
    }
}

/// The largest violation of any constraint of `p` at the primal point `(x, w)`: dynamics
/// `f_k(x_k, w_k) − x_{k+1}`, stage equalities, path bounds, state and terminal
/// equalities; `∞` if any is NaN. What a plan reports as its `max_violation`, measured on the trajectory it
/// returns rather than taken from the solver's filter.
pub fn max_violation<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    x: &[SVector<f64, NX>],
    w: &[SVector<f64, NW>],
) -> f64
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let mut worst = 0.0f64;
    for k in 0..w.len() {
        worst = worst.max((p.dynamics(k, &x[k], &w[k]) - x[k + 1]).amax());
        worst = worst.max(p.equality(k, &x[k], &w[k]).amax());
        let c = p.constraints(k, &x[k], &w[k]);
        let (lo, hi) = p.bounds(k);
        for i in 0..NC {
            worst = worst.max(lo[i] - c[i]).max(c[i] - hi[i]);
        }
    }
    for e in p.state_equalities() {
        worst = worst.max((x[e.stage][e.index] - e.value).abs());
    }
    for r in p.terminal_equalities(&x[w.len()]) {
        worst = worst.max(r.abs());
    }
    if worst.is_nan() {
        f64::INFINITY
    } else {
        worst
    }
}
