//! The WIP's diagnosis from Python: `wip generate` and `wip diagnose` by
//! `robots::wip::diagnose::request`.

use crate::errors::{bad_input, run_failed, Callback};
use crate::wip::params_from;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robots::cli::on_solver_stack;
use robots::diagnose::DiagnoseOptions;
use robots::wip::diagnose::request::{calibration_keys, diagnose_log, generate_run, parse_effects};
use robots::wip::diagnose::WipPlant;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(wip_generate, m)?)?;
    m.add_function(wrap_pyfunction!(wip_diagnose, m)?)?;
    Ok(())
}

/// A synthetic log (`wip generate`): `log.csv`'s and `truth.json`'s text.
#[pyfunction]
#[pyo3(signature = (effect, seed, duration, params))]
fn wip_generate<'py>(
    py: Python<'py>,
    effect: &str,
    seed: u64,
    duration: f64,
    params: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    if !(1.0..=3600.0).contains(&duration) {
        return Err(bad_input(format!(
            "the duration must be in [1, 3600] s, got {duration}"
        )));
    }
    let effects = parse_effects(effect).map_err(bad_input)?;
    let p = params_from(params)?;
    let g = py
        .detach(|| on_solver_stack(|| generate_run(&p, &effects, seed, duration)))
        .map_err(run_failed)?;
    let plant = WipPlant::new(p);
    let truth = serde_json::to_string_pretty(&g.truth_json(seed)).map_err(run_failed)?;
    let d = PyDict::new(py);
    d.set_item("log_csv", g.log_csv(&plant))?;
    d.set_item("truth", truth)?;
    Ok(d)
}

/// Diagnose the log of `log_csv` (`wip diagnose`; `source` names it in messages and the
/// report): `diagnosis.json`, `report.md`, `residuals.csv` and `params_refit.json` as text,
/// and the log's warnings.
#[pyfunction]
#[pyo3(signature = (log_csv, source, params, window, threads, calibrate, exclude,
    max_effects, progress))]
#[allow(clippy::too_many_arguments)]
fn wip_diagnose<'py>(
    py: Python<'py>,
    log_csv: &str,
    source: &str,
    params: Option<&str>,
    window: f64,
    threads: Option<usize>,
    calibrate: Option<&str>,
    exclude: Vec<String>,
    max_effects: usize,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    if !(window > 0.0 && window.is_finite()) {
        return Err(bad_input(format!("window must be positive, got {window}")));
    }
    if max_effects == 0 {
        return Err(bad_input("max_effects must be at least 1"));
    }
    let mut opts = DiagnoseOptions {
        window_s: window,
        max_effects,
        exclude,
        ..Default::default()
    };
    if let Some(n) = threads {
        if !(1..=64).contains(&n) {
            return Err(bad_input(format!("'{n}' is not a thread count in 1..=64")));
        }
        opts.threads = n;
    }
    if let Some(c) = calibrate {
        opts.calibrate = calibration_keys(c);
    }
    let plant = WipPlant::new(params_from(params)?);
    let log = plant.parse_log(log_csv, source).map_err(bad_input)?;
    plant.check_model(log.h).map_err(bad_input)?;
    let callback = progress.map(Callback::new);
    let report = |line: &str| {
        if let Some(c) = &callback {
            c.call(|_| (line.to_string(),));
        }
    };
    let out = py
        .detach(|| on_solver_stack(|| diagnose_log(&plant, &log, &opts, source, &report)))
        .map_err(run_failed)?;
    if let Some(c) = &callback {
        c.finish()?;
    }
    let json = serde_json::to_string_pretty(&out.json).map_err(run_failed)?;
    let d = PyDict::new(py);
    d.set_item("diagnosis", json)?;
    d.set_item("report_md", out.report_md)?;
    d.set_item("residuals_csv", out.residuals_csv)?;
    d.set_item("params_refit", out.refit.to_json())?;
    d.set_item(
        "left_out",
        out.left_out.iter().map(|e| e.name()).collect::<Vec<_>>(),
    )?;
    d.set_item("warnings", log.warnings.clone())?;
    Ok(d)
}
