//! Open-loop simulation of the car with zero-order-hold inputs `(τ_s, u_d)`.

use super::model::{Car, NS};
use super::report::CarTrajectory;
use crate::check::{CheckError, Scheme};
use crate::io::InputSchedule;
use crate::simulation::SimulationError;
use dmech::continuous::ContinuousModel;
use dmech::{Integrator, JacobianPolicy, NewtonCache, VariationalIntegrator, ViState};
use dmech_lie::Se2;
use nalgebra::SVector;

/// Refuse a simulation whose step the car's linearised model at the start shows to be
/// beyond the scheme's stability bound (RK4 on the drive motor's electrical mode, time
/// constant `L_m/R_m` = 1 ms: it needs a step below 2.8 ms), or whose rates are not finite
/// there ([`crate::check::check_step`]).
pub fn check_simulation(
    car: &Car,
    integrator: Integrator,
    h: f64,
    start: &CarState,
    inputs: &InputSchedule,
) -> Result<(), CheckError> {
    let what = "simulate";
    let x = ViState {
        g: Se2::new(start.pose[0], start.pose[1], start.pose[2]),
        s: start.shape,
        v: start.velocity,
    };
    let u = inputs.at(0.0);
    let modes = crate::check::linear_modes(car, &x, &SVector::<f64, 2>::new(u[0], u[1]), what)?;
    crate::check::check_simulation_step(what, &modes, Scheme::from(integrator), h)
}

/// A state of the car: pose `(x, y, θ)`, shape `(φ, ψ, q)`, shape velocity `(φ̇, ψ̇, i)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarState {
    pub pose: [f64; 3],
    pub shape: SVector<f64, NS>,
    pub velocity: SVector<f64, NS>,
}

/// Simulates `n` steps of `h` from `start`. The midpoint scheme starts from the discrete
/// Legendre transform and reports `(v_{k−1} + v_k)/2` at node `k`.
pub fn simulate(
    car: &Car,
    integrator: Integrator,
    h: f64,
    start: &CarState,
    inputs: &InputSchedule,
    n: usize,
) -> Result<CarTrajectory, SimulationError> {
    let (pose0, s0, v0) = (start.pose, start.shape, start.velocity);
    let u_at = |k: usize| {
        let u = inputs.at(k as f64 * h);
        SVector::<f64, 2>::new(u[0], u[1])
    };
    let mut x = ViState {
        g: Se2::new(pose0[0], pose0[1], pose0[2]),
        s: s0,
        v: v0,
    };
    let midpoint = integrator == Integrator::Midpoint;
    let vi = VariationalIntegrator::new(h)
        .with_discretisation(integrator.variational().unwrap_or_default())
        .with_jacobian(JacobianPolicy::ReuseAcrossSteps);
    if midpoint {
        x.v = vi
            .start(car, &s0, &v0, &u_at(0))
            .map_err(SimulationError::Start)?;
    }
    let mut cache = NewtonCache::default();
    let mut traj = CarTrajectory::default();
    let mut v_before = v0;
    for k in 0..=n {
        let v_node = match (midpoint, k) {
            (true, 0) => v0,
            (true, _) => (v_before + x.v) * 0.5,
            _ => x.v,
        };
        v_before = x.v;
        traj.t.push(k as f64 * h);
        traj.pose.push([x.g.x, x.g.y, x.g.theta]);
        traj.shape.push(x.s);
        traj.velocity.push(v_node);
        traj.input.push(u_at(k));
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
                vi.step_cached(car, &x, &u_at(k), &u_at(k + 1), &x.v.clone(), &mut cache)
                    .map_err(fail)?
                    .0
            }
            Some(method) => ContinuousModel::step(car, method, h, &x, &u_at(k)).map_err(fail)?,
        };
    }
    Ok(traj)
}
