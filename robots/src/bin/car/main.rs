//! `car`: plan and simulate the front-wheel-steered, rear-driven car (`docs/car.md`). The
//! second robot's tool: everything it plans with comes from `dmech` and `dmech-ocp`.

mod diagnose;
mod track;

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
    Track(track::TrackArgs),
    Generate(diagnose::GenerateArgs),
    Diagnose(diagnose::DiagnoseArgs),
}

/// The schemes `car plan` offers: the variational ones.
pub(crate) const PLAN_INTEGRATORS: &[Integrator] = &[Integrator::FirstOrder, Integrator::Midpoint];

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
        Command::Track(a) => track::run_track(a),
        Command::Generate(a) => diagnose::run_generate(a),
        Command::Diagnose(a) => diagnose::run_diagnose(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(m) => {
            progress!("car: error: {m}");
            ExitCode::from(1)
        }
    }
}
