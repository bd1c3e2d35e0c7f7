//! Open-loop simulation of the snakeboard with zero-order-hold torques `(τ_ψ, τ_φ)`, on its
//! extended shape (`docs/snakeboard.md`).

use super::model::{Snakeboard, NA};
use super::report::SnakeboardTrajectory;
use crate::check::{CheckError, Scheme};
use crate::io::InputSchedule;
use crate::simulation::{simulate_open_loop, SimulationError};
use dmech::{Integrator, ViState};
use dmech_lie::Se2;
use nalgebra::SVector;

/// A state of the snakeboard: pose `(x, y, θ)`, shape `(ψ, φ)`, shape velocity `(ψ̇, φ̇)`
/// and the forward speed `p` along the free direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SnakeboardState {
    pub pose: [f64; 3],
    pub shape: [f64; 2],
    pub velocity: [f64; 2],
    pub p: f64,
}

impl SnakeboardState {
    /// The integrators' state on the extended shape `(ψ, φ, σ = 0)`.
    pub fn extended(&self) -> ViState<Se2<f64>, NA> {
        ViState {
            g: Se2::new(self.pose[0], self.pose[1], self.pose[2]),
            s: SVector::<f64, NA>::new(self.shape[0], self.shape[1], 0.0),
            v: SVector::<f64, NA>::new(self.velocity[0], self.velocity[1], self.p),
        }
    }
}

/// Why a simulation is refused before it starts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SnakeboardCheckError {
    /// The axle angle is at or beyond ±π/2.
    #[error(
        "simulate: the axle angle {0} rad is at or beyond ±π/2, where the board's turning rate \
         tan φ / l is infinite"
    )]
    AxleAngle(f64),
    /// The step or the model at the start ([`crate::check`]).
    #[error(transparent)]
    Check(#[from] CheckError),
}

/// Refuse a simulation whose step the linearised model at the start shows to be beyond the
/// scheme's stability bound, or whose rates are not finite there
/// ([`crate::check::check_step`]), and an axle angle at or beyond ±π/2.
pub fn check_simulation(
    board: &Snakeboard,
    integrator: Integrator,
    h: f64,
    start: &SnakeboardState,
    inputs: &InputSchedule,
) -> Result<(), SnakeboardCheckError> {
    let what = "simulate";
    if start.shape[1].abs() >= 0.5 * std::f64::consts::PI - 1e-6 {
        return Err(SnakeboardCheckError::AxleAngle(start.shape[1]));
    }
    let u = inputs.at(0.0);
    let modes = crate::check::linear_modes(
        &board.extended(),
        &start.extended(),
        &SVector::<f64, 2>::new(u[0], u[1]),
        what,
    )?;
    Ok(crate::check::check_simulation_step(
        what,
        &modes,
        Scheme::from(integrator),
        h,
    )?)
}

/// Simulates `n` steps of `h` from `start` ([`simulate_open_loop`] on the extended shape).
pub fn simulate(
    board: &Snakeboard,
    integrator: Integrator,
    h: f64,
    start: &SnakeboardState,
    inputs: &InputSchedule,
    n: usize,
) -> Result<SnakeboardTrajectory, SimulationError> {
    let u_at = |k: usize| {
        let u = inputs.at(k as f64 * h);
        SVector::<f64, 2>::new(u[0], u[1])
    };
    let extended = board.extended();
    let mut traj = SnakeboardTrajectory::default();
    for node in simulate_open_loop(&extended, integrator, h, &start.extended(), u_at, n)? {
        let x = node.state;
        traj.t.push(node.t);
        traj.pose.push([x.g.x, x.g.y, x.g.theta]);
        traj.shape.push([x.s[0], x.s[1]]);
        traj.velocity.push(x.v);
        traj.input.push(node.input);
    }
    Ok(traj)
}
