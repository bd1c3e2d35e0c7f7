//! The wheeled inverted pendulum with motor-charge coordinates (`docs/wip.md`).
//!
//! Configuration `q = (x, y, θ, α, φR, φL, qR, qL)`, group `g = (x, y, θ) ∈ SE(2)`, shape
//! `s = (α, φR, φL, qR, qL)`, shape velocity `v_s = (v_α, v_φR, v_φL, iR, iL)`. The wheel
//! angles are absolute (measured from the inertial frame).

pub mod algebraic_current;
pub mod closed_form;
pub mod diagnose;
pub mod invariants;
pub mod model;
pub mod params;
pub mod plan;
pub mod simulate;
pub mod state;
pub mod track;

pub use model::Wip;
pub use params::WipParams;
pub use state::{ReducedState, NS, NU};
