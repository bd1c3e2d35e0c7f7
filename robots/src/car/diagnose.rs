//! The car's diagnosis (`car generate`, `car diagnose`; docs/car.md, "Diagnosis"): the car
//! as an [`ObservedSystem`] of `dmech-diagnose`, its prediction derived by
//! [`SystemPlant`] from the same `ℓ`, connection and forcing it plans with. No predictor
//! is written for it.
//!
//! Readings: the pose `(x, y, θ)` of an external tracker, the steering encoder `φ`, the
//! rear-wheel encoder `ψ` and the yaw-rate gyro (`docs/car.md`, "Sensors"). Catalogue: the
//! car's own effects, Coulomb friction on the drive (`drive_friction`, torque
//! `f_d tanh(ψ̇/ω_c)` on the rear axle) and on the steering (`steering_friction`,
//! `f_s tanh(φ̇/ω_c)`), and the generic hypotheses of every reading (offset, scale) and
//! every input (offset, gain). The motor's charge `q` is read by nothing and enters the
//! equations only through its rate: it is not fitted.

use super::model::{Car, CarParams, NS, NU};
use super::sensors::CarSensorModel;
use dmech_diagnose::model::{Catalogue, ParamSpec};
use dmech_diagnose::{
    ActuatorHypotheses, ChannelSpec, FitScalar, FixedParams, MeasuredLog, ObservedPoint,
    ObservedSystem, ReadingHypotheses, SystemPlant,
};
use dmech_lie::rng::Rng;
use dmech_lie::scalar::tanh_saturating;
use dmech_ocp::transcription::PlannedTrajectory;
use nalgebra::SVector;

/// Wheel or steering rate below which a Coulomb friction is smoothed, rad/s.
pub const FRICTION_SMOOTHING: f64 = 0.05;
/// Runge–Kutta steps per 20-ms sample in the diagnosis: 2 ms, within the classical
/// method's stability limit `2.78 τ_e` of the drive motor's electrical time constant
/// `τ_e = L_m/R_m = 1 ms`.
pub const DIAGNOSIS_SUBSTEPS_PER_SECOND: f64 = 500.0;
/// The generator's steps: four times finer than the diagnosis's.
pub const TRUTH_SUBSTEPS_PER_SECOND: f64 = 2000.0;

/// The channels, in the order of the readings.
pub const CHANNELS: [&str; 6] = ["x", "y", "theta", "steer", "wheel", "yaw_rate"];
/// The input columns: steering torque (N m) and drive voltage (V).
pub const INPUTS: [&str; NU] = ["tau_s", "u_d"];

/// The car as `diagnose` sees it.
pub struct CarObserved {
    car: Car,
    catalogue: Catalogue,
    channels: Vec<ChannelSpec>,
    inputs: Vec<String>,
    readings: ReadingHypotheses,
    actuators: ActuatorHypotheses,
}

/// Where the car's own effects' parameters sit in [`CarObserved`]'s catalogue.
pub mod param {
    /// The drive's Coulomb torque on the rear axle, N m.
    pub const DRIVE_FRICTION: usize = 0;
    /// The steering's Coulomb torque, N m.
    pub const STEERING_FRICTION: usize = 1;
}

impl CarObserved {
    /// The car `p` with its catalogue.
    pub fn new(p: CarParams) -> Self {
        let mut cat = Catalogue::default();
        let fd = cat.param(ParamSpec::linear("f_d", 0.0, 1e-4, (0.0, 0.05)));
        let fs = cat.param(ParamSpec::linear("f_s", 0.0, 1e-4, (0.0, 0.05)));
        debug_assert_eq!((fd, fs), (param::DRIVE_FRICTION, param::STEERING_FRICTION));
        cat.effect("drive_friction", vec![fd]);
        cat.effect("steering_friction", vec![fs]);
        let channel = |name: &str, unit: &str, range: f64, offset_limit: f64, wraps: bool| {
            let mut c = ChannelSpec::new(name, unit, range);
            c.offset_limit = offset_limit;
            c.wraps = wraps;
            c
        };
        // Offsets: a tracker's heading zero and a steering encoder's zero within 0.05 rad
        // (3°), a MEMS gyro's bias within 0.1 rad/s; none on x, y and the wheel angle,
        // which a window's fitted state absorbs.
        // Per channel of `CHANNELS`: unit, range, offset limit, wraps.
        let specs = [
            ("m", 100.0, 0.0, false),
            ("m", 100.0, 0.0, false),
            ("rad", 1e3, 0.05, true),
            ("rad", 1.6, 0.05, false),
            ("rad", 1e5, 0.0, false),
            ("rad/s", 50.0, 0.1, false),
        ];
        let channels: Vec<ChannelSpec> = CHANNELS
            .iter()
            .zip(specs)
            .map(|(name, (unit, range, lim, wraps))| channel(name, unit, range, lim, wraps))
            .collect();
        let additive = [(0, 0), (1, 1), (4, 4)];
        let readings = ReadingHypotheses::declare(&mut cat, &channels, &additive, &[]);
        let inputs: Vec<String> = INPUTS.iter().map(|s| s.to_string()).collect();
        // A driver's zero point within 1 mN m of steering torque and 0.1 V of drive voltage.
        let actuators = ActuatorHypotheses::declare(&mut cat, &inputs, &[1e-3, 0.1]);
        CarObserved {
            car: Car { params: p },
            catalogue: cat,
            channels,
            inputs,
            readings,
            actuators,
        }
    }
}

/// `(x, y, θ)`, `(φ, ψ, q)`, `(φ̇, ψ̇, i)`: `z`'s blocks.
const WHEEL: usize = 4;

impl ObservedSystem<3, NS, NU> for CarObserved {
    type System<T: FitScalar> = FixedParams<Car, T>;

    fn channels(&self) -> &[ChannelSpec] {
        &self.channels
    }
    fn inputs(&self) -> &[String] {
        &self.inputs
    }
    fn catalogue(&self) -> &Catalogue {
        &self.catalogue
    }
    fn system<T: FitScalar>(&self, _theta: &[T]) -> FixedParams<Car, T> {
        FixedParams::new(self.car)
    }
    /// Pose, steering and wheel angles, and the yaw rate `ξ_θ`.
    fn measure<T: FitScalar>(&self, at: &ObservedPoint<'_, T, NS, NU>, _: &[T]) -> Vec<T> {
        let c = at.coords;
        vec![c[0], c[1], c[2], at.s[0], at.s[1], at.xi[2]]
    }
    /// The pose and the angles read at `start`; their rates from the encoders' first
    /// difference; the current at its steady value for the row's voltage.
    fn initial_state(&self, log: &MeasuredLog, start: usize, _len: usize) -> Vec<f64> {
        let read = |k: usize, c: usize| log.value(k, c).unwrap_or(0.0);
        let next = (start + 1).min(log.len() - 1);
        let rate = |c: usize| (read(next, c) - read(start, c)) / log.h;
        let wheel_rate = rate(WHEEL);
        let current = self.car.steady_current(log.input(start)[1], wheel_rate);
        vec![
            read(start, 0),
            read(start, 1),
            read(start, 2),
            read(start, 3),
            read(start, WHEEL),
            0.0,
            rate(3),
            wheel_rate,
            current,
        ]
    }
    /// The car's own effects: Coulomb torques opposing the steering and the rear axle.
    fn shape_force<T: FitScalar>(
        &self,
        _s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        _u: &SVector<T, NU>,
        theta: &[T],
    ) -> SVector<T, NS> {
        let coulomb = |f: T, w: T| -(f * tanh_saturating(w / FRICTION_SMOOTHING));
        SVector::<T, NS>::new(
            coulomb(theta[param::STEERING_FRICTION], v[0]),
            coulomb(theta[param::DRIVE_FRICTION], v[1]),
            T::zero(),
        )
    }
    fn additive(&self) -> &[(usize, usize)] {
        &[(0, 0), (1, 1), (WHEEL, 4)]
    }
    fn unread_shape(&self) -> &[usize] {
        &[2]
    }
    fn reading_hypotheses(&self) -> Option<&ReadingHypotheses> {
        Some(&self.readings)
    }
    fn actuator_hypotheses(&self) -> Option<&ActuatorHypotheses> {
        Some(&self.actuators)
    }
}

/// The car's plant for a log of step `h`.
pub fn car_plant(p: CarParams, h: f64) -> SystemPlant<CarObserved, 3, NS, NU> {
    let substeps = (h * DIAGNOSIS_SUBSTEPS_PER_SECOND).ceil() as usize;
    SystemPlant::new(CarObserved::new(p), substeps)
}

/// Why a car log cannot be generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarGenerateError {
    /// The effect is not in the car's catalogue.
    #[error("unknown effect '{name}' (known: {known})")]
    UnknownEffect { name: String, known: String },
    /// An effect of more than one parameter.
    #[error("effect '{0}' has more than one parameter")]
    NotScalar(String),
    /// The model could not be simulated along the plan's commands.
    #[error("the car could not be simulated along the plan's commands with {0}")]
    NotSimulable(String),
}

/// An encoder's angle `a` read to the nearest of `counts` per revolution. (The tracking's
/// encoders count down, `sensors::quantise`, a bias of half a count; a generated log
/// leaves it out, so that a log without effect has none.)
fn nearest_count(a: f64, counts: u32) -> f64 {
    let q = std::f64::consts::TAU / counts as f64;
    (a / q).round() * q
}

/// A log of the car driven open loop by a plan's commands (each held for a step), with
/// the hidden effects `(name, value)` of its catalogue, read by the paper's sensors
/// (`CarSensorModel::paper`: encoders to the nearest count, the gyro's and the tracker's
/// noise; every pose on time), noise from `seed`; with the catalogue's true parameters.
pub fn generate(
    p: CarParams,
    plan: &PlannedTrajectory<3, NS, NU>,
    effects: &[(String, f64)],
    seed: u64,
) -> Result<(MeasuredLog, Vec<f64>), CarGenerateError> {
    let h = plan.h;
    let truth = SystemPlant::new(
        CarObserved::new(p),
        (h * TRUTH_SUBSTEPS_PER_SECOND).ceil() as usize,
    );
    let cat = truth.observed().catalogue();
    let mut theta = cat.nominal();
    for (name, value) in effects {
        let e = cat
            .effect_index(name)
            .ok_or_else(|| CarGenerateError::UnknownEffect {
                name: name.clone(),
                known: cat
                    .effects
                    .iter()
                    .map(|e| e.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        match cat.effects[e].params[..] {
            [i] => theta[i] = *value,
            _ => return Err(CarGenerateError::NotScalar(name.clone())),
        }
    }
    let n_ch = CHANNELS.len();
    let mut log = MeasuredLog::empty(h, NU, n_ch);
    for (k, stage) in plan.stages.iter().enumerate() {
        let u = if k + 1 < plan.stages.len() {
            stage.input
        } else {
            SVector::zeros()
        };
        log.push_row(k as f64 * h, u.as_slice(), &[0.0; 6]);
    }
    log.channels_present_from_data();
    let s0 = &plan.stages[0];
    let z0: Vec<f64> = s0
        .pose
        .iter()
        .chain(s0.shape.iter())
        .chain(s0.velocity.iter())
        .copied()
        .collect();
    let what = || {
        effects
            .iter()
            .map(|(n, v)| format!("{n} = {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let y = truth
        .simulate(&log, &z0, &theta)
        .ok_or_else(|| CarGenerateError::NotSimulable(what()))?;
    let sensors = CarSensorModel::paper();
    let mut rng = Rng::new(seed);
    for k in 0..log.len() {
        let exact = &y[k * n_ch..(k + 1) * n_ch];
        let row = log.row_mut(k);
        row[0] = exact[0] + sensors.sigma_position * rng.normal();
        row[1] = exact[1] + sensors.sigma_position * rng.normal();
        row[2] = exact[2] + sensors.sigma_heading * rng.normal();
        row[3] = nearest_count(exact[3], sensors.steer_counts);
        row[4] = nearest_count(exact[4], sensors.wheel_counts);
        row[5] = exact[5] + sensors.sigma_gyro * rng.normal();
    }
    Ok((log, theta))
}
