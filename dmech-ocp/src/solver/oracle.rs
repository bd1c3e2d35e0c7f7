//! What the solver's engine reads of a problem, behind a trait object.
//!
//! [`StageProblem`] is generic in its scalar (its stage functions take dual numbers), so it
//! cannot be a trait object, and a solver generic over the problem type was compiled anew
//! for every problem and for each of the problems the solver derives from it (the scaled
//! cost, the restoration problem): four copies of the whole interior-point engine per
//! problem type. The engine needs only `f64` results of a problem: values, the stage
//! derivatives the dual numbers give, and the two derived problems. [`StageOracle`] and
//! [`DerivedProblems`] say exactly that, without a scalar parameter, and every
//! [`StageProblem`] implements both. The engine is then compiled once per set of sizes
//! `(NX, NW, NE, NF, NC)`; what stays per problem type is its own derivative code, which
//! is all that differs between problems. One virtual call per stage and pass is nothing
//! beside the dual-number work behind it.

use super::restoration::Restoration;
use super::scaling::ScaledCost;
use crate::nlp::derivatives::{
    stage_derivatives_into, stage_first_derivatives_into, state_curvature, state_pass,
    terminal_derivatives, Precomputed, StageDerivatives, StageValues, TerminalDerivatives,
};
use crate::nlp::HessianBlocks;
use crate::nlp::{Globals, StageProblem, StateEquality};
use nalgebra::{SMatrix, SVector};

/// A problem's `f64` face: what the engine evaluates, stage by stage.
pub(super) trait StageOracle<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>: Sync
{
    fn horizon(&self) -> usize;
    fn initial_state(&self) -> SVector<f64, NX>;
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>);
    fn state_equalities(&self) -> Vec<StateEquality>;
    fn affine_in_state(&self) -> bool;
    fn constant_cost_curvature(&self) -> bool;
    fn globals(&self) -> Option<Globals>;
    fn cost(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>) -> f64;
    fn terminal_cost(&self, x: &SVector<f64, NX>) -> f64;
    fn terminal_equalities(&self, x: &SVector<f64, NX>) -> Vec<f64>;
    fn constraints(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>)
        -> SVector<f64, NC>;
    fn values(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> StageValues<NX, NE, NC>;
    /// The curvature of `ℓ_k + ζᵀc_k` ([`StageProblem::cost_curvature`] at scale one).
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NW>;
    /// `∇_x ℓ_k` and `C_x` ([`crate::nlp::derivatives::state_pass`]).
    fn state_gradients(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NC, NX>);
    /// The `xx` and `xw` blocks of the curvature of `ℓ_k + ζᵀc_k`.
    fn state_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
    ) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>);
    /// [`stage_derivatives_into`].
    #[allow(clippy::too_many_arguments)] // the stage, its point and multipliers, two options
    fn derivatives_into(
        &self,
        d: &mut StageDerivatives<NX, NW, NE, NC>,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
        lambda: Option<&SVector<f64, NX>>,
        known: Precomputed<'_, NX, NW, NE, NC>,
    );
    /// [`stage_first_derivatives_into`].
    fn first_derivatives_into(
        &self,
        d: &mut StageDerivatives<NX, NW, NE, NC>,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        known: Precomputed<'_, NX, NW, NE, NC>,
    );
    /// [`terminal_derivatives`] with the terminal equalities' multipliers `y`.
    fn terminal_derivatives(&self, x: &SVector<f64, NX>, y: &[f64]) -> TerminalDerivatives<NX>;
}

/// What the restoration problem's solver needs beyond a [`StageOracle`]: its proximity
/// weight follows the barrier parameter.
pub(super) trait RestorationOracle<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>: StageOracle<NX, NW, NE, NF, NC>
{
    /// `ζ = √μ`; `true` if it changed.
    fn follow(&self, mu: f64) -> bool;
}

/// Where a restoration starts: the point `(x̂, ŵ)`, the penalty weight `ρ`, and the
/// problem's state equalities by stage.
pub(super) struct RestorationSetup<'s, const NX: usize, const NW: usize> {
    pub(super) eqs: &'s [StateEquality],
    pub(super) eqs_at: &'s [Vec<usize>],
    pub(super) x_ref: Vec<SVector<f64, NX>>,
    pub(super) w_ref: Vec<SVector<f64, NW>>,
    pub(super) rho: f64,
}

/// The problems the solver derives from the one it was given, built where the problem's
/// type is still known. A trait of its own rather than methods of [`StageOracle`]: the
/// derived problems are oracles too, and a `scaled` in their vtables would ask for the
/// scaled problem of the scaled problem, without end.
pub(super) trait DerivedProblems<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>: Sync
{
    /// The problem with its cost times `c` (`scaling.rs`).
    fn scaled(&self, c: f64) -> Box<dyn StageOracle<NX, NW, NE, NF, NC> + '_>;
    /// The restoration problem around `setup`'s point, its proximity weight first `zeta`
    /// (`restoration.rs`). The same for the scaled problem: it drops the cost.
    fn restoration<'s>(
        &'s self,
        setup: RestorationSetup<'s, NX, NW>,
        zeta: f64,
    ) -> Box<dyn RestorationOracle<NX, NW, NE, NF, NC> + 's>;
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageOracle<NX, NW, NE, NF, NC> for P
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn horizon(&self) -> usize {
        StageProblem::horizon(self)
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        StageProblem::initial_state(self)
    }
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        StageProblem::bounds(self, k)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        StageProblem::state_equalities(self)
    }
    fn affine_in_state(&self) -> bool {
        StageProblem::affine_in_state(self)
    }
    fn constant_cost_curvature(&self) -> bool {
        StageProblem::constant_cost_curvature(self)
    }
    fn globals(&self) -> Option<Globals> {
        StageProblem::globals(self)
    }
    fn cost(&self, k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>) -> f64 {
        StageProblem::cost(self, k, x, w)
    }
    fn terminal_cost(&self, x: &SVector<f64, NX>) -> f64 {
        StageProblem::terminal_cost(self, x)
    }
    fn terminal_equalities(&self, x: &SVector<f64, NX>) -> Vec<f64> {
        StageProblem::terminal_equalities(self, x)
    }
    fn constraints(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> SVector<f64, NC> {
        StageProblem::constraints(self, k, x, w)
    }
    fn values(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> StageValues<NX, NE, NC> {
        crate::nlp::derivatives::stage_values(self, k, x, w)
    }
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NW> {
        StageProblem::cost_curvature(self, k, x, w, 1.0, zeta)
    }
    fn state_gradients(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NC, NX>) {
        let (l, c) = state_pass(self, k, x, w);
        (
            dmech_lie::dual::grad_part(&l),
            dmech_lie::dual::jacobian_part(&c),
        )
    }
    fn state_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
    ) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>) {
        state_curvature(self, k, x, w, zeta)
    }
    fn derivatives_into(
        &self,
        d: &mut StageDerivatives<NX, NW, NE, NC>,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        zeta: &SVector<f64, NC>,
        lambda: Option<&SVector<f64, NX>>,
        known: Precomputed<'_, NX, NW, NE, NC>,
    ) {
        stage_derivatives_into(d, self, k, x, w, zeta, lambda, known);
    }
    fn first_derivatives_into(
        &self,
        d: &mut StageDerivatives<NX, NW, NE, NC>,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        known: Precomputed<'_, NX, NW, NE, NC>,
    ) {
        stage_first_derivatives_into(d, self, k, x, w, known);
    }
    fn terminal_derivatives(&self, x: &SVector<f64, NX>, y: &[f64]) -> TerminalDerivatives<NX> {
        terminal_derivatives(self, x, y)
    }
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    DerivedProblems<NX, NW, NE, NF, NC> for P
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn scaled(&self, c: f64) -> Box<dyn StageOracle<NX, NW, NE, NF, NC> + '_> {
        Box::new(ScaledCost { p: self, c })
    }
    fn restoration<'s>(
        &'s self,
        s: RestorationSetup<'s, NX, NW>,
        zeta: f64,
    ) -> Box<dyn RestorationOracle<NX, NW, NE, NF, NC> + 's> {
        Box::new(Restoration::new(self, s, zeta))
    }
}
