//! The generic integrators and transcriptions on systems with known answers and on random
//! systems, no robot involved. One test binary: each file of `tests/` is compiled and
//! linked on its own, and these share the generic code they instantiate.
//!
//! - `generic_integrator`: the integrators on small systems with known answers;
//! - `midpoint_integrator`: both discretisations of the reduced LDAP principle on random
//!   systems (order, reversibility, energy, momentum);
//! - `midpoint_rest`: a midpoint plan that ends at rest stays there; its objective's order;
//! - `momentum_systems`: systems with free group directions (the sleigh, the disk two
//!   ways, random systems of the class);
//! - `nmpc`: the nonlinear MPC on random systems' references, bounds inactive (first
//!   order equal to the LQ tracker) and active;
//! - `observer`: the observer with late poses on a random linear system, nonlinear readings;
//! - `rolling_disk`: both schemes' steps against their closed forms on the rolling disk;
//! - `rk_transcription`: the RK transcription's structured dynamics Jacobian;
//! - `steered_car_bounds`: the solver on a steered car with an active torque bound, and a
//!   sweep of it;
//! - `tracking`: plans and random systems' references tracked by LQ on mismatched plants;
//! - `tracking_mpc`: the constrained MPC on random systems' references, bounds inactive
//!   and active;
//! - `varint_curvature`: the VI transcription's exact constraint curvature by blocks;
//! - `varint_reduced_state`: its Jacobians on a state without some shape positions.

mod generic_integrator;
mod midpoint_integrator;
mod midpoint_rest;
mod momentum_systems;
mod nmpc;
mod observer;
mod rk_transcription;
mod rolling_disk;
mod steered_car_bounds;
mod tracking;
mod tracking_mpc;
mod varint_curvature;
mod varint_reduced_state;
