//! `car`: plan and simulate the front-wheel-steered, rear-driven car (`docs/car.md`). The
//! second robot's tool: everything it plans with comes from `dmech` and `dmech-ocp`.

use clap::{Parser, Subcommand, ValueEnum};
use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Status};
use robots::car::plan::{plan, CarBounds};
use robots::car::problems::CarProblem;
use robots::car::report::{plots, summary_json, CarTrajectory};
use robots::car::simulate::{simulate, CarIntegrator, CarState};
use robots::car::Car;
use robots::cli::HessianArg;
use robots::io::{parse_input_columns, read_text, OutputSet};
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
}

/// The variational discretisations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Scheme {
    /// First order (the paper's), right-point forcing.
    Varint,
    /// Second order, reversible.
    Midpoint,
    /// Classical Runge–Kutta on the continuous model (simulate only).
    Rk4,
}

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
    #[arg(long, value_enum, default_value_t = Scheme::Varint)]
    integrator: Scheme,
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
    #[arg(long, value_enum, default_value_t = Scheme::Varint)]
    integrator: Scheme,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.005, value_parser = step)]
    step: f64,
    /// Output directory
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(Clone, Copy, Debug)]
struct Vec9([f64; 9]);

fn step(s: &str) -> Result<f64, String> {
    let h: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if h.is_finite() && h > 0.0 && h <= 0.1 {
        Ok(h)
    } else {
        Err(format!("the step must be in (0, 0.1] s, got {s}"))
    }
}

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

fn discretisation(s: Scheme) -> Result<Discretisation, String> {
    match s {
        Scheme::Varint => Ok(Discretisation::FirstOrder),
        Scheme::Midpoint => Ok(Discretisation::Midpoint),
        Scheme::Rk4 => {
            Err("plan: --integrator rk4 is not offered for the car (use varint or midpoint)".into())
        }
    }
}

fn load_problem(arg: &str) -> Result<CarProblem, String> {
    if let Some(p) = CarProblem::builtin(arg) {
        return Ok(p);
    }
    let path = PathBuf::from(arg);
    let what = format!("pose file {}", path.display());
    let text = read_text(&path, &what)
        .map_err(|e| format!("{e} (built-in problems: parallel-park, lane-change)"))?;
    let p: CarProblem = serde_json::from_str(&text).map_err(|e| format!("{what}: {e}"))?;
    let finite = p.poses().iter().flatten().all(|v| v.is_finite());
    if !(finite && p.duration.is_finite() && p.duration > 0.0) {
        return Err(format!("{what}: poses must be finite and the duration > 0"));
    }
    Ok(p)
}

fn run_plan(a: PlanArgs) -> Result<(), String> {
    let problem = load_problem(&a.problem)?;
    let disc = discretisation(a.integrator)?;
    let stages = problem.duration / a.step;
    if stages > 200_000.0 {
        return Err(format!(
            "{} s at {} s is {stages:.0} stages, more than 200000: use a larger --step",
            problem.duration, a.step
        ));
    }
    let mut files = OutputSet::create(&a.out)?;
    let name = a
        .integrator
        .to_possible_value()
        .expect("listed")
        .get_name()
        .to_string();
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
    let o = plan(&Car::default(), &problem, bounds, a.step, disc, opts)?;
    let traj = CarTrajectory::from_plan(&o);
    let pose_error = traj.pose_error_max(&o.stages, &problem);
    files.write("trajectory.csv", traj.csv()?.as_bytes())?;
    files.write(
        "summary.json",
        summary_json(&problem, &name, &o, pose_error).as_bytes(),
    )?;
    for (file, svg) in plots(&problem, &traj, &bounds) {
        files.write(&file, svg.as_bytes())?;
    }
    files.commit()?;
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
    let text = read_text(&a.inputs, &what).map_err(|e| e.to_string())?;
    let inputs = parse_input_columns(&text, &what, ["tau_s", "u_d"])?;
    let steps = inputs.end() / a.step;
    let n = steps.round() as usize;
    if (steps - n as f64).abs() > 1e-6 * steps.max(1.0) {
        return Err(format!(
            "{what}: the last row's t = {} is not a whole number of steps of {} s ({steps:.4})",
            inputs.end(),
            a.step
        ));
    }
    if n > 2_000_000 {
        return Err(format!(
            "{n} steps is more than 2000000: use a larger --step"
        ));
    }
    let mut files = OutputSet::create(&a.out)?;
    let scheme = match a.integrator {
        Scheme::Rk4 => CarIntegrator::Rk4,
        s => CarIntegrator::Variational(discretisation(s)?),
    };
    let x = a.x0.0;
    let start = CarState {
        pose: [x[0], x[1], x[2]],
        shape: nalgebra::Vector3::new(x[3], x[4], x[5]),
        velocity: nalgebra::Vector3::new(x[6], x[7], x[8]),
    };
    let traj = simulate(&Car::default(), scheme, a.step, &start, &inputs, n)?;
    files.write("trajectory.csv", traj.csv()?.as_bytes())?;
    files.commit()?;
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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(m) => {
            progress!("car: error: {m}");
            ExitCode::from(1)
        }
    }
}
