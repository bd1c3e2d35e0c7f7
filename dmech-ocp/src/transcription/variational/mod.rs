//! [`VarIntTranscription`]: a robot's problem on the first-order or the midpoint
//! variational integrator.

use super::problem::*;
use crate::nlp::derivatives::generic_constraint_curvature;
use crate::nlp::HessianBlocks;
use crate::nlp::{StageProblem, StateEquality};
use crate::solver::Iterate;
use crate::transcription::layout::segment;
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use std::marker::PhantomData;

mod curvature;
mod partials;
pub(crate) mod stages;
pub use stages::VarIntStages;

/// A robot's problem on a variational integrator (first order or midpoint):
/// `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`, `w_k = (v_k, u_k)`, stage equality = the
/// momentum matching of node `k`.
pub struct VarIntTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
> {
    /// The stage functions.
    pub stages: VarIntStages<'a, S>,
    /// The robot's problem.
    pub problem: P,
    _sizes: PhantomData<([(); DOF], [(); NS], [(); NU])>,
}

impl<'a, S, P, const DOF: usize, const NP: usize, const NS: usize, const NU: usize>
    VarIntTranscription<'a, S, P, DOF, NP, NS, NU>
{
    /// `problem` on `sys` at step `h`, right-point forcing (the first-order scheme's
    /// default), with the given discretisation.
    pub fn new(sys: &'a S, problem: P, h: f64, discretisation: Discretisation) -> Self
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let stages = VarIntStages::new::<DOF, NS, NU>(sys, h, ForcingQuadrature::Right)
            .with_discretisation(discretisation);
        assert_eq!(
            stages.layout.nc, NP,
            "NP must be the group's number of coordinates"
        );
        VarIntTranscription {
            stages,
            problem,
            _sizes: PhantomData,
        }
    }

    /// The same transcription with the shape coordinates `ignored` left out of the state
    /// (`Layout::ignoring`): they must be ones the stage functions do not read.
    pub fn with_ignored_shape(mut self, ignored: &[usize]) -> Self {
        self.stages.layout = self.stages.layout.ignoring(ignored);
        self
    }

    /// The typed view of `(x_k, w_k)`.
    pub fn stage<T: Real, const NX: usize, const NW: usize>(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> Stage<T, NP, NS, NU> {
        let l = self.stages.layout;
        Stage {
            pose: segment(x, 0),
            shape: l.shape(x),
            velocity: segment(w, 0),
            input: segment(w, NS),
            previous_input: segment(x, l.u_at()),
        }
    }

    /// The solver's iterate as a [`PlannedTrajectory`].
    pub fn trajectory<const NX: usize, const NW: usize, const NC: usize>(
        &self,
        it: &Iterate<NX, NW, NC>,
    ) -> PlannedTrajectory<NP, NS, NU>
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        let n = it.w.len();
        let l = self.stages.layout;
        let mut stages: Vec<_> = (0..n).map(|k| self.stage(&it.x[k], &it.w[k])).collect();
        let x = &it.x[n];
        stages.push(Stage {
            pose: segment(x, 0),
            shape: l.shape(x),
            velocity: segment(x, l.v_at()),
            input: segment(&it.w[n - 1], NS),
            previous_input: segment(x, l.u_at()),
        });
        // The ignored positions, which the state does not carry, by the dynamics they
        // have: `s_{k+1} = s_k + h v_k` from the start's.
        let start = self.problem.start();
        for i in (0..NS).filter(|&i| l.is_ignored(i)) {
            stages[0].shape[i] = start.shape[i];
            for k in 0..n {
                stages[k + 1].shape[i] = stages[k].shape[i] + self.stages.h * stages[k].velocity[i];
            }
        }
        PlannedTrajectory {
            h: self.stages.h,
            stages,
        }
    }
}

impl<
        S,
        P,
        const DOF: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
        const NC: usize,
    > StageProblem<NX, NW, NS, NU, NC> for VarIntTranscription<'_, S, P, DOF, NP, NS, NU>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    fn horizon(&self) -> usize {
        self.stages.layout.check(NX, NW, NS + NU);
        self.problem.horizon()
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        initial_state(self.stages.layout, &self.problem.start())
    }
    fn dynamics<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NX> {
        self.stages.dynamics::<T, DOF, NS, NU, NX, NW>(x, w)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NS> {
        self.stages.equality::<T, DOF, NS, NU, NX, NW>(x, w)
    }
    fn dynamics_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>) {
        self.stages.dynamics_jacobian::<DOF, NS, NU, NX, NW>(x, w)
    }
    fn equality_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>) {
        self.stages.equality_jacobian::<DOF, NS, NU, NX, NW>(x, w)
    }
    fn equality_partials(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>) {
        self.stages.equality_partials::<DOF, NS, NU, NX, NW>(x, w)
    }
    fn constraint_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        lambda: &SVector<f64, NX>,
        nu: &SVector<f64, NS>,
    ) -> HessianBlocks<NX, NW> {
        self.stages
            .constraint_curvature::<DOF, NS, NU, NX, NW>(x, w, lambda, nu)
            .unwrap_or_else(|| generic_constraint_curvature(self, k, x, w, lambda, nu))
    }
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        self.problem.cost(k, &self.stage(x, w))
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NC> {
        self.problem.constraints(k, &self.stage(x, w))
    }
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.problem.bounds(k)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        state_equalities(self.stages.layout, &self.problem.conditions())
    }
    fn affine_in_state(&self) -> bool {
        // The state holds pose, shape, v_{k−1} and u_{k−1}; the view exposes no v_{k−1}.
        self.problem.affine_in_configuration()
    }
    fn constant_cost_curvature(&self) -> bool {
        self.problem.quadratic_cost_affine_constraints()
    }
}
