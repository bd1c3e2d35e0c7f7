//! [`VarIntTranscription`]: a robot's problem on the first-order or the midpoint
//! variational integrator.

use super::problem::*;
use crate::nlp::derivatives::generic_constraint_curvature;
use crate::nlp::HessianBlocks;
use crate::nlp::{StageProblem, StateEquality};
use crate::solver::Iterate;
use crate::toolkit::kinematic_start::{
    varint_start_from_motion, varint_start_in_layout, KinematicStartError, ShapeMotion,
};
use crate::transcription::layout::{check_pose_coordinates, segment, Layout, LayoutError};
use crate::transcription::sizes::{Dims, StageSizes};
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem, VariationalIntegrator};
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
///
/// Its sizes are the robot's (`DOF`, `NP`, `NS`, `NU`) and the layout's (`NX`, `NW`):
/// [`VarIntTranscription::new`] carries every shape position and infers `NX` and `NW`
/// ([`crate::transcription::sizes`]); [`VarIntTranscription::with_layout`] takes any
/// layout, e.g. one without the system's ignorable shape positions.
pub struct VarIntTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
    const NX: usize,
    const NW: usize,
> {
    /// The stage functions.
    pub stages: VarIntStages<'a, S>,
    /// The robot's problem.
    pub problem: P,
    _sizes: PhantomData<([(); DOF], [(); NS], [(); NU])>,
}

impl<
        'a,
        S,
        P,
        const DOF: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    > VarIntTranscription<'a, S, P, DOF, NP, NS, NU, NX, NW>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    /// `problem` on `sys` at step `h` with the given discretisation, every shape position
    /// in the state; right-point forcing (the first-order scheme's, the paper's).
    pub fn new(sys: &'a S, problem: P, h: f64, discretisation: Discretisation) -> Self
    where
        Dims<NP, NS, NU>: StageSizes<NX, NW>,
    {
        let layout = Layout::new(NP, NS, NU);
        Self::with_layout(sys, problem, h, discretisation, layout)
            .expect("the sizes table agrees with the full layout")
    }

    /// `problem` on `sys` at step `h` in `layout` (from [`Layout::new`], with
    /// [`Layout::ignoring`] for shape positions the stage functions do not read). `Err`
    /// if `NP`, `NX` or `NW` disagree with the system and the layout.
    pub fn with_layout(
        sys: &'a S,
        problem: P,
        h: f64,
        discretisation: Discretisation,
        layout: Layout,
    ) -> Result<Self, LayoutError> {
        let mut stages =
            VarIntStages::new(sys, h, ForcingQuadrature::Right).with_discretisation(discretisation);
        layout.agrees_with(&stages.layout)?;
        layout.fits::<NX, NW>(NS + NU)?;
        check_pose_coordinates::<NP>(stages.layout.np)?;
        stages.layout = layout;
        Ok(VarIntTranscription {
            stages,
            problem,
            _sizes: PhantomData,
        })
    }

    /// A start in this transcription's layout from the pose path `poses` (`N + 1` poses,
    /// heading along the motion): the shape motion that realises the path through the
    /// connection from shape `s0` ([`crate::toolkit::kinematic_start`]), inputs zero.
    /// `regularisation` weighs each shape velocity in its least squares.
    #[allow(clippy::type_complexity)]
    pub fn start_from_path(
        &self,
        poses: &[S::Group<f64>],
        s0: &SVector<f64, NS>,
        regularisation: &SVector<f64, NS>,
    ) -> Result<(Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>), KinematicStartError>
    where
        S: Sync,
    {
        varint_start_in_layout(
            self.stages.sys,
            self.stages.h,
            poses,
            s0,
            regularisation,
            self.stages.discretisation,
            self.stages.layout,
        )
    }

    /// A start in this transcription's layout from a shape motion (from
    /// [`crate::toolkit::kinematic_start::shape_motion`], perhaps
    /// [`ShapeMotion::excited`]), the poses rolled forward from `g0` by the scheme's group
    /// update, inputs zero.
    #[allow(clippy::type_complexity)]
    pub fn start_from_motion(
        &self,
        g0: &S::Group<f64>,
        motion: &ShapeMotion<NS>,
    ) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>) {
        varint_start_from_motion::<S, DOF, NS, NU, NX, NW>(
            self.stages.sys,
            self.stages.h,
            g0,
            motion,
            self.stages.discretisation,
            self.stages.layout,
        )
    }

    /// A plan read back into this transcription's layout: `x_k = (pose_k, the carried part
    /// of s_k, v_{k−1}, u_{k−1})` (`v_{−1}` the start's velocity), `w_k = (v_k, u_k)`. The
    /// inverse of [`VarIntTranscription::trajectory`] for a plan of the same problem (to
    /// track it, [`crate::tracking`]). Panics if the plan's horizon is not this problem's.
    #[allow(clippy::type_complexity)]
    pub fn states_of<const NC: usize>(
        &self,
        plan: &PlannedTrajectory<NP, NS, NU>,
    ) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>)
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        let n = self.problem.horizon();
        assert_eq!(
            plan.stages.len(),
            n + 1,
            "the plan's horizon is not the problem's"
        );
        let l = self.stages.layout;
        let start = self.problem.start();
        let xs = (0..=n)
            .map(|k| {
                let st = &plan.stages[k];
                let v_before = if k == 0 {
                    start.velocity
                } else {
                    plan.stages[k - 1].velocity
                };
                state_vector(l, &st.pose, &st.shape, &v_before, &st.previous_input)
            })
            .collect();
        let ws = plan.stages[..n]
            .iter()
            .map(|st| {
                SVector::<f64, NW>::from_fn(|i, _| {
                    if i < NS {
                        st.velocity[i]
                    } else {
                        st.input[i - NS]
                    }
                })
            })
            .collect();
        (xs, ws)
    }

    /// The problem's conditions as this transcription holds them ([`conditions_for_scheme`]).
    pub fn scheme_conditions<const NC: usize>(&self) -> SchemeConditions
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        conditions_for_scheme(
            self.problem.conditions(),
            self.problem.horizon(),
            NS,
            self.stages.discretisation,
        )
    }

    /// The velocity the robot arrives with at the last node, from its state
    /// `x_N = (…, s_N, v_{N−1}, u_{N−1})`: the scheme's node velocity
    /// ([`VariationalIntegrator::node_velocity`]; `v_{N−1}` itself for the first-order
    /// scheme, and if Newton's method fails).
    fn arriving_velocity(&self, x: &SVector<f64, NX>) -> SVector<f64, NS> {
        let l = self.stages.layout;
        let (s, v_prev, u_prev): (SVector<f64, NS>, SVector<f64, NS>, SVector<f64, NU>) =
            (l.shape(x), segment(x, l.v_at()), segment(x, l.u_at()));
        let h = self.stages.h;
        VariationalIntegrator::new(h)
            .with_discretisation(self.stages.discretisation)
            .node_velocity(self.stages.sys, &(s - v_prev * h), &v_prev, &u_prev, &s)
            .unwrap_or(v_prev)
    }

    /// The typed view of `(x_k, w_k)`.
    /// (`w` may trail entries of its own beyond `(v_k, u_k)`, as free timing's do.)
    pub fn stage<T: Real, const NWX: usize>(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NWX>,
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
    pub fn trajectory<const NC: usize>(
        &self,
        it: &Iterate<NX, NW, NC>,
    ) -> PlannedTrajectory<NP, NS, NU>
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        self.trajectory_of(&it.x, &it.w)
    }

    /// The states and decisions `x`, `w` as a [`PlannedTrajectory`] (decisions of any
    /// size that start with `(v_k, u_k)`).
    pub(crate) fn trajectory_of<const NWX: usize, const NC: usize>(
        &self,
        x: &[SVector<f64, NX>],
        w: &[SVector<f64, NWX>],
    ) -> PlannedTrajectory<NP, NS, NU>
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        let n = w.len();
        let l = self.stages.layout;
        let mut stages: Vec<_> = (0..n).map(|k| self.stage(&x[k], &w[k])).collect();
        let x = &x[n];
        stages.push(Stage {
            pose: segment(x, 0),
            shape: l.shape(x),
            velocity: self.arriving_velocity(x),
            input: segment(&w[n - 1], NS),
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
    > StageProblem<NX, NW, NS, NU, NC> for VarIntTranscription<'_, S, P, DOF, NP, NS, NU, NX, NW>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    fn horizon(&self) -> usize {
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
        state_equalities(self.stages.layout, &self.scheme_conditions().state)
    }
    /// Under the midpoint scheme, a plan that arrives at rest ends on node `N`'s momentum
    /// matching with `(v_N, u_N) = (0, 0)` ([`conditions_for_scheme`]).
    fn terminal_equalities<T: Real>(&self, x: &SVector<T, NX>) -> Vec<T> {
        if !self.scheme_conditions().rest_by_momentum {
            return Vec::new();
        }
        let rest = SVector::<T, NW>::zeros();
        let r = self.stages.equality::<T, DOF, NS, NU, NX, NW>(x, &rest);
        r.iter().copied().collect()
    }
    fn affine_in_state(&self) -> bool {
        // The state holds pose, shape, v_{k−1} and u_{k−1}; the view exposes no v_{k−1}.
        self.problem.affine_in_configuration()
    }
    fn constant_cost_curvature(&self) -> bool {
        self.problem.quadratic_cost_affine_constraints()
    }
}
