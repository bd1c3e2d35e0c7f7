//! `wip diagnose`: compare the model with a measured log, name the unmodelled effect, refit.

use crate::common::{load_params, positive_count, positive_number, Failure};
use robots::diagnose::report::{residual_plots, summary_lines};
use robots::diagnose::DiagnoseOptions;
use robots::io::OutputSet;
use robots::wip::diagnose::request::{calibration_keys, diagnose_log, name_list};
use robots::wip::diagnose::WipPlant;
use robots::{progress, say};
use std::path::PathBuf;

/// Compare the model with a measured log and name the unmodelled effect.
///
/// Finds which effect of the catalogue explains the difference between the log
/// (docs/formats.md) and the model (tilt_offset, floor_slope, input_delay, voltage_gain,
/// friction, wheel_radius_asymmetry, payload, dead_zone, stick_slip, tilt_filter,
/// gear_backlash, reversal_lockout; more together when one is not enough), refits its parameters with their
/// uncertainty and reports the gain. With --calibrate, the robot's own parameters are
/// calibrated first (the combinations the log determines). Writes
/// DIR/diagnosis.json, DIR/params_refit.json (the refitted model as a parameter file that
/// plan and simulate read), DIR/report.md, DIR/residual_CHANNEL.svg and
/// DIR/residuals.csv. Method: docs/diagnose.md.
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
    /// Calibrate the robot's own parameters before judging effects: the combinations of
    /// these parameter-file keys that the log determines (comma-separated; without a
    /// value: m_b,l,I_byy,I_wyy,r,I_m,k_e,R_m,d_v,d_c)
    #[arg(long, value_name = "KEYS", num_args = 0..=1, default_missing_value = "default")]
    calibrate: Option<String>,
    /// Leave effects of the catalogue out (comma-separated names)
    #[arg(long, value_name = "NAMES")]
    exclude: Option<String>,
    /// Largest number of data rows accepted (a larger file is refused from its size before
    /// it is read; `wip generate`'s longest log, 3600 s at 5 ms, has 720,001)
    #[arg(long, value_name = "N", default_value = "1000000", value_parser = positive_count)]
    max_rows: usize,
    /// The most effects named together (added one at a time while the chosen ones leave
    /// the error above the noise)
    #[arg(long, value_name = "N", default_value = "2", value_parser = positive_count)]
    max_effects: usize,
}

pub fn run(a: DiagnoseArgs) -> Result<(), Failure> {
    let mut opts = DiagnoseOptions {
        window_s: a.window,
        max_effects: a.max_effects,
        ..Default::default()
    };
    if let Some(n) = a.threads {
        opts.threads = n;
    }
    if let Some(c) = &a.calibrate {
        opts.calibrate = calibration_keys(c);
    }
    if let Some(e) = &a.exclude {
        opts.exclude = name_list(e);
    }
    let p = load_params(a.params.as_deref())?;
    let plant = WipPlant::new(p);
    let hint = format!(
        " ({} bytes a row of --max-rows {}: raise it with --max-rows)",
        robots::wip::diagnose::plant::LOG_ROW_BYTES,
        a.max_rows
    );
    let log = plant.read_log(&a.data, a.max_rows, &hint)?;
    plant.check_model(log.h)?;
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
    let source = a.data.display().to_string();
    let out = diagnose_log(&plant, &log, &opts, &source, &report).map_err(|e| e.to_string())?;
    let d = &out.diagnosis;
    let json =
        serde_json::to_string_pretty(&out.json).map_err(|e| format!("diagnosis.json: {e}"))?;
    files.write("diagnosis.json", (json + "\n").as_bytes())?;
    files.write("report.md", out.report_md.as_bytes())?;
    for (name, svg) in residual_plots(&plant, d, &log) {
        files.write(&name, svg.as_bytes())?;
    }
    files.write("residuals.csv", out.residuals_csv.as_bytes())?;
    // The refitted model as a parameter file that plan/simulate read.
    files.write("params_refit.json", out.refit.to_json().as_bytes())?;
    files.commit()?;
    for line in summary_lines(&plant, d) {
        say!("{line}");
    }
    if let Some(c) = &d.calibration {
        for k in &c.identifiability.combinations {
            say!(
                "  {} {:<40} relative σ {:.2e}",
                if k.determined {
                    "calibrated"
                } else {
                    "left     "
                },
                k.name,
                k.std
            );
        }
    }
    if !out.left_out.is_empty() {
        say!(
            "  params_refit.json cannot hold {} (not parameters of the model file; see diagnosis.json)",
            out.left_out.iter().map(|e| e.name()).collect::<Vec<_>>().join(", ")
        );
    }
    say!(
        "wrote {}/{{diagnosis.json, params_refit.json, report.md, residual_*.svg, residuals.csv}}",
        a.out.display()
    );
    Ok(())
}
