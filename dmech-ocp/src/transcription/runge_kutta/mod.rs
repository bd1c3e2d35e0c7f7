//! [`RkTranscription`]: a robot's problem on an explicit Runge–Kutta step of the
//! continuous model.

use super::problem::*;
use crate::nlp::derivatives::{
    block_hessian, cost_and_inequalities, generic_cost_curvature, StageScalar,
};
use crate::nlp::HessianBlocks;
use crate::nlp::{StageProblem, StateEquality};
use crate::solver::Iterate;
use crate::transcription::layout::{check_pose_coordinates, segment, LayoutError};
use crate::transcription::sizes::{Dims, StageSizes};
use dmech::{PrincipalKinematicSystem, RungeKutta};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use std::marker::PhantomData;

/// The sizes a transcription is built for, carried as a type.
type Sizes<const DOF: usize, const NS: usize, const NU: usize, const NX: usize> =
    PhantomData<([(); DOF], [(); NS], [(); NU], [(); NX])>;

pub(crate) mod stages;
pub use stages::RkStages;

/// A robot's problem on an explicit Runge–Kutta step of the continuous model:
/// `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`, no stage equality. `NX` follows
/// from the robot's sizes ([`crate::transcription::sizes`]) through
/// [`RkTranscription::new`].
pub struct RkTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
    const NX: usize,
> {
    /// The stage functions.
    pub stages: RkStages<'a, S>,
    /// The robot's problem.
    pub problem: P,
    _sizes: Sizes<DOF, NS, NU, NX>,
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
    > RkTranscription<'a, S, P, DOF, NP, NS, NU, NX>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    /// `problem` on `sys` at step `h` with the Runge–Kutta method `method`.
    pub fn new<const NW: usize>(sys: &'a S, problem: P, h: f64, method: RungeKutta) -> Self
    where
        Dims<NP, NS, NU>: StageSizes<NX, NW>,
    {
        Self::with_sizes(sys, problem, h, method).expect("the sizes table agrees with the layout")
    }

    /// [`RkTranscription::new`] for sizes the table does not infer (generic code); `Err`
    /// if `NP` or `NX` disagree with the system.
    pub fn with_sizes(
        sys: &'a S,
        problem: P,
        h: f64,
        method: RungeKutta,
    ) -> Result<Self, LayoutError> {
        let stages = RkStages::new(sys, h, method);
        check_pose_coordinates::<NP>(stages.layout.np)?;
        stages.layout.fits::<NX, NU>(NU)?;
        Ok(RkTranscription {
            stages,
            problem,
            _sizes: PhantomData,
        })
    }

    /// The typed view of `(x_k, w_k = u_k)`.
    pub fn stage<T: Real>(&self, x: &SVector<T, NX>, u: &SVector<T, NU>) -> Stage<T, NP, NS, NU> {
        let l = self.stages.layout;
        Stage {
            pose: segment(x, 0),
            shape: segment(x, l.s_at()),
            velocity: segment(x, l.v_at()),
            input: *u,
            previous_input: segment(x, l.u_at()),
        }
    }

    /// A start in this transcription's layout from a plan of any transcription at the same
    /// step (a variational plan, say): `x_k = (pose_k, s_k, v_k, u_{k−1})`, `w_k = u_k`,
    /// with `v_k` the plan's velocity at stage `k` (a variational plan's is the interval's,
    /// within O(h) of the continuous velocity, O(h²) of the midpoint's node velocity).
    /// Panics if the plan's horizon is not this problem's.
    #[allow(clippy::type_complexity)]
    pub fn start_from_trajectory<const NC: usize>(
        &self,
        plan: &PlannedTrajectory<NP, NS, NU>,
    ) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NU>>)
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
        let xs = plan
            .stages
            .iter()
            .map(|st| state_vector(l, &st.pose, &st.shape, &st.velocity, &st.previous_input))
            .collect();
        let ws = plan.stages[..n].iter().map(|st| st.input).collect();
        (xs, ws)
    }

    /// The solver's iterate as a [`PlannedTrajectory`].
    pub fn trajectory<const NC: usize>(
        &self,
        it: &Iterate<NX, NU, NC>,
    ) -> PlannedTrajectory<NP, NS, NU> {
        let n = it.w.len();
        let stages = (0..=n)
            .map(|k| self.stage(&it.x[k], &it.w[k.min(n - 1)]))
            .collect();
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
        const NC: usize,
    > StageProblem<NX, NU, 0, NU, NC> for RkTranscription<'_, S, P, DOF, NP, NS, NU, NX>
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
        u: &SVector<T, NU>,
    ) -> SVector<T, NX> {
        self.stages.dynamics::<T, DOF, NS, NU, NX, NU>(x, u)
    }
    fn dynamics_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        u: &SVector<f64, NU>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>) {
        self.stages.dynamics_jacobian::<DOF, NS, NU, NX, NU>(x, u)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, NX>,
        _u: &SVector<T, NU>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, u: &SVector<T, NU>) -> T {
        self.problem.cost(k, &self.stage(x, u))
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NC> {
        self.problem.constraints(k, &self.stage(x, u))
    }
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.problem.bounds(k)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        state_equalities(self.stages.layout, &self.problem.conditions())
    }
    /// A problem affine in the configuration and the previous input
    /// ([`PlanningProblem::affine_in_configuration`]) is curved in `(v_k, u_k)` only, and
    /// `v_k` is part of this state: second-order passes over `(v_k, u_k)` (`NS + NU` lanes)
    /// instead of the whole stage, the other blocks zero.
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        u: &SVector<f64, NU>,
        cost_scale: f64,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NU> {
        if !self.problem.affine_in_configuration() {
            return generic_cost_curvature(self, k, x, u, cost_scale, zeta);
        }
        let v_at = self.stages.layout.v_at();
        let part = VelocityPart {
            problem: self,
            k,
            x,
            v_at,
            cost_scale,
            zeta,
        };
        let v: SVector<f64, NS> = segment(x, v_at);
        let (hvv, hvu, huu) = block_hessian(&part, &v, u, true);
        let mut hxx = SMatrix::<f64, NX, NX>::zeros();
        hxx.fixed_view_mut::<NS, NS>(v_at, v_at).copy_from(&hvv);
        let mut hxu = SMatrix::<f64, NX, NU>::zeros();
        hxu.fixed_view_mut::<NS, NU>(v_at, 0).copy_from(&hvu);
        (hxx, hxu, huu)
    }
    fn constant_cost_curvature(&self) -> bool {
        self.problem.quadratic_cost_affine_constraints()
    }
}

/// `s ℓ_k + ζᵀc_k` of an RK stage as a function of its velocity `v_k` and input, the rest of
/// the state held: what [`RkTranscription`]'s cost curvature differentiates.
struct VelocityPart<'a, P, const NX: usize, const NC: usize> {
    problem: &'a P,
    k: usize,
    x: &'a SVector<f64, NX>,
    v_at: usize,
    cost_scale: f64,
    zeta: &'a SVector<f64, NC>,
}

impl<P, const NX: usize, const NS: usize, const NU: usize, const NC: usize> StageScalar<NS, NU>
    for VelocityPart<'_, P, NX, NC>
where
    P: StageProblem<NX, NU, 0, NU, NC>,
{
    fn eval<T: Real>(&self, v: &SVector<T, NS>, u: &SVector<T, NU>) -> T {
        let mut x = self.x.map(T::from);
        x.fixed_rows_mut::<NS>(self.v_at).copy_from(v);
        cost_and_inequalities(self.problem, self.k, self.cost_scale, self.zeta, &x, u)
    }
}
