//! Solving a plan in stages: continuation over a list of problems (each from the previous
//! one's solution), and mesh sequencing for the variational transcriptions (the plan
//! solved on a coarse mesh, then on each finer one from the refined solution).
//!
//! A robot describes its family of meshes and problems once ([`SequencedPlan`]); the
//! driver here is the same for every robot. The measurements behind the constants are in
//! `docs/ocp.md` ("Mesh sequencing").

use crate::nlp::StageProblem;
use crate::solver::{IpOptions, SolveResult, Solver, Status};
use crate::toolkit::refine::{refine_varint_iterate, EqualityLists};
use crate::transcription::layout::Layout;
use nalgebra::SVector;

/// Solve each problem in turn, each from the previous one's solution; all but the last
/// only to tolerance `τ₁ = 10 μ₀^warm` (solving an intermediate problem below the barrier
/// the next one starts at is work thrown away), and each later one restarted at barrier
/// `μ = τ₁`. The iterations and times of all are added; a failure stops the sequence.
pub fn continuation<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    problems: &[P],
    xs: Vec<SVector<f64, NX>>,
    ws: Vec<SVector<f64, NW>>,
    opts: IpOptions,
) -> SolveResult<NX, NW, NC>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let intermediate_tol = (10.0 * opts.warm_mu_init()).max(opts.tol);
    let last = problems.len() - 1;
    let mut start = Some((xs, ws));
    let mut done: Option<SolveResult<NX, NW, NC>> = None;
    for (j, p) in problems.iter().enumerate() {
        // The time limit holds for the whole continuation.
        let mut o = done
            .as_ref()
            .map_or_else(|| opts.clone(), |prev| time_left(&opts, prev));
        if j < last {
            // An intermediate problem has its own end: its tolerance, not the final barrier.
            o.tol = intermediate_tol;
            o.final_barrier = None;
        }
        if j > 0 {
            o.mu_init = intermediate_tol;
        }
        let s: Solver<NX, NW, NE, NF, NC> = Solver::new(p, o);
        let r = match &done {
            None => {
                let (xs, ws) = start.take().expect("only the first problem starts cold");
                s.solve(s.initial_iterate(xs, ws))
            }
            Some(prev) => merge(s.solve(s.warm_iterate(prev.iterate.clone())), prev),
        };
        let solved = r.status == Status::Solved;
        done = Some(r);
        if !solved {
            break;
        }
    }
    done.expect("at least one problem")
}

/// The last problem solved directly from the start; only if that fails, the
/// [`continuation`] over all of them from the same start, within what is left of the time
/// limit. The failed attempt's iterations and times are added to the result. For problems
/// whose continuation is a safeguard rather than a necessity (a continuation over a
/// stiff friction term on an explicit Runge–Kutta plan, say: the direct solve takes
/// fewer iterations, `docs/ocp.md`).
pub fn direct_or_continuation<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    problems: &[P],
    xs: Vec<SVector<f64, NX>>,
    ws: Vec<SVector<f64, NW>>,
    opts: IpOptions,
) -> SolveResult<NX, NW, NC>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let last = &problems[problems.len() - 1..];
    let direct = continuation::<_, NX, NW, NE, NF, NC>(last, xs.clone(), ws.clone(), opts.clone());
    // With one problem the continuation is the direct solve: nothing to fall back to.
    if direct.status == Status::Solved || problems.len() == 1 {
        return direct;
    }
    let o = time_left(&opts, &direct);
    merge(
        continuation::<_, NX, NW, NE, NF, NC>(problems, xs, ws, o),
        &direct,
    )
}

/// `opts` with its time limit less what `spent`, an earlier part of the same solve, took.
fn time_left<const NX: usize, const NW: usize, const NC: usize>(
    opts: &IpOptions,
    spent: &SolveResult<NX, NW, NC>,
) -> IpOptions {
    let mut o = opts.clone();
    o.time_limit = (opts.time_limit - spent.timings.total).max(0.0);
    o
}

/// `r` with the iterations and times of `r0` (an earlier stage of the same solve) added.
pub fn merge<const NX: usize, const NW: usize, const NC: usize>(
    mut r: SolveResult<NX, NW, NC>,
    r0: &SolveResult<NX, NW, NC>,
) -> SolveResult<NX, NW, NC> {
    r.iterations += r0.iterations;
    r.timings.derivatives += r0.timings.derivatives;
    r.timings.kkt += r0.timings.kkt;
    r.timings.line_search += r0.timings.line_search;
    r.timings.riccati += r0.timings.riccati;
    r.timings.factorizations += r0.timings.factorizations;
    r.timings.second_order_corrections += r0.timings.second_order_corrections;
    r.timings.restorations += r0.timings.restorations;
    r.timings.restoration += r0.timings.restoration;
    r.timings.total += r0.timings.total;
    r
}

/// A plan on meshes of different steps, for [`mesh_sequence`]: a variational
/// transcription (the refinement knows its layout) whose problem on a mesh may come in
/// continuation phases (`phases()` problems, the last being the plan itself).
pub trait SequencedPlan<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>
{
    /// A mesh: the problem's data at one step (horizon, step, the stages of its conditions).
    type Mesh;
    /// The transcribed problem on a mesh.
    type Problem<'a>: StageProblem<NX, NW, NE, NF, NC>
    where
        Self: 'a;
    /// The number of steps of `mesh`.
    fn steps(&self, mesh: &Self::Mesh) -> usize;
    /// The step of `mesh`.
    fn step(&self, mesh: &Self::Mesh) -> f64;
    /// The same problem at twice the step, if it exists (e.g. no two conditions share a
    /// stage there).
    fn coarser(&self, mesh: &Self::Mesh) -> Option<Self::Mesh>;
    /// The problem on `mesh` in continuation phase `phase < phases()`.
    fn problem<'a>(&'a self, mesh: &'a Self::Mesh, phase: usize) -> Self::Problem<'a>;
    /// The number of continuation phases on the coarsest mesh (1: none).
    fn phases(&self) -> usize {
        1
    }
    /// The start on `mesh` (the coarsest one).
    fn start(&self, mesh: &Self::Mesh) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>);
    /// The transcription's layout (for the refinement).
    fn layout(&self) -> Layout;
    /// How the cost-to-go, hence the multipliers, scale from `coarse` to `fine`: the ratio
    /// of their step counts for a cost summed over stages without a factor `h` (default).
    fn dual_scale(&self, coarse: &Self::Mesh, fine: &Self::Mesh) -> f64 {
        self.steps(fine) as f64 / self.steps(coarse) as f64
    }
}

/// The knobs of [`mesh_sequence`].
#[derive(Clone, Copy, Debug)]
pub struct SequenceSettings {
    /// The coarsest mesh is the one of step `h·2^L` with the largest `L` at or below this.
    pub coarsest_step: f64,
    /// The barrier a finer mesh restarts at from the refined coarse solution; each coarse
    /// mesh is solved down to it and no further ([`IpOptions::final_barrier`]): below it
    /// is work the refinement throws away.
    pub restart_barrier: f64,
}

/// Mesh sequencing: `finest` solved on the coarsest mesh of step `h·2^L ≤ coarsest_step`
/// (from the plan's start, through its continuation phases), then on each finer mesh from
/// the refined solution ([`refine_varint_iterate`], multipliers matched by what each
/// condition constrains), restarted at `restart_barrier`. If a mesh fails, the finest mesh
/// is solved directly from its own start, so that the status and the iterate are its own.
/// The iterations and times of all meshes are added. `progress` is told of each mesh
/// (index, count, steps, step) and of a fallback. The solves hand their buffers on
/// ([`crate::solver::reuse_workspaces`], room for the finest mesh from the first).
pub fn mesh_sequence<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    plan: &P,
    finest: P::Mesh,
    settings: SequenceSettings,
    opts: IpOptions,
    progress: &dyn Fn(&str),
) -> SolveResult<NX, NW, NC>
where
    P: SequencedPlan<NX, NW, NE, NF, NC>,
{
    crate::solver::reuse_workspaces(plan.steps(&finest), || {
        sequence_meshes::<P, NX, NW, NE, NF, NC>(plan, finest, settings, opts, progress)
    })
}

fn sequence_meshes<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    plan: &P,
    finest: P::Mesh,
    settings: SequenceSettings,
    opts: IpOptions,
    progress: &dyn Fn(&str),
) -> SolveResult<NX, NW, NC>
where
    P: SequencedPlan<NX, NW, NE, NF, NC>,
{
    // Coarsest first, the problem itself last.
    let mut meshes = vec![finest];
    while plan.step(&meshes[0]) * 2.0 <= settings.coarsest_step * (1.0 + 1e-9) {
        match plan.coarser(&meshes[0]) {
            Some(c) => meshes.insert(0, c),
            None => break,
        }
    }
    let last = meshes.len() - 1;
    // A coarse mesh ends where the next one restarts.
    let final_barrier = |j: usize| (j < last).then_some(settings.restart_barrier);
    let announce = |j: usize| {
        if last > 0 {
            progress(&format!(
                "mesh {} of {}: {} stages of {} s",
                j + 1,
                last + 1,
                plan.steps(&meshes[j]),
                plan.step(&meshes[j])
            ));
        }
    };
    // A mesh solved from its start through the continuation phases.
    let from_start = |mesh: &P::Mesh, o: IpOptions| {
        let (xs, ws) = plan.start(mesh);
        let problems: Vec<_> = (0..plan.phases())
            .map(|ph| plan.problem(mesh, ph))
            .collect();
        continuation::<_, NX, NW, NE, NF, NC>(&problems, xs, ws, o)
    };
    announce(0);
    let mut o = opts.clone();
    o.final_barrier = final_barrier(0);
    let mut r = from_start(&meshes[0], o);
    let final_phase = plan.phases() - 1;
    for j in 1..=last {
        if r.status != Status::Solved {
            break;
        }
        announce(j);
        let (coarse, mesh) = (&meshes[j - 1], &meshes[j]);
        let problem = plan.problem(mesh, final_phase);
        let coarse_eqs = plan.problem(coarse, final_phase).state_equalities();
        let fine_eqs = problem.state_equalities();
        let lists = EqualityLists {
            coarse: &coarse_eqs,
            fine: &fine_eqs,
        };
        let start = refine_varint_iterate(
            plan.layout(),
            &r.iterate,
            &lists,
            plan.steps(mesh),
            plan.step(mesh),
            plan.step(coarse),
            plan.dual_scale(coarse, mesh),
        );
        let mut o = time_left(&opts, &r);
        o.final_barrier = final_barrier(j);
        o.mu_init = settings.restart_barrier;
        let s: Solver<NX, NW, NE, NF, NC> = Solver::new(&problem, o);
        r = merge(s.solve(s.warm_iterate(start)), &r);
    }
    if last > 0 && r.status != Status::Solved {
        progress(&format!(
            "mesh sequencing: {}; solving the {} stages of {} s directly",
            r.status.code(),
            plan.steps(&meshes[last]),
            plan.step(&meshes[last])
        ));
        return merge(from_start(&meshes[last], time_left(&opts, &r)), &r);
    }
    r
}
