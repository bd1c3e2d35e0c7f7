//! The snakeboard from Python: plan.

use crate::car::variational;
use crate::errors::bad_input;
use crate::options::{finish, solver_options};
use crate::table::Table;
use dmech_ocp::solver::IpOptions;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robots::cli::on_solver_stack;
use robots::snakeboard::plan::{plan, SnakeboardBounds, SnakeboardPlan, SnakeboardStart};
use robots::snakeboard::problems::SnakeboardProblem;
use robots::snakeboard::report::{summary_json, SnakeboardTrajectory, CSV_HEADER};
use robots::snakeboard::Snakeboard;
use robots::wip::plan::request::not_solved_message;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(snakeboard_plan, m)?)?;
    Ok(())
}

fn start_from(name: &str) -> PyResult<SnakeboardStart> {
    Ok(match name {
        "excited" => SnakeboardStart::Excited,
        "kinematic" => SnakeboardStart::Kinematic,
        "kinematic-excited" => SnakeboardStart::KinematicExcited,
        "zero" => SnakeboardStart::Zero,
        other => {
            return Err(bad_input(format!(
                "unknown start '{other}' (expected excited, kinematic, kinematic-excited or zero)"
            )))
        }
    })
}

/// Plan the snakeboard: `problem` a built-in's name or a pose file's path, or `poses`
/// pose-file JSON (docs/snakeboard.md).
#[pyfunction]
#[pyo3(signature = (problem, poses, step, integrator, start, max_iter, threads, hessian, verbose, progress))]
#[allow(clippy::too_many_arguments)]
fn snakeboard_plan<'py>(
    py: Python<'py>,
    problem: Option<String>,
    poses: Option<String>,
    step: f64,
    integrator: &str,
    start: &str,
    max_iter: usize,
    threads: Option<usize>,
    hessian: &str,
    verbose: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let problem = match (problem, poses) {
        (Some(name), None) => SnakeboardProblem::load(&name).map_err(bad_input)?,
        (None, Some(json)) => {
            SnakeboardProblem::from_json_str(&json).map_err(|e| bad_input(format!("poses: {e}")))?
        }
        _ => return Err(bad_input("give a problem's name or poses, not both")),
    };
    if !(step > 0.0 && step <= 0.1) {
        return Err(bad_input(format!(
            "the step must be in (0, 0.1] s, got {step}"
        )));
    }
    let disc = variational(integrator, "snakeboard")?;
    let start_kind = start_from(start)?;
    let bounds = SnakeboardBounds::default();
    SnakeboardPlan::new(&problem, bounds, step).map_err(bad_input)?;
    // The command line's settings: its plans' measured residual is promised at 1e-9 or less.
    let base = IpOptions {
        constr_viol_tol: 1e-10,
        ..IpOptions::default()
    };
    let (opts, callback) = solver_options(base, max_iter, threads, hessian, verbose, progress)?;
    let board = Snakeboard::default();
    let o = py
        .detach(|| on_solver_stack(|| plan(&board, &problem, bounds, step, disc, start_kind, opts)))
        .map_err(bad_input);
    finish(&callback)?;
    let o = o?;
    let traj = SnakeboardTrajectory::from_plan(&o);
    let end_error = traj.end_error(&problem.end);
    let columns: Vec<&'static str> = CSV_HEADER.split(',').collect();
    let mut table = Table::new(&columns);
    for k in 0..traj.t.len() {
        table.push(traj.row(&board, k));
    }
    let name = integrator
        .parse::<dmech::Integrator>()
        .map_err(bad_input)?
        .name();
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
    d.set_item("end_error", end_error)?;
    d.set_item(
        "summary",
        summary_json(&problem, name, start, &o, end_error),
    )?;
    Ok(d)
}
