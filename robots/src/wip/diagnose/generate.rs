//! Synthetic measured logs for testing `diagnose`: a closed-loop run of the TRUE model (the
//! full model with dynamic current, plus hidden effects), a controller designed on the
//! NOMINAL model, and realistic sensor noise (issue: tilt 0.003 rad, rate 0.02 rad/s,
//! encoders quantised at 3600 counts/rev, currents 0.02 A, pose 1 mm / 0.005 rad at 50 Hz).

use super::effects::{Effect, ModelExtension};
use super::measured::MeasuredLog;
use super::prediction::{Predictor, D, ND};
use crate::wip::{Wip, WipParams};
use dmech::continuous::{ContinuousModel, ContinuousState, RungeKutta};
use dmech_lie::Se2;
use nalgebra::{SMatrix, SVector};

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

/// A small deterministic generator (xoshiro256**), seeded by SplitMix64, with normal
/// deviates by Box–Muller: reproducible logs without a dependency.
#[derive(Clone, Debug)]
pub struct Rng {
    s: [u64; 4],
    spare: Option<f64>,
}

impl Rng {
    pub fn new(seed: u64) -> Self {
        let mut z = seed;
        let mut next = || {
            z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            x ^ (x >> 31)
        };
        Rng {
            s: [next(), next(), next(), next()],
            spare: None,
        }
    }
    pub fn next_u64(&mut self) -> u64 {
        let r = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        r
    }
    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        let (u1, u2) = (1.0 - self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (2.0 * std::f64::consts::PI * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
    /// `±1` with equal probability.
    pub fn sign(&mut self) -> f64 {
        if self.uniform() < 0.5 {
            -1.0
        } else {
            1.0
        }
    }
}

/// The magnitudes at which each effect is drawn in the tests and by `wip generate`, per
/// parameter as `(nominal + sign · U(lo, hi) · scale)`; chosen so that the effect moves
/// the readings clearly above the noise on a 20 s log (`docs/diagnose.md`).
pub fn draw_effect(effect: Effect, p: &WipParams, rng: &mut Rng) -> Vec<f64> {
    let nominal = effect.nominal(p);
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
            nominal[0] * rng.range(1.1, 1.3),
            nominal[1] * rng.range(1.1, 1.25),
        ],
        Effect::DeadZone => vec![rng.range(0.2, 0.5)],
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

/// The true model's state: pose in SE(2), shape `(α, φR, φL, qR, qL)`, shape velocity
/// `(v_α, φ̇R, φ̇L, iR, iL)`.
type TrueState = ContinuousState<Se2<f64>, 5>;

/// One RK4 step of the true model (dmech's continuous model with the floor's force).
fn true_rk4(
    ext: &ModelExtension<f64>,
    sys: &Wip<f64>,
    x: &TrueState,
    u: [f64; 2],
    dt: f64,
) -> Result<TrueState, String> {
    let floor = |y: &TrueState| ext.floor_force(sys, &y.s, y.g.theta);
    ContinuousModel::step_with_force::<Wip<f64>, 3, 2, 5, 2>(
        sys,
        RungeKutta::Rk4,
        dt,
        x,
        &SVector::<f64, 2>::new(u[0], u[1]),
        &floor,
    )
    .map_err(|e| format!("the true model failed: {e:?}"))
}

/// A discrete LQR on the NOMINAL prediction model, linearised at rest upright: state
/// `(α, v_α, φ̇R, φ̇L)`, input `(uR, uL)`, one sample step. Returns `K` with `u = −K e`.
pub fn nominal_lqr(p: &WipParams, h: f64) -> Result<SMatrix<f64, 2, 4>, String> {
    let pred = Predictor::<D>::new(ModelExtension::nominal(p), p);
    let idx = [3usize, 6, 7, 8];
    let mut z = SVector::<D, 9>::zeros();
    for (d, &i) in idx.iter().enumerate() {
        z[i] = D::from(0.0).derivative(d);
    }
    let u = [D::from(0.0).derivative(4), D::from(0.0).derivative(5)];
    let (next, _) = pred
        .step(&z, u, D::from(h))
        .ok_or("the nominal model cannot step from rest: check the parameters")?;
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
            .ok_or("the LQR design failed (R + BᵀSB singular): check the parameters")?
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
        return Err("the LQR design failed (non-finite gain): check the parameters".into());
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
}

/// Simulate a closed-loop run of the true model with the hidden `effects` and record it as
/// a measured log.
pub fn generate(
    p: &WipParams,
    effects: &[(Effect, Vec<f64>)],
    seed: u64,
    settings: &RunSettings,
) -> Result<GeneratedLog, String> {
    let mut rng = Rng::new(seed);
    let reference = Reference::draw(&mut rng);
    let mut ext = ModelExtension::<f64>::nominal(p);
    for (e, theta) in effects {
        ext.set(*e, theta);
    }
    let sys = ext.system(p);
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
    let mut log = MeasuredLog::empty(h);
    let mut clean = Vec::with_capacity(n);
    let (m_delay, f_delay) = {
        let tau = ext.delay;
        let m = (tau / h).floor();
        (m as usize, tau - m * h)
    };
    for k in 0..pre_roll + n {
        let t = (k as f64 - pre_roll as f64) * h;
        // Sensors at t_k.
        let alpha = x.s[0];
        let truth = [
            x.g.x,
            x.g.y,
            x.g.theta,
            ext.tilt_reading(alpha),
            x.v[0],
            x.s[1] - alpha,
            x.s[2] - alpha,
            x.v[3],
            x.v[4],
        ];
        let quant = |a: f64| (a / q_enc).round() * q_enc;
        let meas_alpha = truth[3] + noise.tilt * rng.normal();
        let meas_rate = truth[4] + noise.rate * rng.normal();
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
            log.push_row(t, cmd, &row);
            clean.push(truth);
        }
        if k + 1 == pre_roll + n {
            break;
        }
        if x.s[0].abs() > 1.0 {
            return Err(format!("the robot fell at t = {t:.3} s (seed {seed})"));
        }

        // Advance the true model over [t_k, t_{k+1}): the driver applies the command of
        // `delay` earlier: u_{k−m−1} until t_k + f, then u_{k−m}.
        let applied = |j: isize| -> [f64; 2] {
            let c = cmd_hist[j.max(0) as usize];
            [ext.driver(c[0]), ext.driver(c[1])]
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
                x = true_rk4(&ext, &sys, &x, ua, dt)?;
            }
        }
    }
    log.channels_present_from_data();
    Ok(GeneratedLog { log, clean })
}
