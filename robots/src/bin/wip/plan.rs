//! `wip plan`: the constrained energy-optimal trajectory through waypoints.

use crate::common::{
    load_params, plan_step, positive_count, thread_count, usage_error, CurrentArg, Failure,
};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, KktMethod};
use dmech_ocp::transcription::free_timing::TotalTime;
use robots::cli::integrator_parser;
use robots::cli::HessianArg;
use robots::io::OutputSet;
use robots::wip::plan::report::{plots, waypoint_error_max};
use robots::wip::plan::request::{PlanRequest, PlanRequestError, ProblemSource, SUPPLY_VOLTAGE};
use robots::wip::simulate::trajectory_csv;
use robots::{progress, say};
use std::path::PathBuf;

/// Plan a constrained energy-optimal trajectory through waypoints.
///
/// Solves the paper's optimal control problem (docs/ocp.md) through the waypoints of a
/// built-in benchmark (eight, zigzag) or of a waypoint file, and writes DIR/trajectory.csv,
/// DIR/summary.json and SVG plots (path, voltages, rates, currents, tilt, heading rate;
/// bounds dashed). The iteration table goes to stderr.
///
/// Exit status: 0 solved; 1 not solved (infeasible, iteration limit, failure: one line on
/// stderr, files still written) or a bad input file; 2 bad usage.
#[derive(clap::Args)]
#[command(
    after_help = "Waypoint file (JSON, docs/formats.md): {\"name\": \"square\", \
\"points\": [[0,0],[1,0],[1,1]], \"duration\": 12.0, \"accel\": 0.2, \"start_heading\": 0.0, \
\"end_heading\": 1.5708}"
)]
pub struct PlanArgs {
    /// eight, zigzag, or a waypoint FILE.json
    #[arg(value_name = "PROBLEM")]
    problem: String,
    /// Transcription of the dynamics
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(&Integrator::ALL))]
    integrator: Integrator,
    /// Motor-current model
    #[arg(long, value_enum, default_value_t = CurrentArg::Dynamic)]
    current: CurrentArg,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long = "step", alias = "h", value_name = "SECONDS", default_value = "0.005", allow_negative_numbers = true, value_parser = plan_step)]
    step: f64,
    /// JSON parameter file (docs/formats.md; `wip params` prints the defaults)
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Voltage bound |u| of the plan in volts, in (0, 5]. Below the motors' 5 V it leaves
    /// the tracking controller a margin for feedback (docs/tracking.md)
    #[arg(long, value_name = "VOLTS", default_value = "5", allow_negative_numbers = true, value_parser = voltage_bound)]
    u_max: f64,
    /// Interior-point iteration limit
    #[arg(long, value_name = "N", default_value = "500", value_parser = positive_count)]
    max_iter: usize,
    /// Largest number of stages accepted (each takes about 28 kB while solving)
    #[arg(long, value_name = "N", default_value = "100000", value_parser = positive_count)]
    max_stages: usize,
    /// Worker threads of the solver (default: all cores, at most 8)
    #[arg(long, value_name = "N", value_parser = thread_count)]
    threads: Option<usize>,
    /// Free waypoint timing: the planner chooses when each waypoint is reached (each
    /// segment's step within [0.5, 2] of --step, the total time fixed unless --time-price),
    /// starting from the fixed timing's plan (docs/ocp.md, "Free waypoint timing"). Needs
    /// --integrator varint
    #[arg(long)]
    free_timing: bool,
    /// With --free-timing, the total time free too, at this price per second added to the
    /// objective (the energy ½ Σ u·i, docs/formats.md); the plan then trades energy for
    /// time within the step ratios [0.5, 2]. Without it the total time stays fixed
    #[arg(long, value_name = "PER_SECOND", value_parser = time_price, requires = "free_timing")]
    time_price: Option<f64>,
    /// Linear algebra of the Newton step: the Riccati recursion (augmented by the globals
    /// of --free-timing) or faer's sparse LDLᵀ of the whole KKT matrix (docs/ocp.md)
    #[arg(long, value_enum, default_value_t = KktArg::Riccati)]
    kkt: KktArg,
    /// Curvature of the constraints in the solver: SR1 (default) or the exact Hessian
    #[arg(long, value_enum, default_value_t = HessianArg::Sr1)]
    hessian: HessianArg,
    /// No iteration table on stderr
    #[arg(long)]
    quiet: bool,
}

/// `--kkt`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum KktArg {
    Riccati,
    Sparse,
}

/// `--u-max`: a voltage bound in (0, 5] V (the motors' supply is 5 V).
fn voltage_bound(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a number of volts"))?;
    if v > 0.0 && v <= SUPPLY_VOLTAGE {
        Ok(v)
    } else {
        Err(PlanRequestError::VoltageBound(v).to_string())
    }
}

/// `--time-price`: a price per second, finite and not negative.
fn time_price(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(p) if p.is_finite() && p >= 0.0 => Ok(p),
        _ => Err(format!("'{s}' is not a price per second ≥ 0")),
    }
}

pub fn run(a: PlanArgs) -> Result<(), Failure> {
    let defaults = IpOptions::default();
    let request = PlanRequest {
        problem: ProblemSource::Named(a.problem.clone()),
        integrator: a.integrator,
        current: a.current.model(),
        step: a.step,
        params: load_params(a.params.as_deref())?,
        u_max: a.u_max,
        max_stages: a.max_stages,
        free_timing: a.free_timing.then_some(match a.time_price {
            Some(p) => TotalTime::Priced(p),
            None => TotalTime::Fixed,
        }),
        options: a.hessian.apply(IpOptions {
            verbose: !a.quiet,
            max_iter: a.max_iter,
            threads: a.threads.unwrap_or(defaults.threads),
            kkt: match a.kkt {
                KktArg::Riccati => KktMethod::Riccati,
                KktArg::Sparse => KktMethod::SparseLdlt,
            },
            ..defaults
        }),
    };
    let prepared = request.prepare().map_err(request_failure)?;
    let mut files = OutputSet::create(&a.out)?;
    let problem = &prepared.problem;
    if !a.quiet {
        progress!(
            "wip plan {}: {} stages of {} s, {} waypoints, integrator {}, {} current",
            problem.name,
            problem.n,
            problem.h,
            problem.points.len(),
            a.integrator.name(),
            a.current.model().name()
        );
    }
    let run = prepared.solve().map_err(request_failure)?;
    if let Some(f) = &run.free_timing {
        say!(
            "{}: fixed timing {} after {} iterations in {:.2} s, objective {:.6}",
            run.problem.name,
            f.fixed_status.code(),
            f.fixed.1,
            f.fixed.2,
            f.fixed.0
        );
    }
    let (o, traj) = (&run.outcome, &run.trajectory);
    files.write("trajectory.csv", trajectory_csv(traj)?.as_bytes())?;
    files.write("summary.json", run.summary_json().as_bytes())?;
    for (name, svg) in plots(&run.problem, traj, &run.bounds()) {
        files.write(&name, svg.as_bytes())?;
    }
    files.commit()?;
    say!(
        "{}: {} after {} iterations in {:.2} s (set-up {:.3} s); objective {:.6}, max violation {:.1e}, waypoint error {:.1e} m",
        run.problem.name,
        o.status.code(),
        o.iterations,
        o.timings.total,
        run.setup_s,
        o.objective,
        o.max_violation,
        waypoint_error_max(&run.problem, traj)
    );
    say!(
        "wrote {}/{{trajectory.csv, summary.json, *.svg}}",
        a.out.display()
    );
    match run.not_solved() {
        None => Ok(()),
        Some(why) => Err(Failure::Run(why)),
    }
}

/// A refused request: bad usage (exit 2) or a refused input (exit 1).
fn request_failure(e: PlanRequestError) -> Failure {
    if e.is_usage() {
        usage_error("plan", e)
    } else {
        Failure::Run(e.to_string())
    }
}
