//! `wip generate`: a synthetic measured log from a closed-loop run with hidden effects.

use crate::common::{load_params, usage_error, Failure};
use robots::io::OutputSet;
use robots::say;
use robots::wip::diagnose::request::{check_magnitudes, generate_run, parse_effects};
use robots::wip::diagnose::WipPlant;
use std::path::PathBuf;

/// Generate a synthetic measured log: a closed-loop run of a model with hidden effects.
///
/// Simulates a closed-loop run (LQR designed on the nominal model, sums of sinusoids as speed
/// and turn references) of the model with hidden effects, with sensor noise (tilt 0.003 rad,
/// rate 0.02 rad/s, encoders 3600 counts/rev, currents 0.02 A, pose 1 mm / 0.005 rad at 50
/// Hz), and writes it as a measured log DIR/log.csv that `wip diagnose` reads, and the
/// hidden truth as DIR/truth.json. The effects' magnitudes are drawn from the seed in the
/// ranges of docs/diagnose.md, or given as NAME=V[,V].
#[derive(clap::Args)]
pub struct GenerateArgs {
    /// An effect of the catalogue, two different ones joined by '+', or none; NAME=V[,V]
    /// sets the effect's parameters (in the order of truth.json, within their plausible
    /// ranges) instead of drawing them, e.g. input_delay=0.015
    #[arg(
        long,
        value_name = "NAME[=V[,V]][+NAME[=V[,V]]]",
        default_value = "none"
    )]
    effect: String,
    /// Random seed
    #[arg(long, value_name = "N", default_value = "1")]
    seed: u64,
    /// Length of the log in seconds, in [1, 3600]
    #[arg(long, value_name = "SECONDS", default_value = "30", allow_negative_numbers = true, value_parser = duration)]
    duration: f64,
    /// JSON parameter file of the model (docs/formats.md)
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
}

fn duration(s: &str) -> Result<f64, String> {
    let v = crate::common::positive_number(s)?;
    if (1.0..=3600.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("the duration must be in [1, 3600] s, got {v}"))
    }
}

pub fn run(a: GenerateArgs) -> Result<(), Failure> {
    let names = parse_effects(&a.effect).map_err(|e| usage_error("generate", e))?;
    let p = load_params(a.params.as_deref())?;
    check_magnitudes(&names, &p).map_err(|e| usage_error("generate", e))?;
    let mut files = OutputSet::create(&a.out)?;
    let g = generate_run(&p, &names, a.seed, a.duration)?;
    let plant = WipPlant::new(p);
    files.write("log.csv", g.log_csv(&plant).as_bytes())?;
    let json = serde_json::to_string_pretty(&g.truth_json(a.seed))
        .map_err(|e| format!("truth.json: {e}"))?;
    files.write("truth.json", (json + "\n").as_bytes())?;
    files.commit()?;
    say!(
        "generated {} rows ({} s) with {}; wrote {}/{{log.csv, truth.json}}",
        g.log.len(),
        a.duration,
        if g.effects.is_empty() {
            "no hidden effect".to_string()
        } else {
            a.effect.clone()
        },
        a.out.display()
    );
    Ok(())
}
