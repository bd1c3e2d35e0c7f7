//! The WIP's closed loop from Python: `wip track` by `robots::wip::track::request`.

use crate::errors::{bad_input, run_failed, Callback};
use crate::table::Table;
use crate::wip::params_from;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robots::cli::on_solver_stack;
use robots::wip::track::closed_loop::TrackRun;
use robots::wip::track::report::{parse_plan, tracking_json, tracking_row};
use robots::wip::track::request::{ControllerKind, TrackRequest};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(wip_track, m)?)?;
    Ok(())
}

/// The columns of `tracking.csv`.
pub const TRACKING_COLUMNS: [&str; 18] = [
    "t",
    "x",
    "y",
    "theta",
    "alpha",
    "x_ref",
    "y_ref",
    "theta_ref",
    "alpha_ref",
    "x_est",
    "y_est",
    "theta_est",
    "uR_ff",
    "uL_ff",
    "uR_fb",
    "uL_fb",
    "uR",
    "uL",
];

/// A closed-loop run as the table of `tracking.csv` (full precision).
fn tracking_table(run: &TrackRun) -> Table {
    let mut t = Table::new(&TRACKING_COLUMNS);
    for p in &run.samples {
        t.push(tracking_row(p));
    }
    t
}

/// The request from the keyword arguments, checked as `wip track` checks its options.
#[allow(clippy::too_many_arguments)]
fn request(
    controller: &str,
    seed: u64,
    ideal: bool,
    params: Option<&str>,
    plant_seed: Option<u64>,
    param_error: f64,
    mean_delay: Option<f64>,
) -> PyResult<TrackRequest> {
    if !(param_error > 0.0 && param_error < 1.0) {
        return Err(bad_input(format!(
            "param_error must be in (0, 1) (a relative error of 1 or more can make a mass or \
             an inductance zero or negative), got {param_error}"
        )));
    }
    if let Some(d) = mean_delay {
        if !(d > 0.0 && d.is_finite()) {
            return Err(bad_input(format!("mean_delay must be positive, got {d}")));
        }
    }
    Ok(TrackRequest {
        controller: controller.parse::<ControllerKind>().map_err(bad_input)?,
        params: params_from(params)?,
        seed,
        ideal,
        mean_delay,
        plant_seed,
        param_error,
        // The NMPC ("nmpc") with the command line's defaults.
        ..TrackRequest::default()
    })
}

/// Track the plan of `plan_csv` (a `trajectory.csv`'s text) in closed loop. One run: the
/// table of `tracking.csv` and `tracking.json`'s text; with `monte_carlo = n`: seeds 1..=n,
/// each run's figures as JSON text (a list of `{seed, diverged_at, figures}`).
#[pyfunction]
#[pyo3(signature = (plan_csv, controller, seed, ideal, params, plant_seed, param_error,
    mean_delay, monte_carlo, threads, progress))]
#[allow(clippy::too_many_arguments)]
fn wip_track<'py>(
    py: Python<'py>,
    plan_csv: &str,
    controller: &str,
    seed: u64,
    ideal: bool,
    params: Option<&str>,
    plant_seed: Option<u64>,
    param_error: f64,
    mean_delay: Option<f64>,
    monte_carlo: Option<usize>,
    threads: usize,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let req = request(
        controller,
        seed,
        ideal,
        params,
        plant_seed,
        param_error,
        mean_delay,
    )?;
    if monte_carlo == Some(0) {
        return Err(bad_input("monte_carlo must be at least 1"));
    }
    if monte_carlo.is_some() && plant_seed.is_some() {
        return Err(bad_input("plant_seed and monte_carlo exclude each other"));
    }
    if !(1..=64).contains(&threads) {
        return Err(bad_input(format!(
            "'{threads}' is not a thread count in 1..=64"
        )));
    }
    let plan = parse_plan(plan_csv, "plan", usize::MAX, "").map_err(bad_input)?;
    let prepared = req.prepare(&plan).map_err(bad_input)?;
    let d = PyDict::new(py);
    if let Some(n) = monte_carlo {
        let runs = py
            .detach(|| on_solver_stack(|| prepared.monte_carlo(param_error, n as u64, threads)))
            .map_err(run_failed)?;
        let rows: Vec<serde_json::Value> = runs
            .iter()
            .map(|r| {
                serde_json::json!({
                    "seed": r.seed, "diverged_at": r.diverged_at, "figures": r.figures
                })
            })
            .collect();
        d.set_item("controller", prepared.controller().name())?;
        d.set_item("runs", serde_json::Value::Array(rows).to_string())?;
        return Ok(d);
    }
    let callback = progress.map(Callback::new);
    let run = py.detach(|| {
        on_solver_stack(|| {
            prepared.run(|f| {
                if let Some(c) = &callback {
                    c.call(|_| (f,));
                }
            })
        })
    });
    if let Some(c) = &callback {
        c.finish()?;
    }
    if let Some((t, why)) = &run.diverged {
        return Err(run_failed(format!(
            "the simulation of the plant diverged at t = {t:.3} s ({why}; {} RK4 substeps per \
             sample): a numerical failure, not a fall",
            run.substeps
        )));
    }
    let duration = run.samples.last().map_or(0.0, |s| s.t);
    let json = tracking_json(
        &run.figures(),
        seed,
        ideal,
        prepared.controller().name(),
        run.fell_at,
        duration,
        run.substeps,
    );
    d.set_item("table", tracking_table(&run).into_py(py)?)?;
    d.set_item("figures", json)?;
    Ok(d)
}
