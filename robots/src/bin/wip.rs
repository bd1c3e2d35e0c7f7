//! `wip`: plan, simulate and check the wheeled inverted pendulum.
//! Exit status: 0 success, 1 a failure explained in one line on stderr, 2 bad usage.

use lexopt::prelude::*;
use robots::io::{read_inputs, trajectory_csv, write_atomic};
use robots::wip::simulate::{simulate, Integrator};
use robots::wip::{ReducedState, Wip, WipParams};
use std::path::PathBuf;
use std::process::ExitCode;

/// `println!` that ignores a closed stdout (`wip plan eight | head -1`): the results are in
/// the files and the exit status tells success; std's `println!` would panic on EPIPE.
macro_rules! println {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

const USAGE: &str = "\
usage: wip <subcommand> [options]

subcommands:
  plan       constrained energy-optimal trajectory through waypoints (eight, zigzag, FILE.json)
  simulate   open-loop simulation from a state with given voltages
  bench      the paper's computation-time comparison rerun with our solver
  diagnose   compare the model with a measured log, name the unmodelled effect, refit
  generate   a synthetic measured log: closed-loop run of a model with hidden effects

Run `wip <subcommand> --help` for its options.";

const SIMULATE_HELP: &str = "\
usage: wip simulate --x0 \"x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL\" --inputs FILE.csv
                    [--integrator varint|rk1|rk2|rk4] [--h SECONDS] [--params FILE]
                    [--out DIR]

Simulates the WIP open loop from the reduced state --x0 (SI units, radians) with the
voltages of FILE.csv (columns t,uR,uL; zero-order hold; the first row at t = 0, the last
row's t is the end of the horizon). Writes DIR/trajectory.csv (default DIR: out).

  --integrator  varint (default: the variational integrator, right-point forcing),
                rk1, rk2 (explicit midpoint), rk4 on the continuous model
  --h           step in seconds (default 0.005)
  --params      JSON parameter file; any subset of the keys of model.md's table";

const PLAN_HELP: &str = "\
usage: wip plan <eight|zigzag|FILE.json> [--integrator varint|rk1|rk2|rk4]
                [--current dynamic] [--h SECONDS] [--params FILE] [--out DIR]
                [--max-iter N] [--quiet]

Solves the paper's constrained energy-optimal control problem (benchmarks.md) through the
waypoints of a benchmark or of a waypoint file, and writes DIR/trajectory.csv,
DIR/summary.json and SVG plots (path, voltages, voltage rates, currents, tilt, heading
rate; bounds dashed). The iteration table goes to stderr. Default DIR: out.

  --integrator  varint (default: variational integrator), rk1, rk2, rk4 (continuous model)
  --current     dynamic (default: motor-current dynamics) or algebraic (their steady state)
  --h           step in seconds (default 0.005)
  --params      JSON parameter file (model.md's keys)
  --max-iter    interior-point iteration limit (default 500)
  --quiet       no iteration table

Waypoint file (JSON): {\"name\": \"square\", \"points\": [[0,0],[1,0],[1,1]], \"duration\": 12.0,
  \"accel\": 0.2, \"start_heading\": 0.0, \"end_heading\": 1.5708} (see docs/ocp.md).

Exit status: 0 solved; 1 not solved (infeasible, iteration limit, failure: one line on
stderr, files still written) or a bad input file; 2 bad usage.";

const BENCH_HELP: &str = "\
usage: wip bench [--problems eight,zigzag] [--integrators varint,rk1,rk2,rk4]
                 [--currents dynamic,algebraic] [--time-limit SECONDS] [--out DIR]

Reruns the paper's Figure \"computation time\" (MATLAB + CasADi 3.2.3 + IPOPT, i7-8700;
algebraic current / current dynamics: RK1 690/553 s, RK2 710/544 s, RK4 776/680 s,
VarInt 688/522 s) with our solver: one plan per problem, integrator and current model,
each alone, and prints a table of status, iterations, solve time and objective; writes
DIR/bench.json (default DIR: out). RK runs with the current dynamics take minutes each;
--time-limit stops each plan after that many seconds (status max_iterations; default
none).";

const DIAGNOSE_HELP: &str = "\
usage: wip diagnose <DATA.csv> [--params FILE] [--out DIR] [--window SECONDS]
                    [--threads N] [--quiet]

Compares the model with a measured log (format: interfaces.md), finds which unmodelled
effect of the catalogue explains the difference (tilt_offset, floor_slope, input_delay,
voltage_gain, friction, wheel_radius_asymmetry, payload, dead_zone; pairs of them when one
is not enough), refits its parameters with their uncertainty and reports the gain.
Writes DIR/diagnosis.json, DIR/report.md, DIR/residual_<channel>.svg and
DIR/params_refit.json (the refitted model as a --params file) (default DIR: out).
Readings far outside their channel's range are not fitted (named in the report).
Method: docs/diagnose.md.

  --params   JSON parameter file of the nominal model (model.md's keys)
  --window   length of the prediction windows in seconds (default 0.5)
  --threads  worker threads (default: all cores)
  --quiet    no progress on stderr

Exit status: 0 diagnosed (whatever the verdict); 1 a malformed log (one line naming the
line and column) or a fit that cannot start; 2 bad usage.";

const GENERATE_HELP: &str = "\
usage: wip generate [--effect NAME[+NAME]] [--seed N] [--duration SECONDS]
                    [--params FILE] [--out DIR]

Simulates a closed-loop run (LQR designed on the nominal model, sums of sinusoids as
speed and turn references) of the model with hidden effects, with sensor noise (tilt
0.003 rad, rate 0.02 rad/s, encoders 3600 counts/rev, currents 0.02 A, pose 1 mm /
0.005 rad at 50 Hz), and writes it as a measured log DIR/log.csv that `wip diagnose`
reads, and the hidden truth as DIR/truth.json (default DIR: out). The effects'
magnitudes are drawn from the seed in the ranges of docs/diagnose.md.

  --effect    an effect name of the catalogue, two joined by '+', or none (default)
  --seed      random seed (default 1)
  --duration  length of the log in seconds (default 30)";

/// A failure: exit status and one line.
enum Failure {
    Usage(String),
    Run(String),
}

impl From<lexopt::Error> for Failure {
    fn from(e: lexopt::Error) -> Self {
        Failure::Usage(e.to_string())
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(m)) => {
            eprintln!("wip: {m}\n{USAGE}");
            ExitCode::from(2)
        }
        Err(Failure::Run(m)) => {
            eprintln!("wip: error: {m}");
            ExitCode::from(1)
        }
    }
}

fn run() -> Result<(), Failure> {
    let mut parser = lexopt::Parser::from_env();
    let sub = match parser.next()? {
        Some(Value(v)) => v.string()?,
        Some(Long("help")) | Some(Short('h')) => {
            println!("{USAGE}");
            return Ok(());
        }
        Some(a) => return Err(Failure::Usage(a.unexpected().to_string())),
        None => return Err(Failure::Usage("missing subcommand".into())),
    };
    match sub.as_str() {
        "simulate" => cmd_simulate(parser),
        "plan" => cmd_plan(parser),
        "bench" => cmd_bench(parser),
        "diagnose" => cmd_diagnose(parser),
        "generate" => cmd_generate(parser),
        other => Err(Failure::Usage(format!("unknown subcommand '{other}'"))),
    }
}

fn parse_f64(s: &str, what: &str) -> Result<f64, Failure> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| Failure::Run(format!("{what}: '{s}' is not a finite number")))
}

fn load_params(path: Option<PathBuf>) -> Result<WipParams, Failure> {
    match path {
        None => Ok(WipParams::default()),
        Some(p) => WipParams::from_file(&p).map_err(Failure::Run),
    }
}

fn cmd_simulate(mut parser: lexopt::Parser) -> Result<(), Failure> {
    let (mut x0, mut inputs, mut params, mut out) = (None, None, None, PathBuf::from("out"));
    let mut integrator = "varint".to_string();
    let mut h = 0.005;
    while let Some(arg) = parser.next()? {
        match arg {
            Long("x0") => x0 = Some(parser.value()?.string()?),
            Long("inputs") => inputs = Some(PathBuf::from(parser.value()?)),
            Long("integrator") => integrator = parser.value()?.string()?,
            Long("h") => h = parse_f64(&parser.value()?.string()?, "--h")?,
            Long("params") => params = Some(PathBuf::from(parser.value()?)),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("help") | Short('h') => {
                println!("{SIMULATE_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    let x0 = x0.ok_or_else(|| Failure::Usage("simulate: --x0 is required".into()))?;
    let inputs = inputs.ok_or_else(|| Failure::Usage("simulate: --inputs is required".into()))?;
    let integrator: Integrator = integrator.parse().map_err(Failure::Usage)?;
    if !(h > 0.0 && h <= 1.0) {
        return Err(Failure::Run(format!("--h must be in (0, 1] s, got {h}")));
    }

    let fields: Vec<&str> = x0.split(',').collect();
    if fields.len() != 9 {
        return Err(Failure::Run(format!(
            "--x0 needs 9 comma-separated numbers (x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL), got {}",
            fields.len()
        )));
    }
    let mut x = ReducedState::zeros();
    for (i, f) in fields.iter().enumerate() {
        x[i] = parse_f64(f, &format!("--x0 component {}", i + 1))?;
    }
    let params = load_params(params)?;
    let sched = read_inputs(&inputs).map_err(Failure::Run)?;
    let n = (sched.end() / h).round() as usize;
    if n == 0 {
        return Err(Failure::Run(format!(
            "the inputs file ends at t = {}: the horizon must be at least one step (h = {h})",
            sched.end()
        )));
    }

    let wip = Wip::new(params);
    let t0 = std::time::Instant::now();
    let traj = simulate(&wip, integrator, h, &x, &sched, n).map_err(Failure::Run)?;
    let elapsed = t0.elapsed().as_secs_f64();
    write_atomic(&out, "trajectory.csv", trajectory_csv(&traj).as_bytes()).map_err(Failure::Run)?;
    let xf = traj.x.last().expect("at least one state");
    println!(
        "simulated {n} steps of {h} s with {} in {elapsed:.3} s; final state x={:.6} y={:.6} theta={:.6} alpha={:.6} v_d={:.6} v_theta={:.6} iR={:.6} iL={:.6}",
        integrator.name(),
        xf[0], xf[1], xf[2], xf[3], xf[5], xf[6], xf[7], xf[8]
    );
    println!("wrote {}", out.join("trajectory.csv").display());
    Ok(())
}

fn cmd_plan(mut parser: lexopt::Parser) -> Result<(), Failure> {
    use robots::wip::benchmarks;
    use robots::wip::plan::{plan, CurrentModel, PlanBounds, Transcription};
    use robots::wip::plan_report::{plots, reduced_trajectory, summary_json, waypoint_error_max};
    let t_setup = std::time::Instant::now();
    let (mut which, mut params, mut out) = (None, None, PathBuf::from("out"));
    let mut integrator = "varint".to_string();
    let mut current = "dynamic".to_string();
    let (mut h, mut max_iter, mut quiet) = (0.005, 500usize, false);
    while let Some(arg) = parser.next()? {
        match arg {
            Value(v) if which.is_none() => which = Some(v.string()?),
            Long("integrator") => integrator = parser.value()?.string()?,
            Long("current") => current = parser.value()?.string()?,
            Long("h") => h = parse_f64(&parser.value()?.string()?, "--h")?,
            Long("params") => params = Some(PathBuf::from(parser.value()?)),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("max-iter") => {
                let v = parser.value()?.string()?;
                max_iter = v
                    .parse()
                    .map_err(|_| Failure::Usage(format!("--max-iter: '{v}' is not a count")))?;
            }
            Long("quiet") => quiet = true,
            Long("help") | Short('h') => {
                println!("{PLAN_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    let which = which.ok_or_else(|| {
        Failure::Usage("plan: which problem? (eight, zigzag or a waypoint FILE.json)".into())
    })?;
    let transcription: Transcription = integrator.parse().map_err(Failure::Usage)?;
    let current_model: CurrentModel = current.parse().map_err(Failure::Usage)?;
    if !(h > 0.0 && h <= 0.1) {
        return Err(Failure::Run(format!("--h must be in (0, 0.1] s, got {h}")));
    }
    let problem = match benchmarks::by_name(&which, h) {
        Some(p) => p,
        None => benchmarks::from_file(std::path::Path::new(&which), h).map_err(Failure::Run)?,
    };
    let wip = Wip::new(load_params(params)?);
    let opts = dmech_ocp::ipm::IpOptions {
        verbose: !quiet,
        max_iter,
        ..Default::default()
    };
    let setup = t_setup.elapsed().as_secs_f64();
    if !quiet {
        eprintln!(
            "wip plan {}: {} stages of {} s, {} waypoints, integrator {integrator}, {current} current",
            problem.name,
            problem.n,
            problem.h,
            problem.points.len()
        );
    }
    let o = plan(&wip, &problem, transcription, current_model, opts);
    let traj = reduced_trajectory(&wip, &o);
    let write =
        |name: &str, text: &str| write_atomic(&out, name, text.as_bytes()).map_err(Failure::Run);
    write("trajectory.csv", &trajectory_csv(&traj))?;
    write(
        "summary.json",
        &summary_json(
            &problem.name,
            &integrator,
            &current,
            &problem,
            &o,
            &traj,
            setup,
        ),
    )?;
    for (name, svg) in plots(&problem, &traj, &PlanBounds::default()) {
        write(&name, &svg)?;
    }
    let status = o.status.code();
    println!(
        "{}: {status} after {} iterations in {:.2} s (set-up {:.3} s); objective {:.6}, max violation {:.1e}, waypoint error {:.1e} m",
        problem.name,
        o.iterations,
        o.timings.total,
        setup,
        o.objective,
        o.max_violation,
        waypoint_error_max(&problem, &traj)
    );
    println!(
        "wrote {}/{{trajectory.csv, summary.json, *.svg}}",
        out.display()
    );
    match o.status {
        dmech_ocp::ipm::Status::Solved => Ok(()),
        dmech_ocp::ipm::Status::Infeasible { violation } => Err(Failure::Run(format!(
            "infeasible: the constraint violation stopped decreasing at {violation:.3e} (waypoints or end state out of reach within the bounds)"
        ))),
        dmech_ocp::ipm::Status::MaxIterations => Err(Failure::Run(format!(
            "not solved within {} iterations (--max-iter)",
            o.iterations
        ))),
        dmech_ocp::ipm::Status::Diverged => {
            Err(Failure::Run("the iterates diverged (non-finite or unbounded values)".into()))
        }
        dmech_ocp::ipm::Status::Failed(why) => Err(Failure::Run(format!("solver failed: {why}"))),
    }
}

fn cmd_bench(mut parser: lexopt::Parser) -> Result<(), Failure> {
    use robots::wip::benchmarks;
    use robots::wip::plan::{plan, CurrentModel, Transcription};
    let mut problems = vec!["eight".to_string(), "zigzag".to_string()];
    let mut integrators: Vec<String> = ["varint", "rk1", "rk2", "rk4"].map(String::from).to_vec();
    let mut currents: Vec<String> = ["dynamic", "algebraic"].map(String::from).to_vec();
    let mut out = PathBuf::from("out");
    let mut time_limit = f64::INFINITY;
    let list = |v: String| {
        v.split(',')
            .map(|s| s.trim().to_string())
            .collect::<Vec<_>>()
    };
    while let Some(arg) = parser.next()? {
        match arg {
            Long("problems") => problems = list(parser.value()?.string()?),
            Long("integrators") => integrators = list(parser.value()?.string()?),
            Long("currents") => currents = list(parser.value()?.string()?),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("time-limit") => {
                time_limit = parse_f64(&parser.value()?.string()?, "--time-limit")?
            }
            Long("help") | Short('h') => {
                println!("{BENCH_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    // The paper's times (its Figure "computation time", the eight).
    let paper = |i: &str, c: CurrentModel| match (i, c) {
        ("rk1", CurrentModel::Dynamic) => Some(553.0),
        ("rk2", CurrentModel::Dynamic) => Some(544.0),
        ("rk4", CurrentModel::Dynamic) => Some(680.0),
        ("varint", CurrentModel::Dynamic) => Some(522.0),
        ("rk1", CurrentModel::Algebraic) => Some(690.0),
        ("rk2", CurrentModel::Algebraic) => Some(710.0),
        ("rk4", CurrentModel::Algebraic) => Some(776.0),
        ("varint", CurrentModel::Algebraic) => Some(688.0),
        _ => None,
    };
    let currents = currents
        .iter()
        .map(|c| c.parse::<CurrentModel>())
        .collect::<Result<Vec<_>, _>>()
        .map_err(Failure::Usage)?;
    let wip = Wip::default();
    let mut rows = Vec::new();
    println!(
        "{:<8} {:<7} {:<9} {:<14} {:>6} {:>10} {:>14} {:>12}",
        "problem", "integr.", "current", "status", "iter", "time [s]", "objective", "paper [s]"
    );
    for p in &problems {
        let problem = benchmarks::by_name(p, 0.005)
            .ok_or_else(|| Failure::Usage(format!("unknown benchmark '{p}' (eight, zigzag)")))?;
        for &c in &currents {
            for i in &integrators {
                let tr: Transcription = i.parse().map_err(Failure::Usage)?;
                eprintln!("bench: {p} with {i}, {} current …", c.name());
                let opts = dmech_ocp::ipm::IpOptions {
                    time_limit,
                    ..Default::default()
                };
                let o = plan(&wip, &problem, tr, c, opts);
                let paper_s = if p == "eight" { paper(i, c) } else { None };
                println!(
                    "{:<8} {:<7} {:<9} {:<14} {:>6} {:>10.2} {:>14.4} {:>12}",
                    p,
                    i,
                    c.name(),
                    o.status.code(),
                    o.iterations,
                    o.timings.total,
                    o.objective,
                    paper_s
                        .map(|v| format!("{v:.0}"))
                        .unwrap_or_else(|| "-".into())
                );
                rows.push(serde_json::json!({
                    "problem": p, "integrator": i, "current": c.name(),
                    "status": o.status.code(), "iterations": o.iterations,
                    "solve_time_s": o.timings.total, "objective": o.objective,
                    "max_violation": o.max_violation,
                    "time_breakdown_s": {"derivatives": o.timings.derivatives,
                        "kkt": o.timings.kkt, "line_search": o.timings.line_search},
                    "paper_time_s": paper_s
                }));
            }
        }
    }
    let json = serde_json::to_string_pretty(&serde_json::json!({ "runs": rows }))
        .expect("JSON of numbers and strings");
    write_atomic(&out, "bench.json", (json + "\n").as_bytes()).map_err(Failure::Run)?;
    println!("wrote {}", out.join("bench.json").display());
    Ok(())
}

fn cmd_diagnose(mut parser: lexopt::Parser) -> Result<(), Failure> {
    use robots::wip::diagnose::measured::MeasuredLog;
    use robots::wip::diagnose::report::{diagnosis_json, report_md, residual_plots};
    use robots::wip::diagnose::selection::{diagnose, DiagnoseOptions};
    let (mut data, mut params, mut out, mut quiet) = (None, None, PathBuf::from("out"), false);
    let mut opts = DiagnoseOptions::default();
    while let Some(arg) = parser.next()? {
        match arg {
            Value(v) if data.is_none() => data = Some(PathBuf::from(v)),
            Long("params") => params = Some(PathBuf::from(parser.value()?)),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("window") => opts.window_s = parse_f64(&parser.value()?.string()?, "--window")?,
            Long("threads") => {
                let v = parser.value()?.string()?;
                opts.threads =
                    v.parse().ok().filter(|&n| n > 0).ok_or_else(|| {
                        Failure::Usage(format!("--threads: '{v}' is not a count"))
                    })?;
            }
            Long("quiet") => quiet = true,
            Long("help") | Short('h') => {
                println!("{DIAGNOSE_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    let data = data.ok_or_else(|| Failure::Usage("diagnose: which log? (DATA.csv)".into()))?;
    let p = load_params(params)?;
    let log = MeasuredLog::read(&data).map_err(Failure::Run)?;
    if !quiet {
        for w in &log.warnings {
            eprintln!("wip: warning: {w}");
        }
    }
    // Never panics when stderr is closed (eprintln! would).
    let progress = |line: &str| {
        if !quiet {
            use std::io::Write as _;
            let _ = writeln!(std::io::stderr(), "{line}");
        }
    };
    let d = diagnose(&log, &p, &opts, &progress).map_err(Failure::Run)?;
    let write =
        |name: &str, text: &str| write_atomic(&out, name, text.as_bytes()).map_err(Failure::Run);
    let json =
        serde_json::to_string_pretty(&diagnosis_json(&d)).expect("JSON of numbers and strings");
    write("diagnosis.json", &(json + "\n"))?;
    write(
        "report.md",
        &report_md(&d, &log, &data.display().to_string()),
    )?;
    for (name, svg) in residual_plots(&d, &log) {
        write(&name, &svg)?;
    }
    let (refit, _) = robots::wip::diagnose::refit::refit_params(&d, &p);
    write(
        "params_refit.json",
        &robots::wip::diagnose::refit::params_file_json(&refit),
    )?;
    println!(
        "cause: {}; error {:.3} -> {:.3} (1 = noise floor), gain {:.3}; {:.1} s",
        d.cause, d.error_before, d.error_after, d.gain, d.elapsed_s
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
            println!("  {n} = {v:.6e} ± {u:.1e}");
        }
    }
    println!(
        "wrote {}/{{diagnosis.json, report.md, residual_*.svg, params_refit.json}}",
        out.display()
    );
    Ok(())
}

fn cmd_generate(mut parser: lexopt::Parser) -> Result<(), Failure> {
    use robots::wip::diagnose::effects::Effect;
    use robots::wip::diagnose::generate::{draw_effect, generate, Rng, RunSettings};
    let (mut effect, mut params, mut out) = ("none".to_string(), None, PathBuf::from("out"));
    let (mut seed, mut duration) = (1u64, 30.0);
    while let Some(arg) = parser.next()? {
        match arg {
            Long("effect") => effect = parser.value()?.string()?,
            Long("seed") => {
                let v = parser.value()?.string()?;
                seed = v
                    .parse()
                    .map_err(|_| Failure::Usage(format!("--seed: '{v}' is not a whole number")))?;
            }
            Long("duration") => duration = parse_f64(&parser.value()?.string()?, "--duration")?,
            Long("params") => params = Some(PathBuf::from(parser.value()?)),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("help") | Short('h') => {
                println!("{GENERATE_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    if !(1.0..=3600.0).contains(&duration) {
        return Err(Failure::Run(format!(
            "--duration must be in [1, 3600] s, got {duration}"
        )));
    }
    let p = load_params(params)?;
    let mut effects = Vec::new();
    if effect != "none" {
        // The magnitudes come from their own stream so that the run (reference, noise)
        // does not change with the effect.
        let mut rng = Rng::new(seed.wrapping_add(1000));
        for name in effect.split('+') {
            let e = Effect::from_name(name.trim()).ok_or_else(|| {
                Failure::Usage(format!(
                    "unknown effect '{name}' (expected one of: {})",
                    Effect::ALL.map(|e| e.name()).join(", ")
                ))
            })?;
            effects.push((e, draw_effect(e, &p, &mut rng)));
        }
    }
    let settings = RunSettings {
        duration,
        ..Default::default()
    };
    let g = generate(&p, &effects, seed, &settings).map_err(Failure::Run)?;
    write_atomic(&out, "log.csv", g.log.to_csv().as_bytes()).map_err(Failure::Run)?;
    let truth: Vec<serde_json::Value> = effects
        .iter()
        .map(|(e, theta)| {
            let mut m = serde_json::Map::new();
            for (n, v) in e.parameter_names().iter().zip(theta) {
                m.insert((*n).to_string(), serde_json::json!(v));
            }
            serde_json::json!({ "effect": e.name(), "parameters": m })
        })
        .collect();
    let json = serde_json::to_string_pretty(&serde_json::json!({
        "seed": seed, "duration_s": duration, "h": settings.h, "effects": truth
    }))
    .expect("JSON of numbers and strings");
    write_atomic(&out, "truth.json", (json + "\n").as_bytes()).map_err(Failure::Run)?;
    println!(
        "generated {} rows ({duration} s) with {}; wrote {}/{{log.csv, truth.json}}",
        g.log.len(),
        if effects.is_empty() {
            "no hidden effect".to_string()
        } else {
            effect.clone()
        },
        out.display()
    );
    Ok(())
}
