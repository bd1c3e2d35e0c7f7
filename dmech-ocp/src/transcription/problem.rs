//! The planning problem's vocabulary: a [`Stage`]'s named parts, the start, the planned
//! trajectory, [`Condition`]s and the [`PlanningProblem`] trait a robot implements; where a
//! quantity sits in a transcription's state.

use crate::nlp::StateEquality;
use crate::transcription::layout::Layout;
use dmech_lie::Real;
use nalgebra::SVector;

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
    /// `coords(g_0)`.
    pub pose: SVector<f64, NP>,
    /// `s_0`.
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
/// previous input. At `k = N` the velocity is the one the robot arrives with (the midpoint
/// scheme's: `v(t_N)` by the discrete Legendre transform at the last node,
/// `dmech::VariationalIntegrator::node_velocity`; the first-order scheme's: `v_{N−1}`) and
/// the input repeats `u_{N−1}`.
#[derive(Clone, Debug)]
pub struct PlannedTrajectory<const NP: usize, const NS: usize, const NU: usize> {
    /// The step.
    pub h: f64,
    /// Stages `0 … N`.
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
    /// (Runge–Kutta). Every `Velocity(i) = 0` at the last stage says "arrive at rest": the
    /// robot stays there with zero input afterwards, in every transcription (under the
    /// midpoint scheme held by the momentum at the last node, [`conditions_for_scheme`]).
    Velocity(usize),
    /// Component `i` of the input before the stage, `u_{k−1}`.
    PreviousInput(usize),
}

/// `quantity = value` at `stage` (`stage = N` is the end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Condition {
    /// The stage (`N`: the end).
    pub stage: usize,
    /// What it fixes.
    pub quantity: Quantity,
    /// To what.
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
    /// stage ([`crate::nlp::StageProblem::constant_cost_curvature`]). Default `false`.
    fn quadratic_cost_affine_constraints(&self) -> bool {
        false
    }
    /// The running cost of stage `k` when its step is `ratio` times the nominal one (free
    /// timing, [`crate::transcription::free_timing`]). Default: `ratio · cost`, a cost per stage being the
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
    if let Quantity::Shape(i) = quantity {
        assert!(
            i < layout.ns,
            "{quantity:?} is out of range for the system ({} components)",
            layout.ns
        );
        return layout.shape_slot(i).unwrap_or_else(|| {
            panic!("{quantity:?} is ignored by the layout: no condition can hold it")
        });
    }
    let (offset, i, n) = match quantity {
        Quantity::Pose(i) => (0, i, layout.np),
        Quantity::Shape(_) => unreachable!("handled above"),
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

/// The conditions as a variational transcription holds them under one discretisation
/// ([`conditions_for_scheme`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SchemeConditions {
    /// The conditions held as state equalities.
    pub state: Vec<Condition>,
    /// Whether "arrive at rest" at the last stage is held by the midpoint scheme's terminal
    /// condition on the momentum (the transcription's terminal equalities) instead of by
    /// the velocity conditions there.
    pub rest_by_momentum: bool,
}

/// How a variational transcription holds `conditions` (horizon `n`, `ns` shape
/// coordinates) under `discretisation`: as they are, except under the midpoint scheme
/// when they fix every velocity to zero at the last stage ("arrive at rest"). Those `ns`
/// conditions then give way to the discrete Legendre transform at node `n`: the momentum
/// the last interval brings to the node, `½ h F_{n−½}` of its force included, is the
/// momentum of rest, so that the integrator's next step with zero input has `v_n = 0` as
/// its solution (`VarIntTranscription`'s terminal equalities: node `n`'s momentum
/// matching with `(v_n, u_n) = (0, 0)`). `v_{n−1}` and `u_{n−1}` stay free.
///
/// Why: the midpoint scheme's momentum matching at node `n` weighs the forces of the
/// intervals on both sides equally, `½ (F_{n−½} + F_{n+½})`, and its interval velocity
/// `v_{n−1}` is the motion at `t_{n−½}`. Fixing `v_{n−1} = 0` alone leaves half of the last
/// interval's impulse in the node's momentum, and the robot moves on after the plan (a
/// rolling disk 3.9 mm in 2 s at 20 ms); fixing `u_{n−1} = 0` as well holds it, but puts
/// the robot at rest a whole step early, an O(h) change that makes the plan's objective
/// converge at first order. The condition on the momentum is the rest the continuous
/// problem asks for at `t_n`, and keeps the scheme's second order (docs/ocp.md). The
/// first-order scheme's right-point force `F(s_n, v_n, u_n)` carries nothing of `u_{n−1}`
/// past the node and its `v_{n−1}` is the velocity arriving there; a Runge–Kutta state's
/// `v(t_N)` is the velocity itself: neither needs more.
pub fn conditions_for_scheme(
    conditions: Vec<Condition>,
    n: usize,
    ns: usize,
    discretisation: dmech::Discretisation,
) -> SchemeConditions {
    let rest_at_end = |c: &Condition| {
        c.stage == n && matches!(c.quantity, Quantity::Velocity(_)) && c.value == 0.0
    };
    let at_rest = (0..ns).all(|i| {
        conditions
            .iter()
            .any(|c| rest_at_end(c) && c.quantity == Quantity::Velocity(i))
    });
    if discretisation != dmech::Discretisation::Midpoint || !at_rest || ns == 0 {
        return SchemeConditions {
            state: conditions,
            rest_by_momentum: false,
        };
    }
    SchemeConditions {
        state: conditions.into_iter().filter(|c| !rest_at_end(c)).collect(),
        rest_by_momentum: true,
    }
}

/// `x_0` from the start state.
pub(crate) fn initial_state<const NP: usize, const NS: usize, const NU: usize, const NX: usize>(
    layout: Layout,
    start: &StartState<NP, NS, NU>,
) -> SVector<f64, NX> {
    state_vector(
        layout,
        &start.pose,
        &start.shape,
        &start.velocity,
        &start.previous_input,
    )
}

/// A stage state `x = (coords(g), the carried part of s, the state's velocity, u_{k−1})` in
/// `layout`, the same for both transcriptions.
pub(crate) fn state_vector<const NP: usize, const NS: usize, const NU: usize, const NX: usize>(
    layout: Layout,
    pose: &SVector<f64, NP>,
    shape: &SVector<f64, NS>,
    velocity: &SVector<f64, NS>,
    previous_input: &SVector<f64, NU>,
) -> SVector<f64, NX> {
    let mut x = SVector::<f64, NX>::zeros();
    x.fixed_rows_mut::<NP>(0).copy_from(pose);
    layout.set_shape(&mut x, shape);
    x.fixed_rows_mut::<NS>(layout.v_at()).copy_from(velocity);
    x.fixed_rows_mut::<NU>(layout.u_at())
        .copy_from(previous_input);
    x
}
