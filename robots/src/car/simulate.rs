//! Open-loop simulation of the car with zero-order-hold inputs `(τ_s, u_d)`.

use super::model::{Car, NS};
use super::report::CarTrajectory;
use crate::check::{CheckError, Scheme};
use crate::io::InputSchedule;
use crate::simulation::{simulate_open_loop, SimulationError};
use dmech::{Integrator, ViState};
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
    let u_at = |k: usize| {
        let u = inputs.at(k as f64 * h);
        SVector::<f64, 2>::new(u[0], u[1])
    };
    let x0 = ViState {
        g: Se2::new(start.pose[0], start.pose[1], start.pose[2]),
        s: start.shape,
        v: start.velocity,
    };
    let mut traj = CarTrajectory::default();
    for node in simulate_open_loop(car, integrator, h, &x0, u_at, n)? {
        let x = node.state;
        traj.t.push(node.t);
        traj.pose.push([x.g.x, x.g.y, x.g.theta]);
        traj.shape.push(x.s);
        traj.velocity.push(x.v);
        traj.input.push(node.input);
    }
    Ok(traj)
}
