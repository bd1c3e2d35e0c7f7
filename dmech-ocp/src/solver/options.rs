//! The solver's options, how a solve ended, and where its time went.

/// Options of the solver.
#[derive(Clone, Debug)]
pub struct IpOptions {
    /// Convergence tolerance on the scaled KKT error (IPOPT's `tol`).
    pub tol: f64,
    /// Largest allowed constraint violation at convergence.
    pub constr_viol_tol: f64,
    /// Iterations, at most (restoration's included).
    pub max_iter: usize,
    /// The barrier parameter `μ` to start with.
    pub mu_init: f64,
    /// Dual regularisation of the state equalities at `μ = mu_init`; it shrinks like `μ²`
    /// down to `delta_c_min`.
    pub delta_c: f64,
    /// The floor of that regularisation.
    pub delta_c_min: f64,
    /// Worker threads for the stage derivatives and the line search.
    pub threads: usize,
    /// Print an iteration table on stderr.
    pub verbose: bool,
    /// The curvature of the dynamics and stage equalities in the Newton systems.
    pub curvature: Curvature,
    /// The SR1 update `B += r rᵀ/(sᵀr)` of a stage is skipped when `|sᵀr| ≤ sr1_skip ‖s‖‖r‖`.
    /// The update's norm is `‖r‖²/|sᵀr|`, at most `‖r‖/(sr1_skip ‖s‖)`: this bounds how far
    /// one stage's curvature may leap past what the secant observed. One stage's leap
    /// into negative curvature forces the inertia shift on all stages, so the bound is
    /// tight (1e-2, not the textbook 1e-8: `docs/solver.md`).
    pub sr1_skip: f64,
    /// Wall-clock limit in seconds (reported as `TimeLimit`).
    pub time_limit: f64,
    /// How the Newton step's linear system is solved (`docs/solver.md`, "Global variables
    /// and the two KKT paths": measured, the Riccati recursion is the faster).
    pub kkt: KktMethod,
    /// Stop, solved, once the barrier problem at this `μ` is solved (IPOPT's test,
    /// `E_μ ≤ κ_ε μ`), the barrier never decreased below it; `None`: solve to `tol`. For
    /// a solve whose iterate seeds another that restarts at this barrier: mesh
    /// sequencing's coarse meshes (`docs/ocp.md`, "Mesh sequencing").
    pub final_barrier: Option<f64>,
    /// Called after every iteration with its measures (progress of a long solve), whether
    /// or not the table is printed. `None`: nothing is called.
    pub observer: Option<IterationObserver>,
    /// The objective's scale `c` (the solver works on `c ℓ`): `None`, the rule of
    /// `docs/solver.md`, "Objective scaling" (`1/s` for a mean stage cost `s < 1` at the
    /// start, a probe step when it is zero); `Some(c)`, that scale whatever the start. For
    /// a sequence of solves of one problem family whose scale must not change from solve
    /// to solve (the receding horizons of [`crate::tracking::nmpc`]).
    pub objective_scale: Option<f64>,
}

/// What an iteration reports to an [`IterationObserver`]: the iteration table's row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterationReport {
    /// The iteration of this solve (from 0; a mesh sequence solves once per mesh).
    pub iteration: usize,
    /// The solve's number of stages `N`.
    pub stages: usize,
    /// The objective at the iterate, as the solver minimises it (scaled:
    /// `docs/solver.md`, "Objective scaling").
    pub objective: f64,
    /// The scaled primal infeasibility (`inf_pr`).
    pub primal_infeasibility: f64,
    /// The scaled dual infeasibility (`inf_du`).
    pub dual_infeasibility: f64,
    /// The barrier parameter `μ`.
    pub barrier: f64,
    /// Seconds since the solve started.
    pub elapsed_s: f64,
}

/// A callback per iteration ([`IpOptions::observer`]); shared, so options stay `Clone`.
#[derive(Clone)]
pub struct IterationObserver(pub std::sync::Arc<dyn Fn(&IterationReport) + Send + Sync>);

impl std::fmt::Debug for IterationObserver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("IterationObserver")
    }
}

/// The curvature of the dynamics and the stage equalities, `∇²(λᵀf + νᵀe)`, in the
/// Newton systems (the cost's and the inequalities' curvature is always exact).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Curvature {
    /// A partitioned SR1 approximation per stage, updated from the exact Jacobians.
    #[default]
    Sr1,
    /// The exact second derivatives (exact Newton; the problem's
    /// [`constraint_curvature`](crate::nlp::StageProblem::constraint_curvature)).
    Exact,
    /// None: a Gauss–Newton-type Hessian of the cost and the inequalities alone.
    GaussNewton,
}

/// The linear algebra of the Newton step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum KktMethod {
    /// The Riccati recursion over the stages, augmented by the globals' columns (Schur
    /// complement) when the problem has globals.
    #[default]
    Riccati,
    /// The whole condensed KKT matrix by faer's sparse `LDLᵀ` (in builds with the
    /// `sparse-ldlt` feature; otherwise the solve fails at its first step).
    SparseLdlt,
}

impl IpOptions {
    /// The barrier parameter to restart with from a nearby solution.
    pub fn warm_mu_init(&self) -> f64 {
        (self.mu_init * 1e-2).max(self.tol)
    }
}

impl Default for IpOptions {
    fn default() -> Self {
        IpOptions {
            tol: 1e-6,
            constr_viol_tol: 1e-8,
            max_iter: 500,
            mu_init: 0.1,
            delta_c: 1e-5,
            delta_c_min: 1e-10,
            threads: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
                .min(8),
            verbose: false,
            curvature: Curvature::Sr1,
            sr1_skip: 1e-2,
            time_limit: f64::INFINITY,
            kkt: KktMethod::Riccati,
            final_barrier: None,
            observer: None,
            objective_scale: None,
        }
    }
}

/// How a solve ended. Callers can tell these apart; only `Solved` carries an optimum.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    /// The KKT conditions hold to the tolerances: an optimum.
    Solved,
    /// Feasibility restoration converged to a point of local infeasibility (a stationary
    /// point of the state equalities' squared violation within the dynamics and bounds), or
    /// the dynamics and bounds themselves cannot be met: no feasible point near.
    Infeasible {
        /// The largest constraint violation where restoration stopped.
        violation: f64,
    },
    /// The iteration limit (`max_iter`) was reached.
    MaxIterations,
    /// The wall-clock limit (`time_limit`) was reached.
    TimeLimit,
    /// Non-finite values or iterates growing without bound.
    Diverged,
    /// A numerical failure, or a declaration of the problem that does not hold.
    Failed(Failure),
}

/// Why a solve failed ([`Status::Failed`]); its `Display` is a one-line message.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Failure {
    /// No step the line search accepts, near feasibility, after the forced short steps.
    #[error("line search: no acceptable step (constraint violation {violation:.2e})")]
    LineSearch {
        /// The largest constraint violation at the last iterate.
        violation: f64,
    },
    /// The inertia correction ran out of primal shifts.
    #[error("inertia correction failed")]
    InertiaCorrection,
    /// A stage equality's Jacobian in its dependent decisions is singular.
    #[error("stage {stage}: the stage equality is singular in its dependent decisions")]
    SingularStageEquality {
        /// The stage.
        stage: usize,
    },
    /// [`StageProblem::affine_in_state`](crate::nlp::StageProblem::affine_in_state) is
    /// declared but does not hold at the start.
    #[error(
        "the problem declares its cost and inequalities affine in the state, but at stage \
         {stage} their state Hessian has an entry {entry:.3e}"
    )]
    NotAffineInState {
        /// The stage.
        stage: usize,
        /// The largest entry of the state Hessian there.
        entry: f64,
    },
    /// [`StageProblem::constant_cost_curvature`](crate::nlp::StageProblem::constant_cost_curvature)
    /// is declared but does not hold at the start.
    #[error(
        "the problem declares its cost curvature constant, but at stage {stage} its \
         derivatives change by {change:.3e} (largest entry {scale:.3e}) between two points"
    )]
    CurvatureNotConstant {
        /// The stage.
        stage: usize,
        /// The largest change of an entry.
        change: f64,
        /// The largest entry.
        scale: f64,
    },
    /// The sparse `LDLᵀ` back-end failed beyond a wrong inertia.
    #[error("sparse KKT factorisation: {0}")]
    SparseKkt(String),
    /// The feasibility restoration diverged.
    #[error("restoration diverged")]
    RestorationDiverged,
    /// The feasibility restoration failed.
    #[error("restoration: {0}")]
    Restoration(Box<Failure>),
}

impl Status {
    /// The status as the word the tools write (`summary.json`'s `status`).
    pub fn code(&self) -> &'static str {
        match self {
            Status::Solved => "solved",
            Status::Infeasible { .. } => "infeasible",
            Status::MaxIterations => "max_iterations",
            Status::TimeLimit => "time_limit",
            Status::Diverged => "diverged",
            Status::Failed(_) => "failed",
        }
    }
}

/// Where the time went.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    /// Seconds in the stage derivatives.
    pub derivatives: f64,
    /// All of the KKT solve; of it, the Riccati recursions (`riccati`, one per inertia
    /// correction trial, counted in `factorizations`).
    pub kkt: f64,
    /// Seconds in the Riccati recursions.
    pub riccati: f64,
    /// Factorisations of the KKT system (inertia-correction trials included).
    pub factorizations: usize,
    /// Second-order correction steps tried.
    pub second_order_corrections: usize,
    /// Feasibility restorations entered, and their time (included in `total`; their
    /// iterations are in the solve's count).
    pub restorations: usize,
    /// Seconds in restorations.
    pub restoration: f64,
    /// Seconds in the line search.
    pub line_search: f64,
    /// Seconds in all.
    pub total: f64,
}
