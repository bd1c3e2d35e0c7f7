//! A robot's planning problem in typed terms, and its transcription into a
//! [`StageProblem`] for every discretisation: the first-order and midpoint variational
//! integrators ([`VarIntTranscription`]) and RK1/2/4 ([`RkTranscription`]).
//!
//! A robot supplies a [`PlanningProblem`]: its cost and path constraints over a [`Stage`]
//! (pose, shape, velocity, input, previous input: named fields, no offsets), their
//! bounds, the start, and [`Condition`]s on any pose, shape or velocity component at any
//! stage (waypoints, the end state). The transcription owns the stage layout: where each
//! quantity sits in the solver's `x_k` and `w_k`, which differs between the
//! discretisations (the variational integrators decide `w_k = (v_k, u_k)` and carry
//! `v_{k−1}` in the state; Runge–Kutta carries `v_k` in the state and decides `w_k = u_k`).
//!
//! Sizes: `NP` pose coordinates (`coords(g)`), `NS` shape, `NU` inputs, `NC` path
//! constraints. The solver's `NX = NP + 2 NS + NU`; `NW = NS + NU` (variational) or `NU`
//! (Runge–Kutta). The system's own `DOF` (dimension of `G`) and `DIM` (the dimension of the
//! space it acts on: 2 for SE(2), 3 for SO(3) and SE(3)) are its `PrincipalKinematicSystem`
//! parameters. The solver's `NU` is the number of *free* decisions per stage, `NW − NE`:
//! for a variational transcription the `NE = NS` momentum-matching rows eliminate the
//! velocities, leaving the system's inputs.
//!
//! # Example
//!
//! A differential-drive robot (shape: the two wheel angles, inputs: their torques) driven
//! 1 m straight ahead in 2 s, rest to rest, with least squared torque:
//! ```
//! use dmech::{Discretisation, Lift, PrincipalKinematicSystem};
//! use dmech_lie::{Real, Se2};
//! use dmech_ocp::ipm::{IpOptions, Solver, Status};
//! use dmech_ocp::transcription::*;
//! use nalgebra::{SMatrix, SVector};
//!
//! struct DiffDrive; // mass 1 kg, wheel radius 0.05 m, half-track 0.1 m
//! impl PrincipalKinematicSystem<3, 2, 2, 2> for DiffDrive {
//!     type Param = f64;
//!     type Group<T: Real> = Se2<T>;
//!     fn reduced_lagrangian<T: Lift<f64>>(
//!         &self, _s: &SVector<T, 2>, v: &SVector<T, 2>, xi: &SVector<T, 3>,
//!     ) -> T {
//!         (xi.dot(xi) + v.dot(v) * 1e-3) * 0.5
//!     }
//!     fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
//!         // ξ = −A v: forward r(φ̇R + φ̇L)/2, yaw r(φ̇R − φ̇L)/(2d).
//!         let (half_r, yaw, z) = (T::from(0.025), T::from(0.25), T::zero());
//!         SMatrix::<T, 3, 2>::new(-half_r, -half_r, z, z, -yaw, yaw)
//!     }
//!     fn forcing<T: Lift<f64>>(
//!         &self, _s: &SVector<T, 2>, _v: &SVector<T, 2>, u: &SVector<T, 2>,
//!     ) -> SVector<T, 2> {
//!         *u
//!     }
//! }
//!
//! struct Forward { n: usize }
//! impl PlanningProblem<3, 2, 2, 0> for Forward {
//!     fn horizon(&self) -> usize { self.n }
//!     fn start(&self) -> StartState<3, 2, 2> {
//!         StartState::at_rest(SVector::zeros(), SVector::zeros())
//!     }
//!     fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, 2, 2>) -> T {
//!         stage.input.dot(&stage.input) * 0.5
//!     }
//!     fn constraints<T: Real>(&self, _k: usize, _: &Stage<T, 3, 2, 2>) -> SVector<T, 0> {
//!         SVector::zeros()
//!     }
//!     fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
//!         (SVector::zeros(), SVector::zeros())
//!     }
//!     fn conditions(&self) -> Vec<Condition> {
//!         let end = |quantity, value| Condition { stage: self.n, quantity, value };
//!         vec![
//!             end(Quantity::Pose(0), 1.0), end(Quantity::Pose(1), 0.0), end(Quantity::Pose(2), 0.0),
//!             end(Quantity::Velocity(0), 0.0), end(Quantity::Velocity(1), 0.0),
//!         ]
//!     }
//! }
//!
//! let (n, h) = (100, 0.02);
//! let p = VarIntTranscription::<_, _, 3, 2, 3, 2>::new::<2>(
//!     &DiffDrive, Forward { n }, h, Discretisation::FirstOrder,
//! );
//! // NX = 3 + 2·2 + 2 = 9, NW = 2 + 2 = 4, NE = 2, free inputs NW − NE = 2, NC = 0.
//! let solver: Solver<_, 9, 4, 2, 2, 0> =
//!     Solver::new(&p, IpOptions { verbose: false, ..Default::default() });
//! // Any start: `initial_iterate` puts the problem's start state into x_0.
//! let r = solver.solve(solver.initial_iterate(vec![SVector::zeros(); n + 1], vec![SVector::zeros(); n]));
//! assert_eq!(r.status, Status::Solved);
//! let plan = p.trajectory::<2, 9, 4, 0>(&r.iterate);
//! assert!((plan.stages[n].pose[0] - 1.0).abs() < 1e-8);
//! ```

use crate::derivatives::{
    block_hessian, cost_and_inequalities, generic_constraint_curvature, generic_cost_curvature,
    HessianBlocks, StageScalar,
};
use crate::ipm::Iterate;
use crate::layout::{segment, Layout};
use crate::problem::{StageProblem, StateEquality};
use crate::runge_kutta::RkStages;
use crate::varint::VarIntStages;
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem, RungeKutta};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use std::marker::PhantomData;

/// What a robot's cost and constraints read at stage `k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage<T, const NP: usize, const NS: usize, const NU: usize> {
    /// `coords(g_k)`: the pose's coordinates (SE(2): `x, y, θ`).
    pub pose: SVector<T, NP>,
    /// `s_k`.
    pub shape: SVector<T, NS>,
    /// The shape velocity leaving stage `k`: `v_k` on `[t_k, t_{k+1})` (variational) or
    /// `v(t_k)` (Runge–Kutta).
    pub velocity: SVector<T, NS>,
    /// `u_k`, held on `[t_k, t_{k+1})`.
    pub input: SVector<T, NU>,
    /// `u_{k−1}` (zero before the start), for rate limits.
    pub previous_input: SVector<T, NU>,
}

/// The state a plan starts from.
#[derive(Clone, Debug, PartialEq)]
pub struct StartState<const NP: usize, const NS: usize, const NU: usize> {
    pub pose: SVector<f64, NP>,
    pub shape: SVector<f64, NS>,
    /// The velocity the robot has arrived with (zero: at rest).
    pub velocity: SVector<f64, NS>,
    /// The input before the start.
    pub previous_input: SVector<f64, NU>,
}

impl<const NP: usize, const NS: usize, const NU: usize> StartState<NP, NS, NU> {
    /// At rest at `pose` and `shape`, no input before the start.
    pub fn at_rest(pose: SVector<f64, NP>, shape: SVector<f64, NS>) -> Self {
        StartState {
            pose,
            shape,
            velocity: SVector::zeros(),
            previous_input: SVector::zeros(),
        }
    }
}

/// A plan read back in the robot's terms, whatever the transcription: stage `k = 0..=N`
/// holds the pose, the shape, the velocity leaving it, the input held from it and the
/// previous input. At `k = N` the velocity is the one the robot arrives with and the input
/// repeats `u_{N−1}`.
#[derive(Clone, Debug)]
pub struct PlannedTrajectory<const NP: usize, const NS: usize, const NU: usize> {
    pub h: f64,
    pub stages: Vec<Stage<f64, NP, NS, NU>>,
}

/// A state component a [`Condition`] fixes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Quantity {
    /// Pose coordinate `i`.
    Pose(usize),
    /// Shape component `i`.
    Shape(usize),
    /// Velocity component `i` *arriving* at the stage: `v_{k−1}` (variational) or `v(t_k)`
    /// (Runge–Kutta). `Velocity(i) = 0` at the last stage says "arrive at rest" in both.
    Velocity(usize),
    /// Component `i` of the input before the stage, `u_{k−1}`.
    PreviousInput(usize),
}

/// `quantity = value` at `stage` (`stage = N` is the end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Condition {
    pub stage: usize,
    pub quantity: Quantity,
    pub value: f64,
}

/// A robot's planning problem, in the terms of [`Stage`].
pub trait PlanningProblem<const NP: usize, const NS: usize, const NU: usize, const NC: usize>:
    Sync
{
    /// The number of steps `N`.
    fn horizon(&self) -> usize;
    /// The start state.
    fn start(&self) -> StartState<NP, NS, NU>;
    /// The running cost of stage `k` (`k < N`).
    fn cost<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>) -> T;
    /// The path constraints of stage `k`, bounded by [`PlanningProblem::bounds`].
    fn constraints<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>) -> SVector<T, NC>;
    /// `(lo, hi)`; infinite entries mean "no bound".
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>);
    /// Waypoints and the end state, any order.
    fn conditions(&self) -> Vec<Condition>;
    /// `true` if the cost and the constraints are affine in the pose, the shape and the
    /// previous input, and those multiply neither the velocity nor the input. A variational
    /// transcription then tells the solver its cost is affine in the state (which saves
    /// two of three second-order passes). The same must hold of
    /// [`PlanningProblem::cost_at_step`] and [`PlanningProblem::constraints_at_step`] at a
    /// fixed ratio (the free-timing curvature relies on it). Default `false`.
    fn affine_in_configuration(&self) -> bool {
        false
    }
    /// `true` if the cost is quadratic and the constraints affine in the stage's quantities
    /// (pose, shape, velocity, input, previous input). A transcription's stage vectors hold
    /// those quantities linearly, so the solver may compute the cost's curvature once per
    /// stage ([`StageProblem::constant_cost_curvature`]). Default `false`.
    fn quadratic_cost_affine_constraints(&self) -> bool {
        false
    }
    /// The running cost of stage `k` when its step is `ratio` times the nominal one (free
    /// timing, [`crate::free_timing`]). Default: `ratio · cost`, a cost per stage being the
    /// rectangle rule of a running cost over the step (the same at `ratio = 1`).
    fn cost_at_step<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>, ratio: T) -> T {
        self.cost(k, stage) * ratio
    }
    /// The path constraints of stage `k` at step ratio `ratio`. Default: the constraints
    /// (pointwise in time); a constraint on a difference quotient, such as a rate limit,
    /// overrides this to divide by the actual step.
    fn constraints_at_step<T: Real>(
        &self,
        k: usize,
        stage: &Stage<T, NP, NS, NU>,
        _ratio: T,
    ) -> SVector<T, NC> {
        self.constraints(k, stage)
    }
}

/// A problem borrowed: the transcription of a problem that lives elsewhere (one per mesh,
/// say).
impl<P, const NP: usize, const NS: usize, const NU: usize, const NC: usize>
    PlanningProblem<NP, NS, NU, NC> for &P
where
    P: PlanningProblem<NP, NS, NU, NC>,
{
    fn horizon(&self) -> usize {
        (**self).horizon()
    }
    fn start(&self) -> StartState<NP, NS, NU> {
        (**self).start()
    }
    fn cost<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>) -> T {
        (**self).cost(k, stage)
    }
    fn constraints<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>) -> SVector<T, NC> {
        (**self).constraints(k, stage)
    }
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        (**self).bounds(k)
    }
    fn conditions(&self) -> Vec<Condition> {
        (**self).conditions()
    }
    fn affine_in_configuration(&self) -> bool {
        (**self).affine_in_configuration()
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        (**self).quadratic_cost_affine_constraints()
    }
    fn cost_at_step<T: Real>(&self, k: usize, stage: &Stage<T, NP, NS, NU>, ratio: T) -> T {
        (**self).cost_at_step(k, stage, ratio)
    }
    fn constraints_at_step<T: Real>(
        &self,
        k: usize,
        stage: &Stage<T, NP, NS, NU>,
        ratio: T,
    ) -> SVector<T, NC> {
        (**self).constraints_at_step(k, stage, ratio)
    }
}

/// Where each quantity of a stage state sits in the solver's `x_k`: the same for every
/// transcription (`coords(g)`, `s`, the state's velocity, `u_{k−1}`).
pub fn state_index(layout: Layout, quantity: Quantity) -> usize {
    let (offset, i, n) = match quantity {
        Quantity::Pose(i) => (0, i, layout.nc),
        Quantity::Shape(i) => (layout.s_at(), i, layout.ns),
        Quantity::Velocity(i) => (layout.v_at(), i, layout.ns),
        Quantity::PreviousInput(i) => (layout.u_at(), i, layout.nu),
    };
    assert!(
        i < n,
        "{quantity:?} is out of range for the system ({n} components)"
    );
    offset + i
}

/// The conditions as the solver's state equalities, in the problem's order.
pub fn state_equalities(layout: Layout, conditions: &[Condition]) -> Vec<StateEquality> {
    conditions
        .iter()
        .map(|c| StateEquality {
            stage: c.stage,
            index: state_index(layout, c.quantity),
            value: c.value,
        })
        .collect()
}

/// `x_0` from the start state.
pub(crate) fn initial_state<const NP: usize, const NS: usize, const NU: usize, const NX: usize>(
    layout: Layout,
    start: &StartState<NP, NS, NU>,
) -> SVector<f64, NX> {
    let mut x = SVector::<f64, NX>::zeros();
    x.fixed_rows_mut::<NP>(0).copy_from(&start.pose);
    x.fixed_rows_mut::<NS>(layout.s_at())
        .copy_from(&start.shape);
    x.fixed_rows_mut::<NS>(layout.v_at())
        .copy_from(&start.velocity);
    x.fixed_rows_mut::<NU>(layout.u_at())
        .copy_from(&start.previous_input);
    x
}

/// A robot's problem on a variational integrator (first order or midpoint):
/// `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`, `w_k = (v_k, u_k)`, stage equality = the
/// momentum matching of node `k`.
pub struct VarIntTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const DIM: usize,
    const NP: usize,
    const NU: usize,
> {
    pub stages: VarIntStages<'a, S>,
    pub problem: P,
    _sizes: PhantomData<[(); DOF]>,
    _dim: PhantomData<[(); DIM]>,
}

impl<'a, S, P, const DOF: usize, const DIM: usize, const NP: usize, const NU: usize>
    VarIntTranscription<'a, S, P, DOF, DIM, NP, NU>
{
    /// `problem` on `sys` at step `h`, right-point forcing (the first-order scheme's
    /// default), with the given discretisation.
    pub fn new<const NS: usize>(
        sys: &'a S,
        problem: P,
        h: f64,
        discretisation: Discretisation,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let stages = VarIntStages::new::<DOF, DIM, NS, NU>(sys, h, ForcingQuadrature::Right)
            .with_discretisation(discretisation);
        assert_eq!(
            stages.layout.nc, NP,
            "NP must be the group's number of coordinates"
        );
        VarIntTranscription {
            stages,
            problem,
            _sizes: PhantomData,
            _dim: PhantomData,
        }
    }

    /// The typed view of `(x_k, w_k)`.
    pub fn stage<T: Real, const NS: usize, const NX: usize, const NW: usize>(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> Stage<T, NP, NS, NU> {
        let l = self.stages.layout;
        Stage {
            pose: segment(x, 0),
            shape: segment(x, l.s_at()),
            velocity: segment(w, 0),
            input: segment(w, NS),
            previous_input: segment(x, l.u_at()),
        }
    }

    /// The solver's iterate as a [`PlannedTrajectory`].
    pub fn trajectory<const NS: usize, const NX: usize, const NW: usize, const NC: usize>(
        &self,
        it: &Iterate<NX, NW, NC>,
    ) -> PlannedTrajectory<NP, NS, NU> {
        let n = it.w.len();
        let l = self.stages.layout;
        let mut stages: Vec<_> = (0..n)
            .map(|k| self.stage::<f64, NS, NX, NW>(&it.x[k], &it.w[k]))
            .collect();
        let x = &it.x[n];
        stages.push(Stage {
            pose: segment(x, 0),
            shape: segment(x, l.s_at()),
            velocity: segment(x, l.v_at()),
            input: segment(&it.w[n - 1], NS),
            previous_input: segment(x, l.u_at()),
        });
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
        const DIM: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
        const NC: usize,
    > StageProblem<NX, NW, NS, NC> for VarIntTranscription<'_, S, P, DOF, DIM, NP, NU>
where
    S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64> + Sync,
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
        self.stages.dynamics::<T, DOF, DIM, NS, NU, NX, NW>(x, w)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NS> {
        self.stages.equality::<T, DOF, DIM, NS, NU, NX, NW>(x, w)
    }
    fn equality_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>) {
        self.stages
            .equality_jacobian::<DOF, DIM, NS, NU, NX, NW>(x, w)
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
            .constraint_curvature::<DOF, DIM, NS, NU, NX, NW>(x, w, lambda, nu)
            .unwrap_or_else(|| {
                generic_constraint_curvature::<Self, NX, NW, NS, NC>(self, k, x, w, lambda, nu)
            })
    }
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        self.problem.cost(k, &self.stage::<T, NS, NX, NW>(x, w))
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NC> {
        self.problem
            .constraints(k, &self.stage::<T, NS, NX, NW>(x, w))
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

/// A robot's problem on an explicit Runge–Kutta step of the continuous model:
/// `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`, no stage equality.
pub struct RkTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const DIM: usize,
    const NP: usize,
    const NS: usize,
> {
    pub stages: RkStages<'a, S>,
    pub problem: P,
    _sizes: PhantomData<[(); DOF]>,
    _dim: PhantomData<[(); DIM]>,
}

impl<'a, S, P, const DOF: usize, const DIM: usize, const NP: usize, const NS: usize>
    RkTranscription<'a, S, P, DOF, DIM, NP, NS>
{
    pub fn new<const NU: usize>(sys: &'a S, problem: P, h: f64, method: RungeKutta) -> Self
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let stages = RkStages::new::<DOF, DIM, NS, NU>(sys, h, method);
        assert_eq!(
            stages.layout.nc, NP,
            "NP must be the group's number of coordinates"
        );
        RkTranscription {
            stages,
            problem,
            _sizes: PhantomData,
            _dim: PhantomData,
        }
    }

    /// The typed view of `(x_k, w_k = u_k)`.
    pub fn stage<T: Real, const NU: usize, const NX: usize>(
        &self,
        x: &SVector<T, NX>,
        u: &SVector<T, NU>,
    ) -> Stage<T, NP, NS, NU> {
        let l = self.stages.layout;
        Stage {
            pose: segment(x, 0),
            shape: segment(x, l.s_at()),
            velocity: segment(x, l.v_at()),
            input: *u,
            previous_input: segment(x, l.u_at()),
        }
    }

    /// The solver's iterate as a [`PlannedTrajectory`].
    pub fn trajectory<const NU: usize, const NX: usize, const NC: usize>(
        &self,
        it: &Iterate<NX, NU, NC>,
    ) -> PlannedTrajectory<NP, NS, NU> {
        let n = it.w.len();
        let stages = (0..=n)
            .map(|k| self.stage::<f64, NU, NX>(&it.x[k], &it.w[k.min(n - 1)]))
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
        const DIM: usize,
        const NP: usize,
        const NS: usize,
        const NX: usize,
        const NU: usize,
        const NC: usize,
    > StageProblem<NX, NU, 0, NC> for RkTranscription<'_, S, P, DOF, DIM, NP, NS>
where
    S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64> + Sync,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    fn horizon(&self) -> usize {
        self.stages.layout.check(NX, NU, NU);
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
        self.stages.dynamics::<T, DOF, DIM, NS, NU, NX, NU>(x, u)
    }
    fn dynamics_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        u: &SVector<f64, NU>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>) {
        self.stages
            .dynamics_jacobian::<DOF, DIM, NS, NU, NX, NU>(x, u)
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
        self.problem.cost(k, &self.stage::<T, NU, NX>(x, u))
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NC> {
        self.problem.constraints(k, &self.stage::<T, NU, NX>(x, u))
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
            return generic_cost_curvature::<Self, NX, NU, 0, NC>(self, k, x, u, cost_scale, zeta);
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
    P: StageProblem<NX, NU, 0, NC>,
{
    fn eval<T: Real>(&self, v: &SVector<T, NS>, u: &SVector<T, NU>) -> T {
        let mut x = self.x.map(T::from);
        x.fixed_rows_mut::<NS>(self.v_at).copy_from(v);
        cost_and_inequalities::<P, T, NX, NU, 0, NC>(
            self.problem,
            self.k,
            self.cost_scale,
            self.zeta,
            &x,
            u,
        )
    }
}
