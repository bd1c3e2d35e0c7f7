//! What the robots' open-loop simulators share: the run itself and how it fails.

use dmech::continuous::ContinuousModel;
use dmech::{
    Integrator, JacobianPolicy, NewtonCache, PrincipalKinematicSystem, StepError,
    VariationalIntegrator, ViState,
};
use nalgebra::SVector;

/// Why a simulation stopped before its end.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulationError {
    /// The midpoint scheme's first velocity (the discrete Legendre transform of the start)
    /// was not found.
    #[error("the midpoint scheme's start failed: {0}")]
    Start(StepError),
    /// A step's Newton iteration failed, or a Runge–Kutta step left the finite numbers.
    #[error("step {step} (t = {t:.4} s) failed: {source}{advice}")]
    Step {
        /// The step.
        step: usize,
        /// Its time.
        t: f64,
        /// What failed.
        source: StepError,
        /// What to change, for the message (empty, or beginning with `; `).
        advice: String,
    },
}

/// One node of an open-loop run: its time, the state with the velocity at the node (the
/// first-order scheme's and the Runge–Kutta methods' own; the midpoint scheme's mean
/// `(v_{k−1} + v_k)/2` of the intervals around it, the start's at `k = 0`), and the input
/// held from it.
pub struct SimulatedNode<G, const NS: usize, const NU: usize> {
    pub t: f64,
    pub state: ViState<G, NS>,
    pub input: SVector<f64, NU>,
}

/// `n` steps of `h` of `sys` from `start` under the zero-order-hold inputs `u_at(k)`, by
/// `integrator`: the variational schemes from the discrete Legendre transform of the
/// start (midpoint) or the start's velocity (first order), the Runge–Kutta methods on the
/// continuous model. Returns the `n + 1` nodes.
pub fn simulate_open_loop<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    integrator: Integrator,
    h: f64,
    start: &ViState<S::Group<f64>, NS>,
    u_at: impl Fn(usize) -> SVector<f64, NU>,
    n: usize,
) -> Result<Vec<SimulatedNode<S::Group<f64>, NS, NU>>, SimulationError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let mut x = *start;
    let midpoint = integrator == Integrator::Midpoint;
    let vi = VariationalIntegrator::new(h)
        .with_discretisation(integrator.variational().unwrap_or_default())
        .with_jacobian(JacobianPolicy::ReuseAcrossSteps);
    if midpoint {
        x.v = vi
            .start(sys, &start.s, &start.v, &u_at(0))
            .map_err(SimulationError::Start)?;
    }
    let mut cache = NewtonCache::default();
    let mut nodes = Vec::with_capacity(n + 1);
    let mut v_before = start.v;
    for k in 0..=n {
        let v_node = match (midpoint, k) {
            (true, 0) => start.v,
            (true, _) => (v_before + x.v) * 0.5,
            _ => x.v,
        };
        v_before = x.v;
        nodes.push(SimulatedNode {
            t: k as f64 * h,
            state: ViState { v: v_node, ..x },
            input: u_at(k),
        });
        if k == n {
            break;
        }
        let fail = |source| SimulationError::Step {
            step: k,
            t: k as f64 * h,
            source,
            advice: String::new(),
        };
        x = match integrator.runge_kutta() {
            None => {
                vi.step_cached(sys, &x, &u_at(k), &u_at(k + 1), &x.v.clone(), &mut cache)
                    .map_err(fail)?
                    .0
            }
            Some(method) => ContinuousModel::step(sys, method, h, &x, &u_at(k)).map_err(fail)?,
        };
    }
    Ok(nodes)
}
