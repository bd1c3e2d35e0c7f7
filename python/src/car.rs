//! The car from Python: plan.

use crate::errors::bad_input;
use crate::options::{finish, solver_options};
use crate::table::Table;
use dmech::Integrator;
use dmech_ocp::solver::IpOptions;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robots::car::plan::{plan, CarBounds, CarPlan};
use robots::car::problems::CarProblem;
use robots::car::report::{summary_json, CarTrajectory, CSV_HEADER};
use robots::car::Car;
use robots::cli::on_solver_stack;
use robots::wip::plan::request::not_solved_message;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(car_plan, m)?)?;
    Ok(())
}

/// A problem by name (a built-in or a pose file's path) or as pose-file JSON.
pub fn variational(integrator: &str, robot: &str) -> PyResult<dmech::Discretisation> {
    let i = integrator.parse::<Integrator>().map_err(bad_input)?;
    i.variational().ok_or_else(|| {
        bad_input(format!(
            "{robot} plans take the variational schemes, first-order or midpoint (got {})",
            i.name()
        ))
    })
}

/// Plan the car: `problem` a built-in's name or a pose file's path, or `poses` pose-file
/// JSON (docs/car.md).
#[pyfunction]
#[pyo3(signature = (problem, poses, step, integrator, max_iter, threads, hessian, verbose, progress))]
#[allow(clippy::too_many_arguments)]
fn car_plan<'py>(
    py: Python<'py>,
    problem: Option<String>,
    poses: Option<String>,
    step: f64,
    integrator: &str,
    max_iter: usize,
    threads: Option<usize>,
    hessian: &str,
    verbose: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let problem = match (problem, poses) {
        (Some(name), None) => CarProblem::load(&name).map_err(bad_input)?,
        (None, Some(json)) => {
            CarProblem::from_json_str(&json).map_err(|e| bad_input(format!("poses: {e}")))?
        }
        _ => return Err(bad_input("give a problem's name or poses, not both")),
    };
    if !(step > 0.0 && step <= 0.1) {
        return Err(bad_input(format!(
            "the step must be in (0, 0.1] s, got {step}"
        )));
    }
    let disc = variational(integrator, "car")?;
    problem.check_stages(step).map_err(bad_input)?;
    let bounds = CarBounds::default();
    CarPlan::new(&problem, bounds, step).map_err(bad_input)?;
    let (opts, callback) = solver_options(
        IpOptions::default(),
        max_iter,
        threads,
        hessian,
        verbose,
        progress,
    )?;
    let o = py
        .detach(|| on_solver_stack(|| plan(&Car::default(), &problem, bounds, step, disc, opts)))
        .map_err(bad_input);
    finish(&callback)?;
    let o = o?;
    let traj = CarTrajectory::from_plan(&o);
    let pose_error = traj.pose_error_max(&o.stages, &problem);
    let name = integrator.parse::<Integrator>().map_err(bad_input)?.name();
    let columns: Vec<&'static str> = CSV_HEADER.split(',').collect();
    let mut table = Table::new(&columns);
    for k in 0..traj.t.len() {
        table.push(traj.row(k));
    }
    let d = PyDict::new(py);
    d.set_item("name", &problem.name)?;
    d.set_item("table", table.into_py(py)?)?;
    d.set_item("status", o.status.code())?;
    d.set_item("message", not_solved_message(&o.status, o.iterations))?;
    d.set_item("objective", o.objective)?;
    d.set_item("iterations", o.iterations)?;
    d.set_item("max_violation", o.max_violation)?;
    d.set_item("solve_time_s", o.solve_time_s)?;
    d.set_item("step", o.h)?;
    d.set_item("integrator", name)?;
    d.set_item("pose_error_max", pose_error)?;
    d.set_item("summary", summary_json(&problem, name, &o, pose_error))?;
    Ok(d)
}
