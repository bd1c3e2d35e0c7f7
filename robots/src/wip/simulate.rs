//! Open-loop simulation of the WIP from a reduced state with zero-order-hold voltages.

use super::state::{from_reduced, to_reduced, ReducedState};
use super::Wip;
use crate::check::{CheckError, Scheme};
pub use crate::io::InputSchedule;
use crate::io::NonFiniteValue;
use crate::simulation::SimulationError;
use dmech::continuous::ContinuousModel;
use dmech::{
    Discretisation, ForcingQuadrature, Integrator, JacobianPolicy, NewtonCache, StepError,
    VariationalIntegrator, ViState,
};
use nalgebra::{Complex, SVector};
use std::fmt::Write as _;

/// How [`simulate`] steps: the scheme, and the variational schemes' forcing quadrature and
/// Newton Jacobian. From a [`dmech::Integrator`] alone: right-point forcing, the exact
/// Jacobian carried across steps (refreshed whenever a chord step stalls).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stepping {
    /// The scheme.
    pub integrator: Integrator,
    /// Where the first-order scheme reads the force.
    pub quadrature: ForcingQuadrature,
    /// How the variational schemes' Newton iteration forms its Jacobian.
    pub jacobian: JacobianPolicy,
}

impl From<Integrator> for Stepping {
    fn from(integrator: Integrator) -> Self {
        Stepping {
            integrator,
            quadrature: ForcingQuadrature::Right,
            jacobian: JacobianPolicy::ReuseAcrossSteps,
        }
    }
}

/// `trajectory.csv`: `t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL`. A non-finite
/// value is an error naming its row and column: a file of NaNs is never a result.
pub fn trajectory_csv(traj: &Trajectory) -> Result<String, NonFiniteValue> {
    const COLUMNS: [&str; 12] = [
        "t", "x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL", "uR", "uL",
    ];
    let mut s = COLUMNS.join(",") + "\n";
    for k in 0..traj.t.len() {
        let u = traj.u[k];
        let row = std::iter::once(traj.t[k])
            .chain(traj.x[k].iter().copied())
            .chain(u);
        for (j, v) in row.enumerate() {
            if !v.is_finite() {
                return Err(NonFiniteValue {
                    value: v,
                    t: traj.t[k],
                    column: COLUMNS[j],
                });
            }
            if j == 0 {
                let _ = write!(s, "{v}");
            } else {
                let _ = write!(s, ",{v:.17e}");
            }
        }
        s.push('\n');
    }
    Ok(s)
}

/// A simulated trajectory: reduced states and the inputs applied from each node on.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    pub t: Vec<f64>,
    pub x: Vec<ReducedState>,
    pub u: Vec<[f64; 2]>,
}

/// Simulate from `x0` for `n_steps` steps of size `h`. Fails (with the time) if a step fails.
///
/// The midpoint scheme's interval velocities `v_k` approximate `v(t_k + h/2)`: it starts
/// from the discrete Legendre transform of `x0` and reports at node `k` the average
/// `(v_{k−1} + v_k)/2`, second-order accurate at `t_k` (the first-order scheme reports `v_k`).
pub fn simulate(
    w: &Wip,
    stepping: impl Into<Stepping>,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
    n_steps: usize,
) -> Result<Trajectory, SimulationError> {
    let stepping = stepping.into();
    let p = w.params;
    let (g0, s0, v0) = from_reduced(&p, x0, [0.0; 4]);
    let uvec = |k: usize| {
        let u = inputs.at(k as f64 * h);
        (u, SVector::<f64, 2>::new(u[0], u[1]))
    };
    // One step k → k+1 of the chosen scheme; the VI also carries its Newton cache and the
    // previous velocity, for the start 2 v_k − v_{k−1}.
    let mut cache = NewtonCache::default();
    let mut v_prev = v0;
    let mut advance = |k: usize, x: &ViState<_, 5>| -> Result<ViState<_, 5>, StepError> {
        let (_, uk) = uvec(k);
        match (
            stepping.integrator.variational(),
            stepping.integrator.runge_kutta(),
        ) {
            (Some(discretisation), _) => {
                let vi = VariationalIntegrator::new(h)
                    .with_discretisation(discretisation)
                    .with_quadrature(stepping.quadrature)
                    .with_jacobian(stepping.jacobian);
                let guess = x.v * 2.0 - v_prev;
                v_prev = x.v;
                let (_, unext) = uvec(k + 1);
                Ok(vi.step_cached(w, x, &uk, &unext, &guess, &mut cache)?.0)
            }
            (None, method) => {
                let method = method.expect("a scheme is variational or Runge–Kutta");
                ContinuousModel::step(w, method, h, x, &uk)
            }
        }
    };

    let midpoint = stepping.integrator == Integrator::Midpoint;
    let mut x = ViState {
        g: g0,
        s: s0,
        v: v0,
    };
    if midpoint {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::Midpoint);
        x.v = vi
            .start(w, &s0, &v0, &uvec(0).1)
            .map_err(SimulationError::Start)?;
    }
    let mut traj = Trajectory::default();
    let mut v_before = v0;
    for k in 0..=n_steps {
        traj.t.push(k as f64 * h);
        let v_node = if midpoint && k > 0 {
            (v_before + x.v) * 0.5
        } else if midpoint {
            v0
        } else {
            x.v
        };
        v_before = x.v;
        traj.x.push(to_reduced(&p, &x.g, &x.s, &v_node));
        traj.u.push(uvec(k).0);
        if k == n_steps {
            break;
        }
        x = advance(k, &x).map_err(|source| SimulationError::Step {
            step: k,
            t: k as f64 * h,
            source,
            advice: format!(
                "; the motion left the range the step {h} s resolves (a smaller --step, or \
                 smaller voltages)"
            ),
        })?;
    }
    Ok(traj)
}

/// The modes of the WIP's linearised shape dynamics at a reduced state and input
/// ([`crate::check::linear_modes`]).
pub fn modes_at(
    w: &Wip,
    x0: &ReducedState,
    u: [f64; 2],
    what: &'static str,
) -> Result<Vec<Complex<f64>>, CheckError> {
    let (g, s, v) = from_reduced(&w.params, x0, [0.0; 4]);
    crate::check::linear_modes(
        w,
        &ViState { g, s, v },
        &SVector::<f64, 2>::new(u[0], u[1]),
        what,
    )
}

/// Refuse a plan whose step a growing mode of the model at rest outruns (the robot's own
/// fall, e-fold in 0.13 s, at 0.1 s), or whose rates are not finite there
/// ([`crate::check::check_step`] as for an implicit scheme: a plan's transcription meets
/// its dynamics as constraints, and the explicit ones at steps beyond their stability
/// bound on the motor circuit are the paper's comparison, `wip bench`).
pub fn check_plan_step(w: &Wip, integrator: Integrator, h: f64) -> Result<(), CheckError> {
    let what = "plan";
    let modes = modes_at(w, &ReducedState::zeros(), [0.0; 2], what)?;
    let as_implicit = Scheme {
        kind: crate::check::StepKind::Implicit,
        ..Scheme::from(integrator)
    };
    crate::check::check_step(what, &modes, as_implicit, h, "--step", "")
}

/// Refuse a simulation whose step the linearised model at the start shows to be beyond
/// the scheme's stability bound ([`crate::check::check_step`]: a damped mode an explicit
/// scheme amplifies, such as the motor circuit's electrical one; a growing mode faster
/// than the step, for any scheme), or whose rates are not finite there.
pub fn check_stability(
    w: &Wip,
    integrator: Integrator,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
) -> Result<(), CheckError> {
    let what = "simulate";
    let modes = modes_at(w, x0, inputs.at(0.0), what)?;
    crate::check::check_simulation_step(what, &modes, Scheme::from(integrator), h)
}

/// Why an open-loop run was not made or did not finish: the checks of `wip simulate`
/// before it starts, and the run's own failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulateRequestError {
    /// The step is outside (0, 1] s.
    #[error("the step must be in (0, 1] s, got {0}")]
    Step(f64),
    /// The inputs are off the step grid, beyond their limit, or span no step.
    #[error(transparent)]
    Inputs(#[from] crate::io::InputError),
    /// Too many steps, or a step beyond the scheme's stability bound at the start.
    #[error(transparent)]
    Check(#[from] CheckError),
    /// A step failed.
    #[error(transparent)]
    Run(#[from] SimulationError),
}

impl SimulateRequestError {
    /// Whether the request itself is malformed (the command line's usage errors, exit 2).
    pub fn is_usage(&self) -> bool {
        matches!(self, SimulateRequestError::Step(_))
    }
}

/// The checks of `wip simulate` before a run from `x0` with the voltages of `inputs`
/// (`what` names them in messages): the step in (0, 1] s, every voltage within
/// `±max_voltage`, at most `max_steps` steps, every input on the step grid, and the step
/// within the scheme's stability bound at the start. Returns the number of steps.
#[allow(clippy::too_many_arguments)]
pub fn check_simulation(
    w: &Wip,
    integrator: Integrator,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
    what: &str,
    max_steps: usize,
    max_voltage: f64,
) -> Result<usize, SimulateRequestError> {
    if !(h > 0.0 && h <= 1.0) {
        return Err(SimulateRequestError::Step(h));
    }
    inputs.check_limits(
        what,
        [
            ("uR", max_voltage, "V", "--max-voltage"),
            ("uL", max_voltage, "V", "--max-voltage"),
        ],
    )?;
    crate::check::check_size(
        "simulate: steps",
        inputs.end() / h,
        max_steps,
        300.0,
        "--max-steps",
    )?;
    let n = inputs.steps_on_grid(h, what, "--step")?;
    check_stability(w, integrator, h, x0, inputs)?;
    Ok(n)
}
