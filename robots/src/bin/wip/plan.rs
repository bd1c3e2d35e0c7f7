//! `wip plan`: the constrained energy-optimal trajectory through waypoints.

use crate::common::{
    load_params, plan_step, positive_count, thread_count, usage_error, CurrentArg, Failure,
};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, KktMethod, Status};
use dmech_ocp::transcription::free_timing::TotalTime;
use robots::check::check_size;
use robots::cli::integrator_parser;
use robots::cli::HessianArg;
use robots::io::OutputSet;
use robots::wip::plan::free_timing::plan_free_timing;
use robots::wip::plan::problems;
use robots::wip::plan::report::{plots, reduced_trajectory, summary_json, waypoint_error_max};
use robots::wip::plan::{plan, PlanBounds};
use robots::wip::simulate::{check_plan_step, trajectory_csv};
use robots::wip::Wip;
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
    if v > 0.0 && v <= 5.0 {
        Ok(v)
    } else {
        Err(format!("{v} V is outside (0, 5] V"))
    }
}

/// `--time-price`: a price per second, finite and not negative.
fn time_price(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(p) if p.is_finite() && p >= 0.0 => Ok(p),
        _ => Err(format!("'{s}' is not a price per second ≥ 0")),
    }
}

/// Memory per stage while solving: 466 MB peak at 16,940 stages (docs/ocp.md, scale table).
const BYTES_PER_STAGE: f64 = 28e3;

pub fn run(a: PlanArgs) -> Result<(), Failure> {
    let t_setup = std::time::Instant::now();
    let h = a.step;
    let problem = match problems::by_name(&a.problem, h) {
        Some(p) => p,
        None if a.problem.ends_with(".json") || std::path::Path::new(&a.problem).exists() => {
            problems::from_file(std::path::Path::new(&a.problem), h)?
        }
        None => {
            return Err(usage_error(
                "plan",
                format!(
                    "unknown problem '{}': expected eight, zigzag or a waypoint FILE.json",
                    a.problem
                ),
            ))
        }
    };
    check_size(
        &format!("plan {}: stages at h = {h} s", problem.name),
        problem.n as f64,
        a.max_stages,
        BYTES_PER_STAGE,
        "--max-stages",
    )?;
    if a.free_timing && a.integrator != Integrator::FirstOrder {
        return Err(usage_error(
            "plan",
            format!(
                "--free-timing needs --integrator first-order (got {})",
                a.integrator.name()
            ),
        ));
    }
    let wip = Wip::new(load_params(a.params.as_deref())?);
    check_plan_step(&wip, a.integrator, h)?;
    let mut files = OutputSet::create(&a.out)?;
    let defaults = IpOptions::default();
    let opts = a.hessian.apply(IpOptions {
        verbose: !a.quiet,
        max_iter: a.max_iter,
        threads: a.threads.unwrap_or(defaults.threads),
        kkt: match a.kkt {
            KktArg::Riccati => KktMethod::Riccati,
            KktArg::Sparse => KktMethod::SparseLdlt,
        },
        ..defaults
    });
    let (integrator, current) = (a.integrator.name(), a.current.model().name());
    let setup = t_setup.elapsed().as_secs_f64();
    if !a.quiet {
        progress!(
            "wip plan {}: {} stages of {} s, {} waypoints, integrator {integrator}, {current} current",
            problem.name,
            problem.n,
            problem.h,
            problem.points.len()
        );
    }
    let bounds = PlanBounds {
        u_max: a.u_max,
        ..PlanBounds::default()
    };
    let total = match a.time_price {
        Some(p) => TotalTime::Priced(p),
        None => TotalTime::Fixed,
    };
    let (o, free) = if a.free_timing {
        let f = plan_free_timing(&wip, &problem, bounds, a.current.model(), total, opts)
            .map_err(|e| Failure::Run(e.to_string()))?;
        let fixed = (f.fixed.objective, f.fixed.iterations, f.fixed.timings.total);
        say!(
            "{}: fixed timing {} after {} iterations in {:.2} s, objective {:.6}",
            problem.name,
            f.fixed.status.code(),
            fixed.1,
            fixed.2,
            fixed.0
        );
        (f.free, Some((fixed, f.ratios, f.time_cost)))
    } else {
        let o = plan(
            &wip,
            &problem,
            bounds,
            a.integrator,
            a.current.model(),
            opts,
        );
        (o, None)
    };
    let traj = reduced_trajectory(&wip, &o);
    let csv = trajectory_csv(&traj)?;
    files.write("trajectory.csv", csv.as_bytes())?;
    let summary = summary_json(
        &problem.name,
        integrator,
        current,
        &problem,
        &o,
        &traj,
        &bounds,
        setup,
    );
    let summary = match &free {
        None => summary,
        Some(((objective, iterations, time), ratios, time_cost)) => {
            let mut v: serde_json::Value =
                serde_json::from_str(&summary).expect("summary_json writes JSON");
            let t = &traj.t;
            let durations: Vec<f64> = problem
                .stages
                .windows(2)
                .map(|w| t[w[1]] - t[w[0]])
                .collect();
            v["free_timing"] = serde_json::json!({
                "time_price": a.time_price,
                "duration_s": t.last(),
                "time_cost": time_cost,
                "step_ratios": ratios,
                "segment_durations_s": durations,
                "waypoint_times_s": problem.stages.iter().map(|&k| t[k]).collect::<Vec<f64>>(),
                "fixed_timing": {
                    "objective": objective, "iterations": iterations, "solve_time_s": time
                }
            });
            serde_json::to_string_pretty(&v).expect("JSON") + "\n"
        }
    };
    files.write("summary.json", summary.as_bytes())?;
    for (name, svg) in plots(&problem, &traj, &bounds) {
        files.write(&name, svg.as_bytes())?;
    }
    files.commit()?;
    let status = o.status.code();
    say!(
        "{}: {status} after {} iterations in {:.2} s (set-up {:.3} s); objective {:.6}, max violation {:.1e}, waypoint error {:.1e} m",
        problem.name,
        o.iterations,
        o.timings.total,
        setup,
        o.objective,
        o.max_violation,
        waypoint_error_max(&problem, &traj)
    );
    say!(
        "wrote {}/{{trajectory.csv, summary.json, *.svg}}",
        a.out.display()
    );
    match o.status {
        Status::Solved => Ok(()),
        Status::Infeasible { violation } => Err(Failure::Run(format!(
            "infeasible: feasibility restoration ended at a point of local infeasibility, largest violation {violation:.3e} (waypoints or end state out of reach within the bounds)"
        ))),
        Status::MaxIterations => Err(Failure::Run(format!(
            "not solved within {} iterations (--max-iter)",
            o.iterations
        ))),
        Status::TimeLimit => Err(Failure::Run(format!(
            "not solved within the time limit ({} iterations)",
            o.iterations
        ))),
        Status::Diverged => Err(Failure::Run(
            "the iterates diverged (non-finite or unbounded values)".into(),
        )),
        Status::Failed(why) => Err(Failure::Run(format!("solver failed: {why}"))),
    }
}
