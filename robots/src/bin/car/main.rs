//! `car`: plan and simulate the front-wheel-steered, rear-driven car (`docs/car.md`). The
//! second robot's tool: everything it plans with comes from `dmech` and `dmech-ocp`.

use clap::{Parser, Subcommand};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use robots::car::plan::{plan, CarBounds, CarPlan};
use robots::car::problems::CarProblem;
use robots::car::report::{plots, summary_json, CarTrajectory};
use robots::car::simulate::{check_simulation, simulate, CarState};
use robots::car::Car;
use robots::check::check_size;
use robots::cli::{integrator_parser, positive, step, HessianArg};
use robots::io::{read_input_columns, OutputSet};
use robots::{progress, say};
use std::path::PathBuf;
use std::process::ExitCode;

/// Plan and simulate a front-wheel-steered car with a DC drive motor.
///
/// Exit status: 0 success; 1 bad input or a plan not solved, explained in one line on
/// stderr; 2 bad usage. File formats: docs/car.md.
#[derive(Parser)]
#[command(name = "car", version, propagate_version = true, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Plan(PlanArgs),
    Simulate(SimulateArgs),
    Track(TrackArgs),
}

/// The schemes `car plan` offers: the variational ones.
const PLAN_INTEGRATORS: &[Integrator] = &[Integrator::FirstOrder, Integrator::Midpoint];

/// Plan a rest-to-rest manoeuvre: a built-in problem (parallel-park, lane-change) or a
/// pose file.
#[derive(clap::Args)]
struct PlanArgs {
    /// `parallel-park`, `lane-change`, or a JSON pose file (docs/car.md)
    problem: String,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.02, value_parser = step)]
    step: f64,
    /// Transcription
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(PLAN_INTEGRATORS))]
    integrator: Integrator,
    /// Iteration limit of the solver
    #[arg(long, default_value_t = 500)]
    max_iter: usize,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Worker threads of the solver (default: all cores, at most 8)
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=64))]
    threads: Option<u64>,
    /// Curvature of the constraints in the solver: SR1 (default) or the exact Hessian
    #[arg(long, value_enum, default_value_t = HessianArg::Sr1)]
    hessian: HessianArg,
    /// No iteration log
    #[arg(long)]
    quiet: bool,
}

/// Simulate the car open loop from a state with given inputs.
#[derive(clap::Args)]
struct SimulateArgs {
    /// Initial state "x,y,theta,phi,psi,q,v_phi,v_psi,i"
    #[arg(long, value_parser = state)]
    x0: Vec9,
    /// Inputs: CSV with columns t,tau_s,u_d (zero-order hold; the last row's t ends the run)
    #[arg(long)]
    inputs: PathBuf,
    /// Time-stepping scheme
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(&Integrator::ALL))]
    integrator: Integrator,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.005, value_parser = step)]
    step: f64,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Largest number of steps accepted (each row of trajectory.csv takes about 300 bytes)
    #[arg(long, value_name = "N", default_value_t = 2_000_000, value_parser = clap::value_parser!(u64).range(1..))]
    max_steps: u64,
    /// Largest |u_d| accepted in the inputs file, in volts; the model has no saturation, and
    /// the plans drive the motor within 6 V
    #[arg(long, value_name = "VOLTS", default_value_t = 24.0, value_parser = positive)]
    max_voltage: f64,
    /// Largest |tau_s| accepted in the inputs file, in N m (the plans' bound is 0.05 N m)
    #[arg(long, value_name = "NM", default_value_t = 1.0, value_parser = positive)]
    max_torque: f64,
}

/// Plan a built-in problem or a pose file, then track the plan in closed loop by LQ or MPC
/// on a plant car whose masses, inertias and motor constants differ from the plan's
/// (docs/car.md, "Tracking"). Full-state feedback; inputs saturate at ±6 V and ±0.1 N m
/// (the MPC's hard bounds).
#[derive(clap::Args)]
struct TrackArgs {
    /// `parallel-park`, `lane-change`, or a JSON pose file
    problem: String,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.02, value_parser = step)]
    step: f64,
    /// Transcription of the plan and the plant's integrator
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(PLAN_INTEGRATORS))]
    integrator: Integrator,
    /// The controller: LQ feedback along the plan, the constrained MPC, or the plan's inputs
    /// alone
    #[arg(long, value_enum, default_value_t = ControllerArg::Lq)]
    controller: ControllerArg,
    /// The MPC's horizon in stages (with --controller mpc)
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=1000))]
    horizon: u64,
    /// The plant is the plan's car, started on the plan (error zero to round-off)
    #[arg(long)]
    ideal: bool,
    /// Relative error of every mass, inertia and motor constant of the plant, uniform in
    /// ±REL, in [0, 1)
    #[arg(long, value_name = "REL", default_value_t = 0.1, value_parser = unit_interval)]
    param_error: f64,
    /// The plant's start, this far to the left of the plan's, m
    #[arg(long, value_name = "M", default_value_t = 0.02, value_parser = finite)]
    offset: f64,
    /// Seed of the plant's parameters
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run this many plants (seeds SEED, SEED+1, …) and report the errors' median and 95th
    /// percentile
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=10_000))]
    monte_carlo: Option<u64>,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ControllerArg {
    /// Time-varying LQ along the plan (dmech_ocp::tracking)
    Lq,
    /// Constrained MPC along the plan: a QP per stage (dmech_ocp::tracking::Mpc)
    Mpc,
    /// The plan's inputs, open loop
    OpenLoop,
}

fn unit_interval(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..1.0).contains(&v) => Ok(v),
        _ => Err(format!("must be in [0, 1), got {s}")),
    }
}

fn finite(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 1.0 => Ok(v),
        _ => Err(format!("'{s}' is not a finite number of metres within ±1")),
    }
}

#[derive(Clone, Copy, Debug)]
struct Vec9([f64; 9]);

fn state(s: &str) -> Result<Vec9, String> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|f| f.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == 9 && v.iter().all(|z| z.is_finite()) => {
            Ok(Vec9(std::array::from_fn(|i| v[i])))
        }
        _ => Err(format!(
            "'{s}' is not nine finite numbers x,y,theta,phi,psi,q,v_phi,v_psi,i"
        )),
    }
}

fn run_plan(a: PlanArgs) -> Result<(), String> {
    let problem = CarProblem::load(&a.problem).map_err(|e| e.to_string())?;
    let disc = a
        .integrator
        .variational()
        .expect("the parser offers the variational schemes");
    problem.check_stages(a.step).map_err(|e| e.to_string())?;
    let stages = problem.duration / a.step;
    // The mesh's checks (whole steps, distinct poses, no two on one stage) before any work.
    CarPlan::new(&problem, CarBounds::default(), a.step).map_err(|e| e.to_string())?;
    let mut files = OutputSet::create(&a.out).map_err(|e| e.to_string())?;
    let name = a.integrator.name();
    if !a.quiet {
        progress!(
            "car plan {}: {:.0} stages of {} s, integrator {name}",
            problem.name,
            stages,
            a.step
        );
    }
    let defaults = IpOptions::default();
    let opts = a.hessian.apply(IpOptions {
        verbose: !a.quiet,
        max_iter: a.max_iter,
        threads: a.threads.map_or(defaults.threads, |n| n as usize),
        ..defaults
    });
    let bounds = CarBounds::default();
    let o =
        plan(&Car::default(), &problem, bounds, a.step, disc, opts).map_err(|e| e.to_string())?;
    let traj = CarTrajectory::from_plan(&o);
    let pose_error = traj.pose_error_max(&o.stages, &problem);
    let put = |e: robots::io::OutputError| e.to_string();
    files
        .write(
            "trajectory.csv",
            traj.csv().map_err(|e| e.to_string())?.as_bytes(),
        )
        .map_err(put)?;
    files
        .write(
            "summary.json",
            summary_json(&problem, name, &o, pose_error).as_bytes(),
        )
        .map_err(put)?;
    for (file, svg) in plots(&problem, &traj, &bounds) {
        files.write(&file, svg.as_bytes()).map_err(put)?;
    }
    files.commit().map_err(put)?;
    say!(
        "{}: {} after {} iterations in {:.2} s; objective {:.6}, max violation {:.1e}, pose error {:.1e}",
        problem.name,
        o.status.code(),
        o.iterations,
        o.solve_time_s,
        o.objective,
        o.max_violation,
        pose_error
    );
    say!(
        "wrote {}/{{trajectory.csv, summary.json, *.svg}}",
        a.out.display()
    );
    match o.status {
        Status::Solved => Ok(()),
        other => Err(format!("not solved: {}", other.code())),
    }
}

fn run_simulate(a: SimulateArgs) -> Result<(), String> {
    let what = format!("inputs file {}", a.inputs.display());
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let max_steps = usize::try_from(a.max_steps).unwrap_or(usize::MAX);
    // Every row lies on the step grid, so the file holds at most one row per step.
    let inputs = read_input_columns(
        &a.inputs,
        ["tau_s", "u_d"],
        max_steps.saturating_add(1),
        " (one row a step at most: raise it with --max-steps)",
    )
    .map_err(|e| text(&e))?;
    inputs
        .check_limits(
            &what,
            [
                ("tau_s", a.max_torque, "N m", "--max-torque"),
                ("u_d", a.max_voltage, "V", "--max-voltage"),
            ],
        )
        .map_err(|e| text(&e))?;
    check_size(
        "simulate: steps",
        inputs.end() / a.step,
        max_steps,
        300.0,
        "--max-steps",
    )
    .map_err(|e| text(&e))?;
    let n = inputs
        .steps_on_grid(a.step, &what, "--step")
        .map_err(|e| text(&e))?;
    let scheme = a.integrator;
    let x = a.x0.0;
    let start = CarState {
        pose: [x[0], x[1], x[2]],
        shape: nalgebra::Vector3::new(x[3], x[4], x[5]),
        velocity: nalgebra::Vector3::new(x[6], x[7], x[8]),
    };
    let car = Car::default();
    check_simulation(&car, scheme, a.step, &start, &inputs).map_err(|e| text(&e))?;
    let mut files = OutputSet::create(&a.out).map_err(|e| text(&e))?;
    let traj = simulate(&car, scheme, a.step, &start, &inputs, n).map_err(|e| text(&e))?;
    files
        .write(
            "trajectory.csv",
            traj.csv().map_err(|e| text(&e))?.as_bytes(),
        )
        .map_err(|e| text(&e))?;
    files.commit().map_err(|e| text(&e))?;
    let last = traj.pose.last().expect("at least the start");
    say!(
        "simulated {n} steps of {} s; final pose x={:.6} y={:.6} theta={:.6}",
        a.step,
        last[0],
        last[1],
        last[2]
    );
    say!("wrote {}/trajectory.csv", a.out.display());
    Ok(())
}

fn run_track(a: TrackArgs) -> Result<(), String> {
    use robots::car::track::{mismatched, Controller, TrackingDesign};
    let problem = CarProblem::load(&a.problem).map_err(|e| e.to_string())?;
    let disc = a
        .integrator
        .variational()
        .expect("the parser offers the variational schemes");
    let bounds = CarBounds::default();
    CarPlan::new(&problem, bounds, a.step).map_err(|e| e.to_string())?;
    let mut files = OutputSet::create(&a.out).map_err(|e| e.to_string())?;
    let car = Car::default();
    let opts = IpOptions {
        verbose: false,
        ..IpOptions::default()
    };
    let o = plan(&car, &problem, bounds, a.step, disc, opts).map_err(|e| e.to_string())?;
    if o.status != Status::Solved {
        return Err(format!("the plan was not solved: {}", o.status.code()));
    }
    let controller = match a.controller {
        ControllerArg::Lq => Controller::Lq,
        ControllerArg::OpenLoop => Controller::OpenLoop,
        ControllerArg::Mpc => Controller::Mpc {
            horizon: a.horizon as usize,
        },
    };
    let design =
        TrackingDesign::new(&car, &problem, &o, disc, controller).map_err(|e| e.to_string())?;
    let (error, offset) = if a.ideal {
        (0.0, 0.0)
    } else {
        (a.param_error, a.offset)
    };
    let runs = a.monte_carlo.unwrap_or(1);
    let mut results = Vec::new();
    let mut first = None;
    let mut moves = Vec::new();
    for i in 0..runs {
        let seed = a.seed.wrapping_add(i);
        let params = mismatched(&car.params, error, seed);
        let t = design
            .run(&params, offset)
            .map_err(|e| format!("seed {seed}: {e}"))?;
        results.push((seed, t.max_error(), t.end_error()));
        moves.extend_from_slice(&t.mpc_moves);
        first.get_or_insert(t);
    }
    let t = first.expect("at least one run");
    let mut max_errors: Vec<f64> = results.iter().map(|r| r.1).collect();
    let mut end_errors: Vec<f64> = results.iter().map(|r| r.2).collect();
    let mut summary = serde_json::json!({
        "problem": problem.name,
        "integrator": a.integrator.name(),
        "controller": controller.name(),
        "ideal": a.ideal,
        "param_error": error,
        "offset_m": offset,
        "runs": runs,
        "max_position_error_m": spread(&mut max_errors),
        "end_position_error_m": spread(&mut end_errors),
        "seeds": results.iter().map(|(s, m, e)| serde_json::json!({"seed": s, "max_position_error_m": m, "end_position_error_m": e})).collect::<Vec<_>>(),
    });
    if let Controller::Mpc { horizon } = controller {
        summary["horizon"] = horizon.into();
        summary["qp"] = qp_figures(&moves);
    }
    let csv = robots::car::report::tracking_csv(&t).map_err(|e| e.to_string())?;
    let put = |e: robots::io::OutputError| e.to_string();
    files.write("tracking.csv", csv.as_bytes()).map_err(put)?;
    let json = serde_json::to_string_pretty(&summary).expect("a JSON value serialises") + "\n";
    files.write("tracking.json", json.as_bytes()).map_err(put)?;
    for (name, svg) in robots::car::report::tracking_plots(&t) {
        files.write(&name, svg.as_bytes()).map_err(put)?;
    }
    files.commit().map_err(put)?;
    say_tracked(&problem.name, runs, controller, &summary, &a.out);
    Ok(())
}

/// The one-line result of `car track` (and the QPs' figures for the MPC), and where the
/// files are.
fn say_tracked(
    name: &str,
    runs: u64,
    controller: robots::car::track::Controller,
    summary: &serde_json::Value,
    out: &std::path::Path,
) {
    use robots::car::track::Controller;
    say!(
        "{}: {} run(s), {}: max position error median {:.2} mm, p95 {:.2} mm; end error median {:.2} mm",
        name,
        runs,
        match controller {
            Controller::Lq => "LQ",
            Controller::Mpc { .. } => "MPC",
            Controller::OpenLoop => "open loop",
        },
        1e3 * summary["max_position_error_m"]["median"].as_f64().unwrap_or(f64::NAN),
        1e3 * summary["max_position_error_m"]["p95"].as_f64().unwrap_or(f64::NAN),
        1e3 * summary["end_position_error_m"]["median"].as_f64().unwrap_or(f64::NAN)
    );
    if let Some(qp) = summary.get("qp") {
        say!(
            "{} QPs: CPU per sample median {:.3} ms, max {:.3} ms; {} not solved (LQ move)",
            qp["samples"],
            1e3 * qp["cpu_s"]["median"].as_f64().unwrap_or(f64::NAN),
            1e3 * qp["cpu_s"]["max"].as_f64().unwrap_or(f64::NAN),
            qp["not_solved"]
        );
    }
    say!(
        "wrote {}/{{tracking.csv, tracking.json, tracking_*.svg}}",
        out.display()
    );
}

/// The `q`-quantile of `values` (sorted in place; nearest rank).
fn percentile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

/// `{median, p95, worst}` of a nonempty list.
fn spread(values: &mut [f64]) -> serde_json::Value {
    serde_json::json!({
        "median": percentile(values, 0.5),
        "p95": percentile(values, 0.95),
        "worst": percentile(values, 1.0),
    })
}

/// The MPC's QPs over every run: how many, how many not solved, their iterations and the
/// CPU time per sample (the calling thread's: set-up and solve), median and max.
fn qp_figures(moves: &[dmech_ocp::tracking::MpcMove<2>]) -> serde_json::Value {
    if moves.is_empty() {
        return serde_json::json!({ "samples": 0 });
    }
    let mut cpu: Vec<f64> = moves.iter().map(|m| m.cpu_s).collect();
    let mut iterations: Vec<f64> = moves.iter().map(|m| m.iterations as f64).collect();
    serde_json::json!({
        "samples": moves.len(),
        "not_solved": moves.iter().filter(|m| !m.solved()).count(),
        "iterations": {
            "median": percentile(&mut iterations, 0.5),
            "max": percentile(&mut iterations, 1.0),
        },
        "cpu_s": {
            "median": percentile(&mut cpu, 0.5),
            "max": percentile(&mut cpu, 1.0),
        },
    })
}

fn main() -> ExitCode {
    // First, before any thread starts: SIGINT and SIGTERM remove the staging directories.
    robots::io::clean_up_on_signals();
    robots::cli::on_solver_stack(run_command)
}

/// The command line parsed and run.
fn run_command() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(e.exit_code().clamp(0, 255) as u8);
        }
    };
    let result = match cli.command {
        Command::Plan(a) => run_plan(a),
        Command::Simulate(a) => run_simulate(a),
        Command::Track(a) => run_track(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(m) => {
            progress!("car: error: {m}");
            ExitCode::from(1)
        }
    }
}
