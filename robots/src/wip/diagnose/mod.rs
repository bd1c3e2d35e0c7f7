//! `wip diagnose`: compare the model with a measured log, find which unmodelled effect
//! explains the difference, refit, report the gain (method: `docs/diagnose.md`).

pub mod adequacy;
pub mod conditions;
pub mod effects;
pub mod fit;
pub mod generate;
pub mod measured;
pub mod prediction;
pub mod refit;
pub mod report;
pub mod selection;
