//! The solver's options from the keyword arguments every robot's `plan` takes, and the
//! progress callback on the solver's iterations.

use crate::errors::{bad_input, Callback};
use dmech_ocp::solver::{Curvature, IpOptions, IterationObserver, IterationReport};
use pyo3::prelude::*;
use std::sync::Arc;

/// The solver's options: `base` with the iteration limit, threads, curvature (`"sr1"` or
/// `"exact"`), the table on stderr if `verbose`, and `progress` called per iteration with
/// the table's row. Returns the callback too, to raise its exception after the solve.
pub fn solver_options(
    base: IpOptions,
    max_iter: usize,
    threads: Option<usize>,
    hessian: &str,
    verbose: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(IpOptions, Option<Arc<Callback>>)> {
    let curvature = match hessian {
        "sr1" => Curvature::Sr1,
        "exact" => Curvature::Exact,
        other => {
            return Err(bad_input(format!(
                "unknown hessian '{other}' (expected sr1 or exact)"
            )))
        }
    };
    if max_iter == 0 {
        return Err(bad_input("max_iter must be at least 1"));
    }
    if let Some(n) = threads {
        if !(1..=64).contains(&n) {
            return Err(bad_input(format!("'{n}' is not a thread count in 1..=64")));
        }
    }
    let callback = progress.map(|f| Arc::new(Callback::new(f)));
    let observer = callback.clone().map(|cb| {
        IterationObserver(Arc::new(move |r: &IterationReport| {
            let r = *r;
            cb.call(|_| {
                (
                    r.iteration,
                    r.stages,
                    r.objective,
                    r.primal_infeasibility,
                    r.dual_infeasibility,
                    r.barrier,
                    r.elapsed_s,
                )
            })
        }))
    });
    let options = IpOptions {
        verbose,
        max_iter,
        threads: threads.unwrap_or(base.threads),
        curvature,
        observer,
        ..base
    };
    Ok((options, callback))
}

/// The callback's exception, if it raised.
pub fn finish(callback: &Option<Arc<Callback>>) -> PyResult<()> {
    match callback {
        Some(cb) => cb.finish(),
        None => Ok(()),
    }
}
