//! `car track`: the plan tracked in closed loop (docs/car.md, "Tracking").

use crate::PLAN_INTEGRATORS;
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use robots::car::nmpc::{NmpcOptions, BUDGET_S, NEWTON_STEPS};
use robots::car::plan::{plan, CarBounds, CarPlan};
use robots::car::problems::CarProblem;
use robots::car::sensors::CarSensorModel;
use robots::car::track::{mismatched, CarTracking, Controller, Sensing, TrackingDesign};
use robots::car::Car;
use robots::cli::{integrator_parser, positive, step};
use robots::io::OutputSet;
use robots::say;
use std::path::PathBuf;

/// Plan a built-in problem or a pose file, then track the plan in closed loop by LQ, MPC or
/// the nonlinear MPC on a plant car whose masses, inertias and motor constants differ from
/// the plan's (docs/car.md, "Tracking"), on the estimate of an observer from the car's
/// encoders, gyro and late poses (or on the exact state); inputs saturate at ±6 V and
/// ±0.1 N m (the MPC's and the NMPC's hard bounds).
#[derive(clap::Args)]
pub struct TrackArgs {
    /// `parallel-park`, `lane-change`, or a JSON pose file
    problem: String,
    /// Time step in seconds, in (0, 0.1]
    #[arg(long, default_value_t = 0.02, value_parser = step)]
    step: f64,
    /// Transcription of the plan and the plant's integrator
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(PLAN_INTEGRATORS))]
    integrator: Integrator,
    /// The controller: LQ feedback along the plan, the constrained MPC, the nonlinear MPC,
    /// or the plan's inputs alone
    #[arg(long, value_enum, default_value_t = ControllerArg::Lq)]
    controller: ControllerArg,
    /// The MPC's and the NMPC's horizon in stages (with --controller mpc or nmpc)
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=1000))]
    horizon: u64,
    /// The NMPC's Newton steps per stage (real-time iteration)
    #[arg(long, value_name = "N", default_value_t = NEWTON_STEPS as u64, value_parser = clap::value_parser!(u64).range(1..=100))]
    newton_steps: u64,
    /// The NMPC's wall-clock budget per stage (s); a solve past it falls back to the LQ
    /// move. Default: none (the Newton steps bound the compute, and the moves do not depend
    /// on the machine's load)
    #[arg(long, value_name = "SECONDS", value_parser = positive, allow_negative_numbers = true)]
    budget: Option<f64>,
    /// What the controller acts on: the observer's estimate from the paper-like sensors
    /// (default; `exact` with --ideal), from noise-free immediate readings, or the plant's
    /// state read exactly
    #[arg(long, value_enum)]
    sensors: Option<SensorsArg>,
    /// The plant is the plan's car, started on the plan, its state read exactly unless
    /// --sensors says otherwise (error zero to round-off)
    #[arg(long)]
    ideal: bool,
    /// The position error against the pose's mean delay (0.063 s × 1, 2, 4, 8, 16), the
    /// paper's sensors, seeds SEED … SEED + N − 1 (N from --monte-carlo, default 20) at
    /// each: a table and delay_sweep.json
    #[arg(long, conflicts_with_all = ["sensors", "ideal"])]
    delay_sweep: bool,
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
enum SensorsArg {
    /// Wheel and steering encoders, a gyro and late 50-Hz poses, fused by the observer
    Paper,
    /// The same sensors without noise, quantisation, delay or loss, through the observer
    Ideal,
    /// The plant's state read exactly, no observer
    Exact,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ControllerArg {
    /// Time-varying LQ along the plan (dmech_ocp::tracking)
    Lq,
    /// Constrained MPC along the plan: a QP per stage (dmech_ocp::tracking::Mpc)
    Mpc,
    /// Nonlinear MPC on the plan's own transcription, a few Newton steps per stage from the
    /// previous solution (--horizon, --newton-steps, --budget); the LQ move when a stage's
    /// solve fails or runs out of its budget (dmech_ocp::tracking::nmpc)
    Nmpc,
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

pub fn run_track(a: TrackArgs) -> Result<(), String> {
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
        ControllerArg::Nmpc => Controller::Nmpc(NmpcOptions {
            horizon: a.horizon as usize,
            newton_steps: a.newton_steps as usize,
            budget_s: a.budget.unwrap_or(BUDGET_S),
        }),
    };
    let design =
        TrackingDesign::new(&car, &problem, &o, disc, controller).map_err(|e| e.to_string())?;
    let (error, offset) = if a.ideal {
        (0.0, 0.0)
    } else {
        (a.param_error, a.offset)
    };
    let runs = a.monte_carlo.unwrap_or(1);
    if a.delay_sweep {
        return delay_sweep(&a, &design, controller, files, a.monte_carlo.unwrap_or(20));
    }
    let sensing = match a.sensors {
        Some(SensorsArg::Paper) => Sensing::Sensors(CarSensorModel::paper()),
        Some(SensorsArg::Ideal) => Sensing::Sensors(CarSensorModel::ideal()),
        Some(SensorsArg::Exact) => Sensing::Exact,
        None if a.ideal => Sensing::Exact,
        None => Sensing::Sensors(CarSensorModel::paper()),
    };
    let plants = Plants {
        error,
        offset,
        sensing: &sensing,
    };
    let (results, first, solves) = run_seeds(&design, &car, &plants, a.seed, runs)?;
    let t = first.expect("at least one run");
    let mut max_errors: Vec<f64> = results.iter().map(|r| r.max).collect();
    let mut end_errors: Vec<f64> = results.iter().map(|r| r.end).collect();
    let mut rms_errors: Vec<f64> = results.iter().map(|r| r.rms).collect();
    let exact = sensing == Sensing::Exact;
    let seeds: Vec<serde_json::Value> = results
        .iter()
        .map(|r| {
            let mut v = serde_json::json!({"seed": r.seed, "max_position_error_m": r.max, "rms_position_error_m": r.rms, "end_position_error_m": r.end});
            if !exact {
                v["max_estimate_error_m"] = r.estimate.into();
            }
            v
        })
        .collect();
    let mut summary = serde_json::json!({
        "problem": problem.name,
        "integrator": a.integrator.name(),
        "controller": controller.name(),
        "sensors": sensing.name(),
        "ideal": a.ideal,
        "param_error": error,
        "offset_m": offset,
        "runs": runs,
        "max_position_error_m": spread(&mut max_errors),
        "rms_position_error_m": spread(&mut rms_errors),
        "end_position_error_m": spread(&mut end_errors),
        "seeds": seeds,
    });
    if !exact {
        let mut est: Vec<f64> = results.iter().map(|r| r.estimate).collect();
        summary["max_estimate_error_m"] = spread(&mut est);
        summary["poses"] = serde_json::json!({
            "fused": results.iter().map(|r| r.fused).sum::<usize>(),
            "dropped": results.iter().map(|r| r.dropped).sum::<usize>(),
        });
    }
    match controller {
        Controller::Mpc { horizon } => {
            summary["horizon"] = horizon.into();
            summary["qp"] = solve_figures(&solves);
        }
        Controller::Nmpc(o) => {
            summary["horizon"] = o.horizon.into();
            summary["newton_steps"] = o.newton_steps.into();
            summary["budget_s"] = if o.budget_s.is_finite() {
                o.budget_s.into()
            } else {
                serde_json::Value::Null
            };
            summary["nmpc"] = solve_figures(&solves);
        }
        _ => {}
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

/// The plants of a Monte Carlo: the parameter error, the start's offset, the sensing.
struct Plants<'a> {
    error: f64,
    offset: f64,
    sensing: &'a Sensing,
}

/// One run's figures.
struct RunFigures {
    seed: u64,
    max: f64,
    rms: f64,
    end: f64,
    estimate: f64,
    fused: usize,
    dropped: usize,
}

/// One stage's solve of the MPC or the NMPC: solved (else the LQ move), iterations, CPU and
/// wall-clock time (s; the MPC's wall time is not measured, NaN).
#[derive(Clone, Copy, Debug)]
struct Solve {
    solved: bool,
    iterations: usize,
    cpu_s: f64,
    wall_s: f64,
}

/// The runs of seeds `seed … seed + runs − 1`: their figures, the first run's record and
/// every MPC or NMPC solve.
#[allow(clippy::type_complexity)]
fn run_seeds(
    design: &TrackingDesign<'_>,
    car: &Car,
    plants: &Plants<'_>,
    seed: u64,
    runs: u64,
) -> Result<(Vec<RunFigures>, Option<CarTracking>, Vec<Solve>), String> {
    let mut results = Vec::new();
    let mut first = None;
    let mut solves = Vec::new();
    for i in 0..runs {
        let seed = seed.wrapping_add(i);
        let params = mismatched(&car.params, plants.error, seed);
        let t = design
            .run(&params, plants.offset, plants.sensing, seed)
            .map_err(|e| format!("seed {seed}: {e}"))?;
        results.push(RunFigures {
            seed,
            max: t.max_error(),
            rms: t.rms_error(),
            end: t.end_error(),
            estimate: t.max_estimate_error(),
            fused: t.poses_fused,
            dropped: t.poses_dropped,
        });
        solves.extend(t.mpc_moves.iter().map(|m| Solve {
            solved: m.solved(),
            iterations: m.iterations,
            cpu_s: m.cpu_s,
            wall_s: f64::NAN,
        }));
        solves.extend(t.nmpc_samples.iter().map(|m| Solve {
            solved: m.solved,
            iterations: m.iterations,
            cpu_s: m.cpu_s,
            wall_s: m.wall_s,
        }));
        first.get_or_insert(t);
    }
    Ok((results, first, solves))
}

/// `--delay-sweep`: for each mean pose delay, `n` seeds of the plants the options give,
/// tracked on the paper's sensors with the delays scaled; a table and delay_sweep.json.
fn delay_sweep(
    a: &TrackArgs,
    design: &TrackingDesign<'_>,
    controller: Controller,
    mut files: OutputSet,
    n: u64,
) -> Result<(), String> {
    let car = Car::default();
    let mut rows = Vec::new();
    say!("mean_delay[s]  max_error_median[mm]  max_error_p95[mm]  end_error_median[mm]  end_error_p95[mm]");
    for factor in [1.0, 2.0, 4.0, 8.0, 16.0] {
        let delay = 0.063 * factor;
        robots::progress!("delay sweep: mean delay {delay:.3} s, {n} seeds …");
        let sensing = Sensing::Sensors(CarSensorModel::with_mean_delay(delay));
        let plants = Plants {
            error: a.param_error,
            offset: a.offset,
            sensing: &sensing,
        };
        let (results, _, _) = run_seeds(design, &car, &plants, a.seed, n)?;
        let mut max: Vec<f64> = results.iter().map(|r| r.max).collect();
        let mut end: Vec<f64> = results.iter().map(|r| r.end).collect();
        let (max, end) = (spread(&mut max), spread(&mut end));
        let mm = |v: &serde_json::Value, q: &str| 1e3 * v[q].as_f64().unwrap_or(f64::NAN);
        say!(
            "{delay:13.3}  {:20.2}  {:17.2}  {:20.2}  {:17.2}",
            mm(&max, "median"),
            mm(&max, "p95"),
            mm(&end, "median"),
            mm(&end, "p95")
        );
        rows.push(serde_json::json!({
            "mean_delay_s": delay,
            "runs": n,
            "poses_dropped": results.iter().map(|r| r.dropped).sum::<usize>(),
            "max_position_error_m": max,
            "end_position_error_m": end,
        }));
    }
    let json = serde_json::json!({
        "problem": a.problem,
        "integrator": a.integrator.name(),
        "controller": controller.name(),
        "param_error": a.param_error,
        "offset_m": a.offset,
        "sweep": rows,
    });
    let put = |e: robots::io::OutputError| e.to_string();
    files
        .write(
            "delay_sweep.json",
            (serde_json::to_string_pretty(&json).expect("serialisable") + "\n").as_bytes(),
        )
        .map_err(put)?;
    files.commit().map_err(put)?;
    say!("wrote {}", a.out.join("delay_sweep.json").display());
    Ok(())
}

/// The one-line result of `car track` (and the solves' figures for the MPC and the NMPC),
/// and where the files are.
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
            Controller::Nmpc(_) => "NMPC",
            Controller::OpenLoop => "open loop",
        },
        1e3 * summary["max_position_error_m"]["median"].as_f64().unwrap_or(f64::NAN),
        1e3 * summary["max_position_error_m"]["p95"].as_f64().unwrap_or(f64::NAN),
        1e3 * summary["end_position_error_m"]["median"].as_f64().unwrap_or(f64::NAN)
    );
    for (key, what) in [("qp", "QPs"), ("nmpc", "NMPC solves")] {
        if let Some(f) = summary.get(key) {
            let ms = |q: &str| 1e3 * f["cpu_s"][q].as_f64().unwrap_or(f64::NAN);
            say!(
                "{} {what}: CPU per stage median {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} not solved (LQ move)",
                f["samples"],
                ms("median"),
                ms("p99"),
                ms("max"),
                f["not_solved"]
            );
        }
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

/// The MPC's QPs or the NMPC's solves over every run: how many, how many not solved (the
/// LQ move applied), their iterations and the CPU time of the calling thread per stage
/// (set-up and solve; the NMPC's also as wall-clock time), median, p99 and max.
fn solve_figures(solves: &[Solve]) -> serde_json::Value {
    if solves.is_empty() {
        return serde_json::json!({ "samples": 0 });
    }
    let mut iterations: Vec<f64> = solves.iter().map(|m| m.iterations as f64).collect();
    let times = |f: fn(&Solve) -> f64| {
        let mut t: Vec<f64> = solves.iter().map(f).collect();
        if t.iter().any(|v| v.is_nan()) {
            return serde_json::Value::Null;
        }
        serde_json::json!({
            "median": percentile(&mut t, 0.5),
            "p99": percentile(&mut t, 0.99),
            "max": percentile(&mut t, 1.0),
        })
    };
    let mut figures = serde_json::json!({
        "samples": solves.len(),
        "not_solved": solves.iter().filter(|m| !m.solved).count(),
        "iterations": {
            "median": percentile(&mut iterations, 0.5),
            "max": percentile(&mut iterations, 1.0),
        },
        "cpu_s": times(|m| m.cpu_s),
    });
    let wall = times(|m| m.wall_s);
    if !wall.is_null() {
        figures["wall_s"] = wall;
    }
    figures
}
