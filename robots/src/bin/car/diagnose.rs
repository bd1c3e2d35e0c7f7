//! `car generate` and `car diagnose`: a log of the car with a hidden effect, and the
//! diagnosis of a log (docs/car.md, "Diagnosis"; method: docs/diagnose.md).

use dmech_ocp::solver::{IpOptions, Status};
use robots::car::diagnose::{car_plant, generate};
use robots::car::plan::{plan, CarBounds};
use robots::car::problems::CarProblem;
use robots::car::{Car, CarParams};
use robots::diagnose::read_log::parse_log_limited;
use robots::diagnose::report::{
    diagnosis_json, report_md, residual_plots, residuals_csv, summary_lines,
};
use robots::diagnose::{diagnose, DiagnoseOptions, Plant};
use robots::io::{csv_byte_limit, read_text_limited, OutputSet};
use robots::{progress, say};
use std::path::PathBuf;

/// A log of the car driven by a plan's commands, with hidden effects.
///
/// Plans the problem, then drives the car open loop by the plan's commands (each held for
/// a step) with the hidden effects, read by the paper's sensors (pose of a tracker,
/// steering and wheel encoders, yaw-rate gyro; docs/car.md). Writes DIR/log.csv
/// (columns t, tau_s, u_d, x, y, theta, steer, wheel, yaw_rate) and DIR/truth.json.
#[derive(clap::Args)]
pub struct GenerateArgs {
    /// `parallel-park`, `lane-change`, or a JSON pose file
    problem: String,
    /// A hidden effect NAME=VALUE (repeatable): drive_friction, steering_friction,
    /// reading_offset:<channel>, reading_scale:<channel>, input_offset:<input>,
    /// input_gain:<input>
    #[arg(long, value_name = "NAME=VALUE", value_parser = effect_value)]
    effect: Vec<(String, f64)>,
    /// Seed of the sensor noise
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
}

fn effect_value(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}' is not NAME=VALUE"))?;
    match value.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok((name.trim().to_string(), v)),
        _ => Err(format!("'{value}' is not a finite number")),
    }
}

pub fn run_generate(a: GenerateArgs) -> Result<(), String> {
    let problem = CarProblem::load(&a.problem).map_err(|e| e.to_string())?;
    let opts = IpOptions {
        verbose: false,
        ..IpOptions::default()
    };
    let o = plan(
        &Car::default(),
        &problem,
        CarBounds::default(),
        0.02,
        dmech::Discretisation::FirstOrder,
        opts,
    )
    .map_err(|e| e.to_string())?;
    if o.status != Status::Solved {
        return Err(format!("the plan was not solved: {}", o.status.code()));
    }
    let (log, theta) = generate(CarParams::default(), &o.trajectory, &a.effect, a.seed)
        .map_err(|e| e.to_string())?;
    let plant = car_plant(CarParams::default(), log.h);
    let channels = plant.channels().to_vec();
    let mut files = OutputSet::create(&a.out).map_err(|e| e.to_string())?;
    files
        .write("log.csv", log.to_csv(&channels, plant.inputs()).as_bytes())
        .map_err(|e| e.to_string())?;
    let cat = plant.catalogue();
    let params: serde_json::Map<String, serde_json::Value> = cat
        .params
        .iter()
        .zip(&theta)
        .map(|(p, v)| (p.name.clone(), serde_json::json!(v)))
        .collect();
    let truth = serde_json::json!({
        "problem": a.problem,
        "seed": a.seed,
        "effects": a.effect.iter().map(|(n, v)| serde_json::json!({"name": n, "value": v})).collect::<Vec<_>>(),
        "params": params,
    });
    let json = serde_json::to_string_pretty(&truth).map_err(|e| e.to_string())? + "\n";
    files
        .write("truth.json", json.as_bytes())
        .map_err(|e| e.to_string())?;
    files.commit().map_err(|e| e.to_string())?;
    say!(
        "{} rows of {} s with {}; wrote {}/{{log.csv, truth.json}}",
        log.len(),
        log.h,
        if a.effect.is_empty() {
            "no hidden effect".to_string()
        } else {
            a.effect
                .iter()
                .map(|(n, v)| format!("{n} = {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        },
        a.out.display()
    );
    Ok(())
}

/// Compare the car's model with a measured log and name what it misses.
///
/// The log's columns: t, tau_s, u_d and any of x, y, theta, steer, wheel, yaw_rate (SI
/// units, a uniform time grid). The catalogue: drive_friction, steering_friction, and the
/// offset and scale of every reading and the offset and gain of every input. Writes
/// DIR/diagnosis.json, DIR/report.md, DIR/residuals.csv and DIR/residual_CHANNEL.svg.
///
/// Exit status: 0 diagnosed (whatever the verdict); 1 a malformed log or a fit that cannot
/// start; 2 bad usage.
#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// The measured log (CSV)
    #[arg(value_name = "DATA.csv")]
    data: PathBuf,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores)
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=64))]
    threads: Option<u64>,
    /// The most effects named together
    #[arg(long, value_name = "N", default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=8))]
    max_effects: u64,
    /// No progress on stderr
    #[arg(long)]
    quiet: bool,
}

/// The largest log `car diagnose` reads: an hour at 20 ms.
const MAX_ROWS: usize = 180_001;
/// Bytes a row of a log may take (nine numbers in full precision and separators).
const ROW_BYTES: u64 = 9 * 26;

pub fn run_diagnose(a: DiagnoseArgs) -> Result<(), String> {
    let what = a.data.display().to_string();
    let hint = format!(" (at most {MAX_ROWS} rows)");
    let text = read_text_limited(&a.data, &what, csv_byte_limit(MAX_ROWS, ROW_BYTES), &hint)
        .map_err(|e| e.to_string())?;
    let probe = car_plant(CarParams::default(), 0.02);
    let log = parse_log_limited(
        &text,
        &what,
        probe.channels(),
        probe.inputs(),
        MAX_ROWS,
        &hint,
    )
    .map_err(|e| e.to_string())?;
    let plant = car_plant(CarParams::default(), log.h);
    let mut opts = DiagnoseOptions {
        max_effects: a.max_effects as usize,
        ..Default::default()
    };
    if let Some(n) = a.threads {
        opts.threads = n as usize;
    }
    let mut files = OutputSet::create(&a.out).map_err(|e| e.to_string())?;
    let quiet = a.quiet;
    if !quiet {
        for w in &log.warnings {
            progress!("car: warning: {w}");
        }
    }
    let report = |line: &str| {
        if !quiet {
            progress!("{line}");
        }
    };
    let d = diagnose(&plant, &log, &opts, &report).map_err(|e| e.to_string())?;
    let json = serde_json::to_string_pretty(&diagnosis_json(&plant, &d))
        .map_err(|e| format!("diagnosis.json: {e}"))?;
    let io = |e: robots::io::OutputError| e.to_string();
    files
        .write("diagnosis.json", (json + "\n").as_bytes())
        .map_err(io)?;
    let note = "The car's diagnosis refits no parameter of its model: its effects are forces and the readings' and inputs' offsets, scales and gains, reported here.";
    files
        .write(
            "report.md",
            report_md(&plant, &d, &log, &what, note).as_bytes(),
        )
        .map_err(io)?;
    for (name, svg) in residual_plots(&plant, &d, &log) {
        files.write(&name, svg.as_bytes()).map_err(io)?;
    }
    files
        .write("residuals.csv", residuals_csv(&plant, &d, &log).as_bytes())
        .map_err(io)?;
    files.commit().map_err(io)?;
    for line in summary_lines(&plant, &d) {
        say!("{line}");
    }
    Ok(())
}
