//! What the subcommands share: the failure type and its exit status, value parsers that
//! check ranges, the integrator and current-model value enums, and parameter loading (the
//! checks of a run before it starts are `robots::check`).

use clap::CommandFactory;
use robots::wip::plan::CurrentModel;
use robots::wip::WipParams;
use std::path::Path;

/// A failure: bad usage (exit 2, with the subcommand's usage) or a failed run (exit 1,
/// one line).
pub enum Failure {
    Usage(clap::Error),
    Run(String),
}

/// A library error is a failed run: its message is the line printed.
macro_rules! run_failures {
    ($($t:ty),*) => {$(
        impl From<$t> for Failure {
            fn from(e: $t) -> Self {
                Failure::Run(e.to_string())
            }
        }
    )*};
}

run_failures!(
    robots::io::ReadError,
    robots::io::OutputError,
    robots::io::InputError,
    robots::check::CheckError,
    robots::wip::track::closed_loop::TrackError,
    robots::io::NonFiniteValue,
    robots::simulation::SimulationError,
    robots::wip::track::mpc::MpcDesignError,
    robots::wip::diagnose::generate::GenerateError,
    robots::wip::diagnose::request::GenerateRunError
);

impl From<String> for Failure {
    fn from(m: String) -> Self {
        Failure::Run(m)
    }
}

/// A usage error of subcommand `sub`, printed with that subcommand's usage line.
pub fn usage_error(sub: &str, msg: impl std::fmt::Display) -> Failure {
    let mut cmd = crate::Cli::command();
    let cmd = cmd
        .find_subcommand_mut(sub)
        .expect("the subcommand exists")
        .clone()
        .bin_name(format!("wip {sub}"));
    let mut cmd = cmd;
    Failure::Usage(cmd.error(clap::error::ErrorKind::ValueValidation, msg))
}

fn finite(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("'{s}' is not a finite number"))
}

fn step_up_to(s: &str, max: f64) -> Result<f64, String> {
    let h = finite(s)?;
    if h > 0.0 && h <= max {
        Ok(h)
    } else {
        Err(format!("the step must be in (0, {max}] s, got {h}"))
    }
}

/// A step `h` for planning: (0, 0.1] s.
pub fn plan_step(s: &str) -> Result<f64, String> {
    step_up_to(s, 0.1)
}

/// A step `h` for simulation: (0, 1] s.
pub fn sim_step(s: &str) -> Result<f64, String> {
    step_up_to(s, 1.0)
}

/// A positive, finite number of seconds.
pub fn positive_number(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be positive, got {v}"))
    }
}

/// A relative error in (0, 1): below 1, so that every perturbed parameter stays positive.
pub fn relative_error(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(format!(
            "must be in (0, 1) (a relative error of 1 or more can make a mass or an \
             inductance zero or negative), got {v}"
        ))
    }
}

/// A count ≥ 1.
pub fn positive_count(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("'{s}' is not a count ≥ 1")),
    }
}

/// A thread count in 1..=64 (more would only add scheduling on the machines this runs on).
pub fn thread_count(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=64).contains(&n) => Ok(n),
        _ => Err(format!("'{s}' is not a thread count in 1..=64")),
    }
}

/// The motor-current models of a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CurrentArg {
    /// The motor circuit's dynamics (the full model).
    Dynamic,
    /// Its steady state (the paper's algebraic current).
    Algebraic,
}

impl CurrentArg {
    pub fn model(self) -> CurrentModel {
        match self {
            CurrentArg::Dynamic => CurrentModel::Dynamic,
            CurrentArg::Algebraic => CurrentModel::Algebraic,
        }
    }
}

/// The nominal parameters, or a parameter file's, validated (docs/formats.md).
pub fn load_params(path: Option<&Path>) -> Result<WipParams, Failure> {
    match path {
        None => Ok(WipParams::default()),
        Some(p) => Ok(WipParams::from_file(p)?),
    }
}
