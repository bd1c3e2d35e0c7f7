//! `diagnose` in the tools: the framework's model validation ([`dmech_diagnose`], re-exported
//! here whole) with what only the tools need: reading a log from CSV ([`read_log`]) and the
//! output files ([`report`]). The WIP's plant is `crate::wip::diagnose::plant`.

pub use dmech_diagnose::*;

pub mod read_log;
pub mod report;
