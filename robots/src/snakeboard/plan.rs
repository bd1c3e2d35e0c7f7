//! The snakeboard's planning problem in the toolkit's terms, on its extended shape
//! `(ψ, φ, σ)` with the positions `ψ` and `σ` left out of the state (neither enters the
//! equations), and the starts it is solved from (`docs/snakeboard.md`).
//!
//! Cost `½ Σ_k ((τ_ψ/τ_ψ,max)² + (τ_φ/τ_φ,max)²)`; path constraints on both torques, the
//! axle angle and the rotor rate; rest to rest (every velocity of the extended shape zero
//! at the end: the shape at rest and the board's forward speed `p = σ̇` zero).

use super::model::{ExtendedSnakeboard, Snakeboard, NA, NU};
use super::problems::SnakeboardProblem;
use crate::pose_path::start_path;
use dmech::{Discretisation, PrincipalKinematicSystem};
use dmech_lie::Real;
use dmech_ocp::solver::{IpOptions, Status};
use dmech_ocp::toolkit::plan::{plan_in_layout, PlanSettings, PlanStart};
use dmech_ocp::transcription::layout::Layout;
use dmech_ocp::transcription::{
    Condition, PlannedTrajectory, PlanningProblem, Quantity, Stage, StartState,
};
use nalgebra::SVector;

/// Path constraints per stage: τ_ψ, τ_φ, φ, ψ̇.
pub const NC: usize = 4;
/// The solver's state: pose 3, the axle angle, the extended velocity 3, the previous input.
pub const NX: usize = 3 + 1 + NA + NU;
/// The solver's stage decision: `(v_k, u_k)`.
pub const NW: usize = NA + NU;

/// Bounds of the path constraints (magnitudes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SnakeboardBounds {
    /// Rotor torque, N m.
    pub rotor_torque: f64,
    /// Axle torque, N m.
    pub axle_torque: f64,
    /// Axle angle, rad (the free direction's yaw `tan φ / l` grows without bound at π/2).
    pub axle_angle: f64,
    /// Rotor rate, rad/s.
    pub rotor_rate: f64,
}

impl Default for SnakeboardBounds {
    fn default() -> Self {
        SnakeboardBounds {
            rotor_torque: 0.1,
            axle_torque: 0.05,
            axle_angle: 1.0,
            rotor_rate: 10.0,
        }
    }
}

/// What the solver starts from (measured against each other in `docs/snakeboard.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SnakeboardStart {
    /// At rest at the start pose, the rotor and the axles oscillating a quarter period
    /// apart ([`ShapeMotion::excited`]): a gait that drives no net motion, so that the
    /// momentum equation's linearisation sees both shape velocities. Needs no path: the
    /// default.
    Excited,
    /// The kinematic start along the pose path ([`start_path`]) on the extended shape: the
    /// axle angle and the forward speed `p` that realise the path through the free
    /// direction, the rotor at rest.
    Kinematic,
    /// [`SnakeboardStart::Kinematic`] with the oscillation of [`SnakeboardStart::Excited`].
    KinematicExcited,
    /// Every pose at the start, every velocity and input zero.
    Zero,
}

/// Why a snakeboard plan cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SnakeboardPlanError {
    /// The duration is not a whole number of steps.
    #[error("the duration {duration} s is not a whole number of steps of {h} s ({steps:.4})")]
    NotWholeSteps { duration: f64, h: f64, steps: f64 },
    /// Fewer than two steps.
    #[error("the duration {duration} s is {steps:.0} step(s) of {h} s; a plan needs at least 2")]
    TooFewSteps { duration: f64, h: f64, steps: f64 },
    /// Start and end are the same pose.
    #[error("start and end are the same pose {pose:?}: nothing to plan")]
    SamePose { pose: [f64; 3] },
}

/// A [`SnakeboardProblem`] on a mesh of step `h`.
pub struct SnakeboardPlan<'a> {
    pub problem: &'a SnakeboardProblem,
    pub bounds: SnakeboardBounds,
    pub h: f64,
    pub n: usize,
}

impl<'a> SnakeboardPlan<'a> {
    /// The plan of `problem` at step `h`; an error unless the duration is a whole number of
    /// at least two steps and the poses differ.
    pub fn new(
        problem: &'a SnakeboardProblem,
        bounds: SnakeboardBounds,
        h: f64,
    ) -> Result<Self, SnakeboardPlanError> {
        let steps = problem.duration / h;
        let n = steps.round() as usize;
        let duration = problem.duration;
        if (steps - n as f64).abs() > 1e-6 * steps.max(1.0) {
            return Err(SnakeboardPlanError::NotWholeSteps { duration, h, steps });
        }
        if n < 2 {
            return Err(SnakeboardPlanError::TooFewSteps { duration, h, steps });
        }
        let (a, b) = (problem.start, problem.end);
        if (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12) {
            return Err(SnakeboardPlanError::SamePose { pose: a });
        }
        Ok(SnakeboardPlan {
            problem,
            bounds,
            h,
            n,
        })
    }
}

impl PlanningProblem<3, NA, NU, NC> for SnakeboardPlan<'_> {
    fn horizon(&self) -> usize {
        self.n
    }
    fn start(&self) -> StartState<3, NA, NU> {
        StartState::at_rest(SVector::from(self.problem.start), SVector::zeros())
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NA, NU>) -> T {
        let rotor = stage.input[0] * (1.0 / self.bounds.rotor_torque);
        let axle = stage.input[1] * (1.0 / self.bounds.axle_torque);
        (rotor * rotor + axle * axle) * 0.5
    }
    fn constraints<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NA, NU>) -> SVector<T, NC> {
        SVector::<T, NC>::new(
            stage.input[0],
            stage.input[1],
            stage.shape[1],
            stage.velocity[0],
        )
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let b = &self.bounds;
        let hi = SVector::<f64, NC>::new(b.rotor_torque, b.axle_torque, b.axle_angle, b.rotor_rate);
        (-hi, hi)
    }
    fn conditions(&self) -> Vec<Condition> {
        let end = self.problem.end;
        let pose = (0..3).map(|i| (Quantity::Pose(i), end[i]));
        let rest = (0..NA).map(|i| (Quantity::Velocity(i), 0.0));
        pose.chain(rest)
            .map(|(quantity, value)| Condition {
                stage: self.n,
                quantity,
                value,
            })
            .collect()
    }
    fn affine_in_configuration(&self) -> bool {
        // The cost reads the input; the constraints read φ, ψ̇ and u linearly.
        true
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        true
    }
}

/// A solved (or not) snakeboard plan.
pub struct SnakeboardOutcome {
    pub status: Status,
    pub iterations: usize,
    pub objective: f64,
    /// Largest violation of any constraint recomputed on the returned trajectory.
    pub max_violation: f64,
    pub solve_time_s: f64,
    pub h: f64,
    pub trajectory: PlannedTrajectory<3, NA, NU>,
}

/// The transcription's layout: the extended shape with `ψ` and `σ` left out.
pub fn layout(board: &ExtendedSnakeboard) -> Layout {
    Layout::new(3, NA, NU).ignoring(board.ignorable_shape())
}

/// Plans `problem` at step `h` from `start` by the toolkit's one call
/// (`dmech_ocp::toolkit::plan::plan_in_layout`, in [`layout`]), by mesh sequencing from
/// the coarsest mesh at or below 80 ms.
pub fn plan(
    board: &Snakeboard,
    problem: &SnakeboardProblem,
    bounds: SnakeboardBounds,
    h: f64,
    discretisation: Discretisation,
    start: SnakeboardStart,
    opts: IpOptions,
) -> Result<SnakeboardOutcome, SnakeboardPlanError> {
    SnakeboardPlan::new(problem, bounds, h)?;
    let extended = board.extended();
    let poses = [problem.start, problem.end];
    let path = |n: usize| start_path(&poses, false, n);
    // ρ for (ψ̇, φ̇, p): the path fixes φ and p through E(φ); the rotor, which E does not
    // read, rests.
    let weights = SVector::<f64, NA>::new(1e-4, 1e-6, 1e-6);
    // A rotor swing of 1 rad and an axle swing of 0.3 of its angle bound, a cycle every
    // 2 s (at 0.5 Hz the rotor's peak rate is π rad/s, a third of its bound).
    let amplitudes = SVector::<f64, NA>::new(1.0, 0.3 * bounds.axle_angle, 0.0);
    let cycles = problem.duration / 2.0;
    let plan_start = match start {
        SnakeboardStart::Zero => PlanStart::Rest,
        SnakeboardStart::Kinematic => PlanStart::Path {
            path: &path,
            regularisation: weights,
        },
        SnakeboardStart::Excited => PlanStart::Excited {
            path: None,
            amplitudes,
            cycles,
        },
        SnakeboardStart::KinematicExcited => PlanStart::Excited {
            path: Some((&path, weights)),
            amplitudes,
            cycles,
        },
    };
    let verbose = opts.verbose;
    let progress = |m: &str| {
        if verbose {
            crate::progress!("{m}");
        }
    };
    let settings = PlanSettings {
        coarsest_step: 0.08,
        solver: opts,
        ..PlanSettings::new(h, discretisation)
    };
    let p = plan_in_layout::<_, _, _, 3, 3, NA, NU, NC, NX, NW>(
        &extended,
        |h| SnakeboardPlan::new(problem, bounds, h).ok(),
        &settings,
        &plan_start,
        layout(&extended),
        &progress,
    )
    .expect("the reduced layout fits NX and NW, and the finest mesh exists");
    Ok(SnakeboardOutcome {
        status: p.status,
        iterations: p.iterations,
        objective: p.objective,
        max_violation: p.max_violation,
        solve_time_s: p.solve_time_s,
        h,
        trajectory: p.trajectory,
    })
}
