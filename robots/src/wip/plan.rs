//! The WIP's energy-optimal planning problem (paper eq. (opt), `docs/problems.md`) declared
//! for the generic solver of `dmech-ocp`: cost, bounds, waypoints, boundary states, and a
//! start along the waypoint polyline.
//!
//! Two models ([`PlanModel`]): the full WIP (`NS = 5`, shape `(α, φR, φL, qR, qL)`, the
//! currents are shape velocities) and the algebraic-current WIP (`NS = 3`, the currents
//! follow from `v` and `u`). Stage layout of both transcriptions, `NX = 2 NS + 5`:
//! `x = (x, y, θ, s(NS), v(NS), u_prev(2))`, where `v` is `v_{k−1}` for the variational
//! integrator and `v_k` for Runge–Kutta. The VI decides `w = (v_k, u_k)`, RK decides
//! `w = u_k`.

use super::algebraic_current::WipAlgebraicCurrent;
use super::benchmarks::PlanProblem;
pub use super::plan_free_timing::{plan_free_timing, FreeTimingOutcome, FREE_TIMING_RATIOS};
use super::plan_sequence::{friction_continuation, varint_solve};
pub use super::plan_start::{polyline_start, rk_start, varint_start};
use super::simulate::Integrator;
use super::Wip;
use dmech::{Discretisation, PrincipalKinematicSystem, RungeKutta};
use dmech_lie::Real;
use dmech_ocp::ipm::{IpOptions, SolveResult};
use dmech_ocp::sequencing::{continuation, direct_or_continuation};
use dmech_ocp::transcription::{
    Condition, PlannedTrajectory as GenericTrajectory, PlanningProblem, Quantity, RkTranscription,
    Stage, StartState, VarIntTranscription,
};
use nalgebra::SVector;

/// Stage state size of the full model (`NS = 5`).
pub const NX: usize = 15;
/// Stage state size of the algebraic-current model (`NS = 3`).
pub const NX_ALGEBRAIC: usize = 11;
/// Inequalities per stage: uR, uL, the rates (uR_k − uR_{k−1})/h and (uL_k − uL_{k−1})/h, iR, iL, α, v_θ.
pub const NC: usize = 8;

/// `d_0` of the first (smoothed-friction) phase, s/rad.
pub const SMOOTH_FRICTION_SLOPE: f64 = 1.0;

/// A WIP model the planner transcribes: what differs between the current models.
pub trait PlanModel<const NS: usize>:
    PrincipalKinematicSystem<3, 2, NS, 2, Param = f64> + Clone + PartialEq + Sync
{
    /// Whether the currents are states with their (stiff) dynamics; if not, the outcome
    /// reconstructs currents and charges from `currents`.
    const CURRENT_DYNAMICS: bool;
    /// The mechanics and parameters shared by all models.
    fn wip(&self) -> &Wip;
    fn wip_mut(&mut self) -> &mut Wip;
    /// The currents `(iR, iL)` at shape velocity `v_k` and voltages `u_k`.
    fn currents<T: Real>(&self, v: &SVector<T, NS>, u: &SVector<T, 2>) -> [T; 2];
    /// A shape velocity with whatever the model holds of the currents set to their steady
    /// state for `u = 0` (the starts' velocities come from kinematics alone).
    fn settle_currents(&self, v: &mut SVector<f64, NS>);
}

impl PlanModel<5> for Wip {
    const CURRENT_DYNAMICS: bool = true;
    fn wip(&self) -> &Wip {
        self
    }
    fn wip_mut(&mut self) -> &mut Wip {
        self
    }
    fn currents<T: Real>(&self, v: &SVector<T, 5>, _u: &SVector<T, 2>) -> [T; 2] {
        [v[3], v[4]]
    }
    fn settle_currents(&self, v: &mut SVector<f64, 5>) {
        let q = &self.params;
        v[3] = q.steady_current(0.0, v[1] - v[0]);
        v[4] = q.steady_current(0.0, v[2] - v[0]);
    }
}

impl PlanModel<3> for WipAlgebraicCurrent {
    const CURRENT_DYNAMICS: bool = false;
    fn wip(&self) -> &Wip {
        &self.wip
    }
    fn wip_mut(&mut self) -> &mut Wip {
        &mut self.wip
    }
    fn currents<T: Real>(&self, v: &SVector<T, 3>, u: &SVector<T, 2>) -> [T; 2] {
        WipAlgebraicCurrent::currents(self, v, u)
    }
    fn settle_currents(&self, _v: &mut SVector<f64, 3>) {}
}

/// The bounds of docs/problems.md.
#[derive(Clone, Copy, Debug)]
pub struct PlanBounds {
    pub u_max: f64,
    /// Voltage rate limit in V/s (the bound on `|u_k − u_{k−1}|` is `h` times it).
    pub du_max_per_s: f64,
    pub i_max: f64,
    pub alpha_max: f64,
    pub v_theta_max: f64,
}

impl Default for PlanBounds {
    fn default() -> Self {
        PlanBounds {
            u_max: 5.0,
            du_max_per_s: 2.0,
            i_max: 3.0,
            alpha_max: 15f64.to_radians(),
            v_theta_max: 120f64.to_radians(),
        }
    }
}

/// What is common to both transcriptions.
pub struct WipPlan<'a, M> {
    pub model: &'a M,
    pub problem: &'a PlanProblem,
    pub bounds: PlanBounds,
}

impl<M> WipPlan<'_, M> {
    fn bounds_vec(&self) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let b = &self.bounds;
        let hi = SVector::<f64, NC>::from_column_slice(&[
            b.u_max,
            b.u_max,
            b.du_max_per_s,
            b.du_max_per_s,
            b.i_max,
            b.i_max,
            b.alpha_max,
            b.v_theta_max,
        ]);
        (-hi, hi)
    }

    /// Waypoint positions at their stages; at the end the full pose, `α = 0` and the
    /// arriving shape velocity zero (velocities and, in the full model, currents).
    fn conditions<const NS: usize>(&self) -> Vec<Condition> {
        let p = self.problem;
        let mut conds = Vec::new();
        for (pt, &k) in p.points.iter().zip(&p.stages) {
            if k == 0 || k == p.n {
                continue;
            }
            for (i, &value) in pt.iter().enumerate() {
                conds.push(Condition {
                    stage: k,
                    quantity: Quantity::Pose(i),
                    value,
                });
            }
        }
        let end = p.points.last().expect("at least two points");
        let mut fix = |quantity, value| {
            conds.push(Condition {
                stage: p.n,
                quantity,
                value,
            })
        };
        fix(Quantity::Pose(0), end[0]);
        fix(Quantity::Pose(1), end[1]);
        fix(Quantity::Pose(2), p.end_heading);
        fix(Quantity::Shape(0), 0.0);
        for i in 0..NS {
            fix(Quantity::Velocity(i), 0.0);
        }
        conds
    }
}

impl<M> WipPlan<'_, M> {
    /// `v_θ` from the wheel rates.
    fn heading_rate<T: Real, const NS: usize>(&self, vr: T, vl: T) -> T
    where
        M: PlanModel<NS>,
    {
        let p = &self.model.wip().params;
        (vr - vl) * (p.r / (2.0 * p.d))
    }

    /// The inequalities at shape velocity `v`, tilt `alpha`, voltages `u` after `u_prev`.
    fn constraints<T: Real, const NS: usize>(
        &self,
        v: &SVector<T, NS>,
        alpha: T,
        u: &SVector<T, 2>,
        u_prev: [T; 2],
    ) -> SVector<T, NC>
    where
        M: PlanModel<NS>,
    {
        let [ir, il] = self.model.currents(v, u);
        // The rate limit as a rate, `(u_k − u_{k−1})/h ≤ 2 V/s`: the bound as a difference,
        // `2h`, shrinks with the step (0.0025 V at 1.25 ms) and the barrier, on the scale
        // of the other bounds, then holds these constraints far inside it.
        let rate = 1.0 / self.problem.h;
        SVector::<T, NC>::from_column_slice(&[
            u[0],
            u[1],
            (u[0] - u_prev[0]) * rate,
            (u[1] - u_prev[1]) * rate,
            ir,
            il,
            alpha,
            self.heading_rate::<T, NS>(v[1], v[2]),
        ])
    }

    /// The running cost `½ (uR iR + uL iL)`.
    fn cost<T: Real, const NS: usize>(&self, v: &SVector<T, NS>, u: &SVector<T, 2>) -> T
    where
        M: PlanModel<NS>,
    {
        let [ir, il] = self.model.currents(v, u);
        (u[0] * ir + u[1] * il) * 0.5
    }
}

/// The WIP's problem in the toolkit's terms: cost and inequalities read the stage's
/// velocity, tilt, inputs and previous inputs; waypoints and the end state are conditions.
impl<M: PlanModel<NS>, const NS: usize> PlanningProblem<3, NS, 2, NC> for WipPlan<'_, M> {
    fn horizon(&self) -> usize {
        self.problem.n
    }
    fn start(&self) -> StartState<3, NS, 2> {
        let p = self.problem;
        StartState::at_rest(
            SVector::<f64, 3>::new(p.points[0][0], p.points[0][1], p.start_heading),
            SVector::zeros(),
        )
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, 2>) -> T {
        self.cost(&stage.velocity, &stage.input)
    }
    fn constraints<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, 2>) -> SVector<T, NC> {
        let u_prev = [stage.previous_input[0], stage.previous_input[1]];
        self.constraints(&stage.velocity, stage.shape[0], &stage.input, u_prev)
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.bounds_vec()
    }
    fn conditions(&self) -> Vec<Condition> {
        self.conditions::<NS>()
    }
    fn affine_in_configuration(&self) -> bool {
        // The cost reads velocity and input only; the inequalities read α and u_{k−1}
        // linearly.
        true
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        // The cost `½ u·i` with currents linear in (v, u) (the charges' rates, or the
        // steady currents `(u − k_e n ω)/R`); voltages, rates, currents, tilt and heading
        // rate are linear.
        true
    }
    /// The rate limit divides by the stage's actual step; the cost is the default's
    /// `ratio · cost` (the energy of the stage at its step, in units of the nominal one).
    fn constraints_at_step<T: Real>(
        &self,
        k: usize,
        stage: &Stage<T, 3, NS, 2>,
        ratio: T,
    ) -> SVector<T, NC> {
        let mut c = PlanningProblem::constraints(self, k, stage);
        c[2] /= ratio;
        c[3] /= ratio;
        c
    }
}

/// The WIP on a variational integrator (first order or midpoint).
pub type VarIntPlan<'a, M> = VarIntTranscription<'a, M, WipPlan<'a, M>, 3, 2, 3, 2>;

/// The WIP on a Runge–Kutta step.
pub type RkPlan<'a, M, const NS: usize> = RkTranscription<'a, M, WipPlan<'a, M>, 3, 2, 3, NS>;

/// The first-order VI plan of `problem` for `model` (the paper's transcription).
pub fn varint_plan<'a, M: PlanModel<NS>, const NS: usize>(
    model: &'a M,
    problem: &'a PlanProblem,
    bounds: PlanBounds,
    discretisation: Discretisation,
) -> VarIntPlan<'a, M> {
    let plan = WipPlan {
        model,
        problem,
        bounds,
    };
    VarIntTranscription::new::<NS>(model, plan, problem.h, discretisation)
}

/// The RK plan of `problem` for `model`.
pub fn rk_plan<'a, M: PlanModel<NS>, const NS: usize>(
    model: &'a M,
    problem: &'a PlanProblem,
    bounds: PlanBounds,
    rk: RungeKutta,
) -> RkPlan<'a, M, NS> {
    let plan = WipPlan {
        model,
        problem,
        bounds,
    };
    RkTranscription::new::<2>(model, plan, problem.h, rk)
}

/// The planned trajectory in a transcription-independent form, per stage `k = 0..=N`:
/// `(g, s, v_k, u_k)` with `v_N = 0` and `u_N = u_{N−1}`.
#[derive(Clone, Debug)]
pub struct PlannedTrajectory {
    pub h: f64,
    pub g: Vec<SVector<f64, 3>>,
    pub s: Vec<SVector<f64, 5>>,
    pub v: Vec<SVector<f64, 5>>,
    pub u: Vec<SVector<f64, 2>>,
}

/// Which transcription a plan uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transcription {
    /// The variational integrator: the paper's first-order scheme or the midpoint one.
    VarInt(Discretisation),
    Rk(RungeKutta),
}

/// The same names as the simulator's integrators (`varint`, `midpoint`, `rk1`, `rk2`, `rk4`).
impl std::str::FromStr for Transcription {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s.parse::<Integrator>()? {
            Integrator::VarInt { discretisation, .. } => Transcription::VarInt(discretisation),
            Integrator::Rk(rk) => Transcription::Rk(rk),
        })
    }
}

/// The current model of a plan: the motor circuit's dynamics (`L_m i̇ = u − R_m i − k_e n_wm w`,
/// the full model) or its steady state ([`WipAlgebraicCurrent`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurrentModel {
    Dynamic,
    Algebraic,
}

impl CurrentModel {
    pub fn name(self) -> &'static str {
        match self {
            CurrentModel::Dynamic => "dynamic",
            CurrentModel::Algebraic => "algebraic",
        }
    }
}

impl std::str::FromStr for CurrentModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "dynamic" => Ok(CurrentModel::Dynamic),
            "algebraic" => Ok(CurrentModel::Algebraic),
            other => Err(format!(
                "unknown current model '{other}' (expected dynamic or algebraic)"
            )),
        }
    }
}

/// A finished solve, transcription-independent.
pub struct PlanOutcome {
    pub status: dmech_ocp::ipm::Status,
    pub iterations: usize,
    pub objective: f64,
    pub max_violation: f64,
    pub timings: dmech_ocp::ipm::Timings,
    pub trajectory: PlannedTrajectory,
    /// The stage times of a plan with free timing (`None`: `k h`).
    pub times: Option<Vec<f64>>,
}

/// The solution in the full model's terms: the algebraic-current model's currents from
/// [`PlanModel::currents`], its charges `q_{k+1} = q_k + h i_k`.
pub(super) fn outcome<M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>(
    model: &M,
    r: SolveResult<NX, NW, NC>,
    plan: GenericTrajectory<3, NS, 2>,
    at_rest_exactly: bool,
) -> PlanOutcome {
    let (h, n) = (plan.h, plan.stages.len() - 1);
    let mut t = PlannedTrajectory {
        h,
        g: Vec::with_capacity(n + 1),
        s: Vec::with_capacity(n + 1),
        v: Vec::with_capacity(n + 1),
        u: Vec::with_capacity(n + 1),
    };
    let mut charges = [0.0; 2];
    for (k, stage) in plan.stages.iter().enumerate() {
        t.g.push(stage.pose);
        // The variational plans arrive at rest by a condition that holds to the solver's
        // tolerance; their last row says so exactly.
        let v = if k == n && at_rest_exactly {
            SVector::zeros()
        } else {
            stage.velocity
        };
        let u = stage.input;
        let (mut s5, mut v5) = (SVector::<f64, 5>::zeros(), SVector::<f64, 5>::zeros());
        s5.fixed_rows_mut::<NS>(0).copy_from(&stage.shape);
        v5.fixed_rows_mut::<NS>(0).copy_from(&v);
        if !M::CURRENT_DYNAMICS {
            let i = if k < n {
                model.currents(&v, &u)
            } else {
                [0.0; 2]
            };
            (s5[3], s5[4]) = (charges[0], charges[1]);
            (v5[3], v5[4]) = (i[0], i[1]);
            charges = [charges[0] + h * i[0], charges[1] + h * i[1]];
        }
        t.s.push(s5);
        t.v.push(v5);
        t.u.push(u);
    }
    PlanOutcome {
        status: r.status,
        iterations: r.iterations,
        objective: r.objective,
        max_violation: r.max_violation,
        timings: r.timings,
        trajectory: t,
        times: None,
    }
}

/// Plan with the given transcription and current model from the polyline start.
///
/// VI plans run by mesh sequencing ([`dmech_ocp::sequencing::mesh_sequence`]): the coarsest mesh, and an RK plan,
/// are solved in two phases: the problem with a gentler Coulomb friction (`d_0 = 1 s/rad` instead of 8:
/// same saturated torque, 8× smaller slope at zero relative wheel speed) from the
/// polyline start; then the true problem, warm-started from that solution with a small
/// barrier parameter. The `tanh` of the Coulomb friction has slope `d_c d_0` at zero wheel
/// speed and saturates within ~0.3 rad/s: Newton steps from a start at rest or with wrong
/// wheel speeds overshoot it by orders of magnitude and the line search stalls. Switching
/// the Coulomb friction off entirely in phase one (tried) leaves phase two too far to go:
/// it is 60 % of the optimal energy.
pub fn plan(
    wip: &Wip,
    problem: &PlanProblem,
    bounds: PlanBounds,
    transcription: Transcription,
    current: CurrentModel,
    opts: IpOptions,
) -> PlanOutcome {
    match current {
        CurrentModel::Dynamic => {
            plan_model::<Wip, 5, NX, 7>(wip, problem, bounds, transcription, opts)
        }
        CurrentModel::Algebraic => plan_model::<_, 3, NX_ALGEBRAIC, 5>(
            &WipAlgebraicCurrent::new(*wip),
            problem,
            bounds,
            transcription,
            opts,
        ),
    }
}

/// [`plan`] for one model; `NW = NS + 2` is the VI's decision size.
fn plan_model<M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>(
    model: &M,
    problem: &PlanProblem,
    bounds: PlanBounds,
    transcription: Transcription,
    opts: IpOptions,
) -> PlanOutcome {
    let stiff_explicit = matches!(transcription, Transcription::Rk(RungeKutta::Rk4));
    let models = friction_continuation(model, stiff_explicit && M::CURRENT_DYNAMICS);
    match transcription {
        Transcription::VarInt(disc) => {
            let r = varint_solve::<M, NS, NX, NW>(model, models, problem, bounds, disc, opts);
            let traj = varint_plan::<M, NS>(model, problem, bounds, disc)
                .trajectory::<NS, NX, NW, NC>(&r.iterate);
            outcome::<M, NS, NX, NW>(model, r, traj, true)
        }
        Transcription::Rk(rk) => {
            let (xs, ws) = rk_start::<M, NS, NX>(model, problem);
            let plans: Vec<_> = models
                .iter()
                .map(|m| rk_plan::<M, NS>(m, problem, bounds, rk))
                .collect();
            // RK1 and RK2 solve the model's own friction directly: on the eight and the
            // zigzag, with either current model, it takes 31–65 iterations against 40–63
            // through the continuation (7 of 8 plans faster, `docs/ocp.md`); the
            // continuation stays their fallback. RK4 goes through it (from the direct start
            // its zigzag did not finish in 300 s). The continuation restarts each phase at
            // `10 μ_end` of the last: the switch to the steep friction moves the optimum
            // where the voltage-rate limits are active, and slacks within `μ` of them let
            // the fraction-to-the-boundary rule cut the steps (docs/ocp.md).
            let r = if stiff_explicit {
                continuation::<_, NX, 2, 0, 2, NC>(&plans, xs, ws, opts)
            } else {
                direct_or_continuation::<_, NX, 2, 0, 2, NC>(&plans, xs, ws, opts)
            };
            let own = plans.last().expect("the model's own plan is last");
            let traj = own.trajectory::<2, NX, NC>(&r.iterate);
            outcome::<M, NS, NX, 2>(model, r, traj, false)
        }
    }
}
