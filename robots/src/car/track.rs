//! The car's plan tracked in closed loop on the framework's pieces (`dmech_ocp::tracking`):
//! the plan's linearisation along its transcription, the Riccati gains or the constrained
//! MPC on the same weights, and a plant car whose parameters differ from the plan's
//! (`docs/car.md`).
//!
//! Full-state feedback: the plant's state is read exactly (no sensors, no observer, no
//! delay); the inputs saturate at the drive's ±6 V and the steering servo's ±0.1 N m.

use super::model::{Car, CarParams};
use super::plan::{CarBounds, CarOutcome, CarPlan};
use super::problems::CarProblem;
use dmech::Discretisation;
use dmech_lie::lcg::Lcg;
use dmech_ocp::qp::QpSettings;
use dmech_ocp::tracking::{
    linearise_along, lq_gains, plant_step, Mpc, MpcError, MpcMove, MpcSettings, TrackingError,
    TrackingWeights,
};
use dmech_ocp::transcription::VarIntTranscription;
use nalgebra::{SMatrix, SVector};

/// The solver's state size of the car's transcription.
const NX: usize = super::plan::NX;

/// The drive voltage's and the steering torque's saturation on the plant.
pub const VOLTAGE_LIMIT: f64 = 6.0;
/// See [`VOLTAGE_LIMIT`].
pub const STEER_TORQUE_LIMIT: f64 = 0.1;

/// What a closed-loop run of the car recorded, one row per stage.
#[derive(Clone, Debug, Default)]
pub struct CarTracking {
    pub t: Vec<f64>,
    /// The plan's pose and the plant's.
    pub planned: Vec<[f64; 3]>,
    pub actual: Vec<[f64; 3]>,
    /// The applied inputs `(τ_s, u_d)` (after saturation), one per step.
    pub input: Vec<[f64; 2]>,
    /// The MPC's moves, one per step (empty for the other controllers).
    pub mpc_moves: Vec<MpcMove<2>>,
}

impl CarTracking {
    /// The position error at every stage, m.
    pub fn position_errors(&self) -> Vec<f64> {
        self.planned
            .iter()
            .zip(&self.actual)
            .map(|(p, a)| (p[0] - a[0]).hypot(p[1] - a[1]))
            .collect()
    }
    /// The largest position error, m.
    pub fn max_error(&self) -> f64 {
        self.position_errors().into_iter().fold(0.0, f64::max)
    }
    /// The position error at the end, m.
    pub fn end_error(&self) -> f64 {
        *self.position_errors().last().expect("at least the start")
    }
}

/// The parameters with every mass, inertia and motor constant scaled by an independent
/// factor uniform in `[1 − e, 1 + e]` from `seed` (the geometry kept).
pub fn mismatched(p: &CarParams, e: f64, seed: u64) -> CarParams {
    let mut rng = Lcg(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xCA7);
    let mut f = || 1.0 + 2.0 * e * rng.uniform();
    CarParams {
        m: p.m * f(),
        j: p.j * f(),
        i_w: p.i_w * f(),
        i_s: p.i_s * f(),
        I_m: p.I_m * f(),
        k_e: p.k_e * f(),
        R_m: p.R_m * f(),
        L_m: p.L_m * f(),
        ..*p
    }
}

/// The LQ weights: a position error of 1 cm and a heading error of 0.05 rad weigh as an
/// input at its bound; the shape, velocities and previous inputs lightly (1e-2); the end
/// ten times the stages'.
fn weights(bounds: &CarBounds) -> (SMatrix<f64, NX, NX>, SMatrix<f64, 2, 2>) {
    let mut q = SMatrix::<f64, NX, NX>::from_diagonal_element(1e-2);
    for (i, scale) in [(0, 0.01), (1, 0.01), (2, 0.05)] {
        q[(i, i)] = 1.0 / (scale * scale);
    }
    let r = SMatrix::<f64, 2, 2>::from_diagonal(&nalgebra::Vector2::new(
        1.0 / bounds.steer_torque.powi(2),
        1.0 / bounds.voltage.powi(2),
    ));
    (q, r)
}

/// The feedback along the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// The plan's inputs alone.
    OpenLoop,
    /// Time-varying LQ along the plan, saturated at the plant's limits.
    Lq,
    /// The constrained MPC (`dmech_ocp::tracking::Mpc`) over `horizon` stages with the
    /// LQ's weights and the plant's limits as hard input bounds.
    Mpc {
        /// Stages in the horizon.
        horizon: usize,
    },
}

impl Controller {
    /// The name in `tracking.json` and on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Controller::OpenLoop => "open-loop",
            Controller::Lq => "lq",
            Controller::Mpc { .. } => "mpc",
        }
    }
}

/// Why a plan could not be tracked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarTrackError {
    /// Linearisation, LQ design or the plant's step.
    #[error(transparent)]
    Tracking(#[from] TrackingError),
    /// The MPC's design or a move.
    #[error(transparent)]
    Mpc(#[from] MpcError),
}

/// The control law built once per plan.
#[derive(Clone, Debug)]
enum Law {
    OpenLoop,
    Lq(Vec<SMatrix<f64, 2, NX>>),
    Mpc(Box<Mpc<NX, 2>>),
}

/// A plan made ready for tracking: its states and decisions in the transcription's layout
/// and the control law along them, reused for every plant ([`TrackingDesign::run`]).
pub struct TrackingDesign<'a> {
    h: f64,
    discretisation: Discretisation,
    on_mesh: CarPlan<'a>,
    px: Vec<SVector<f64, NX>>,
    pw: Vec<SVector<f64, { super::plan::NW }>>,
    law: Law,
}

impl<'a> TrackingDesign<'a> {
    /// The plan `o` of `problem` (planned on `car` with `discretisation`) and the
    /// `controller` along it.
    pub fn new(
        car: &Car,
        problem: &'a CarProblem,
        o: &CarOutcome,
        discretisation: Discretisation,
        controller: Controller,
    ) -> Result<Self, CarTrackError> {
        let bounds = CarBounds::default();
        let on_mesh = CarPlan::new(problem, bounds, o.h).expect("the plan's own mesh");
        let tr = VarIntTranscription::new(car, &on_mesh, o.h, discretisation);
        let (px, pw) = tr.states_of::<{ super::plan::NC }>(&o.trajectory);
        let (q, r) = weights(&bounds);
        let law = match controller {
            Controller::OpenLoop => Law::OpenLoop,
            Controller::Lq => {
                let lin = linearise_along(&tr, &px, &pw)?;
                Law::Lq(lq_gains(&lin, &q, &(q * 10.0), &r)?)
            }
            Controller::Mpc { horizon } => {
                let lin = linearise_along(&tr, &px, &pw)?;
                let inputs = pw
                    .iter()
                    .map(|w| w.fixed_rows::<2>(3).into_owned())
                    .collect();
                let weights = TrackingWeights {
                    state: q,
                    terminal: q * 10.0,
                    input: r,
                };
                let limit = SVector::<f64, 2>::new(STEER_TORQUE_LIMIT, VOLTAGE_LIMIT);
                let settings = MpcSettings {
                    horizon,
                    lower: -limit,
                    upper: limit,
                    qp: QpSettings::default(),
                };
                Law::Mpc(Box::new(Mpc::new(lin, inputs, &weights, settings)?))
            }
        };
        Ok(TrackingDesign {
            h: o.h,
            discretisation,
            on_mesh,
            px,
            pw,
            law,
        })
    }

    /// A closed-loop run on a plant car with parameters `plant`, started `offset` m to the
    /// plan's left.
    pub fn run(&self, plant: &CarParams, offset: f64) -> Result<CarTracking, CarTrackError> {
        let (px, pw) = (&self.px, &self.pw);
        let mut law = self.law.clone();
        let plant_car = Car { params: *plant };
        let plant_tr =
            VarIntTranscription::new(&plant_car, &self.on_mesh, self.h, self.discretisation);
        let mut x = px[0];
        let heading = x[2];
        x[0] -= offset * heading.sin();
        x[1] += offset * heading.cos();
        let mut out = CarTracking::default();
        let pose = |x: &SVector<f64, NX>| [x[0], x[1], x[2]];
        for k in 0..pw.len() {
            out.t.push(k as f64 * self.h);
            out.planned.push(pose(&px[k]));
            out.actual.push(pose(&x));
            let u_plan = pw[k].fixed_rows::<2>(3).into_owned();
            let mut u = match &mut law {
                Law::Lq(g) => u_plan - g[k] * (x - px[k]),
                Law::OpenLoop => u_plan,
                Law::Mpc(mpc) => {
                    let m = mpc.input(k, &(x - px[k]))?;
                    out.mpc_moves.push(m);
                    m.input
                }
            };
            u[0] = u[0].clamp(-STEER_TORQUE_LIMIT, STEER_TORQUE_LIMIT);
            u[1] = u[1].clamp(-VOLTAGE_LIMIT, VOLTAGE_LIMIT);
            out.input.push([u[0], u[1]]);
            let guess = pw[k].fixed_rows::<3>(0).into_owned();
            x = plant_step::<_, NX, { super::plan::NW }, 3, 2, { super::plan::NC }>(
                &plant_tr, k, &x, &u, &guess,
            )?
            .0;
        }
        let n = pw.len();
        out.t.push(n as f64 * self.h);
        out.planned.push(pose(&px[n]));
        out.actual.push(pose(&x));
        Ok(out)
    }
}
