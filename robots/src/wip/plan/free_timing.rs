//! The WIP's plan with free waypoint timing (`wip plan … --free-timing`, `docs/ocp.md`,
//! "Free waypoint timing"): the fixed-timing plan, then from its solution the problem whose
//! segments between waypoints each choose their own step ([`dmech_ocp::transcription::free_timing`]).

use crate::wip::algebraic_current::WipAlgebraicCurrent;
use crate::wip::plan::problem::{varint_plan, PlanBounds, PlanModel, NC, NX, NX_ALGEBRAIC};
use crate::wip::plan::problems::PlanProblem;
use crate::wip::plan::sequence::{friction_continuation, varint_solve};
use crate::wip::plan::{outcome, CurrentModel, PlanOutcome};
use crate::wip::Wip;
use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Solver};
use dmech_ocp::transcription::free_timing::{
    FreeTiming, FreeTimingError, FreeTimingTranscription, TotalTime,
};

/// Bounds on each segment's step ratio `h_j / h` in a plan with free timing: within a
/// factor of two of the nominal step, so that the first-order integrator's error stays
/// within twice that of the fixed-timing plan.
pub const FREE_TIMING_RATIOS: (f64, f64) = (0.5, 2.0);

/// The barrier the free-timing solve starts at from the fixed plan's solution. At the
/// fixed optimum the bounds that will move (voltage rates, currents) are active; a small
/// barrier holds their slacks within it, and the fraction-to-the-boundary rule cut the
/// first steps to 1e-2. Measured (iterations of the free solve; zigzag and eight at
/// 20 ms): 1e-4: failed after 191 / –; 1e-3: 49 / 91; 1e-2: 32 / 44; 1e-1: 65 / –; at
/// 5 ms 1e-4 took 268 / 412, 1e-2 74 / 152.
const FREE_TIMING_BARRIER: f64 = 1e-2;

/// A plan with free waypoint timing, and the fixed-timing plan it started from.
pub struct FreeTimingOutcome {
    pub fixed: PlanOutcome,
    /// The free plan; its `objective` is the energy alone (the price of its duration, which
    /// the solver minimised with it, is `time_cost`).
    pub free: PlanOutcome,
    /// Each segment's step ratio `h_j / h`, between consecutive waypoints.
    pub ratios: Vec<f64>,
    /// `P T` for a total time priced at `P` per second (`TotalTime::Priced`), else 0.
    pub time_cost: f64,
}

/// The plan with free waypoint timing (the first-order VI): the fixed-timing plan by mesh
/// sequencing, then, from its solution, the problem whose segments between waypoints each
/// have their own step `h_j = σ_j h`, `σ_j` in [`FREE_TIMING_RATIOS`]
/// ([`dmech_ocp::transcription::free_timing`]), with the total time fixed (`Σ N_j σ_j = N`) or priced
/// (`total`). The fixed timing is a feasible point of the free problem, so its objective
/// (plus, when priced, the price of its duration) is an upper bound.
pub fn plan_free_timing(
    wip: &Wip,
    problem: &PlanProblem,
    bounds: PlanBounds,
    current: CurrentModel,
    total: TotalTime,
    opts: IpOptions,
) -> Result<FreeTimingOutcome, FreeTimingError> {
    match current {
        CurrentModel::Dynamic => free_model::<Wip, 5, NX, 7, 9>(wip, problem, bounds, total, opts),
        CurrentModel::Algebraic => free_model::<_, 3, NX_ALGEBRAIC, 5, 7>(
            &WipAlgebraicCurrent::new(*wip),
            problem,
            bounds,
            total,
            opts,
        ),
    }
}

/// [`plan_free_timing`] for one model: `NW0` the fixed-timing decision size, `NW = NW0 + 2`.
fn free_model<
    M: PlanModel<NS>,
    const NS: usize,
    const NX: usize,
    const NW0: usize,
    const NW: usize,
>(
    model: &M,
    problem: &PlanProblem,
    bounds: PlanBounds,
    total: TotalTime,
    opts: IpOptions,
) -> Result<FreeTimingOutcome, FreeTimingError> {
    let disc = Discretisation::FirstOrder;
    let models = friction_continuation(model, false);
    let r = varint_solve::<M, NS, NX, NW0>(model, models, problem, bounds, disc, opts.clone());
    let traj = varint_plan::<M, NS, NX, NW0>(model, problem, bounds, disc).trajectory(&r.iterate);
    let start = r.iterate.clone();
    let fixed = outcome::<M, NS, NX, NW0>(model, r, traj, true);
    let timing = FreeTiming {
        segment_starts: problem.stages[..problem.stages.len() - 1].to_vec(),
        ratio_bounds: FREE_TIMING_RATIOS,
        total,
    };
    let ft = FreeTimingTranscription::new(
        varint_plan::<M, NS, NX, NW0>(model, problem, bounds, disc),
        timing,
    )?;
    if opts.verbose {
        crate::progress!(
            "free timing: {} segments, step ratios in [{}, {}], total time {}, from the fixed-timing plan",
            ft.segments(),
            FREE_TIMING_RATIOS.0,
            FREE_TIMING_RATIOS.1,
            match total {
                TotalTime::Fixed => "fixed".to_string(),
                TotalTime::Priced(p) => format!("free at {p} per second"),
            }
        );
    }
    let o = IpOptions {
        mu_init: FREE_TIMING_BARRIER,
        ..opts
    };
    let s: Solver<NX, NW, NS, 2, NC> = Solver::new(&ft, o);
    let r = s.solve(s.warm_iterate(ft.start_from_fixed(start)));
    let (ratios, _) = ft.times(&r.iterate);
    let (plan, times) = ft.trajectory(&r.iterate);
    let mut free = outcome::<M, NS, NX, NW>(model, r, plan, true);
    let time_cost = match total {
        TotalTime::Priced(p) => p * times.last().copied().unwrap_or(0.0),
        TotalTime::Fixed => 0.0,
    };
    free.objective -= time_cost;
    free.times = Some(times);
    Ok(FreeTimingOutcome {
        fixed,
        free,
        ratios,
        time_cost,
    })
}
