//! The models, integrators and transcriptions against independent answers, in one binary:
//! every test file of `tests/` is compiled and linked as its own binary, and these all
//! instantiate the same generic code (the WIP's and the car's models through `dmech` and
//! `dmech-ocp`), so together they pay for it once.
//!
//! - `car_model`: the car's steady circle against the kinematic bicycle;
//! - `car_plan`: the car's built-in problems planned through the toolkit;
//! - `plan_derivatives`: the transcriptions' structured Jacobians against the generic path;
//! - `reader_fuzz`: property tests of every reader of the `wip` tool;
//! - `reference_objectives`: the benchmarks' objectives against independent solutions;
//! - `snakeboard_model`: the snakeboard against the published momentum equation, coasting
//!   and orders;
//! - `transcription`: the OCP transcriptions against the integrators;
//! - `wip_continuous`: the WIP's continuous model, generic path against the closed form;
//! - `wip_variational`: the variational integrator on the WIP.
//!
//! One module's tests: `cargo test -p robots --test model -- wip_continuous::`.

mod car_model;
mod car_plan;
mod plan_derivatives;
mod reader_fuzz;
mod reference_objectives;
mod snakeboard_model;
mod transcription;
mod wip_continuous;
mod wip_variational;
