//! A plan replayed through the variational integrator it was planned with, and continued
//! for a while with zero input: how far the integrator's motion is from the plan's (the
//! plan's dynamics held to the solver's tolerance, so this is that tolerance through the
//! motion's sensitivity), and whether a plan that ends at rest stays there.

use crate::transcription::PlannedTrajectory;
use dmech::{Discretisation, PrincipalKinematicSystem, StepError, VariationalIntegrator, ViState};
use dmech_lie::LieGroup;
use nalgebra::SVector;

/// What [`replay`] measured.
#[derive(Clone, Debug)]
pub struct Replay<G, const NS: usize> {
    /// The integrator's nodes: `N + 1` along the plan, then the steps after it.
    pub nodes: Vec<ViState<G, NS>>,
    /// The largest distance `|log(g_plan⁻¹ g)| + |s_plan − s|` over the plan's stages
    /// (shape coordinates the system declares ignorable left out).
    pub plan_deviation: f64,
    /// The largest distance of a node after the plan from the plan's last configuration:
    /// zero for a plan that ends at rest, to round-off.
    pub drift_after: f64,
}

/// Replays `plan` (a variational transcription's, step `h`, scheme `discretisation`) from
/// its first stage with its inputs, then `rest_steps` steps with zero input. The group
/// coordinates of the plan's poses are read by `G::from_coordinates`.
pub fn replay<S, const DOF: usize, const NP: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    discretisation: Discretisation,
    plan: &PlannedTrajectory<NP, NS, NU>,
    rest_steps: usize,
) -> Result<Replay<S::Group<f64>, NS>, StepError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let group = |k: usize| {
        <S::Group<f64> as LieGroup<DOF>>::from_coordinates(plan.stages[k].pose.as_slice())
            .expect("the plan's pose coordinates are the group's")
    };
    let ignored = sys.ignorable_shape();
    let distance = |a: &ViState<S::Group<f64>, NS>, g: &S::Group<f64>, s: &SVector<f64, NS>| {
        let ds: f64 = (0..NS)
            .filter(|i| !ignored.contains(i))
            .map(|i| (a.s[i] - s[i]).powi(2))
            .sum();
        g.inverse().compose(&a.g).log().norm() + ds.sqrt()
    };
    let n = plan.stages.len() - 1;
    let vi = VariationalIntegrator::new(h).with_discretisation(discretisation);
    let input = |k: usize| {
        if k < n {
            plan.stages[k].input
        } else {
            SVector::zeros()
        }
    };
    let mut x = ViState {
        g: group(0),
        s: plan.stages[0].shape,
        v: plan.stages[0].velocity,
    };
    let mut nodes = vec![x];
    let (mut plan_deviation, mut drift_after) = (0.0f64, 0.0f64);
    let (g_end, s_end) = (group(n), plan.stages[n].shape);
    for k in 0..n + rest_steps {
        x = vi.step(sys, &x, &input(k), &input(k + 1))?.0;
        nodes.push(x);
        if k < n {
            plan_deviation =
                plan_deviation.max(distance(&x, &group(k + 1), &plan.stages[k + 1].shape));
        } else {
            drift_after = drift_after.max(distance(&x, &g_end, &s_end));
        }
    }
    Ok(Replay {
        nodes,
        plan_deviation,
        drift_after,
    })
}
