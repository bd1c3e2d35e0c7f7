//! Synthetic measured logs for testing `diagnose`: a closed-loop run of the TRUE model (the
//! full model with dynamic current, plus hidden effects), a controller designed on the
//! NOMINAL model, and realistic sensor noise (issue: tilt 0.003 rad, rate 0.02 rad/s,
//! encoders quantised at 3600 counts/rev, currents 0.02 A, pose 1 mm / 0.005 rad at 50 Hz).

use super::effects::{Effect, ModelExtension};
use super::plant::{Channel, WipPlant};
use super::prediction::Predictor;
use super::reversal_lockout::ReversalLockout;
use crate::diagnose::{MeasuredLog, Plant, ReadingFamily};
use crate::wip::{Wip, WipParams};
use dmech::continuous::{acceleration_with_force, ContinuousModel, ContinuousState, RungeKutta};
pub use dmech_lie::rng::Rng;
use dmech_lie::Se2;
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

/// Dual directions of the LQR design (four states, two inputs).
const ND: usize = 6;
type D = DualSVec64<ND>;

/// Sensor noise of the generated logs (standard deviations; encoders are quantised).
#[derive(Clone, Copy, Debug)]
pub struct SensorNoise {
    pub tilt: f64,
    pub rate: f64,
    pub encoder_counts_per_rev: f64,
    pub current: f64,
    pub position: f64,
    pub heading: f64,
    /// Pose samples come every this many rows (200 Hz / 50 Hz = 4).
    pub pose_every: usize,
}

impl Default for SensorNoise {
    fn default() -> Self {
        SensorNoise {
            tilt: 0.003,
            rate: 0.02,
            encoder_counts_per_rev: 3600.0,
            current: 0.02,
            position: 0.001,
            heading: 0.005,
            pose_every: 4,
        }
    }
}

impl SensorNoise {
    /// The standard deviation of a channel's reading (an encoder's quantisation `q/√12`).
    pub fn sigma(&self, c: Channel) -> f64 {
        match c {
            Channel::X | Channel::Y => self.position,
            Channel::Theta => self.heading,
            Channel::Alpha => self.tilt,
            Channel::VAlpha => self.rate,
            Channel::PhiRRel | Channel::PhiLRel => {
                std::f64::consts::TAU / self.encoder_counts_per_rev / 12f64.sqrt()
            }
            Channel::IR | Channel::IL => self.current,
        }
    }
}

/// The magnitudes at which each effect is drawn in the tests and by `wip generate`, per
/// parameter as `(nominal + sign · U(lo, hi) · scale)`; chosen so that the effect moves
/// the readings clearly above the noise on a 20 s log (`docs/diagnose.md`).
pub fn draw_effect(effect: Effect, p: &WipParams, rng: &mut Rng) -> Vec<f64> {
    let nominal = [p.d_v, p.d_c, p.m_b, p.l];
    match effect {
        Effect::TiltOffset => vec![rng.sign() * rng.range(0.01, 0.05)],
        Effect::FloorSlope => vec![
            rng.sign() * rng.range(0.02, 0.06),
            rng.sign() * rng.range(0.02, 0.06),
        ],
        Effect::InputDelay => vec![rng.range(0.003, 0.012)],
        Effect::VoltageGain => vec![1.0 + rng.sign() * rng.range(0.1, 0.25)],
        Effect::Friction => vec![
            nominal[0] * rng.range(2.0, 4.0),
            nominal[1] * rng.range(0.3, 0.6),
        ],
        Effect::WheelRadiusAsymmetry => {
            let d = rng.sign() * rng.range(0.02, 0.05) * p.r;
            vec![p.r + d / 2.0, p.r - d / 2.0]
        }
        Effect::Payload => vec![
            nominal[2] * rng.range(1.1, 1.3),
            nominal[3] * rng.range(1.1, 1.25),
        ],
        Effect::DeadZone => vec![rng.range(0.2, 0.5)],
        Effect::StickSlip => vec![p.d_c * rng.range(1.5, 3.0), rng.range(0.1, 0.5)],
        Effect::TiltFilter => vec![rng.range(0.02, 0.2)],
        Effect::GearBacklash => vec![rng.range(0.01, 0.04)],
        Effect::ReversalLockout => vec![rng.range(0.03, 0.08)],
        // A reading's offset of 1–3 times the channel's noise (the generator's
        // [`SensorNoise`]): at 1σ the mean of a 10-s log's 2,000 readings moves 45 standard
        // errors, and at 3σ the sensor is still one a controller balances on. A scale off
        // by 2–5 %, a sensitivity tolerance or an encoder's counts per revolution off by
        // a few.
        Effect::Reading(ReadingFamily::Offset, c) => {
            vec![rng.sign() * rng.range(1.0, 3.0) * SensorNoise::default().sigma(c)]
        }
        Effect::Reading(ReadingFamily::Scale, _) => {
            vec![1.0 + rng.sign() * rng.range(0.02, 0.05)]
        }
    }
}

/// Noise of the controller's wheel-rate estimate (rad/s).
const WHEEL_RATE_NOISE: f64 = 0.05;

/// Settings of a generated run.
#[derive(Clone, Debug)]
pub struct RunSettings {
    pub duration: f64,
    pub h: f64,
    pub substeps: usize,
    pub noise: SensorNoise,
    pub max_voltage: f64,
}

impl Default for RunSettings {
    fn default() -> Self {
        RunSettings {
            duration: 20.0,
            h: 0.005,
            substeps: 20,
            noise: SensorNoise::default(),
            max_voltage: 6.0,
        }
    }
}

/// The RK4 substeps per control step that keep the true model of `p` with `effects` within
/// RK4's stability bound ([`crate::check::stable_substeps`] on its modes at rest):
/// `settings.substeps` where that suffices (the paper's robot), more for a faster motor
/// circuit, an error where none would do or the model's rates are not finite. Set
/// `settings.substeps` to it before [`generate`], whose plant would otherwise blow up (and
/// the blow-up read as a fall).
pub fn truth_substeps(
    p: &WipParams,
    effects: &[(Effect, Vec<f64>)],
    settings: &RunSettings,
) -> Result<usize, crate::check::CheckError> {
    let what = "generate: the model";
    let (_, _, ext) = truth_model(p, effects);
    let x = TrueState {
        g: Se2::new(0.0, 0.0, 0.0),
        s: SVector::zeros(),
        v: SVector::zeros(),
    };
    let modes = crate::check::linear_modes(&ext.system(), &x, &SVector::zeros(), what)?;
    crate::check::stable_substeps(
        what,
        &modes,
        crate::check::Scheme::from(dmech::Integrator::Rk4),
        settings.h,
        settings.substeps,
        4000,
    )
}

/// The WIP's plant, the full parameter vector with the hidden `effects` and the model
/// extension it gives.
fn truth_model(
    p: &WipParams,
    effects: &[(Effect, Vec<f64>)],
) -> (WipPlant, Vec<f64>, ModelExtension<f64>) {
    let plant = WipPlant::new(*p);
    let layout = plant.layout();
    let theta = layout.theta_with(plant.catalogue(), effects);
    let ext = layout.extension(p, &theta);
    (plant, theta, ext)
}

/// The true model's state: pose in SE(2), shape `(α, φR, φL, qR, qL)`, shape velocity
/// `(v_α, φ̇R, φ̇L, iR, iL)`.
type TrueState = ContinuousState<Se2<f64>, 5>;

/// A wheel's mode in the true model under the stick-slip law.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TrueWheel {
    Stuck,
    Slipping(f64),
}

/// Why a closed-loop log could not be generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GenerateError {
    /// The true model's mass matrix is singular at a state.
    #[error("the true model's mass matrix is singular")]
    SingularMassMatrix,
    /// The stuck wheels' holding torques have no solution.
    #[error("the stuck wheels' response is singular")]
    SingularStuckWheels,
    /// A step of the true model left the finite numbers.
    #[error("the true model failed: {0:?}")]
    TrueModel(dmech::StepError),
    /// The nominal prediction model cannot step from rest.
    #[error("the nominal model cannot step from rest: check the parameters")]
    NominalCannotStep,
    /// The controller's LQR design failed.
    #[error("the LQR design failed ({0}): check the parameters")]
    Lqr(&'static str),
    /// The robot fell during the run.
    #[error("the robot fell at t = {t:.3} s (seed {seed})")]
    Fell {
        /// When.
        t: f64,
        /// The run's seed.
        seed: u64,
    },
}

/// The true model: the WIP of the extension with the dynamic current, by `dmech`'s generic
/// path. Under the stick-slip law its friction comes as an external force: slip friction
/// for a slipping wheel, and for a stuck wheel the torque that keeps it at rest relative to
/// the body (the accelerations are affine in the force: two probes give the response).
struct Truth<'a> {
    ext: &'a ModelExtension<f64>,
    sys: Wip<f64>,
}

impl Truth<'_> {
    fn accel(
        &self,
        y: &TrueState,
        u: &SVector<f64, 2>,
        f: &SVector<f64, 5>,
    ) -> Result<SVector<f64, 5>, GenerateError> {
        acceleration_with_force(&self.sys, &y.s, &y.v, u, f)
            .ok_or(GenerateError::SingularMassMatrix)
    }

    /// The external shape force at `y` and the holding torques of the stuck wheels.
    fn force(
        &self,
        y: &TrueState,
        u: &SVector<f64, 2>,
        modes: [TrueWheel; 2],
    ) -> Result<(SVector<f64, 5>, [f64; 2]), GenerateError> {
        let mut f = self.ext.floor_force(&self.sys, &y.s, y.g.theta);
        if !self.ext.sticks() {
            return Ok((f, [0.0; 2]));
        }
        let dir = |j: usize| {
            let mut d = SVector::<f64, 5>::zeros();
            d[0] = 1.0;
            d[1 + j] = -1.0;
            d
        };
        let w = [y.v[1] - y.v[0], y.v[2] - y.v[0]];
        for j in 0..2 {
            if let TrueWheel::Slipping(sign) = modes[j] {
                f += dir(j) * self.ext.slip_friction(w[j], sign);
            }
        }
        let stuck: Vec<usize> = (0..2).filter(|&j| modes[j] == TrueWheel::Stuck).collect();
        if stuck.is_empty() {
            return Ok((f, [0.0; 2]));
        }
        let a0 = self.accel(y, u, &f)?;
        let wdot = |a: &SVector<f64, 5>, j: usize| a[1 + j] - a[0];
        let g: Vec<SVector<f64, 5>> = stuck
            .iter()
            .map(|&j| self.accel(y, u, &(f + dir(j))).map(|a| a - a0))
            .collect::<Result<_, _>>()?;
        let mut hold = [0.0; 2];
        if stuck.len() == 1 {
            let j = stuck[0];
            hold[j] = -wdot(&a0, j) / wdot(&g[0], j);
        } else {
            let m = nalgebra::Matrix2::new(
                wdot(&g[0], 0),
                wdot(&g[1], 0),
                wdot(&g[0], 1),
                wdot(&g[1], 1),
            );
            let x = m.try_inverse().ok_or(GenerateError::SingularStuckWheels)?
                * nalgebra::Vector2::new(-wdot(&a0, 0), -wdot(&a0, 1));
            hold = [x[0], x[1]];
        }
        for &j in &stuck {
            f += dir(j) * hold[j];
        }
        Ok((f, hold))
    }

    fn rk4(
        &self,
        x: &TrueState,
        u: [f64; 2],
        dt: f64,
        modes: [TrueWheel; 2],
    ) -> Result<TrueState, GenerateError> {
        let u = SVector::<f64, 2>::new(u[0], u[1]);
        let force = |y: &TrueState| {
            self.force(y, &u, modes)
                .map(|r| r.0)
                .unwrap_or_else(|_| SVector::from_element(f64::NAN))
        };
        ContinuousModel::step_with_force(&self.sys, RungeKutta::Rk4, dt, x, &u, &force)
            .map_err(GenerateError::TrueModel)
    }

    /// One step of the true model; under the stick-slip law a switch within the step (a
    /// slipping wheel reaching rest, a stuck wheel's holding torque passing the static
    /// limit) cuts it at the interpolated time.
    fn step(
        &self,
        x: &TrueState,
        u: [f64; 2],
        dt: f64,
        modes: &mut [TrueWheel; 2],
    ) -> Result<TrueState, GenerateError> {
        if !self.ext.sticks() {
            return self.rk4(x, u, dt, *modes);
        }
        let limit = self.ext.static_limit();
        let uv = SVector::<f64, 2>::new(u[0], u[1]);
        let rel = |y: &TrueState| [y.v[1] - y.v[0], y.v[2] - y.v[0]];
        let mut x = *x;
        let mut remaining = dt;
        for _ in 0..6 {
            let m = *modes;
            let (_, hold0) = self.force(&x, &uv, m)?;
            let x1 = self.rk4(&x, u, remaining, m)?;
            let (_, hold1) = self.force(&x1, &uv, m)?;
            let (w0, w1) = (rel(&x), rel(&x1));
            let mut first: Option<(f64, usize)> = None;
            for j in 0..2 {
                let frac = match m[j] {
                    TrueWheel::Slipping(s) => (w1[j] * s < 0.0).then(|| w0[j] / (w0[j] - w1[j])),
                    TrueWheel::Stuck => (hold1[j].abs() > limit)
                        .then(|| (limit - hold0[j].abs()) / (hold1[j].abs() - hold0[j].abs())),
                };
                if let Some(fr) = frac {
                    let fr = if fr.is_finite() {
                        fr.clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    if first.is_none_or(|(g, _)| fr < g) {
                        first = Some((fr, j));
                    }
                }
            }
            let Some((fr, j)) = first else {
                return Ok(x1);
            };
            let piece = remaining * fr;
            if piece > 0.0 {
                x = self.rk4(&x, u, piece, m)?;
            }
            remaining -= piece;
            match m[j] {
                TrueWheel::Slipping(s) => {
                    let mut trial = m;
                    trial[j] = TrueWheel::Stuck;
                    x.v[1 + j] = x.v[0];
                    let (_, hold) = self.force(&x, &uv, trial)?;
                    modes[j] = if hold[j].abs() <= limit {
                        TrueWheel::Stuck
                    } else {
                        TrueWheel::Slipping(-s)
                    };
                }
                TrueWheel::Stuck => modes[j] = TrueWheel::Slipping(hold1[j].signum()),
            }
            if remaining <= 1e-12 * dt {
                return Ok(x);
            }
        }
        self.rk4(&x, u, remaining, *modes)
    }
}

/// A discrete LQR on the NOMINAL prediction model, linearised at rest upright: state
/// `(α, v_α, φ̇R, φ̇L)`, input `(uR, uL)`, one sample step. Returns `K` with `u = −K e`.
pub fn nominal_lqr(p: &WipParams, h: f64) -> Result<SMatrix<f64, 2, 4>, GenerateError> {
    let pred = Predictor::<D>::new(ModelExtension::nominal(p));
    let idx = [3usize, 6, 7, 8];
    let mut z = SVector::<D, 9>::zeros();
    for (d, &i) in idx.iter().enumerate() {
        z[i] = D::from(0.0).derivative(d);
    }
    let u = [D::from(0.0).derivative(4), D::from(0.0).derivative(5)];
    let (next, _) = pred
        .step(&z, u, D::from(h))
        .ok_or(GenerateError::NominalCannotStep)?;
    let eps = |x: &D, j: usize| {
        x.eps
            .unwrap_generic(nalgebra::Const::<ND>, nalgebra::Const::<1>)[j]
    };
    let a = SMatrix::<f64, 4, 4>::from_fn(|r, c| eps(&next[idx[r]], c));
    let b = SMatrix::<f64, 4, 2>::from_fn(|r, c| eps(&next[idx[r]], 4 + c));
    // Weights: tilt 0.05 rad, tilt rate 0.5 rad/s, wheel rates 20 rad/s, voltage 1 V.
    let q = SMatrix::<f64, 4, 4>::from_diagonal(&SVector::<f64, 4>::new(
        1.0 / 0.05f64.powi(2),
        1.0 / 0.5f64.powi(2),
        1.0 / 20.0f64.powi(2),
        1.0 / 20.0f64.powi(2),
    ));
    let r = SMatrix::<f64, 2, 2>::identity();
    let mut s = q;
    let mut k = SMatrix::<f64, 2, 4>::zeros();
    for _ in 0..20000 {
        let btsb = r + b.transpose() * s * b;
        let k_new = btsb
            .try_inverse()
            .ok_or(GenerateError::Lqr("R + BᵀSB singular"))?
            * (b.transpose() * s * a);
        let s_new = q + a.transpose() * s * (a - b * k_new);
        let done = (k_new - k).norm() < 1e-12 * k_new.norm().max(1.0);
        k = k_new;
        s = (s_new + s_new.transpose()) * 0.5;
        if done {
            break;
        }
    }
    if !k.iter().all(|v| v.is_finite()) {
        return Err(GenerateError::Lqr("non-finite gain"));
    }
    Ok(k)
}

/// A reference motion: speed and heading rate as sums of sinusoids drawn from the seed.
struct Reference {
    speed: Vec<(f64, f64, f64)>,
    turn: Vec<(f64, f64, f64)>,
}

impl Reference {
    fn draw(rng: &mut Rng) -> Self {
        let mut comps = |amp: f64| -> Vec<(f64, f64, f64)> {
            (0..3)
                .map(|_| {
                    (
                        amp * rng.range(0.3, 1.0),
                        2.0 * std::f64::consts::PI / rng.range(2.0, 9.0),
                        rng.range(0.0, 6.3),
                    )
                })
                .collect()
        };
        Reference {
            speed: comps(0.2),
            turn: comps(0.8),
        }
    }
    fn at(&self, t: f64) -> (f64, f64) {
        let ramp = (t / 1.0).min(1.0);
        let f = |c: &[(f64, f64, f64)]| {
            c.iter()
                .map(|(a, w, ph)| a * (w * t + ph).sin())
                .sum::<f64>()
        };
        (ramp * f(&self.speed), ramp * f(&self.turn))
    }
}

/// A generated log and the clean readings it came from (for the tests' noise floor).
pub struct GeneratedLog {
    pub log: MeasuredLog,
    pub clean: Vec<[f64; 9]>,
    /// The true state per row in the prediction's coordinates
    /// `(x, y, θ, α, φR, φL, v_α, φ̇R, φ̇L)` (to check the prediction model against the
    /// truth).
    pub states: Vec<[f64; 9]>,
}

/// Simulate a closed-loop run of the true model with the hidden `effects` and record it as
/// a measured log.
pub fn generate(
    p: &WipParams,
    effects: &[(Effect, Vec<f64>)],
    seed: u64,
    settings: &RunSettings,
) -> Result<GeneratedLog, GenerateError> {
    let mut rng = Rng::new(seed);
    let reference = Reference::draw(&mut rng);
    let (plant, theta, ext) = truth_model(p, effects);
    let readings = plant.readings().expect("the WIP declares its readings");
    let mut sys = ext.system();
    if ext.sticks() {
        // The stick-slip law supplies the friction.
        sys.params.d_v = 0.0;
        sys.params.d_c = 0.0;
    }
    let model = Truth { ext: &ext, sys };
    let mut modes = [TrueWheel::Slipping(1.0); 2];
    // The firmware's tilt estimate (a complementary filter), when the effect is on.
    let mut filter: Option<f64> = None;
    let k_lqr = nominal_lqr(p, settings.h)?;
    let h = settings.h;
    let noise = settings.noise;
    let q_enc = 2.0 * std::f64::consts::PI / noise.encoder_counts_per_rev;
    let pre_roll = (1.0 / h).round() as usize;
    let n = (settings.duration / h).round() as usize + 1;

    let mut x = TrueState {
        g: Se2::new(0.0, 0.0, 0.0),
        s: SVector::zeros(),
        v: SVector::zeros(),
    };
    let mut cmd_hist: Vec<[f64; 2]> = Vec::with_capacity(pre_roll + n);
    // The fraction of each step for which the firmware passes the command (its reversal
    // lockout, when the effect is on).
    let mut passed_hist: Vec<[f64; 2]> = Vec::with_capacity(pre_roll + n);
    let mut lockout = [ReversalLockout::default(); 2];
    let mut log = WipPlant::empty_log(h);
    let mut clean = Vec::with_capacity(n);
    let mut states = Vec::with_capacity(n);
    let (m_delay, f_delay) = {
        let tau = ext.delay;
        let m = (tau / h).floor();
        (m as usize, tau - m * h)
    };
    for k in 0..pre_roll + n {
        let t = (k as f64 - pre_roll as f64) * h;
        // Sensors at t_k.
        let alpha = x.s[0];
        let lost = [ext.backlash_offset(x.v[3]), ext.backlash_offset(x.v[4])];
        let mut truth = [
            x.g.x,
            x.g.y,
            x.g.theta,
            ext.tilt_reading(alpha),
            x.v[0],
            x.s[1] - alpha + lost[0],
            x.s[2] - alpha + lost[1],
            x.v[3],
            x.v[4],
        ];
        // The hidden reading offsets and scales: the sensors, and so the controller and
        // the firmware's filter, see `s · reading + b`.
        readings.apply(&mut truth, Channel::ALL.len(), &theta);
        let quant = |a: f64| (a / q_enc).round() * q_enc;
        let tilt = truth[3];
        let mut meas_alpha = tilt + noise.tilt * rng.normal();
        let meas_rate = truth[4] + noise.rate * rng.normal();
        if ext.accel_weight < 1.0 {
            // The firmware's complementary filter f_k = (1 − a)(f_{k−1} + h g_k) + a acc_k,
            // from the first accelerometer reading on; the clean reading is the filter
            // with this sample's accelerometer noise removed (what a perfect model of the
            // filter predicts from the previous reading).
            let a = ext.accel_weight;
            if let Some(f) = filter {
                let prior = (1.0 - a) * (f + h * meas_rate);
                truth[3] = prior + a * tilt;
                meas_alpha = prior + a * meas_alpha;
            }
            filter = Some(meas_alpha);
        }
        let enc = [quant(truth[5]), quant(truth[6])];
        let meas_i = [
            truth[7] + noise.current * rng.normal(),
            truth[8] + noise.current * rng.normal(),
        ];
        let pose_now = k >= pre_roll && (k - pre_roll).is_multiple_of(noise.pose_every);
        let meas_pose = [
            truth[0] + noise.position * rng.normal(),
            truth[1] + noise.position * rng.normal(),
            truth[2] + noise.heading * rng.normal(),
        ];

        // The controller, designed on the nominal model, sees the tilt sensors (with their
        // offset, if any) and wheel rates as an encoder-based estimator gives them (a
        // plain backward difference of the quantised angles excites the period-2 mode of a
        // loop this fast, so the estimate is the true rate plus noise of the same size).
        let wheel = [
            x.v[1] + WHEEL_RATE_NOISE * rng.normal(),
            x.v[2] + WHEEL_RATE_NOISE * rng.normal(),
        ];
        let (vd_ref, vt_ref) = reference.at(t.max(0.0));
        let (wr_ref, wl_ref) = ((vd_ref + p.d * vt_ref) / p.r, (vd_ref - p.d * vt_ref) / p.r);
        let e = SVector::<f64, 4>::new(meas_alpha, meas_rate, wheel[0] - wr_ref, wheel[1] - wl_ref);
        let u = -(k_lqr * e);
        let cmd = [
            u[0].clamp(-settings.max_voltage, settings.max_voltage),
            u[1].clamp(-settings.max_voltage, settings.max_voltage),
        ];
        cmd_hist.push(cmd);
        // The lockout starts with the log (nothing pending at its first row, the state the
        // prediction assumes: before it the firmware's state is unknown).
        passed_hist.push(if ext.lockout > 0.0 && k >= pre_roll {
            [0, 1].map(|m| lockout[m].pass(t, cmd[m], ext.lockout, h))
        } else {
            [1.0; 2]
        });

        if k >= pre_roll {
            let mut row = [f64::NAN; 9];
            if pose_now {
                row[0..3].copy_from_slice(&meas_pose);
            }
            row[3] = meas_alpha;
            row[4] = meas_rate;
            row[5] = enc[0];
            row[6] = enc[1];
            row[7] = meas_i[0];
            row[8] = meas_i[1];
            log.push_row(t, &cmd, &row);
            clean.push(truth);
            states.push([
                x.g.x, x.g.y, x.g.theta, x.s[0], x.s[1], x.s[2], x.v[0], x.v[1], x.v[2],
            ]);
        }
        if k + 1 == pre_roll + n {
            break;
        }
        if x.s[0].abs() > 1.0 {
            return Err(GenerateError::Fell { t, seed });
        }

        // Advance the true model over [t_k, t_{k+1}): the driver applies the command of
        // `delay` earlier: u_{k−m−1} until t_k + f, then u_{k−m}.
        let applied = |j: isize| -> [f64; 2] {
            let (c, p) = (cmd_hist[j.max(0) as usize], passed_hist[j.max(0) as usize]);
            [ext.driver(c[0]) * p[0], ext.driver(c[1]) * p[1]]
        };
        let kk = k as isize - m_delay as isize;
        let pieces = [(f_delay, applied(kk - 1)), (h - f_delay, applied(kk))];
        for (len, ua) in pieces {
            if len <= 0.0 {
                continue;
            }
            let n_sub = ((len / h) * settings.substeps as f64).ceil().max(1.0) as usize;
            let dt = len / n_sub as f64;
            for _ in 0..n_sub {
                x = model.step(&x, ua, dt, &mut modes)?;
            }
        }
    }
    log.channels_present_from_data();
    Ok(GeneratedLog { log, clean, states })
}
