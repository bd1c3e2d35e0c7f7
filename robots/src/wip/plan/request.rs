//! A plan as one library call: the problem (by name, a waypoint file or waypoint JSON), the
//! checks before the solve, the solve, and its report. What `wip plan` and the Python
//! package share, so that both refuse the same inputs with the same one-line messages and
//! report the same numbers.

use crate::check::{check_size, CheckError};
use crate::io::ReadError;
use crate::wip::plan::free_timing::plan_free_timing;
use crate::wip::plan::problems::{self, PlanProblem, WaypointError};
use crate::wip::plan::report::{reduced_trajectory, summary_json};
use crate::wip::plan::{plan, CurrentModel, PlanBounds, PlanOutcome};
use crate::wip::simulate::{check_plan_step, Trajectory};
use crate::wip::{Wip, WipParams};
use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use dmech_ocp::transcription::free_timing::{FreeTimingError, TotalTime};
use std::path::PathBuf;

/// The largest planning step, s: a coarser mesh does not resolve the WIP's tilt dynamics.
pub const MAX_PLAN_STEP: f64 = 0.1;
/// The motors' supply, V: the largest voltage bound a plan may take.
pub const SUPPLY_VOLTAGE: f64 = 5.0;
/// Memory per stage while solving: 466 MB peak at 16,940 stages (docs/ocp.md, scale table).
pub const BYTES_PER_STAGE: f64 = 28e3;

/// Where the waypoints come from.
#[derive(Clone, Debug, PartialEq)]
pub enum ProblemSource {
    /// A built-in benchmark (`eight`, `zigzag`), or a path to a waypoint file if no
    /// benchmark has the name and the name ends in `.json` or names a file.
    Named(String),
    /// Waypoint JSON in the format of a waypoint file (docs/formats.md).
    Json(String),
}

/// Everything a plan of the WIP takes; [`PlanRequest::default`] is `wip plan`'s defaults.
#[derive(Clone, Debug)]
pub struct PlanRequest {
    /// The waypoints.
    pub problem: ProblemSource,
    /// The transcription.
    pub integrator: Integrator,
    /// The motor-current model.
    pub current: CurrentModel,
    /// The step `h`, s, in (0, [`MAX_PLAN_STEP`]].
    pub step: f64,
    /// The model's parameters.
    pub params: WipParams,
    /// The voltage bound `|u|`, V, in (0, [`SUPPLY_VOLTAGE`]].
    pub u_max: f64,
    /// The largest number of stages accepted.
    pub max_stages: usize,
    /// Free waypoint timing (first-order scheme only), with the total time fixed or priced.
    pub free_timing: Option<TotalTime>,
    /// The solver's options.
    pub options: IpOptions,
}

impl Default for PlanRequest {
    fn default() -> Self {
        PlanRequest {
            problem: ProblemSource::Named("eight".into()),
            integrator: Integrator::FirstOrder,
            current: CurrentModel::Dynamic,
            step: 0.005,
            params: WipParams::default(),
            u_max: SUPPLY_VOLTAGE,
            max_stages: 100_000,
            free_timing: None,
            options: IpOptions {
                max_iter: 500,
                ..IpOptions::default()
            },
        }
    }
}

/// Why a plan was not run. [`PlanRequestError::is_usage`] tells a bad request (the command
/// line's usage errors) from an input that was read and refused.
#[derive(Debug, thiserror::Error)]
pub enum PlanRequestError {
    /// No benchmark of that name, and no waypoint file there.
    #[error("unknown problem '{0}': expected eight, zigzag or a waypoint FILE.json")]
    UnknownProblem(String),
    /// Free timing needs the first-order scheme.
    #[error("--free-timing needs --integrator first-order (got {0})")]
    FreeTimingScheme(&'static str),
    /// The step is outside (0, [`MAX_PLAN_STEP`]].
    #[error("the step must be in (0, {MAX_PLAN_STEP}] s, got {0}")]
    Step(f64),
    /// The voltage bound is outside (0, [`SUPPLY_VOLTAGE`]].
    #[error("{0} V is outside (0, {SUPPLY_VOLTAGE}] V")]
    VoltageBound(f64),
    /// A waypoint file that cannot be read or is refused.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Waypoint JSON that is refused.
    #[error("waypoints: {0}")]
    Waypoints(#[from] WaypointError),
    /// Too many stages, or a step the model's modes refuse.
    #[error(transparent)]
    Check(#[from] CheckError),
    /// The free-timing problem could not be set up.
    #[error("{0}")]
    FreeTiming(#[from] FreeTimingError),
}

impl PlanRequestError {
    /// Whether the request itself is malformed (the command line's exit status 2), as
    /// opposed to an input that was read and refused (exit status 1).
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            PlanRequestError::UnknownProblem(_)
                | PlanRequestError::FreeTimingScheme(_)
                | PlanRequestError::Step(_)
                | PlanRequestError::VoltageBound(_)
        )
    }
}

/// A request checked and its problem built, ready to solve.
pub struct PreparedPlan {
    /// The problem at the request's step.
    pub problem: PlanProblem,
    /// The model.
    pub wip: Wip,
    request: PlanRequest,
    setup_s: f64,
}

/// What free timing adds to a plan's report.
#[derive(Clone, Debug)]
pub struct FreeTimingReport {
    /// How the fixed-timing plan it started from ended.
    pub fixed_status: Status,
    /// The fixed-timing plan: objective, iterations, solve time (s).
    pub fixed: (f64, usize, f64),
    /// Each segment's step ratio `h_j / h`.
    pub ratios: Vec<f64>,
    /// The price of the duration in the objective (0 for a fixed total time).
    pub time_cost: f64,
    /// The price per second, if the total time was priced.
    pub time_price: Option<f64>,
}

/// A solved (or not solved) plan with its report.
pub struct PlanRun {
    /// The problem.
    pub problem: PlanProblem,
    /// The solver's outcome.
    pub outcome: PlanOutcome,
    /// The plan in the reduced state of `trajectory.csv`.
    pub trajectory: Trajectory,
    /// Free timing's part, if any.
    pub free_timing: Option<FreeTimingReport>,
    /// The request it answers.
    pub request: PlanRequest,
    /// Seconds from the request to the solve.
    pub setup_s: f64,
}

impl PlanRequest {
    /// Check the request, build the problem and check its size and step.
    pub fn prepare(self) -> Result<PreparedPlan, PlanRequestError> {
        let t0 = std::time::Instant::now();
        let h = self.step;
        if !(h > 0.0 && h <= MAX_PLAN_STEP) {
            return Err(PlanRequestError::Step(h));
        }
        if !(self.u_max > 0.0 && self.u_max <= SUPPLY_VOLTAGE) {
            return Err(PlanRequestError::VoltageBound(self.u_max));
        }
        let problem = match &self.problem {
            ProblemSource::Named(name) => match problems::by_name(name, h) {
                Some(p) => p,
                None if name.ends_with(".json") || std::path::Path::new(name).exists() => {
                    problems::from_file(&PathBuf::from(name), h)?
                }
                None => return Err(PlanRequestError::UnknownProblem(name.clone())),
            },
            ProblemSource::Json(text) => problems::from_json_str(text, h)?,
        };
        check_size(
            &format!("plan {}: stages at h = {h} s", problem.name),
            problem.n as f64,
            self.max_stages,
            BYTES_PER_STAGE,
            "--max-stages",
        )?;
        if self.free_timing.is_some() && self.integrator != Integrator::FirstOrder {
            return Err(PlanRequestError::FreeTimingScheme(self.integrator.name()));
        }
        let wip = Wip::new(self.params);
        check_plan_step(&wip, self.integrator, h)?;
        Ok(PreparedPlan {
            problem,
            wip,
            request: self,
            setup_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// [`PlanRequest::prepare`] and [`PreparedPlan::solve`].
    pub fn run(self) -> Result<PlanRun, PlanRequestError> {
        self.prepare()?.solve()
    }
}

impl PreparedPlan {
    /// The request.
    pub fn request(&self) -> &PlanRequest {
        &self.request
    }

    /// Solve it: the fixed-timing plan, or with free timing the fixed plan and then the
    /// free one. A plan that is not solved is still a `PlanRun` ([`PlanRun::not_solved`]).
    pub fn solve(self) -> Result<PlanRun, PlanRequestError> {
        let PreparedPlan {
            problem,
            wip,
            request: r,
            setup_s,
        } = self;
        let bounds = PlanBounds {
            u_max: r.u_max,
            ..PlanBounds::default()
        };
        let (outcome, free_timing) = match r.free_timing {
            Some(total) => {
                let f =
                    plan_free_timing(&wip, &problem, bounds, r.current, total, r.options.clone())?;
                let report = FreeTimingReport {
                    fixed_status: f.fixed.status.clone(),
                    fixed: (f.fixed.objective, f.fixed.iterations, f.fixed.timings.total),
                    ratios: f.ratios,
                    time_cost: f.time_cost,
                    time_price: match total {
                        TotalTime::Priced(p) => Some(p),
                        TotalTime::Fixed => None,
                    },
                };
                (f.free, Some(report))
            }
            None => (
                plan(
                    &wip,
                    &problem,
                    bounds,
                    r.integrator,
                    r.current,
                    r.options.clone(),
                ),
                None,
            ),
        };
        let trajectory = reduced_trajectory(&wip, &outcome);
        Ok(PlanRun {
            problem,
            outcome,
            trajectory,
            free_timing,
            request: r,
            setup_s,
        })
    }
}

impl PlanRun {
    /// The plan's bounds.
    pub fn bounds(&self) -> PlanBounds {
        PlanBounds {
            u_max: self.request.u_max,
            ..PlanBounds::default()
        }
    }

    /// `summary.json` (docs/formats.md).
    pub fn summary_json(&self) -> String {
        let r = &self.request;
        let summary = summary_json(
            &self.problem.name,
            r.integrator.name(),
            r.current.name(),
            &self.problem,
            &self.outcome,
            &self.trajectory,
            &self.bounds(),
            self.setup_s,
        );
        let Some(f) = &self.free_timing else {
            return summary;
        };
        let mut v: serde_json::Value =
            serde_json::from_str(&summary).expect("summary_json writes JSON");
        let t = &self.trajectory.t;
        let durations: Vec<f64> = self
            .problem
            .stages
            .windows(2)
            .map(|w| t[w[1]] - t[w[0]])
            .collect();
        let (objective, iterations, time) = f.fixed;
        v["free_timing"] = serde_json::json!({
            "time_price": f.time_price,
            "duration_s": t.last(),
            "time_cost": f.time_cost,
            "step_ratios": f.ratios,
            "segment_durations_s": durations,
            "waypoint_times_s": self.problem.stages.iter().map(|&k| t[k]).collect::<Vec<f64>>(),
            "fixed_timing": {
                "objective": objective, "iterations": iterations, "solve_time_s": time
            }
        });
        serde_json::to_string_pretty(&v).expect("JSON") + "\n"
    }

    /// `None` if solved, else the one-line reason the command line prints.
    pub fn not_solved(&self) -> Option<String> {
        not_solved_message(&self.outcome.status, self.outcome.iterations)
    }
}

/// `None` for a solved plan, else the one line that says why it was not (every robot's
/// planner prints it).
pub fn not_solved_message(status: &Status, iterations: usize) -> Option<String> {
    match status {
        Status::Solved => None,
        Status::Infeasible { violation } => Some(format!(
            "infeasible: feasibility restoration ended at a point of local infeasibility, largest violation {violation:.3e} (waypoints or end state out of reach within the bounds)"
        )),
        Status::MaxIterations => Some(format!(
            "not solved within {iterations} iterations (--max-iter)"
        )),
        Status::TimeLimit => Some(format!(
            "not solved within the time limit ({iterations} iterations)"
        )),
        Status::Diverged => {
            Some("the iterates diverged (non-finite or unbounded values)".into())
        }
        Status::Failed(why) => Some(format!("solver failed: {why}")),
    }
}
