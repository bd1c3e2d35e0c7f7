//! The interior point on problems defined here on the traits alone. One test binary: each
//! file of `tests/` is compiled and linked on its own, and these share the solver's code
//! for their sizes and the crates they build on.
//!
//! - `clarabel_oracle`: a convex linear–quadratic OCP against `clarabel` on the same QP;
//! - `free_timing`: global variables (free waypoint timing) against a golden-section search;
//! - `ipm_small`: small problems of known structure;
//! - `restoration`: feasibility restoration and the infeasible status;
//! - `terminal_equalities`: a nonlinear condition on the end state.

mod clarabel_oracle;
mod free_timing;
mod ipm_small;
mod restoration;
mod terminal_equalities;
