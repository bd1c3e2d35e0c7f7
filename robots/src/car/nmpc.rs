//! The nonlinear MPC of the car (`car track --controller nmpc`): [`dmech_ocp::tracking::nmpc`]
//! on the plan's own transcription (the plan's variational scheme of the full model, the
//! drive current a state, at the plan's step), its first state the measured or estimated
//! one.
//!
//! The state is the transcription's, `x = (x, y, θ, φ, ψ, q, φ̇, ψ̇, i, u_prev)`; the
//! weights are the LQ's and the MPC's (`super::track`): `Q`, `R` at every stage, `10 Q` at
//! the end of the reference, the terminal weight of a horizon the LQ tracker's cost-to-go
//! along the reference's linearisation. The reference is the plan followed by a horizon of
//! rest at its end pose ([`at_rest_after`]): the plan ends at rest, and rest with no input
//! is an equilibrium of the car, so that the horizons of the last stages ask for the
//! plan's own moves. (The plan's last stage held instead, its last input kept, is not a
//! rest: in the reference, it pulled the NMPC 3.2 µm off the plan over the last stages of
//! the `--ideal` runs, whose error is otherwise the barrier's, 2.7e-8 m on parallel-park
//! and 2.8e-7 m on lane-change.)
//!
//! The hard inequalities are the plant's input limits, ±0.1 N m and ±6 V, as the MPC has
//! them; the plan's other rows (voltage rate, current, steering angle and rate) are the
//! plan's choices, not limits of the plant, and are left free, as the MPC leaves them: the
//! two controllers differ by the model alone.
//!
//! When a sample's solve fails or runs out of its budget, the move is the car's LQ
//! controller's, `ū_k − K_k (x − x̄_k)` (`--controller lq`'s gains; counted; the loop
//! clamps it at the limits).

use super::model::Car;
use super::plan::{CarBounds, CarPlan, NC, NW, NX};
use super::problems::CarProblem;
use super::track::{STEER_TORQUE_LIMIT, VOLTAGE_LIMIT};
use dmech::Discretisation;
use dmech_ocp::solver::Curvature;
use dmech_ocp::tracking::nmpc::{Nmpc, NmpcError, NmpcMemory, NmpcSettings, SoftRow};
use dmech_ocp::tracking::{plant_step, TrackingError, TrackingWeights};
use dmech_ocp::transcription::VarIntTranscription;
use nalgebra::{SMatrix, SVector};

/// The stage equality's size: the interval's shape velocity `v_k`.
const NE: usize = 3;
/// The inputs `(τ_s, u_d)`.
const NF: usize = 2;
/// The plan's inequality rows left free (a soft row of no weight): voltage rate, current,
/// steering angle, steering rate (`super::plan::CarPlan`'s constraints).
pub const FREE_ROWS: [usize; 4] = [2, 3, 4, 5];
/// Stages in the horizon by default (`--horizon`; 0.2 s at 20 ms, the MPC's).
pub const HORIZON: usize = 10;
/// Newton steps per sample by default (`--newton-steps`).
pub const NEWTON_STEPS: usize = 2;
/// The barrier parameter of the real-time iteration, held (the solver's tolerance ten
/// times it, as the WIP's: its barrier rule then never lowers it within a sample). The
/// `--ideal` error scales with it (2.8e-7 m on lane-change at 1e-3, 2.8e-10 m at 1e-6);
/// on the mismatched car, seeds 1–3, the errors at 1e-3 and 1e-6 agree within 0.03 mm.
pub const BARRIER: f64 = 1e-3;
/// The wall-clock budget of a sample's solve by default: none, so that a run's moves do
/// not depend on the machine's load (`--budget` sets one).
pub const BUDGET_S: f64 = f64::INFINITY;

/// `car track --controller nmpc`'s options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NmpcOptions {
    /// Stages in the horizon.
    pub horizon: usize,
    /// Newton steps per sample.
    pub newton_steps: usize,
    /// The wall-clock budget of a sample's solve (s).
    pub budget_s: f64,
}

impl Default for NmpcOptions {
    fn default() -> Self {
        NmpcOptions {
            horizon: HORIZON,
            newton_steps: NEWTON_STEPS,
            budget_s: BUDGET_S,
        }
    }
}

/// What one NMPC sample did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NmpcSample {
    /// The input to apply (the NMPC's, or the LQ's when it fell back), before clamping.
    pub input: SVector<f64, NF>,
    /// `false` when the LQ move was applied instead.
    pub solved: bool,
    /// Interior-point iterations taken.
    pub iterations: usize,
    /// The sample's compute as the calling thread's CPU time (s).
    pub cpu_s: f64,
    /// The same as wall-clock time (s).
    pub wall_s: f64,
}

/// Why the car's NMPC could not be designed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarNmpcError {
    /// The rest after the plan's end: the transcription's step failed.
    #[error("the rest after the plan's end: {0}")]
    Rest(#[from] TrackingError),
    /// The NMPC along the plan could not be set up.
    #[error(transparent)]
    Nmpc(#[from] NmpcError),
    /// The fallback's gains do not match the plan.
    #[error("{gains} LQ gains for a plan of {stages} stages")]
    Gains {
        /// Gains given.
        gains: usize,
        /// The plan's stages.
        stages: usize,
    },
}

/// The bounds of the NMPC's transcription: the plant's input limits, the plan's other rows
/// (left free, [`FREE_ROWS`]).
pub fn limits() -> CarBounds {
    CarBounds {
        steer_torque: STEER_TORQUE_LIMIT,
        voltage: VOLTAGE_LIMIT,
        ..CarBounds::default()
    }
}

/// The plan `(px, pw)` of `tr` followed by `stages` of rest: from its last state, the
/// transcription's own steps with no input (the eliminated velocities from the plan's
/// last ones).
#[allow(clippy::type_complexity)]
pub fn at_rest_after(
    tr: &VarIntTranscription<'_, Car, &CarPlan<'_>, 3, 3, 3, 2, NX, NW>,
    (mut px, mut pw): (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>),
    stages: usize,
) -> Result<(Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>), TrackingError> {
    let n = pw.len();
    for _ in 0..stages {
        let last = *px.last().expect("a plan has states");
        let guess: SVector<f64, NE> = pw[n - 1].fixed_rows::<NE>(0).into_owned();
        let (x, w) =
            plant_step::<_, NX, NW, NE, NF, NC>(tr, n - 1, &last, &SVector::zeros(), &guess)?;
        px.push(x);
        pw.push(w);
    }
    Ok((px, pw))
}

/// The NMPC along one car plan (module documentation), with the last iterate of the run
/// it is in (a run clones the design's, which holds none, and starts cold).
#[derive(Clone, Debug)]
pub struct CarNmpc<'a> {
    car: Car,
    mesh: CarPlan<'a>,
    discretisation: Discretisation,
    nmpc: Nmpc<NX, NW, NF>,
    lq_gains: Vec<SMatrix<f64, NF, NX>>,
    memory: NmpcMemory<NX, NW, NC>,
}

impl<'a> CarNmpc<'a> {
    /// The NMPC of the nominal `car` along the plan `(px, pw)` of `mesh`'s problem (its
    /// transcription's states and decisions), with the tracking `weights`; `lq_gains`, the
    /// LQ controller's `K_k` along the plan, give the fallback.
    pub fn new(
        car: &Car,
        mesh: &CarPlan<'a>,
        discretisation: Discretisation,
        plan: (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>),
        weights: &TrackingWeights<NX, NF>,
        lq_gains: Vec<SMatrix<f64, NF, NX>>,
        options: NmpcOptions,
    ) -> Result<Self, CarNmpcError> {
        if lq_gains.len() != plan.1.len() {
            return Err(CarNmpcError::Gains {
                gains: lq_gains.len(),
                stages: plan.1.len(),
            });
        }
        let mesh = CarPlan {
            bounds: limits(),
            ..mesh.clone()
        };
        let settings = NmpcSettings {
            horizon: options.horizon,
            newton_steps: options.newton_steps,
            barrier: BARRIER,
            tol: 10.0 * BARRIER,
            budget_s: options.budget_s,
            curvature: Curvature::GaussNewton,
            soft: FREE_ROWS
                .iter()
                .map(|&row| SoftRow { row, weight: 0.0 })
                .collect(),
        };
        let nmpc = {
            let tr = VarIntTranscription::new(car, &mesh, mesh.h, discretisation);
            let (px, pw) = at_rest_after(&tr, plan, options.horizon)?;
            Nmpc::new(&tr, px, pw, weights, settings)?
        };
        Ok(CarNmpc {
            car: *car,
            mesh,
            discretisation,
            nmpc,
            lq_gains,
            memory: NmpcMemory::default(),
        })
    }

    /// The NMPC beneath.
    pub fn nmpc(&self) -> &Nmpc<NX, NW, NF> {
        &self.nmpc
    }

    /// The problem the plan solves.
    pub fn problem(&self) -> &CarProblem {
        self.mesh.problem
    }

    /// The LQ controller's move at stage `k < N` from `x`.
    pub fn lq_input(&self, k: usize, x: &SVector<f64, NX>) -> SVector<f64, NF> {
        let u: SVector<f64, NF> = self
            .nmpc
            .reference_decision(k)
            .fixed_rows::<NF>(NE)
            .into_owned();
        u - self.lq_gains[k.min(self.lq_gains.len() - 1)] * (x - self.nmpc.reference_state(k))
    }

    /// The move at stage `k < N` from the state `x0`: the NMPC's first input, or the LQ
    /// controller's move where the sample's solve failed or ran out of its budget.
    pub fn sample(&mut self, k: usize, x0: &SVector<f64, NX>) -> Result<NmpcSample, NmpcError> {
        let tr = VarIntTranscription::new(&self.car, &self.mesh, self.mesh.h, self.discretisation);
        let m = self.nmpc.step(&tr, k, x0, &mut self.memory)?;
        Ok(NmpcSample {
            input: m.input.unwrap_or_else(|| self.lq_input(k, x0)),
            solved: m.input.is_some(),
            iterations: m.iterations,
            cpu_s: m.cpu_s,
            wall_s: m.wall_s,
        })
    }
}
