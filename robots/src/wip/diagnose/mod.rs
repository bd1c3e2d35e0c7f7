//! `wip diagnose`: the WIP's part of the generic diagnosis (`crate::diagnose`): its
//! catalogue of effects, its prediction model, its plant, the synthetic logs of the tests
//! and the refitted parameter file (method: `docs/diagnose.md`).

pub mod effects;
pub mod generate;
pub mod plant;
pub mod prediction;
pub mod refit;
pub mod request;
pub mod reversal_lockout;

pub use plant::{Channel, WipPlant};
