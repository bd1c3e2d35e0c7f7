//! The snakeboard (`docs/snakeboard.md`): the third robot, a nonholonomic system whose
//! constraints leave a group direction free, built on `dmech`'s [`dmech::WithMomentum`]
//! and the planning toolkit alone.

pub mod model;

pub use model::{ExtendedSnakeboard, Snakeboard, SnakeboardParams};
pub mod plan;
pub mod problems;
pub mod report;
pub mod simulate;
