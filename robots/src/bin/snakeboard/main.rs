//! `snakeboard`: plan and simulate the snakeboard (`docs/snakeboard.md`), a robot whose
//! constraints leave a group direction free; everything it plans with comes from `dmech`
//! and `dmech-ocp`.

use clap::{Parser, Subcommand, ValueEnum};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use robots::check::check_size;
use robots::cli::{integrator_parser, positive, step, HessianArg};
use robots::io::{read_input_columns, OutputSet};
use robots::snakeboard::plan::{plan, SnakeboardBounds, SnakeboardPlan, SnakeboardStart};
use robots::snakeboard::problems::SnakeboardProblem;
use robots::snakeboard::report::{plots, summary_json, SnakeboardTrajectory};
use robots::snakeboard::simulate::{check_simulation, simulate, SnakeboardState};
use robots::snakeboard::Snakeboard;
use robots::{progress, say};
use std::path::PathBuf;
use std::process::ExitCode;

/// Plan and simulate a snakeboard: a board on two steerable axles with a rotor, driven
/// forward by swinging the rotor and the axles together.
///
/// Exit status: 0 success; 1 bad input or a plan not solved, explained in one line on
/// stderr; 2 bad usage. File formats: docs/snakeboard.md.
#[derive(Parser)]
#[command(
    name = "snakeboard",
    version,
    propagate_version = true,
    max_term_width = 100
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Plan(PlanArgs),
    Simulate(SimulateArgs),
}

const PLAN_INTEGRATORS: &[Integrator] = &[Integrator::FirstOrder, Integrator::Midpoint];

/// The start the solver begins from.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum StartArg {
    /// At rest, the rotor and the axles oscillating a quarter period apart
    Excited,
    /// The kinematic start along the pose path on the extended shape
    Kinematic,
    /// The kinematic start with the oscillation of `excited`
    KinematicExcited,
    /// Everything at the start pose and at rest
    Zero,
}

/// Plan a rest-to-rest manoeuvre: a built-in problem (forward, sideways, turn) or a pose
/// file.
#[derive(clap::Args)]
struct PlanArgs {
    /// `forward`, `sideways`, `turn`, or a JSON pose file (docs/snakeboard.md)
    problem: String,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.02, value_parser = step)]
    step: f64,
    /// Transcription
    #[arg(long, default_value = "midpoint", value_parser = integrator_parser(PLAN_INTEGRATORS))]
    integrator: Integrator,
    /// The solver's start
    #[arg(long, value_enum, default_value_t = StartArg::Excited)]
    start: StartArg,
    /// Iteration limit of the solver
    #[arg(long, default_value_t = 1000)]
    max_iter: usize,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Worker threads of the solver (default: all cores, at most 8)
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=64))]
    threads: Option<u64>,
    /// Curvature of the constraints in the solver: the exact Hessian (default) or SR1
    #[arg(long, value_enum, default_value_t = HessianArg::Exact)]
    hessian: HessianArg,
    /// No iteration log
    #[arg(long)]
    quiet: bool,
}

/// Simulate the snakeboard open loop from a state with given torques.
#[derive(clap::Args)]
struct SimulateArgs {
    /// Initial state "x,y,theta,psi,phi,v_psi,v_phi,p" (p: forward speed, m/s)
    #[arg(long, value_parser = state)]
    x0: [f64; 8],
    /// Torques: CSV with columns t,tau_psi,tau_phi (zero-order hold; the last row's t ends
    /// the run)
    #[arg(long)]
    inputs: PathBuf,
    /// Time-stepping scheme
    #[arg(long, default_value = "midpoint", value_parser = integrator_parser(&Integrator::ALL))]
    integrator: Integrator,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.01, value_parser = step)]
    step: f64,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Largest number of steps accepted (each row of trajectory.csv takes about 290 bytes)
    #[arg(long, value_name = "N", default_value_t = 2_000_000, value_parser = clap::value_parser!(u64).range(1..))]
    max_steps: u64,
    /// Largest |tau_psi| and |tau_phi| accepted in the inputs file, in N m (the plans'
    /// bounds are 0.1 and 0.05 N m)
    #[arg(long, value_name = "NM", default_value_t = 10.0, value_parser = positive)]
    max_torque: f64,
}

fn state(s: &str) -> Result<[f64; 8], String> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|f| f.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == 8 && v.iter().all(|z| z.is_finite()) => {
            Ok(std::array::from_fn(|i| v[i]))
        }
        _ => Err(format!(
            "'{s}' is not eight finite numbers x,y,theta,psi,phi,v_psi,v_phi,p"
        )),
    }
}

fn run_plan(a: PlanArgs) -> Result<(), String> {
    let problem = SnakeboardProblem::load(&a.problem).map_err(|e| e.to_string())?;
    let disc = a
        .integrator
        .variational()
        .expect("the parser offers the variational schemes");
    let bounds = SnakeboardBounds::default();
    SnakeboardPlan::new(&problem, bounds, a.step).map_err(|e| e.to_string())?;
    let defaults = IpOptions::default();
    let opts = a.hessian.apply(IpOptions {
        verbose: !a.quiet,
        max_iter: a.max_iter,
        threads: a.threads.map_or(defaults.threads, |n| n as usize),
        // The plans' measured residual is promised at 1e-9 or less.
        constr_viol_tol: 1e-10,
        ..defaults
    });
    let start = match a.start {
        StartArg::Kinematic => SnakeboardStart::Kinematic,
        StartArg::Excited => SnakeboardStart::Excited,
        StartArg::KinematicExcited => SnakeboardStart::KinematicExcited,
        StartArg::Zero => SnakeboardStart::Zero,
    };
    let start_name = a
        .start
        .to_possible_value()
        .expect("no skipped variants")
        .get_name()
        .to_string();
    let mut files = OutputSet::create(&a.out).map_err(|e| e.to_string())?;
    if !a.quiet {
        progress!(
            "snakeboard plan {}: {:.0} stages of {} s, integrator {}, start {start_name}",
            problem.name,
            problem.duration / a.step,
            a.step,
            a.integrator.name()
        );
    }
    let board = Snakeboard::default();
    let o = plan(&board, &problem, bounds, a.step, disc, start, opts).map_err(|e| e.to_string())?;
    let traj = SnakeboardTrajectory::from_plan(&o);
    let end_error = traj.end_error(&problem.end);
    let put = |e: robots::io::OutputError| e.to_string();
    let csv = traj.csv(&board).map_err(|e| e.to_string())?;
    files.write("trajectory.csv", csv.as_bytes()).map_err(put)?;
    let summary = summary_json(&problem, a.integrator.name(), &start_name, &o, end_error);
    files
        .write("summary.json", summary.as_bytes())
        .map_err(put)?;
    for (file, svg) in plots(&problem, &traj, &bounds) {
        files.write(&file, svg.as_bytes()).map_err(put)?;
    }
    files.commit().map_err(put)?;
    say!(
        "{}: {} after {} iterations in {:.2} s; objective {:.6}, max violation {:.1e}, end error {:.1e}",
        problem.name,
        o.status.code(),
        o.iterations,
        o.solve_time_s,
        o.objective,
        o.max_violation,
        end_error
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
    let inputs = read_input_columns(
        &a.inputs,
        ["tau_psi", "tau_phi"],
        max_steps.saturating_add(1),
        " (one row a step at most: raise it with --max-steps)",
    )
    .map_err(|e| text(&e))?;
    inputs
        .check_limits(
            &what,
            [
                ("tau_psi", a.max_torque, "N m", "--max-torque"),
                ("tau_phi", a.max_torque, "N m", "--max-torque"),
            ],
        )
        .map_err(|e| text(&e))?;
    check_size(
        "simulate: steps",
        inputs.end() / a.step,
        max_steps,
        290.0,
        "--max-steps",
    )
    .map_err(|e| text(&e))?;
    let n = inputs
        .steps_on_grid(a.step, &what, "--step")
        .map_err(|e| text(&e))?;
    let x = a.x0;
    let start = SnakeboardState {
        pose: [x[0], x[1], x[2]],
        shape: [x[3], x[4]],
        velocity: [x[5], x[6]],
        p: x[7],
    };
    let board = Snakeboard::default();
    check_simulation(&board, a.integrator, a.step, &start, &inputs).map_err(|e| text(&e))?;
    let mut files = OutputSet::create(&a.out).map_err(|e| text(&e))?;
    let traj = simulate(&board, a.integrator, a.step, &start, &inputs, n).map_err(|e| text(&e))?;
    let csv = traj.csv(&board).map_err(|e| text(&e))?;
    files
        .write("trajectory.csv", csv.as_bytes())
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
    robots::io::clean_up_on_signals();
    robots::cli::on_solver_stack(run_command)
}

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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(m) => {
            progress!("snakeboard: error: {m}");
            ExitCode::from(1)
        }
    }
}
