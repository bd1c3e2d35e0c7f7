//! A front-wheel-steered, rear-wheel-driven car with a DC drive motor (`docs/car.md`): the
//! second robot, built on the system traits and the planning toolkit alone.

pub mod diagnose;
pub mod model;
pub mod nmpc;
pub mod plan;
pub mod problems;
pub mod report;
pub mod sensors;
pub mod simulate;
pub mod track;

pub use model::{Car, CarParams};
