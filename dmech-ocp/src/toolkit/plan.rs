//! A plan in one call: a robot's problem at any step, a start, the variational
//! transcription, mesh sequencing from a coarse step, the solve, and the plan measured on
//! its own trajectory. What a robot otherwise writes as glue (a [`SequencedPlan`], the
//! start in the transcription's layout, the measured residual) is here once.
//!
//! ```
//! # use dmech::{Discretisation, Lift, PrincipalKinematicSystem};
//! # use dmech_lie::{Real, Rn};
//! # use nalgebra::{SMatrix, SVector};
//! use dmech_ocp::toolkit::plan::{plan, PlanSettings, PlanStart};
//! use dmech_ocp::transcription::{Condition, PlanningProblem, Quantity, Stage, StartState};
//! # /// A point mass on a line, pushed: G = R (its position), no shape but a "wheel" angle.
//! # struct Cart;
//! # impl PrincipalKinematicSystem<1, 1, 1> for Cart {
//! #     type Param = f64;
//! #     type Group<T: Real> = Rn<T, 1>;
//! #     fn reduced_lagrangian<T: Lift<f64>>(&self, _s: &SVector<T, 1>, v: &SVector<T, 1>, xi: &SVector<T, 1>) -> T {
//! #         (xi[0] * xi[0] + v[0] * v[0] * 1e-3) * 0.5
//! #     }
//! #     fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 1>) -> SMatrix<T, 1, 1> {
//! #         SMatrix::<T, 1, 1>::new(-T::from(0.1))
//! #     }
//! #     fn forcing<T: Lift<f64>>(&self, _s: &SVector<T, 1>, _v: &SVector<T, 1>, u: &SVector<T, 1>) -> SVector<T, 1> { *u }
//! # }
//! /// From rest at 0 to rest at 1 m in 2 s, least effort.
//! struct Push { n: usize }
//! impl PlanningProblem<1, 1, 1, 1> for Push {
//!     fn horizon(&self) -> usize { self.n }
//!     fn start(&self) -> StartState<1, 1, 1> { StartState::at_rest(SVector::zeros(), SVector::zeros()) }
//!     fn cost<T: Real>(&self, _k: usize, st: &Stage<T, 1, 1, 1>) -> T { st.input[0] * st.input[0] * 0.5 }
//!     fn constraints<T: Real>(&self, _k: usize, st: &Stage<T, 1, 1, 1>) -> SVector<T, 1> { st.input }
//!     fn bounds(&self, _k: usize) -> (SVector<f64, 1>, SVector<f64, 1>) { (SVector::repeat(-1.0), SVector::repeat(1.0)) }
//!     fn conditions(&self) -> Vec<Condition> {
//!         let end = |quantity, value| Condition { stage: self.n, quantity, value };
//!         vec![end(Quantity::Pose(0), 1.0), end(Quantity::Velocity(0), 0.0)]
//!     }
//! }
//! let settings = PlanSettings::new(0.01, Discretisation::Midpoint);
//! let p = plan(&Cart, |h| Some(Push { n: (2.0 / h).round() as usize }), &settings, &PlanStart::Rest)?;
//! assert!(p.max_violation < 1e-8);
//! assert!((p.trajectory.stages.last().unwrap().pose[0] - 1.0).abs() < 1e-8);
//! # Ok::<(), dmech_ocp::toolkit::plan::PlanError>(())
//! ```

use crate::nlp::max_violation;
use crate::solver::{IpOptions, Status};
use crate::toolkit::kinematic_start::{shape_motion, ShapeMotion};
use crate::toolkit::sequencing::{mesh_sequence, SequenceSettings, SequencedPlan};
use crate::transcription::layout::Layout;
use crate::transcription::sizes::{Dims, StageSizes};
use crate::transcription::{PlannedTrajectory, PlanningProblem, VarIntTranscription};
use dmech::{Discretisation, PrincipalKinematicSystem};
use dmech_lie::LieGroup;
use nalgebra::SVector;
use std::marker::PhantomData;

/// A pose path sampled for a mesh: `n ↦ (g_0, …, g_n)`, the poses at the `n + 1` stages of
/// an `n`-step horizon.
pub type PosePath<'a, G> = &'a (dyn Fn(usize) -> Vec<G> + Sync);

/// What the solver starts from on the coarsest mesh.
pub enum PlanStart<'a, G, const NS: usize> {
    /// Every state the problem's start state, every decision zero.
    Rest,
    /// The kinematic start ([`crate::toolkit::kinematic_start`]) along the pose path
    /// `path(n)` sampled at the mesh's `n + 1` stages, with the least-squares weight of
    /// each shape velocity.
    Path {
        /// The path at each mesh's stages.
        path: PosePath<'a, G>,
        /// `ρ_i`, one per shape velocity.
        regularisation: SVector<f64, NS>,
    },
    /// A shape motion ([`ShapeMotion::excited`]) from rest, or from the kinematic start of
    /// `path` (as [`PlanStart::Path`]): for systems whose free directions gain momentum only
    /// from two shape velocities together.
    Excited {
        /// The path and weights of a kinematic start to excite, or `None`: from rest.
        path: Option<(PosePath<'a, G>, SVector<f64, NS>)>,
        /// The oscillation's amplitude on each shape coordinate.
        amplitudes: SVector<f64, NS>,
        /// Its cycles over the horizon.
        cycles: f64,
    },
}

/// The settings of [`plan`].
#[derive(Clone, Debug)]
pub struct PlanSettings {
    /// The finest step, the plan's.
    pub h: f64,
    /// The variational scheme.
    pub discretisation: Discretisation,
    /// Mesh sequencing from the coarsest step `h·2^L` at or below this (no coarser mesh
    /// than `h` itself if it is below `2h`).
    pub coarsest_step: f64,
    /// The barrier a finer mesh restarts at ([`SequenceSettings`]).
    pub restart_barrier: f64,
    /// The solver's options.
    pub solver: IpOptions,
}

impl PlanSettings {
    /// Step `h` and `discretisation`; sequencing from 40 ms down, restarts at μ = 1e-4 (the
    /// robots' settings, docs/ocp.md); the solver's defaults, quiet.
    pub fn new(h: f64, discretisation: Discretisation) -> Self {
        PlanSettings {
            h,
            discretisation,
            coarsest_step: 0.04,
            restart_barrier: 1e-4,
            solver: IpOptions {
                verbose: false,
                ..IpOptions::default()
            },
        }
    }
}

/// A plan: the trajectory and what the solve reports, its residual measured on it.
#[derive(Clone, Debug)]
pub struct Plan<const NP: usize, const NS: usize, const NU: usize> {
    /// How the finest mesh's solve ended.
    pub status: Status,
    /// Iterations over every mesh.
    pub iterations: usize,
    /// The objective on the finest mesh.
    pub objective: f64,
    /// The largest violation of any constraint on the returned trajectory
    /// ([`crate::nlp::max_violation`]).
    pub max_violation: f64,
    /// Solve time over every mesh, seconds.
    pub solve_time_s: f64,
    /// The plan in the robot's terms.
    pub trajectory: PlannedTrajectory<NP, NS, NU>,
}

/// Why [`plan`] could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// `problem_at(h)` gave no problem at the plan's own step.
    #[error("the problem has no mesh at the step {h} s")]
    NoMesh {
        /// The step asked for.
        h: f64,
    },
    /// The layout does not fit the system or the sizes `NX`, `NW`.
    #[error(transparent)]
    Layout(#[from] crate::transcription::layout::LayoutError),
}

/// One mesh: the problem at a step.
struct Mesh<P> {
    problem: P,
    h: f64,
}

/// The types a [`Sequence`] is built for, carried as a type.
type Marker<P, const DOF: usize, const NP: usize> = PhantomData<(fn() -> P, [(); DOF], [(); NP])>;

struct Sequence<'s, S, F, P, G, const DOF: usize, const NP: usize, const NS: usize> {
    sys: &'s S,
    problem_at: F,
    discretisation: Discretisation,
    start: &'s PlanStart<'s, G, NS>,
    layout: Layout,
    _sizes: Marker<P, DOF, NP>,
}

impl<
        S,
        F,
        P,
        const DOF: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NC: usize,
        const NX: usize,
        const NW: usize,
    > SequencedPlan<NX, NW, NS, NU, NC> for Sequence<'_, S, F, P, S::Group<f64>, DOF, NP, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    F: Fn(f64) -> Option<P>,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    type Mesh = Mesh<P>;
    type Problem<'a>
        = VarIntTranscription<'a, S, &'a P, DOF, NP, NS, NU, NX, NW>
    where
        Self: 'a;
    fn steps(&self, mesh: &Mesh<P>) -> usize {
        mesh.problem.horizon()
    }
    fn step(&self, mesh: &Mesh<P>) -> f64 {
        mesh.h
    }
    fn coarser(&self, mesh: &Mesh<P>) -> Option<Mesh<P>> {
        let h = 2.0 * mesh.h;
        (self.problem_at)(h).map(|problem| Mesh { problem, h })
    }
    fn problem<'a>(&'a self, mesh: &'a Mesh<P>, _phase: usize) -> Self::Problem<'a> {
        VarIntTranscription::with_layout(
            self.sys,
            &mesh.problem,
            mesh.h,
            self.discretisation,
            self.layout,
        )
        .expect("plan_in_layout checked the layout against NX and NW")
    }
    fn start(&self, mesh: &Mesh<P>) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>) {
        let n = mesh.problem.horizon();
        let tr = self.problem(mesh, 0);
        let start = mesh.problem.start();
        let g0 = <S::Group<f64> as LieGroup<DOF>>::from_coordinates(start.pose.as_slice())
            .expect("the start's pose coordinates are the group's");
        let rest = ShapeMotion {
            shapes: vec![start.shape; n + 1],
            velocities: vec![SVector::zeros(); n],
        };
        let along = |path: PosePath<'_, S::Group<f64>>, weights: &SVector<f64, NS>| {
            shape_motion(self.sys, mesh.h, &path(n), &start.shape, weights).ok()
        };
        let motion = match self.start {
            PlanStart::Rest => rest,
            PlanStart::Path {
                path,
                regularisation,
            } => along(*path, regularisation).unwrap_or(rest),
            PlanStart::Excited {
                path,
                amplitudes,
                cycles,
            } => path
                .and_then(|(p, w)| along(p, &w))
                .unwrap_or(rest)
                .excited(mesh.h, amplitudes, *cycles),
        };
        tr.start_from_motion(&g0, &motion)
    }
    fn layout(&self) -> Layout {
        self.layout
    }
}

/// Plans the problem `problem_at(h)` on `sys` by the variational transcription of
/// `settings.discretisation`, every shape position in the state, by mesh sequencing from
/// the coarsest step `h·2^L ≤ settings.coarsest_step` for which `problem_at` gives a
/// problem (`None`: no such mesh, e.g. two conditions on one stage), from `start`. The
/// returned plan is the finest mesh's, its residual measured on it.
pub fn plan<
    S,
    F,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
    const NC: usize,
    const NX: usize,
    const NW: usize,
>(
    sys: &S,
    problem_at: F,
    settings: &PlanSettings,
    start: &PlanStart<'_, S::Group<f64>, NS>,
) -> Result<Plan<NP, NS, NU>, PlanError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    F: Fn(f64) -> Option<P>,
    P: PlanningProblem<NP, NS, NU, NC>,
    Dims<NP, NS, NU>: StageSizes<NX, NW>,
{
    plan_in_layout::<S, F, P, DOF, NP, NS, NU, NC, NX, NW>(
        sys,
        problem_at,
        settings,
        start,
        Layout::new(NP, NS, NU),
        &|_| {},
    )
}

/// [`plan`] in `layout` (from [`Layout::new`], with [`Layout::ignoring`] for shape
/// positions no equation reads: `NX` and `NW` then named by the caller), telling
/// `progress` of each mesh.
pub fn plan_in_layout<
    S,
    F,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
    const NC: usize,
    const NX: usize,
    const NW: usize,
>(
    sys: &S,
    problem_at: F,
    settings: &PlanSettings,
    start: &PlanStart<'_, S::Group<f64>, NS>,
    layout: Layout,
    progress: &dyn Fn(&str),
) -> Result<Plan<NP, NS, NU>, PlanError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    F: Fn(f64) -> Option<P>,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    let h = settings.h;
    let finest = Mesh {
        problem: problem_at(h).ok_or(PlanError::NoMesh { h })?,
        h,
    };
    VarIntTranscription::<S, &P, DOF, NP, NS, NU, NX, NW>::with_layout(
        sys,
        &finest.problem,
        h,
        settings.discretisation,
        layout,
    )
    .map_err(PlanError::Layout)?;
    let seq = Sequence {
        sys,
        problem_at,
        discretisation: settings.discretisation,
        start,
        layout,
        _sizes: PhantomData,
    };
    let sequence = SequenceSettings {
        coarsest_step: settings.coarsest_step,
        restart_barrier: settings.restart_barrier,
    };
    let on_mesh = Mesh {
        problem: (seq.problem_at)(h).ok_or(PlanError::NoMesh { h })?,
        h,
    };
    let r = mesh_sequence::<_, NX, NW, NS, NU, NC>(
        &seq,
        finest,
        sequence,
        settings.solver.clone(),
        progress,
    );
    let tr = SequencedPlan::<NX, NW, NS, NU, NC>::problem(&seq, &on_mesh, 0);
    Ok(Plan {
        status: r.status,
        iterations: r.iterations,
        objective: r.objective,
        max_violation: max_violation(&tr, &r.iterate.x, &r.iterate.w),
        solve_time_s: r.timings.total,
        trajectory: tr.trajectory(&r.iterate),
    })
}
