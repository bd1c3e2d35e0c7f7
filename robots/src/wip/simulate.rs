//! Open-loop simulation of the WIP from a reduced state with zero-order-hold voltages.

use super::state::{from_reduced, to_reduced, ReducedState};
use super::Wip;
use dmech::continuous::{ContinuousModel, RungeKutta};
use dmech::{
    ForcingQuadrature, JacobianPolicy, NewtonCache, StepError, VariationalIntegrator, ViState,
};
use nalgebra::SVector;

/// The time-stepping schemes `wip` offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// The variational integrator, with its forcing quadrature and Newton Jacobian policy.
    VarInt {
        quadrature: ForcingQuadrature,
        jacobian: JacobianPolicy,
    },
    Rk(RungeKutta),
}

impl std::str::FromStr for Integrator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "varint" => Ok(Integrator::varint()),
            "rk1" => Ok(Integrator::Rk(RungeKutta::Rk1)),
            "rk2" => Ok(Integrator::Rk(RungeKutta::Rk2)),
            "rk4" => Ok(Integrator::Rk(RungeKutta::Rk4)),
            _ => Err(format!(
                "unknown integrator '{s}' (expected varint, rk1, rk2 or rk4)"
            )),
        }
    }
}

impl Integrator {
    /// The default variational integrator: right-point forcing, and the exact Newton
    /// Jacobian carried across steps (refreshed whenever a chord step stalls).
    pub fn varint() -> Self {
        Integrator::VarInt {
            quadrature: ForcingQuadrature::Right,
            jacobian: JacobianPolicy::ReuseAcrossSteps,
        }
    }
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::VarInt { .. } => "varint",
            Integrator::Rk(RungeKutta::Rk1) => "rk1",
            Integrator::Rk(RungeKutta::Rk2) => "rk2",
            Integrator::Rk(RungeKutta::Rk4) => "rk4",
        }
    }
}

/// Voltages `(uR, uL)` held from `t_j` until the next sample (zero-order hold).
#[derive(Clone, Debug)]
pub struct InputSchedule {
    pub t: Vec<f64>,
    pub u: Vec<[f64; 2]>,
}

impl InputSchedule {
    /// The input in force at time `t` (the last sample at or before `t`, with a tolerance
    /// of 1e-9 s so that grid times computed as `k h` do not fall just short of a sample).
    pub fn at(&self, t: f64) -> [f64; 2] {
        let idx = self.t.partition_point(|&tj| tj <= t + 1e-9);
        self.u[idx.saturating_sub(1)]
    }
    /// The last sample time: the end of the horizon.
    pub fn end(&self) -> f64 {
        *self.t.last().unwrap_or(&0.0)
    }
}

/// A simulated trajectory: reduced states and the inputs applied from each node on.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    pub t: Vec<f64>,
    pub x: Vec<ReducedState>,
    pub u: Vec<[f64; 2]>,
}

/// Simulate from `x0` for `n_steps` steps of size `h`. Fails (with the time) if a step fails.
pub fn simulate(
    w: &Wip,
    integrator: Integrator,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
    n_steps: usize,
) -> Result<Trajectory, String> {
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
        match integrator {
            Integrator::VarInt {
                quadrature,
                jacobian,
            } => {
                let vi = VariationalIntegrator::new(h)
                    .with_quadrature(quadrature)
                    .with_jacobian(jacobian);
                let guess = x.v * 2.0 - v_prev;
                v_prev = x.v;
                let (_, unext) = uvec(k + 1);
                Ok(vi.step_cached(w, x, &uk, &unext, &guess, &mut cache)?.0)
            }
            Integrator::Rk(m) => ContinuousModel::step(w, m, h, x, &uk),
        }
    };

    let mut traj = Trajectory::default();
    let mut x = ViState {
        g: g0,
        s: s0,
        v: v0,
    };
    for k in 0..=n_steps {
        traj.t.push(k as f64 * h);
        traj.x.push(to_reduced(&p, &x.g, &x.s, &x.v));
        traj.u.push(uvec(k).0);
        if k == n_steps {
            break;
        }
        x = advance(k, &x)
            .map_err(|e| format!("step {k} (t = {:.4} s) failed: {e}", k as f64 * h))?;
    }
    Ok(traj)
}
