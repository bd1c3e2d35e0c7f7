//! `wip track`: the closed loop along a plan (feedforward + LQ + guidance + observer).

use crate::common::{load_params, Failure};
use robots::check::check_size;
use robots::io::OutputSet;
use robots::say;
use robots::wip::simulate::Trajectory;
use robots::wip::track::closed_loop::{Controller, Push, TrackConfig};
use robots::wip::track::lq::SAMPLE;
use robots::wip::track::monte_carlo::{monte_carlo, quantile, with_mean_delay, McRun};
use robots::wip::track::nmpc::{NmpcOptions, BUDGET_S, HORIZON, NEWTON_STEPS};
use robots::wip::track::report::{plan_path, plots, read_plan, tracking_csv, tracking_json};
use robots::wip::track::request::{ControllerKind, PreparedTrack, TrackRequest};
use std::path::PathBuf;

/// Track a planned trajectory in closed loop.
///
/// Applies the plan's voltages as feedforward plus the feedback (LQ, or the constrained MPC)
/// on the errors of the guidance and the observer, saturated at ±5 V, to the full nonlinear model
/// (RK4, 0.5 ms substeps), with the sensors' rates, delays and noise (docs/tracking.md).
/// Writes DIR/{tracking.csv, tracking.json, tracking_*.svg} (docs/formats.md).
#[derive(clap::Args)]
pub struct TrackArgs {
    /// A plan: a directory holding trajectory.csv, or the file
    #[arg(value_name = "DIR-or-trajectory.csv")]
    plan: PathBuf,
    /// Seed of the sensor noise, delays and losses
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// No noise, no delay, no loss: the observer sees the true state
    #[arg(long)]
    ideal: bool,
    /// The tracking controller
    #[arg(long, value_enum, default_value_t = ControllerArg::Lq)]
    controller: ControllerArg,
    /// JSON parameter file of the plant and the controller's design (docs/formats.md)
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Run seeds 1..=N instead of one, each with its own random plant parameter error
    /// (--param-error), in parallel; writes montecarlo.json and a table
    #[arg(long, value_name = "N", value_parser = crate::common::positive_count)]
    monte_carlo: Option<usize>,
    /// Relative error of every mass, inertia and motor parameter of the plant in a Monte
    /// Carlo run (uniform in ±REL)
    #[arg(long, value_name = "REL", default_value = "0.1", allow_negative_numbers = true, value_parser = crate::common::relative_error)]
    param_error: f64,
    /// Mean delay of the external pose (s); the paper's law (13–148 ms, mean 63 ms) scaled
    #[arg(long, value_name = "SECONDS", value_parser = crate::common::positive_number)]
    mean_delay: Option<f64>,
    /// A single run with the plant of Monte Carlo seed N (its parameter error, --param-error)
    #[arg(long, value_name = "N", conflicts_with = "monte_carlo")]
    plant_seed: Option<u64>,
    /// Sweep the mean pose delay (0.063 s × 1, 2, 4, 8, 16) over the seeds of --monte-carlo
    /// (default 20) with the nominal plant; reports the largest delay without a fall
    #[arg(long, conflicts_with = "plant_seed")]
    delay_sweep: bool,
    /// The NMPC's horizon in 5-ms samples
    #[arg(long, value_name = "N", default_value_t = HORIZON, value_parser = crate::common::positive_count)]
    horizon: usize,
    /// The NMPC's Newton steps per sample (real-time iteration)
    #[arg(long, value_name = "N", default_value_t = NEWTON_STEPS, value_parser = crate::common::positive_count)]
    newton_steps: usize,
    /// The NMPC's wall-clock budget per sample (s); a solve past it falls back to the LQ
    /// move. Default: none (the Newton steps bound the compute, and the moves do not depend
    /// on the machine's load)
    #[arg(long, value_name = "SECONDS", value_parser = crate::common::positive_number)]
    budget: Option<f64>,
    /// Push the robot at this time (s): its tilt rate changed at once by --push
    #[arg(long, value_name = "SECONDS", requires = "push", conflicts_with_all = ["monte_carlo", "delay_sweep"])]
    push_at: Option<f64>,
    /// The push's change of the tilt rate (rad/s; the sign says which way)
    #[arg(
        long,
        value_name = "RAD_PER_S",
        requires = "push_at",
        allow_negative_numbers = true
    )]
    push: Option<f64>,
    /// Threads of a Monte Carlo run
    #[arg(long, value_name = "N", default_value = "2", value_parser = crate::common::positive_count)]
    threads: usize,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Largest number of 5-ms samples of a run, and of rows of the plan (each row of
    /// tracking.csv takes about 300 bytes)
    #[arg(long, value_name = "N", default_value = "1000000", value_parser = crate::common::positive_count)]
    max_samples: usize,
}

/// The tracking controllers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ControllerArg {
    /// The paper's LQ controller on the ZOH-discretised linear model.
    Lq,
    /// A QP per sample over 0.1 s along the plan (linear time-varying model; voltage bound
    /// hard, rate and tilt bounds soft), solved by the stage-structured interior point
    /// `dmech_ocp::qp`.
    Mpc,
    /// The nonlinear MPC on the plan's own transcription (the first-order variational
    /// integrator of the full model, the plan's bounds; the voltage rate soft), a few
    /// Newton steps per sample from the previous solution (--horizon, --newton-steps,
    /// --budget); the LQ move when a sample's solve fails or runs out of its budget.
    Nmpc,
}

pub fn run(a: TrackArgs) -> Result<(), Failure> {
    let params = load_params(a.params.as_deref())?;
    let path = plan_path(&a.plan);
    let plan = read_plan(&path, a.max_samples, " (raise it with --max-samples)")?;
    check_size(
        "track: samples",
        plan.t.last().copied().unwrap_or(0.0) / SAMPLE,
        a.max_samples,
        300.0,
        "--max-samples",
    )?;
    let request = TrackRequest {
        controller: match a.controller {
            ControllerArg::Lq => ControllerKind::Lq,
            ControllerArg::Mpc => ControllerKind::Mpc,
            ControllerArg::Nmpc => ControllerKind::Nmpc,
        },
        params,
        seed: a.seed,
        ideal: a.ideal,
        mean_delay: a.mean_delay,
        plant_seed: a.plant_seed,
        param_error: a.param_error,
        nmpc: NmpcOptions {
            horizon: a.horizon,
            newton_steps: a.newton_steps,
            budget_s: a.budget.unwrap_or(BUDGET_S),
        },
        push: a
            .push_at
            .zip(a.push)
            .map(|(at_s, tilt_rate)| Push { at_s, tilt_rate }),
    };
    let prepared = request
        .prepare(&plan)
        .map_err(|e| Failure::Run(e.to_string()))?;
    let controller = prepared.controller();
    let cfg = &prepared.config;
    if a.delay_sweep {
        return delay_sweep(&a, &plan, controller, cfg, a.monte_carlo.unwrap_or(20));
    }
    if let Some(n) = a.monte_carlo {
        return monte_carlo_run(&a, &prepared, n);
    }
    let mut files = OutputSet::create(&a.out)?;
    let t0 = std::time::Instant::now();
    let long = *plan.t.last().unwrap_or(&0.0) > 2.0;
    let run = prepared.run(|f| {
        if long {
            robots::progress!("\rtrack: {:3.0} %", 100.0 * f);
        }
    });
    if long {
        robots::progress!("\rtrack: done ");
    }
    if let Some((t, why)) = &run.diverged {
        return Err(Failure::Run(format!(
            "the simulation of the plant diverged at t = {t:.3} s ({why}; {} RK4 substeps per \
             sample): a numerical failure, not a fall; nothing written",
            run.substeps
        )));
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let fig = run.figures();
    let duration = run.samples.last().map_or(0.0, |s| s.t);
    files.write("tracking.csv", tracking_csv(&run).as_bytes())?;
    let json = tracking_json(
        &fig,
        a.seed,
        a.ideal,
        controller.name(),
        run.fell_at,
        duration,
        run.substeps,
    );
    files.write("tracking.json", json.as_bytes())?;
    for (name, svg) in plots(&run) {
        files.write(&name, svg.as_bytes())?;
    }
    files.commit()?;
    say!(
        "tracked {duration:.2} s in {elapsed:.2} s: position error max {:.2} mm rms {:.2} mm, \
         heading error max {:.2} deg rms {:.2} deg, tilt max {:.2} deg, feedback max {:.2} V{}",
        1e3 * fig.position_error_max_m,
        1e3 * fig.position_error_rms_m,
        fig.heading_error_max_rad.to_degrees(),
        fig.heading_error_rms_rad.to_degrees(),
        fig.tilt_max_rad.to_degrees(),
        fig.feedback_voltage_max,
        run.fell_at
            .map_or(String::new(), |t| format!("; FELL at t = {t:.2} s"))
    );
    if let (Some(med), Some(p99), Some(max), Some(wall_med), Some(wall_p99), Some(wall)) = (
        fig.qp_solve_ms_median,
        fig.qp_solve_ms_p99,
        fig.qp_solve_ms_max,
        fig.qp_wall_ms_median,
        fig.qp_wall_ms_p99,
        fig.qp_wall_ms_max,
    ) {
        let what = match controller {
            Controller::Nmpc(_) => "NMPC: solve",
            _ => "MPC: QP solve",
        };
        say!(
            "{what} time per sample (CPU) median {med:.3} ms, p99 {p99:.3} ms, largest \
             {max:.3} ms (wall-clock {wall_med:.3} / {wall_p99:.3} / {wall:.3} ms; the \
             sample is 5 ms); {} samples fell back to the LQ move",
            fig.qp_fallbacks
        );
    }
    say!(
        "wrote {}/{{tracking.csv, tracking.json, tracking_*.svg}}",
        a.out.display()
    );
    if let Some(t) = run.fell_at {
        return Err(Failure::Run(format!("the WIP fell at t = {t:.2} s")));
    }
    Ok(())
}

/// `--monte-carlo N`: seeds 1..=N with plant parameter error, a table on stdout and
/// montecarlo.json (docs/formats.md).
fn monte_carlo_run(a: &TrackArgs, prepared: &PreparedTrack<'_>, n: usize) -> Result<(), Failure> {
    let controller = prepared.controller();
    let mut files = OutputSet::create(&a.out)?;
    let t0 = std::time::Instant::now();
    let runs = prepared.monte_carlo(a.param_error, n as u64, a.threads)?;
    let elapsed = t0.elapsed().as_secs_f64();
    // A diverged run's figures are not a result: the quantiles are over the others.
    let results = || runs.iter().filter(|r| r.diverged_at.is_none());
    let pos: Vec<f64> = results().map(|r| r.figures.position_error_max_m).collect();
    let head: Vec<f64> = results().map(|r| r.figures.heading_error_max_rad).collect();
    let falls: Vec<u64> = runs
        .iter()
        .filter(|r| r.figures.fell)
        .map(|r| r.seed)
        .collect();
    let diverged: Vec<u64> = runs
        .iter()
        .filter(|r| r.diverged_at.is_some())
        .map(|r| r.seed)
        .collect();
    say!("seed  outcome    pos_max[mm]  pos_rms[mm]  head_max[deg]  tilt_max[deg]  fb_max[V]");
    for r in &runs {
        let f = &r.figures;
        if let Some(t) = r.diverged_at {
            say!(
                "{:4}  {:9}  (the plant's simulation diverged at t = {t:.3} s: no figures)",
                r.seed,
                f.outcome
            );
            continue;
        }
        say!(
            "{:4}  {:9}  {:11.2}  {:11.2}  {:13.2}  {:13.2}  {:9.2}",
            r.seed,
            f.outcome,
            1e3 * f.position_error_max_m,
            1e3 * f.position_error_rms_m,
            f.heading_error_max_rad.to_degrees(),
            f.tilt_max_rad.to_degrees(),
            f.feedback_voltage_max
        );
    }
    let json = serde_json::json!({
        "controller": controller.name(),
        "runs": n,
        "param_error": a.param_error,
        "mean_delay_s": a.mean_delay.unwrap_or(0.063),
        "falls": falls.len(),
        "fallen_seeds": falls,
        "diverged": diverged.len(),
        "diverged_seeds": diverged,
        "position_error_max_m": { "median": quantile(&pos, 0.5), "p95": quantile(&pos, 0.95) },
        "heading_error_max_rad": { "median": quantile(&head, 0.5), "p95": quantile(&head, 0.95) },
        "wall_time_s": elapsed,
        "threads": a.threads,
    });
    files.write(
        "montecarlo.json",
        (serde_json::to_string_pretty(&json).expect("serialisable") + "\n").as_bytes(),
    )?;
    files.commit()?;
    say!(
        "{n} runs in {elapsed:.1} s on {} threads: {} fell; max position error median {:.2} mm, \
         95th percentile {:.2} mm",
        a.threads,
        falls.len(),
        1e3 * quantile(&pos, 0.5),
        1e3 * quantile(&pos, 0.95)
    );
    say!("wrote {}", a.out.join("montecarlo.json").display());
    diverged_runs(&diverged)
}

/// Exit 1 if the plant's simulation diverged in any run (seeds listed in the files).
fn diverged_runs(seeds: &[u64]) -> Result<(), Failure> {
    if seeds.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = seeds.iter().map(u64::to_string).collect();
    Err(Failure::Run(format!(
        "the simulation of the plant diverged for seed(s) {} (a numerical failure, not a fall; \
         their figures are left out)",
        list.join(", ")
    )))
}

/// `--delay-sweep`: for each mean pose delay, seeds 1..=n with the nominal plant; a table
/// and delay_sweep.json (docs/formats.md).
fn delay_sweep(
    a: &TrackArgs,
    plan: &Trajectory,
    controller: Controller<'_>,
    cfg: &TrackConfig,
    n: usize,
) -> Result<(), Failure> {
    let mut files = OutputSet::create(&a.out)?;
    let mut rows = Vec::new();
    let mut tolerated: Option<f64> = None;
    let mut all_diverged: Vec<u64> = Vec::new();
    say!("mean_delay[s]  falls  pos_max_median[mm]  pos_max_p95[mm]");
    for factor in [1.0, 2.0, 4.0, 8.0, 16.0] {
        let delay = 0.063 * factor;
        robots::progress!("delay sweep: mean delay {delay:.3} s, {n} seeds …");
        let runs: Vec<McRun> = monte_carlo(
            plan,
            controller,
            &cfg.nominal,
            &with_mean_delay(delay),
            0.0,
            n as u64,
            a.threads,
        )?;
        let pos: Vec<f64> = runs
            .iter()
            .filter(|r| r.diverged_at.is_none())
            .map(|r| r.figures.position_error_max_m)
            .collect();
        let falls = runs.iter().filter(|r| r.figures.fell).count();
        let diverged: Vec<u64> = runs
            .iter()
            .filter(|r| r.diverged_at.is_some())
            .map(|r| r.seed)
            .collect();
        all_diverged.extend(&diverged);
        // The largest delay with no fall (and no run that diverged) at it nor at any
        // smaller one.
        if falls == 0
            && diverged.is_empty()
            && rows
                .iter()
                .all(|r: &serde_json::Value| r["falls"] == 0 && r["diverged"] == 0)
        {
            tolerated = Some(delay);
        }
        say!(
            "{delay:13.3}  {falls:5}  {:18.2}  {:15.2}",
            1e3 * quantile(&pos, 0.5),
            1e3 * quantile(&pos, 0.95)
        );
        rows.push(serde_json::json!({
            "mean_delay_s": delay, "runs": n, "falls": falls, "diverged": diverged.len(),
            "position_error_max_m": { "median": quantile(&pos, 0.5), "p95": quantile(&pos, 0.95) },
        }));
    }
    let json = serde_json::json!({
        "controller": controller.name(),
        "largest_mean_delay_without_fall_s": tolerated,
        "sweep": rows,
    });
    files.write(
        "delay_sweep.json",
        (serde_json::to_string_pretty(&json).expect("serialisable") + "\n").as_bytes(),
    )?;
    files.commit()?;
    match tolerated {
        Some(t) => say!(
            "{}: no fall up to a mean pose delay of {t:.3} s (the largest swept: 1.008 s)",
            controller.name()
        ),
        None => say!(
            "{}: falls already at the paper's mean delay 0.063 s",
            controller.name()
        ),
    }
    say!("wrote {}", a.out.join("delay_sweep.json").display());
    all_diverged.sort_unstable();
    all_diverged.dedup();
    diverged_runs(&all_diverged)
}
