//! A robot's planning problem in typed terms, and its transcription into a
//! [`StageProblem`](crate::nlp::StageProblem) for every discretisation: the first-order and midpoint variational
//! integrators ([`VarIntTranscription`]) and RK1/2/4 ([`RkTranscription`]).
//!
//! A robot supplies a [`PlanningProblem`]: its cost and path constraints over a [`Stage`]
//! (pose, shape, velocity, input, previous input: named fields, no offsets), their
//! bounds, the start, and [`Condition`]s on any pose, shape or velocity component at any
//! stage (waypoints, the end state). The transcription owns the stage layout: where each
//! quantity sits in the solver's `x_k` and `w_k`, which differs between the
//! discretisations (the variational integrators decide `w_k = (v_k, u_k)` and carry
//! `v_{k−1}` in the state; Runge–Kutta carries `v_k` in the state and decides `w_k = u_k`).
//!
//! Sizes, in this order everywhere: the system's `DOF` (dimension of `G`), `NS` (shape),
//! `NU` (inputs); the problem's `NP` (pose coordinates, `coords(g)`) and `NC` (path
//! constraints); the solver's `NX` (state), `NW` (stage decision), `NE` (stage
//! equalities) and `NF` (free decisions per stage, `NW − NE`: the variational
//! transcriptions' `NE = NS` momentum-matching rows eliminate the velocities and leave the
//! inputs). With every shape position carried, `NX = NP + 2 NS + NU` and `NW = NS + NU`
//! (variational) or `NU` (Runge–Kutta); the compiler infers them ([`sizes`]).
//!
//! # Example
//!
//! A differential-drive robot (shape: the two wheel angles, inputs: their torques) driven
//! 1 m straight ahead in 2 s, rest to rest, with least squared torque:
//! ```
//! use dmech::{Discretisation, Lift, PrincipalKinematicSystem};
//! use dmech_lie::{Real, Se2};
//! use dmech_ocp::solver::{IpOptions, Solver, Status};
//! use dmech_ocp::transcription::*;
//! use nalgebra::{Matrix3x2, SMatrix, SVector};
//!
//! struct DiffDrive; // mass 1 kg, wheel radius 0.05 m, half-track 0.1 m
//! impl PrincipalKinematicSystem<3, 2, 2> for DiffDrive {
//!     type Param = f64;
//!     type Group<T: Real> = Se2<T>;
//!     fn reduced_lagrangian<T: Lift<f64>>(
//!         &self, _s: &SVector<T, 2>, v: &SVector<T, 2>, xi: &SVector<T, 3>,
//!     ) -> T {
//!         (xi.dot(xi) + v.dot(v) * 1e-3) * 0.5
//!     }
//!     fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
//!         // ξ = −A v: forward r(φ̇R + φ̇L)/2, yaw r(φ̇R − φ̇L)/(2d).
//!         let (half_r, yaw, z) = (T::from(0.025), T::from(0.25), T::zero());
//!         Matrix3x2::new(-half_r, -half_r, z, z, -yaw, yaw)
//!     }
//!     fn forcing<T: Lift<f64>>(
//!         &self, _s: &SVector<T, 2>, _v: &SVector<T, 2>, u: &SVector<T, 2>,
//!     ) -> SVector<T, 2> {
//!         *u
//!     }
//! }
//!
//! struct Forward { n: usize }
//! impl PlanningProblem<3, 2, 2, 0> for Forward {
//!     fn horizon(&self) -> usize { self.n }
//!     fn start(&self) -> StartState<3, 2, 2> {
//!         StartState::at_rest(SVector::zeros(), SVector::zeros())
//!     }
//!     fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, 2, 2>) -> T {
//!         stage.input.dot(&stage.input) * 0.5
//!     }
//!     fn constraints<T: Real>(&self, _k: usize, _: &Stage<T, 3, 2, 2>) -> SVector<T, 0> {
//!         SVector::zeros()
//!     }
//!     fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
//!         (SVector::zeros(), SVector::zeros())
//!     }
//!     fn conditions(&self) -> Vec<Condition> {
//!         let end = |quantity, value| Condition { stage: self.n, quantity, value };
//!         vec![
//!             end(Quantity::Pose(0), 1.0), end(Quantity::Pose(1), 0.0), end(Quantity::Pose(2), 0.0),
//!             end(Quantity::Velocity(0), 0.0), end(Quantity::Velocity(1), 0.0),
//!         ]
//!     }
//! }
//!
//! let (n, h) = (100, 0.02);
//! let p = VarIntTranscription::new(&DiffDrive, Forward { n }, h, Discretisation::FirstOrder);
//! // Inferred: NX = 3 + 2·2 + 2 = 9, NW = 2 + 2 = 4, NE = 2, free decisions NF = 2, NC = 0.
//! let solver = Solver::new(&p, IpOptions { verbose: false, ..Default::default() });
//! // Any start: `initial_iterate` puts the problem's start state into x_0.
//! let r = solver.solve(solver.initial_iterate(vec![SVector::zeros(); n + 1], vec![SVector::zeros(); n]));
//! assert_eq!(r.status, Status::Solved);
//! let plan = p.trajectory(&r.iterate);
//! assert!((plan.stages[n].pose[0] - 1.0).abs() < 1e-8);
//! ```

pub mod free_timing;
pub mod layout;
mod problem;
pub mod runge_kutta;
pub mod sizes;
pub mod variational;
pub use problem::*;
pub use runge_kutta::RkTranscription;
pub use variational::VarIntTranscription;
