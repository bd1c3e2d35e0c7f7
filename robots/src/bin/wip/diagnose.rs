//! `wip diagnose`: compare the model with a measured log, name the unmodelled effect, refit.

use crate::common::{load_params, positive_count, positive_number, Failure};
use robots::io::OutputSet;
use robots::wip::diagnose::measured::MeasuredLog;
use robots::wip::diagnose::refit::refit_params;
use robots::wip::diagnose::report::{diagnosis_json, report_md, residual_plots};
use robots::wip::diagnose::selection::{diagnose, DiagnoseOptions};
use robots::{progress, say};
use std::path::PathBuf;

/// Compare the model with a measured log and name the unmodelled effect.
///
/// Finds which effect of the catalogue explains the difference between the log
/// (docs/formats.md) and the model (tilt_offset, floor_slope, input_delay, voltage_gain,
/// friction, wheel_radius_asymmetry, payload, dead_zone; pairs when one is not enough),
/// refits its parameters with their uncertainty and reports the gain. Writes
/// DIR/diagnosis.json, DIR/params_refit.json (the refitted model as a parameter file that
/// plan and simulate read), DIR/report.md and DIR/residual_<channel>.svg. Method:
/// docs/diagnose.md.
///
/// Exit status: 0 diagnosed (whatever the verdict); 1 a malformed log (one line naming the
/// line and column) or a fit that cannot start; 2 bad usage.
#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// The measured log (CSV)
    #[arg(value_name = "DATA.csv")]
    data: PathBuf,
    /// JSON parameter file of the nominal model (docs/formats.md)
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Length of the prediction windows in seconds (at least 10 samples of the log)
    #[arg(long, value_name = "SECONDS", default_value = "0.5", allow_negative_numbers = true, value_parser = positive_number)]
    window: f64,
    /// Worker threads (default: all cores)
    #[arg(long, value_name = "N", value_parser = positive_count)]
    threads: Option<usize>,
    /// No progress on stderr
    #[arg(long)]
    quiet: bool,
}

pub fn run(a: DiagnoseArgs) -> Result<(), Failure> {
    let mut opts = DiagnoseOptions {
        window_s: a.window,
        ..Default::default()
    };
    if let Some(n) = a.threads {
        opts.threads = n;
    }
    let p = load_params(a.params.as_deref())?;
    let log = MeasuredLog::read(&a.data)?;
    let mut files = OutputSet::create(&a.out)?;
    if !a.quiet {
        for w in &log.warnings {
            progress!("wip: warning: {w}");
        }
    }
    let quiet = a.quiet;
    let report = |line: &str| {
        if !quiet {
            progress!("{line}");
        }
    };
    let d = diagnose(&log, &p, &opts, &report)?;
    let json = serde_json::to_string_pretty(&diagnosis_json(&d))
        .map_err(|e| format!("diagnosis.json: {e}"))?;
    files.write("diagnosis.json", (json + "\n").as_bytes())?;
    let md = report_md(&d, &log, &a.data.display().to_string());
    files.write("report.md", md.as_bytes())?;
    for (name, svg) in residual_plots(&d, &log) {
        files.write(&name, svg.as_bytes())?;
    }
    // The refitted model as a parameter file that plan/simulate read.
    let (refit, left_out) = refit_params(&d, &p);
    refit
        .validate()
        .map_err(|e| format!("params_refit.json: {e}"))?;
    files.write("params_refit.json", refit.to_json().as_bytes())?;
    files.commit()?;
    say!(
        "cause: {}; error {:.3} -> {:.3} (1 = noise floor), gain {:.3}; {:.1} s",
        d.cause,
        d.error_before,
        d.error_after,
        d.gain,
        d.elapsed_s
    );
    if !d.effects.is_empty() {
        let c = &d.chosen;
        for ((n, v), u) in c
            .fit
            .candidate
            .parameter_names()
            .iter()
            .zip(&c.fit.theta)
            .zip(&c.fit.std)
        {
            say!("  {n} = {v:.6e} ± {u:.1e}");
        }
    }
    if !left_out.is_empty() {
        say!(
            "  params_refit.json cannot hold {} (not parameters of the model file; see diagnosis.json)",
            left_out.iter().map(|e| e.name()).collect::<Vec<_>>().join(", ")
        );
    }
    say!(
        "wrote {}/{{diagnosis.json, params_refit.json, report.md, residual_*.svg}}",
        a.out.display()
    );
    Ok(())
}
