//! Command-line arguments shared by the robots' tools.

use dmech_ocp::solver::{Curvature, IpOptions};

/// `--hessian`: the curvature of the constraints in the solver's Newton systems.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HessianArg {
    /// A partitioned SR1 approximation per stage, updated from the exact Jacobians
    Sr1,
    /// The exact second derivatives (by blocks for the first-order VI; several times the
    /// cost of an SR1 iteration, docs/ocp.md)
    Exact,
}

impl HessianArg {
    /// `opts` with this curvature.
    pub fn apply(self, opts: IpOptions) -> IpOptions {
        let curvature = match self {
            HessianArg::Sr1 => Curvature::Sr1,
            HessianArg::Exact => Curvature::Exact,
        };
        IpOptions { curvature, ..opts }
    }
}

/// `f` run on a thread with the stack of the solver's stage-loop threads
/// ([`dmech_ocp::solver::STAGE_THREAD_STACK`]): with one thread the stage loops run on the
/// calling thread, and a tool's main thread has only the 8 MiB the system gives it. If no
/// thread can be started, `f` runs here. A panic in `f` carries on here.
pub fn on_solver_stack<R: Send, F: FnOnce() -> R + Send>(f: F) -> R {
    let mut task = Some(f);
    let ran = std::thread::scope(|sc| {
        let spawned = std::thread::Builder::new()
            .stack_size(dmech_ocp::solver::STAGE_THREAD_STACK)
            .spawn_scoped(sc, || task.take().map(|f| f()));
        match spawned {
            Ok(h) => h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)),
            Err(_) => None,
        }
    });
    ran.unwrap_or_else(|| (task.take().expect("the command runs once"))())
}
