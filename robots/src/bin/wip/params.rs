//! `wip params`: the parameters as a parameter file.

use crate::common::{load_params, Failure};
use robots::say;
use std::path::PathBuf;

/// Print the model parameters as a valid parameter file (every key, SI units).
///
/// Without --params: the defaults (the paper's robot). With --params: that file's values
/// merged over the defaults and validated. Keys, units and meanings: docs/formats.md.
#[derive(clap::Args)]
pub struct ParamsArgs {
    /// A parameter file to complete with the defaults and check
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
}

pub fn run(a: ParamsArgs) -> Result<(), Failure> {
    let p = load_params(a.params.as_deref())?;
    say!("{}", p.to_json().trim_end());
    Ok(())
}
