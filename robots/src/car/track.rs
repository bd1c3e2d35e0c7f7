//! The car's plan tracked in closed loop on the framework's pieces (`dmech_ocp::tracking`):
//! the plan's linearisation along its transcription, the Riccati gains, the constrained
//! MPC on the same weights or the nonlinear MPC on the transcription itself
//! (`super::nmpc`), and a plant car whose parameters differ from the plan's
//! (`docs/car.md`).
//!
//! The controller acts on the state read exactly ([`Sensing::Exact`]) or on the estimate of
//! the framework's observer from the car's sensors ([`Sensing::Sensors`], `super::sensors`);
//! the inputs saturate at the drive's ±6 V and the steering servo's ±0.1 N m.

use super::model::{Car, CarParams};
use super::nmpc::{CarNmpc, CarNmpcError, NmpcOptions, NmpcSample};
use super::plan::{CarBounds, CarOutcome, CarPlan};
use super::problems::CarProblem;
use super::sensors::{start_covariance, CarReadings, CarSensorModel, NP, NY};
use dmech::Discretisation;
use dmech_lie::lcg::Lcg;
use dmech_lie::rng::Rng;
use dmech_ocp::qp::QpSettings;
use dmech_ocp::tracking::{
    linearise_along, lq_gains, plant_step, DelayLaw, LinearisedPlan, Mpc, MpcError, MpcMove,
    MpcSettings, NmpcError, Observer, ObserverError, PlanView, TrackingError, TrackingWeights,
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
    /// The NMPC's samples, one per step (empty for the other controllers).
    pub nmpc_samples: Vec<NmpcSample>,
    /// The pose the controller acted on (the observer's estimate, or the plant's pose when
    /// it is read exactly), one per step.
    pub estimated: Vec<[f64; 3]>,
    /// The first sample at which a pose had been fused (none with exact sensing).
    pub first_pose: Option<usize>,
    /// Poses fused, and poses that arrived older than the observer's memory (dropped).
    pub poses_fused: usize,
    pub poses_dropped: usize,
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
    /// The root mean square of the position error over the stages, m.
    pub fn rms_error(&self) -> f64 {
        let e = self.position_errors();
        (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
    }
    /// The position error at the end, m.
    pub fn end_error(&self) -> f64 {
        *self.position_errors().last().expect("at least the start")
    }
    /// The largest distance between the estimated and the true position from the first
    /// pose fused on (before it the estimate is the plan's start), m; 0 if none was.
    pub fn max_estimate_error(&self) -> f64 {
        let Some(first) = self.first_pose else {
            return 0.0;
        };
        self.estimated
            .iter()
            .zip(&self.actual)
            .skip(first)
            .map(|(e, a)| (e[0] - a[0]).hypot(e[1] - a[1]))
            .fold(0.0, f64::max)
    }
}

/// What the controller acts on.
#[derive(Clone, Debug, PartialEq)]
pub enum Sensing {
    /// The plant's state, read exactly.
    Exact,
    /// The observer's estimate from the car's sensors of this model.
    Sensors(CarSensorModel),
}

impl Sensing {
    /// The name in `tracking.json`.
    pub fn name(&self) -> &'static str {
        match self {
            Sensing::Exact => "exact",
            Sensing::Sensors(s) if *s == CarSensorModel::ideal() => "ideal",
            Sensing::Sensors(s) if *s == CarSensorModel::paper() => "paper",
            Sensing::Sensors(_) => "custom",
        }
    }
}

/// How far back (s) a late pose can be fused: 1 s, beyond any delay of the paper's law.
const MEMORY_S: f64 = 1.0;

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
#[derive(Clone, Copy, Debug, PartialEq)]
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
    /// The nonlinear MPC by real-time iteration on the plan's transcription
    /// (`super::nmpc`), the LQ move where a sample's solve fails.
    Nmpc(NmpcOptions),
}

impl Controller {
    /// The name in `tracking.json` and on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Controller::OpenLoop => "open-loop",
            Controller::Lq => "lq",
            Controller::Mpc { .. } => "mpc",
            Controller::Nmpc(_) => "nmpc",
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
    /// A sample of the NMPC.
    #[error("the NMPC: {0}")]
    Nmpc(#[from] NmpcError),
    /// The NMPC's design.
    #[error("the NMPC's design: {0}")]
    NmpcDesign(#[from] CarNmpcError),
    /// The observer refused a reading or an input.
    #[error("the observer: {0}")]
    Observer(#[from] ObserverError),
}

/// The control law built once per plan.
#[derive(Clone, Debug)]
enum Law<'a> {
    OpenLoop,
    Lq(Vec<SMatrix<f64, 2, NX>>),
    Mpc(Box<Mpc<NX, 2>>),
    Nmpc(Box<CarNmpc<'a>>),
}

/// A plan made ready for tracking: its states and decisions in the transcription's layout
/// and the control law along them, reused for every plant ([`TrackingDesign::run`]).
pub struct TrackingDesign<'a> {
    h: f64,
    discretisation: Discretisation,
    on_mesh: CarPlan<'a>,
    px: Vec<SVector<f64, NX>>,
    pw: Vec<SVector<f64, { super::plan::NW }>>,
    inputs: Vec<SVector<f64, 2>>,
    lin: LinearisedPlan<NX, 2>,
    readings: CarReadings,
    law: Law<'a>,
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
        let tracking_weights = TrackingWeights {
            state: q,
            terminal: q * 10.0,
            input: r,
        };
        let lin = linearise_along(&tr, &px, &pw)?;
        let inputs: Vec<SVector<f64, 2>> = pw
            .iter()
            .map(|w| w.fixed_rows::<2>(3).into_owned())
            .collect();
        let law = match controller {
            Controller::OpenLoop => Law::OpenLoop,
            Controller::Lq => Law::Lq(lq_gains(&lin, &q, &(q * 10.0), &r)?),
            Controller::Mpc { horizon } => {
                let limit = SVector::<f64, 2>::new(STEER_TORQUE_LIMIT, VOLTAGE_LIMIT);
                let settings = MpcSettings {
                    horizon,
                    lower: -limit,
                    upper: limit,
                    qp: QpSettings::default(),
                };
                Law::Mpc(Box::new(Mpc::new(
                    lin.clone(),
                    inputs.clone(),
                    &tracking_weights,
                    settings,
                )?))
            }
            Controller::Nmpc(options) => Law::Nmpc(Box::new(CarNmpc::new(
                car,
                &on_mesh,
                discretisation,
                (px.clone(), pw.clone()),
                &tracking_weights,
                lq_gains(&lin, &q, &(q * 10.0), &r)?,
                options,
            )?)),
        };
        Ok(TrackingDesign {
            h: o.h,
            discretisation,
            on_mesh,
            px,
            pw,
            inputs,
            lin,
            readings: CarReadings::new(&car.params),
            law,
        })
    }

    /// A closed-loop run on a plant car with parameters `plant`, started `offset` m to the
    /// plan's left, acting on what `sensing` gives; `seed` draws the sensors' noise, delays
    /// and losses.
    pub fn run(
        &self,
        plant: &CarParams,
        offset: f64,
        sensing: &Sensing,
        seed: u64,
    ) -> Result<CarTracking, CarTrackError> {
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
        let mut sensors = match sensing {
            Sensing::Exact => None,
            Sensing::Sensors(model) => Some(self.sensors(model, seed)?),
        };
        let pose = |x: &SVector<f64, NX>| [x[0], x[1], x[2]];
        for k in 0..pw.len() {
            out.t.push(k as f64 * self.h);
            out.planned.push(pose(&px[k]));
            out.actual.push(pose(&x));
            let estimate = match &mut sensors {
                None => x,
                Some(s) => s.sample(k, &x, &self.readings, &mut out)?,
            };
            out.estimated.push(pose(&estimate));
            let u_plan = pw[k].fixed_rows::<2>(3).into_owned();
            let mut u = match &mut law {
                Law::Lq(g) => u_plan - g[k] * (estimate - px[k]),
                Law::OpenLoop => u_plan,
                Law::Mpc(mpc) => {
                    let m = mpc.input(k, &(estimate - px[k]))?;
                    out.mpc_moves.push(m);
                    m.input
                }
                Law::Nmpc(nmpc) => {
                    let m = nmpc.sample(k, &estimate)?;
                    out.nmpc_samples.push(m);
                    m.input
                }
            };
            u[0] = u[0].clamp(-STEER_TORQUE_LIMIT, STEER_TORQUE_LIMIT);
            u[1] = u[1].clamp(-VOLTAGE_LIMIT, VOLTAGE_LIMIT);
            out.input.push([u[0], u[1]]);
            if let Some(s) = &mut sensors {
                s.observer.advance(&u)?;
            }
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

    /// The sensors of one run: the model, its noise's generator, the observer along the
    /// plan from the plan's start, and the poses in flight.
    fn sensors(&self, model: &CarSensorModel, seed: u64) -> Result<OnBoard<'_>, CarTrackError> {
        let plan = PlanView {
            linearised: &self.lin,
            states: &self.px,
            inputs: &self.inputs,
        };
        let memory = ((MEMORY_S / self.h).round() as usize).max(1);
        let observer = Observer::new(
            self.readings,
            plan,
            model.observer_noise(self.h),
            self.px[0],
            start_covariance(),
            memory,
        )?;
        Ok(OnBoard {
            model: model.clone(),
            rng: Rng::new(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5E45),
            observer,
            pose_every: model.pose_every(self.h),
            h: self.h,
            in_flight: Vec::new(),
        })
    }
}

/// The sensors and the observer during a run.
struct OnBoard<'a> {
    model: CarSensorModel,
    rng: Rng,
    observer: Observer<'a, CarReadings, NX, 2, NY, NP>,
    pose_every: usize,
    h: f64,
    /// Poses in flight: (arrival sample, measured at, reading).
    in_flight: Vec<(usize, usize, SVector<f64, NP>)>,
}

impl OnBoard<'_> {
    /// Sample `k` of the true state `x`: the on-board readings, a pose sent off if it is
    /// a pose sample and not lost, the poses that have arrived fused; the estimate.
    fn sample(
        &mut self,
        k: usize,
        x: &SVector<f64, NX>,
        readings: &CarReadings,
        out: &mut CarTracking,
    ) -> Result<SVector<f64, NX>, CarTrackError> {
        let y = self.model.on_board(readings, x, &mut self.rng);
        self.observer.read(&y)?;
        if k.is_multiple_of(self.pose_every) && self.rng.uniform() >= self.model.loss {
            let delay = self.model.delay.draw(&mut self.rng);
            let arrive = k + DelayLaw::samples_late(delay, self.h);
            let p = self.model.pose(x, &mut self.rng);
            self.in_flight.push((arrive, k, p));
        }
        let mut result = Ok(());
        self.in_flight.retain(|(arrive, m, p)| {
            if *arrive > k || result.is_err() {
                return true;
            }
            match self.observer.pose(*m, p) {
                Ok(true) => {
                    out.poses_fused += 1;
                    out.first_pose.get_or_insert(k);
                }
                Ok(false) => out.poses_dropped += 1,
                Err(e) => result = Err(e),
            }
            false
        });
        result?;
        Ok(self.observer.estimate())
    }
}
