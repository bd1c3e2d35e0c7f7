//! Planning the WIP (`wip plan`): the transcription and current model chosen, the
//! friction continuation or mesh sequencing run, and the outcome (trajectory, currents,
//! status). The problem itself is declared in `plan_problem.rs`, its starts in
//! `plan_start.rs`, the mesh sequencing in `plan_sequence.rs`, free timing in
//! `plan_free_timing.rs`.

pub mod free_timing;
mod problem;
pub mod problems;
pub mod report;
pub mod request;
mod sequence;
pub mod start;

use crate::wip::algebraic_current::WipAlgebraicCurrent;
pub use crate::wip::plan::problem::{
    rk_plan, varint_layout, varint_plan, PlanBounds, PlanModel, RkPlan, VarIntPlan, WipPlan, NC,
    NX, NX_ALGEBRAIC, NX_VI, NX_VI_ALGEBRAIC, SMOOTH_FRICTION_SLOPE,
};
use crate::wip::plan::problems::PlanProblem;
use crate::wip::plan::sequence::{friction_continuation, varint_solve};
pub use crate::wip::plan::start::{polyline_start, rk_start, varint_start};
use crate::wip::Wip;
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, SolveResult};
use dmech_ocp::toolkit::sequencing::{continuation, direct_or_continuation};
use dmech_ocp::transcription::PlannedTrajectory as GenericTrajectory;
use nalgebra::SVector;

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

/// A name that is not a [`CurrentModel`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown current model '{0}' (expected dynamic or algebraic)")]
pub struct UnknownCurrentModel(pub String);

impl std::str::FromStr for CurrentModel {
    type Err = UnknownCurrentModel;
    fn from_str(s: &str) -> Result<Self, UnknownCurrentModel> {
        match s {
            "dynamic" => Ok(CurrentModel::Dynamic),
            "algebraic" => Ok(CurrentModel::Algebraic),
            other => Err(UnknownCurrentModel(other.to_string())),
        }
    }
}

/// A finished solve, transcription-independent.
pub struct PlanOutcome {
    /// How the last solve ended.
    pub status: dmech_ocp::solver::Status,
    /// Iterations over every mesh and phase.
    pub iterations: usize,
    /// The objective `J` of the returned plan.
    pub objective: f64,
    /// The largest violation of any constraint, measured on the returned plan.
    pub max_violation: f64,
    /// The solver's duality gap at the returned plan (`SolveResult::duality_gap`): how far
    /// above its optimum `J` may lie, to first order.
    pub duality_gap: f64,
    /// Where the time went.
    pub timings: dmech_ocp::solver::Timings,
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
        duality_gap: r.duality_gap,
        timings: r.timings,
        trajectory: t,
        times: None,
    }
}

/// Plan with the given transcription and current model from the polyline start.
///
/// VI plans run by mesh sequencing ([`dmech_ocp::toolkit::sequencing::mesh_sequence`]): the coarsest mesh, and an RK plan,
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
    integrator: Integrator,
    current: CurrentModel,
    opts: IpOptions,
) -> PlanOutcome {
    match current {
        CurrentModel::Dynamic => {
            plan_model::<Wip, 5, NX, NX_VI, 7>(wip, problem, bounds, integrator, opts)
        }
        CurrentModel::Algebraic => plan_model::<_, 3, NX_ALGEBRAIC, NX_VI_ALGEBRAIC, 5>(
            &WipAlgebraicCurrent::new(*wip),
            problem,
            bounds,
            integrator,
            opts,
        ),
    }
}

/// [`plan`] for one model; `NX` is the RK state size, `NXV` the VI's (without the
/// ignorable shape positions), `NW = NS + 2` the VI's decision size.
fn plan_model<
    M: PlanModel<NS>,
    const NS: usize,
    const NX: usize,
    const NXV: usize,
    const NW: usize,
>(
    model: &M,
    problem: &PlanProblem,
    bounds: PlanBounds,
    integrator: Integrator,
    opts: IpOptions,
) -> PlanOutcome {
    let stiff_explicit = integrator == Integrator::Rk4;
    let models = friction_continuation(model, stiff_explicit && M::CURRENT_DYNAMICS);
    match (integrator.variational(), integrator.runge_kutta()) {
        (Some(disc), _) => {
            let r = varint_solve::<M, NS, NXV, NW>(model, models, problem, bounds, disc, opts);
            let traj =
                varint_plan::<M, NS, NXV, NW>(model, problem, bounds, disc).trajectory(&r.iterate);
            outcome::<M, NS, NXV, NW>(model, r, traj, true)
        }
        (None, rk) => {
            let rk = rk.expect("a scheme is variational or Runge–Kutta");
            let (xs, ws) = rk_start::<M, NS, NX>(model, problem);
            let plans: Vec<_> = models
                .iter()
                .map(|m| rk_plan::<M, NS, NX>(m, problem, bounds, rk))
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
            let traj = own.trajectory(&r.iterate);
            outcome::<M, NS, NX, 2>(model, r, traj, false)
        }
    }
}
