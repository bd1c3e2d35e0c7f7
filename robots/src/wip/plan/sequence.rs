//! The WIP's VI plan by mesh sequencing (`docs/ocp.md`, "Mesh sequencing"): the meshes,
//! the friction continuation's phases on the coarsest, and the sequencing's constants.

use crate::wip::plan::problem::{
    varint_layout, varint_plan, PlanBounds, PlanModel, VarIntPlan, NC, SMOOTH_FRICTION_SLOPE,
};
use crate::wip::plan::problems::PlanProblem;
use crate::wip::plan::start::varint_start;
use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, SolveResult};
use dmech_ocp::toolkit::sequencing::{mesh_sequence, SequenceSettings, SequencedPlan};
use dmech_ocp::transcription::layout::Layout;
use nalgebra::SVector;

/// The VI plan by mesh sequencing over the friction continuation's `models`.
pub(super) fn varint_solve<M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>(
    model: &M,
    models: Vec<M>,
    problem: &PlanProblem,
    bounds: PlanBounds,
    disc: Discretisation,
    opts: IpOptions,
) -> SolveResult<NX, NW, NC> {
    let seq = WipSequence {
        model,
        models,
        bounds,
        disc,
    };
    let settings = SequenceSettings {
        coarsest_step: MESH_COARSEST_STEP,
        restart_barrier: MESH_RESTART_BARRIER,
    };
    let verbose = opts.verbose;
    let progress = |m: &str| {
        if verbose {
            crate::progress!("{m}");
        }
    };
    mesh_sequence::<_, NX, NW, NS, 2, NC>(&seq, problem.clone(), settings, opts, &progress)
}

/// The coarsest step of mesh sequencing: the VI plan starts on the mesh of step
/// `h·2^L ≤ MESH_COARSEST_STEP` (20 ms: the scale series' coarsest mesh, solved directly
/// in 38 iterations and 0.4 s for the eight).
const MESH_COARSEST_STEP: f64 = 0.02;

/// The barrier a finer mesh restarts at from the refined coarse solution, and the one
/// each coarse mesh is solved down to. Measured on the eight at 1.25 ms from the 2.5 ms
/// solution (iterations of the fine mesh): 1e-3: 54, 1e-4: 34–37, 1e-5: 39–40.
const MESH_RESTART_BARRIER: f64 = 1e-4;

/// The WIP's VI plan as a family of meshes for [`dmech_ocp::toolkit::sequencing::mesh_sequence`]:
/// the meshes are [`PlanProblem::at_step`], the continuation phases the friction
/// continuation's models (the last is the model itself), the start the polyline start.
///
/// Why: where the robot leaves and reaches rest the voltage rate is bang-bang, and the
/// interior point moves its switch by one or two stages per iteration; on the finest mesh
/// alone the switch has a fixed time to travel, i.e. `∝ 1/h` stages, and the iteration
/// count grew like `N^0.29` (eight: 38 iterations at 20 ms, 86 at 1.25 ms). From the
/// coarse solution the switch is within a coarse step of its place, each finer mesh takes
/// 14–36 iterations (eight, 10 ms … 1.25 ms), and the coarse meshes cost a geometric fraction of the finest
/// (`docs/ocp.md`).
struct WipSequence<'m, M> {
    model: &'m M,
    models: Vec<M>,
    bounds: PlanBounds,
    disc: Discretisation,
}

impl<M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>
    SequencedPlan<NX, NW, NS, 2, NC> for WipSequence<'_, M>
where
    M: PlanModel<NS>,
{
    type Mesh = PlanProblem;
    type Problem<'a>
        = VarIntPlan<'a, M, NS, NX, NW>
    where
        Self: 'a;
    fn steps(&self, mesh: &PlanProblem) -> usize {
        mesh.n
    }
    fn step(&self, mesh: &PlanProblem) -> f64 {
        mesh.h
    }
    fn coarser(&self, mesh: &PlanProblem) -> Option<PlanProblem> {
        mesh.at_step(mesh.h * 2.0)
    }
    fn problem<'a>(&'a self, mesh: &'a PlanProblem, phase: usize) -> VarIntPlan<'a, M, NS, NX, NW> {
        varint_plan::<M, NS, NX, NW>(&self.models[phase], mesh, self.bounds, self.disc)
    }
    fn phases(&self) -> usize {
        self.models.len()
    }
    fn start(&self, mesh: &PlanProblem) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>) {
        varint_start::<M, NS, NX, NW>(self.model, mesh)
    }
    fn layout(&self) -> Layout {
        varint_layout::<M, NS, NX>(self.model)
    }
}

/// The problems of the friction continuation: the model with `d_0` lowered to
/// [`SMOOTH_FRICTION_SLOPE`], with `intermediate` one more at the geometric mean of the two
/// slopes, then the model itself (only the model if its `d_0` is not above that already).
/// See [`crate::wip::plan::plan`].
///
/// The intermediate step is for RK4 with the current dynamics: the change of the friction
/// slope changes the wheel accelerations, hence the back-EMF the current sees, and an
/// explicit step amplifies a current off its slow manifold by its stability function at
/// `z = −h R_m/L_m = −18.75`: 17.75 for RK1, 157 for RK2, 4209 for RK4. Measured on the
/// eight: the violation at the start of the model's phase is 9.8e-2 (RK1) and 4.18 (RK4);
/// from there RK4 did not converge within 300 s (198 iterations), with the intermediate
/// step it solves in 121 iterations (zigzag: 125). Without any continuation RK4 solves the
/// eight (72 iterations) but not the zigzag, and RK2 neither (`docs/ocp.md`).
pub(super) fn friction_continuation<M: PlanModel<NS>, const NS: usize>(
    model: &M,
    intermediate: bool,
) -> Vec<M> {
    let d_0 = model.wip().params.d_0;
    if d_0 <= SMOOTH_FRICTION_SLOPE {
        return vec![model.clone()];
    }
    let mut slopes = vec![SMOOTH_FRICTION_SLOPE];
    if intermediate {
        slopes.push((SMOOTH_FRICTION_SLOPE * d_0).sqrt());
    }
    let mut models: Vec<M> = slopes
        .into_iter()
        .map(|slope| {
            let mut m = model.clone();
            m.wip_mut().params.d_0 = slope;
            m
        })
        .collect();
    models.push(model.clone());
    models
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wip::Wip;

    /// The slopes of the continuation: the smooth one, the geometric mean when asked for,
    /// the model's; a model already as smooth is solved alone.
    #[test]
    fn friction_continuation_slopes() {
        let wip = Wip::default();
        let d_0 = wip.params.d_0;
        let slopes = |ms: Vec<Wip>| ms.iter().map(|m| m.params.d_0).collect::<Vec<_>>();
        assert_eq!(
            slopes(friction_continuation(&wip, false)),
            vec![SMOOTH_FRICTION_SLOPE, d_0]
        );
        let three = slopes(friction_continuation(&wip, true));
        assert_eq!(three.len(), 3);
        assert_eq!((three[0], three[2]), (SMOOTH_FRICTION_SLOPE, d_0));
        // The middle slope is equally far from both in log scale.
        assert!(((three[1] / three[0]).ln() - (three[2] / three[1]).ln()).abs() < 1e-14);
        let mut smooth = wip;
        smooth.params.d_0 = SMOOTH_FRICTION_SLOPE;
        assert_eq!(
            slopes(friction_continuation(&smooth, true)),
            vec![SMOOTH_FRICTION_SLOPE]
        );
        // Only the slope changes.
        let m = &friction_continuation(&wip, true)[1];
        let mut back = *m;
        back.params.d_0 = d_0;
        assert_eq!(back, wip);
    }
}
