//! `wip bench`: the paper's computation-time comparison rerun with our solver.

use crate::common::{positive_number, CurrentArg, Failure};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use robots::cli::integrator_parser;
use robots::io::OutputSet;
use robots::wip::plan::problems;
use robots::wip::plan::{plan, CurrentModel, PlanBounds};
use robots::wip::Wip;
use robots::{progress, say};
use serde::Serialize;
use std::path::PathBuf;

/// Rerun the paper's computation-time comparison with our solver.
///
/// The paper's Figure "computation time" (MATLAB + CasADi 3.2.3 + IPOPT, i7-8700; algebraic
/// current / current dynamics: RK1 690/553 s, RK2 710/544 s, RK4 776/680 s, VarInt 688/522
/// s): one plan per problem, integrator and current model, each alone; a table of status,
/// iterations, solve time and objective on stdout, and DIR/bench.json. RK runs with the
/// current dynamics take minutes each.
#[derive(clap::Args)]
pub struct BenchArgs {
    /// Problems, comma-separated
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST",
        default_value = "eight,zigzag"
    )]
    problems: Vec<Problem>,
    /// Integrators, comma-separated
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST",
        default_value = "first-order,rk1,rk2,rk4",
        value_parser = integrator_parser(&Integrator::ALL)
    )]
    integrators: Vec<Integrator>,
    /// Current models, comma-separated
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        value_name = "LIST",
        default_value = "dynamic,algebraic"
    )]
    currents: Vec<CurrentArg>,
    /// Stop each plan after this many seconds (status time_limit: objective and violation
    /// null, the run did not reach its end); default: none
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true, value_parser = positive_number)]
    time_limit: Option<f64>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Problem {
    Eight,
    Zigzag,
}

/// One row of bench.json (docs/formats.md), fields in this order.
#[derive(Serialize)]
struct BenchRun {
    problem: &'static str,
    integrator: &'static str,
    current: &'static str,
    status: &'static str,
    iterations: usize,
    solve_time_s: f64,
    objective: Option<f64>,
    max_violation: Option<f64>,
    time_breakdown_s: Breakdown,
    paper_time_s: Option<f64>,
}

#[derive(Serialize)]
struct Breakdown {
    derivatives: f64,
    kkt: f64,
    line_search: f64,
}

/// The paper's times for the eight (its Figure "computation time").
fn paper_time(i: Integrator, c: CurrentModel) -> Option<f64> {
    use CurrentModel::{Algebraic, Dynamic};
    use Integrator::*;
    match (i, c) {
        (Rk1, Dynamic) => Some(553.0),
        (Rk2, Dynamic) => Some(544.0),
        (Rk4, Dynamic) => Some(680.0),
        (FirstOrder, Dynamic) => Some(522.0),
        (Rk1, Algebraic) => Some(690.0),
        (Rk2, Algebraic) => Some(710.0),
        (Rk4, Algebraic) => Some(776.0),
        (FirstOrder, Algebraic) => Some(688.0),
        (Midpoint, _) => None,
    }
}

fn unique<T: PartialEq + Copy>(v: &[T]) -> Vec<T> {
    let mut out: Vec<T> = Vec::new();
    for &x in v {
        if !out.contains(&x) {
            out.push(x);
        }
    }
    out
}

pub fn run(a: BenchArgs) -> Result<(), Failure> {
    let mut files = OutputSet::create(&a.out)?;
    let wip = Wip::default();
    let mut rows = Vec::new();
    say!(
        "{:<8} {:<7} {:<9} {:<14} {:>6} {:>10} {:>14} {:>12}",
        "problem",
        "integr.",
        "current",
        "status",
        "iter",
        "time [s]",
        "objective",
        "paper [s]"
    );
    for p in unique(&a.problems) {
        let name = match p {
            Problem::Eight => "eight",
            Problem::Zigzag => "zigzag",
        };
        let problem = problems::by_name(name, 0.005).expect("a built-in benchmark");
        for c in unique(&a.currents) {
            let c = c.model();
            for i in unique(&a.integrators) {
                progress!("bench: {name} with {}, {} current …", i.name(), c.name());
                let opts = IpOptions {
                    time_limit: a.time_limit.unwrap_or(f64::INFINITY),
                    ..Default::default()
                };
                let o = plan(&wip, &problem, PlanBounds::default(), i, c, opts);
                // A plan stopped by the clock did not reach its end: the iterate it returns
                // may be a mesh's start (mesh sequencing falls back to the finest mesh with
                // no time left) or a continuation phase's, so its figures are not the
                // plan's and are left out.
                let reached_end = o.status != Status::TimeLimit;
                let figure = |v: f64| (reached_end && v.is_finite()).then_some(v);
                let (objective, max_violation) = (figure(o.objective), figure(o.max_violation));
                let paper_s = if name == "eight" {
                    paper_time(i, c)
                } else {
                    None
                };
                say!(
                    "{:<8} {:<7} {:<9} {:<14} {:>6} {:>10.2} {:>14} {:>12}",
                    name,
                    i.name(),
                    c.name(),
                    o.status.code(),
                    o.iterations,
                    o.timings.total,
                    objective.map_or_else(|| "-".into(), |v| format!("{v:.4}")),
                    paper_s
                        .map(|v| format!("{v:.0}"))
                        .unwrap_or_else(|| "-".into())
                );
                rows.push(BenchRun {
                    problem: name,
                    integrator: i.name(),
                    current: c.name(),
                    status: o.status.code(),
                    iterations: o.iterations,
                    solve_time_s: o.timings.total,
                    objective,
                    max_violation,
                    time_breakdown_s: Breakdown {
                        derivatives: o.timings.derivatives,
                        kkt: o.timings.kkt,
                        line_search: o.timings.line_search,
                    },
                    paper_time_s: paper_s,
                });
            }
        }
    }
    #[derive(Serialize)]
    struct Bench {
        runs: Vec<BenchRun>,
    }
    let json = serde_json::to_string_pretty(&Bench { runs: rows })
        .map_err(|e| format!("bench.json: {e}"))?;
    files.write("bench.json", (json + "\n").as_bytes())?;
    files.commit()?;
    say!("wrote {}", a.out.join("bench.json").display());
    Ok(())
}
