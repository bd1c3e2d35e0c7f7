//! Command-line arguments shared by the robots' tools.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use dmech::Integrator;
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

/// What `--help` says of each scheme.
fn integrator_help(i: Integrator) -> &'static str {
    match i {
        Integrator::FirstOrder => {
            "the first-order variational integrator (the paper's VarInt; also `varint`)"
        }
        Integrator::Midpoint => "the midpoint variational integrator: second order, reversible",
        Integrator::Rk1 => "explicit Euler on the continuous model",
        Integrator::Rk2 => "explicit midpoint on the continuous model",
        Integrator::Rk4 => "classical Runge–Kutta on the continuous model",
    }
}

/// `--integrator` of every tool: parses [`dmech::Integrator`]'s names (and `varint`, the
/// paper's name of the first-order scheme, as a hidden alias), listed with their help in
/// `--help`. `offered` is the schemes the command takes.
pub fn integrator_parser(
    offered: &'static [Integrator],
) -> impl TypedValueParser<Value = Integrator> {
    PossibleValuesParser::new(offered.iter().map(|&i| {
        let value = PossibleValue::new(i.name()).help(integrator_help(i));
        if i == Integrator::FirstOrder {
            value.alias("varint")
        } else {
            value
        }
    }))
    .map(|name| name.parse::<Integrator>().expect("a listed name"))
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

/// A positive, finite number (a voltage or torque limit of `car` and `snakeboard`).
pub fn positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive, finite number")),
    }
}

/// A time step in (0, 0.1] s (`car` and `snakeboard`).
pub fn step(s: &str) -> Result<f64, String> {
    let h: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if h.is_finite() && h > 0.0 && h <= 0.1 {
        Ok(h)
    } else {
        Err(format!("the step must be in (0, 0.1] s, got {s}"))
    }
}
