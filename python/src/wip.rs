//! The WIP from Python: plan, simulate, parameters.

use crate::errors::{bad_input, run_failed};
use crate::options::{finish, solver_options};
use crate::table::Table;
use dmech::Integrator;
use dmech_ocp::transcription::free_timing::TotalTime;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robots::cli::on_solver_stack;
use robots::io::parse_inputs;
use robots::wip::plan::request::{PlanRequest, PlanRun, ProblemSource};
use robots::wip::plan::CurrentModel;
use robots::wip::simulate::{check_simulation, simulate, Trajectory};
use robots::wip::{ReducedState, Wip, WipParams};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(wip_plan, m)?)?;
    m.add_function(wrap_pyfunction!(wip_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(wip_default_params, m)?)?;
    m.add_function(wrap_pyfunction!(wip_check_params, m)?)?;
    Ok(())
}

/// The columns of `trajectory.csv`.
pub const TRAJECTORY_COLUMNS: [&str; 12] = [
    "t", "x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL", "uR", "uL",
];

/// The parameters from JSON text (`None`: the defaults), refused with the file's message.
pub fn params_from(json: Option<&str>) -> PyResult<WipParams> {
    match json {
        None => Ok(WipParams::default()),
        Some(text) => WipParams::from_json_str(text).map_err(|e| bad_input(format!("params: {e}"))),
    }
}

fn integrator_from(name: &str) -> PyResult<Integrator> {
    name.parse::<Integrator>().map_err(bad_input)
}

/// A trajectory as the table of `trajectory.csv`.
pub fn trajectory_table(traj: &Trajectory) -> Table {
    let mut t = Table::new(&TRAJECTORY_COLUMNS);
    for k in 0..traj.t.len() {
        t.push(
            std::iter::once(traj.t[k])
                .chain(traj.x[k].iter().copied())
                .chain(traj.u[k]),
        );
    }
    t
}

/// Plan: `problem` a benchmark's name or a waypoint file's path, or `waypoints` waypoint
/// JSON. Returns the plan's table and figures; a plan that is not solved is returned with
/// its `message` (the command line's line), for the Python side to raise.
#[pyfunction]
#[pyo3(signature = (problem, waypoints, step, integrator, current, params, u_max, max_iter,
    max_stages, threads, free_timing, time_price, hessian, verbose, progress))]
#[allow(clippy::too_many_arguments)]
fn wip_plan<'py>(
    py: Python<'py>,
    problem: Option<String>,
    waypoints: Option<String>,
    step: f64,
    integrator: &str,
    current: &str,
    params: Option<&str>,
    u_max: f64,
    max_iter: usize,
    max_stages: usize,
    threads: Option<usize>,
    free_timing: bool,
    time_price: Option<f64>,
    hessian: &str,
    verbose: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let defaults = PlanRequest::default();
    let source = match (problem, waypoints) {
        (Some(name), None) => ProblemSource::Named(name),
        (None, Some(json)) => ProblemSource::Json(json),
        _ => return Err(bad_input("give a problem's name or waypoints, not both")),
    };
    if max_stages == 0 {
        return Err(bad_input("max_stages must be at least 1"));
    }
    let (options, callback) = solver_options(
        defaults.options.clone(),
        max_iter,
        threads,
        hessian,
        verbose,
        progress,
    )?;
    let total = match time_price {
        Some(p) if !(p.is_finite() && p >= 0.0) => {
            return Err(bad_input(format!("'{p}' is not a price per second ≥ 0")))
        }
        Some(p) => TotalTime::Priced(p),
        None => TotalTime::Fixed,
    };
    if time_price.is_some() && !free_timing {
        return Err(bad_input("time_price needs free_timing"));
    }
    let request = PlanRequest {
        problem: source,
        integrator: integrator_from(integrator)?,
        current: current.parse::<CurrentModel>().map_err(bad_input)?,
        step,
        params: params_from(params)?,
        u_max,
        max_stages,
        free_timing: free_timing.then_some(total),
        options,
    };
    let run = py.detach(|| on_solver_stack(|| request.run()));
    finish(&callback)?;
    plan_dict(py, &run.map_err(bad_input)?)
}

fn plan_dict<'py>(py: Python<'py>, run: &PlanRun) -> PyResult<Bound<'py, PyDict>> {
    let o = &run.outcome;
    let d = PyDict::new(py);
    d.set_item("name", &run.problem.name)?;
    d.set_item("table", trajectory_table(&run.trajectory).into_py(py)?)?;
    d.set_item("status", o.status.code())?;
    d.set_item("message", run.not_solved())?;
    d.set_item("objective", o.objective)?;
    d.set_item("iterations", o.iterations)?;
    d.set_item("max_violation", o.max_violation)?;
    d.set_item("duality_gap", o.duality_gap)?;
    d.set_item("solve_time_s", o.timings.total)?;
    d.set_item("setup_time_s", run.setup_s)?;
    d.set_item("step", run.problem.h)?;
    d.set_item("integrator", run.request.integrator.name())?;
    d.set_item("current", run.request.current.name())?;
    d.set_item("waypoints", run.problem.points.clone())?;
    d.set_item("waypoint_stages", run.problem.stages.clone())?;
    d.set_item("summary", run.summary_json())?;
    Ok(d)
}

/// Simulate open loop from `x0` with the voltages of `inputs_csv` (columns `t,uR,uL`).
#[pyfunction]
#[pyo3(signature = (x0, inputs_csv, step, integrator, params, max_steps, max_voltage))]
#[allow(clippy::too_many_arguments)]
fn wip_simulate<'py>(
    py: Python<'py>,
    x0: Vec<f64>,
    inputs_csv: &str,
    step: f64,
    integrator: &str,
    params: Option<&str>,
    max_steps: usize,
    max_voltage: f64,
) -> PyResult<Bound<'py, PyDict>> {
    if x0.len() != 9 || x0.iter().any(|v| !v.is_finite()) {
        return Err(bad_input(format!(
            "x0 needs 9 finite numbers (x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL), got {}",
            x0.len()
        )));
    }
    if !(max_voltage > 0.0 && max_voltage.is_finite()) {
        return Err(bad_input(format!(
            "max_voltage must be positive, got {max_voltage}"
        )));
    }
    let x = ReducedState::from_column_slice(&x0);
    let wip = Wip::new(params_from(params)?);
    let integrator = integrator_from(integrator)?;
    let what = "inputs";
    let inputs = parse_inputs(inputs_csv, what).map_err(bad_input)?;
    let n = check_simulation(
        &wip,
        integrator,
        step,
        &x,
        &inputs,
        what,
        max_steps,
        max_voltage,
    )
    .map_err(bad_input)?;
    let traj = py
        .detach(|| on_solver_stack(|| simulate(&wip, integrator, step, &x, &inputs, n)))
        .map_err(run_failed)?;
    let d = PyDict::new(py);
    d.set_item("table", trajectory_table(&traj).into_py(py)?)?;
    Ok(d)
}

/// The default parameters as a parameter file (JSON).
#[pyfunction]
fn wip_default_params() -> String {
    WipParams::default().to_json()
}

/// A parameter file checked and written back whole (every key, SI units).
#[pyfunction]
fn wip_check_params(json: &str) -> PyResult<String> {
    Ok(params_from(Some(json))?.to_json())
}
