//! The car's planning problem in the toolkit's terms (`dmech_ocp::transcription`), its
//! geometric start path, and the solve.
//!
//! Cost `½ Σ_k ((τ_s/τ_max)² + (u_d/u_max)²)`; path constraints on the steering torque, the
//! drive voltage and its rate, the drive current, the steering angle and its rate; rest to
//! rest between the problem's poses, waypoints at times proportional to the path length.

use super::model::{Car, NS, NU};
use super::problems::CarProblem;
use crate::pose_path::{path_fractions, start_path, time_of_path_fraction};
use dmech::Discretisation;
use dmech_lie::{LieGroup, Real};
use dmech_ocp::nlp::max_violation;
use dmech_ocp::solver::{IpOptions, Status};
use dmech_ocp::toolkit::sequencing::{mesh_sequence, SequenceSettings, SequencedPlan};
use dmech_ocp::transcription::layout::Layout;
use dmech_ocp::transcription::{
    Condition, PlannedTrajectory, PlanningProblem, Quantity, Stage, StartState, VarIntTranscription,
};
use nalgebra::SVector;

/// The stage state: the pose `(x, y, θ)`, the shape `(φ, ψ, q)`, its velocity
/// `(φ̇, ψ̇, i)` and the previous inputs.
pub const LAYOUT: Layout = Layout::new(3, NS, NU);

/// Path constraints per stage: τ_s, u_d, u̇_d, i, φ, φ̇.
pub const NC: usize = 6;
/// The solver's state size: pose 3 + 2 NS + NU.
pub const NX: usize = 3 + 2 * NS + NU;
/// The solver's stage decision: `(v_k, u_k)`.
pub const NW: usize = NS + NU;

/// Bounds of the path constraints (magnitudes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarBounds {
    /// N m.
    pub steer_torque: f64,
    /// V.
    pub voltage: f64,
    /// V/s.
    pub voltage_rate: f64,
    /// A.
    pub current: f64,
    /// rad.
    pub steer_angle: f64,
    /// rad/s.
    pub steer_rate: f64,
}

impl Default for CarBounds {
    fn default() -> Self {
        CarBounds {
            steer_torque: 0.05,
            voltage: 6.0,
            voltage_rate: 20.0,
            current: 2.0,
            steer_angle: 0.6,
            steer_rate: 2.0,
        }
    }
}

/// A [`CarProblem`] on a mesh of step `h`.
#[derive(Clone, Debug)]
pub struct CarPlan<'a> {
    pub problem: &'a CarProblem,
    pub bounds: CarBounds,
    pub h: f64,
    pub n: usize,
    /// The stage of every pose of `problem.poses()`.
    pub stages: Vec<usize>,
}

/// Why a car plan cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarPlanError {
    /// The duration is not a whole number of steps.
    #[error("the duration {duration} s is not a whole number of steps of {h} s ({steps:.4})")]
    NotWholeSteps { duration: f64, h: f64, steps: f64 },
    /// Fewer than two steps: a rest-to-rest plan needs at least two.
    #[error(
        "the duration {duration} s is {steps:.0} step(s) of {h} s; a plan needs at least 2: use \
         --step {half} or less"
    )]
    TooFewSteps {
        duration: f64,
        h: f64,
        steps: f64,
        half: f64,
    },
    /// Two consecutive poses are the same: nothing to move.
    #[error("{first} and {second} are the same pose {pose:?}: nothing to plan, the car is already there")]
    SamePose {
        first: String,
        second: String,
        pose: [f64; 3],
    },
    /// Two consecutive poses at one position with different headings.
    #[error(
        "{first} and {second} are both at ({x}, {y}) with headings {from} and {to}: a car \
         cannot turn in place (and the timing follows the path's length); add a waypoint that \
         moves it, e.g. the corners of a three-point turn"
    )]
    TurnInPlace {
        first: String,
        second: String,
        x: f64,
        y: f64,
        from: f64,
        to: f64,
    },
    /// Two poses' stages coincide on this mesh.
    #[error("{first} and {second} fall on one stage at {h} s: use a smaller step")]
    SharedStage {
        first: String,
        second: String,
        h: f64,
    },
}

/// The name of pose `i` of `n` in messages: `start`, `waypoints[j]`, `end`.
fn pose_name(i: usize, n: usize) -> String {
    match i {
        0 => "start".into(),
        i if i + 1 == n => "end".into(),
        i => format!("waypoints[{}]", i - 1),
    }
}

impl<'a> CarPlan<'a> {
    /// The plan of `problem` at step `h`; an error if the duration is not a whole number of
    /// at least two steps, if two consecutive poses share a position (the same pose, or a
    /// turn in place), or if two poses fall on one stage.
    pub fn new(problem: &'a CarProblem, bounds: CarBounds, h: f64) -> Result<Self, CarPlanError> {
        let steps = problem.duration / h;
        let n = steps.round() as usize;
        if (steps - n as f64).abs() > 1e-6 * steps.max(1.0) {
            return Err(CarPlanError::NotWholeSteps {
                duration: problem.duration,
                h,
                steps,
            });
        }
        if n < 2 {
            return Err(CarPlanError::TooFewSteps {
                duration: problem.duration,
                h,
                steps,
                half: problem.duration / 2.0,
            });
        }
        let poses = problem.poses();
        let count = poses.len();
        for (i, w) in poses.windows(2).enumerate() {
            let (a, b) = (w[0], w[1]);
            if (b[0] - a[0]).hypot(b[1] - a[1]) < 1e-9 {
                let (first, second) = (pose_name(i, count), pose_name(i + 1, count));
                return Err(if (b[2] - a[2]).abs() < 1e-9 {
                    CarPlanError::SamePose {
                        first,
                        second,
                        pose: a,
                    }
                } else {
                    CarPlanError::TurnInPlace {
                        first,
                        second,
                        x: a[0],
                        y: a[1],
                        from: a[2],
                        to: b[2],
                    }
                });
            }
        }
        let stages: Vec<usize> = path_fractions(&poses)
            .iter()
            .map(|&f| (time_of_path_fraction(f) * n as f64).round() as usize)
            .collect();
        if let Some(i) = stages.windows(2).position(|s| s[0] >= s[1]) {
            return Err(CarPlanError::SharedStage {
                first: pose_name(i, count),
                second: pose_name(i + 1, count),
                h,
            });
        }
        Ok(CarPlan {
            problem,
            bounds,
            h,
            n,
            stages,
        })
    }
}

impl PlanningProblem<3, NS, NU, NC> for CarPlan<'_> {
    fn horizon(&self) -> usize {
        self.n
    }
    fn start(&self) -> StartState<3, NS, NU> {
        StartState::at_rest(SVector::from(self.problem.start), SVector::zeros())
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, NU>) -> T {
        let steer = stage.input[0] * (1.0 / self.bounds.steer_torque);
        let drive = stage.input[1] * (1.0 / self.bounds.voltage);
        (steer * steer + drive * drive) * 0.5
    }
    fn constraints<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, NU>) -> SVector<T, NC> {
        SVector::<T, NC>::from_column_slice(&[
            stage.input[0],
            stage.input[1],
            (stage.input[1] - stage.previous_input[1]) * (1.0 / self.h),
            stage.velocity[2],
            stage.shape[0],
            stage.velocity[0],
        ])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let b = &self.bounds;
        let hi = SVector::<f64, NC>::from_column_slice(&[
            b.steer_torque,
            b.voltage,
            b.voltage_rate,
            b.current,
            b.steer_angle,
            b.steer_rate,
        ]);
        (-hi, hi)
    }
    fn conditions(&self) -> Vec<Condition> {
        let poses = self.problem.poses();
        let mut conds = Vec::new();
        for (pose, &stage) in poses.iter().zip(&self.stages).skip(1) {
            for (i, &value) in pose.iter().enumerate() {
                conds.push(Condition {
                    stage,
                    quantity: Quantity::Pose(i),
                    value,
                });
            }
        }
        for i in 0..NS {
            conds.push(Condition {
                stage: self.n,
                quantity: Quantity::Velocity(i),
                value: 0.0,
            });
        }
        conds
    }
    fn affine_in_configuration(&self) -> bool {
        // The cost reads the input; the constraints read φ and u_{k−1} linearly.
        true
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        // `½|u|²` (scaled) and the constraints above, all linear.
        true
    }
}

/// A solved (or not) car plan.
pub struct CarOutcome {
    pub status: Status,
    pub iterations: usize,
    pub objective: f64,
    /// Largest violation of any constraint (dynamics, momentum matching, bounds,
    /// conditions) recomputed on the returned trajectory.
    pub max_violation: f64,
    pub solve_time_s: f64,
    pub h: f64,
    /// The stage of every pose of the problem.
    pub stages: Vec<usize>,
    pub trajectory: PlannedTrajectory<3, NS, NU>,
}

/// The car's plan on meshes of different steps, for
/// [`dmech_ocp::toolkit::sequencing::mesh_sequence`]: a mesh is a step, the start the kinematic one
/// along [`start_path`] of the problem's poses.
struct CarSequence<'p> {
    car: &'p Car,
    problem: &'p CarProblem,
    bounds: CarBounds,
    disc: Discretisation,
}

/// A mesh of the car's plan: its step and the plan's data on it.
pub struct CarMesh<'p> {
    pub plan: CarPlan<'p>,
}

impl<'p> SequencedPlan<NX, NW, NS, NU, NC> for CarSequence<'p> {
    type Mesh = CarMesh<'p>;
    type Problem<'a>
        = VarIntTranscription<'a, Car, &'a CarPlan<'p>, 3, 3, NS, NU, NX, NW>
    where
        Self: 'a;
    fn steps(&self, mesh: &CarMesh) -> usize {
        mesh.plan.n
    }
    fn step(&self, mesh: &CarMesh) -> f64 {
        mesh.plan.h
    }
    fn coarser(&self, mesh: &CarMesh) -> Option<CarMesh<'p>> {
        CarPlan::new(self.problem, self.bounds, mesh.plan.h * 2.0)
            .ok()
            .map(|plan| CarMesh { plan })
    }
    fn problem<'a>(&'a self, mesh: &'a CarMesh<'p>, _phase: usize) -> Self::Problem<'a> {
        VarIntTranscription::new(self.car, &mesh.plan, mesh.plan.h, self.disc)
    }
    fn start(&self, mesh: &CarMesh) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>) {
        let path = start_path(&self.problem.poses(), self.problem.reverse, mesh.plan.n);
        // ρ: the wheel rate shrinks by ρ/(ρ + r²) where the path sets it (r² = 2.5e-3):
        // 1e-6 is a 0.04 % shrink, and holds the charge at rest. The steering rate's 1e-4
        // costs (2 rad/s)² × 1e-4 per step against (r ψ̇ δφ/L)² ≈ 6e-3 for a steering error
        // δφ = 0.1 rad at 1 m/s: the steering follows the path's curvature, smoothly, on
        // the branch |φ| < π/2 it starts on.
        let weights = SVector::<f64, NS>::new(1e-4, 1e-6, 1e-6);
        self.problem(mesh, 0)
            .start_from_path(&path, &SVector::zeros(), &weights)
            .unwrap_or_else(|_| {
                // The path's poses with the shape at rest: the solver still starts from the
                // right places (a kinematic start that fails is reported by the solve).
                let xs = path
                    .iter()
                    .map(|g| SVector::from_fn(|i, _| if i < 3 { g.coordinates()[i] } else { 0.0 }))
                    .collect();
                (xs, vec![SVector::zeros(); mesh.plan.n])
            })
    }
    fn layout(&self) -> Layout {
        LAYOUT
    }
}

/// Plans `problem` at step `h` from the kinematic start along [`start_path`] of its poses, by mesh
/// sequencing from the coarsest mesh at or below 40 ms.
pub fn plan(
    car: &Car,
    problem: &CarProblem,
    bounds: CarBounds,
    h: f64,
    discretisation: Discretisation,
    opts: IpOptions,
) -> Result<CarOutcome, CarPlanError> {
    let finest = CarMesh {
        plan: CarPlan::new(problem, bounds, h)?,
    };
    let stages = finest.plan.stages.clone();
    let seq = CarSequence {
        car,
        problem,
        bounds,
        disc: discretisation,
    };
    // The WIP's settings (docs/ocp.md): restart a finer mesh at μ = 1e-4 (the coarse ones
    // are solved down to that barrier).
    let settings = SequenceSettings {
        coarsest_step: 0.04,
        restart_barrier: 1e-4,
    };
    let verbose = opts.verbose;
    let progress = |m: &str| {
        if verbose {
            crate::progress!("{m}");
        }
    };
    let r = mesh_sequence::<_, NX, NW, NS, NU, NC>(&seq, finest, settings, opts, &progress);
    let problem_on_mesh = CarPlan::new(problem, bounds, h)?;
    let tr = VarIntTranscription::new(car, &problem_on_mesh, h, discretisation);
    let max_violation = max_violation(&tr, &r.iterate.x, &r.iterate.w);
    Ok(CarOutcome {
        status: r.status,
        iterations: r.iterations,
        objective: r.objective,
        max_violation,
        solve_time_s: r.timings.total,
        h,
        stages,
        trajectory: tr.trajectory(&r.iterate),
    })
}
