//! The diagnosis machinery on a second system that knows nothing of the WIP: a driven,
//! damped pendulum `θ̈ = −(g/L) sin θ − c θ̇ + b κ u` with an angle sensor and a rate gyro,
//! and its own catalogue (a sensor offset, an input gain, extra damping) and own parameter
//! (`L`, for calibration). Logs are simulated with hidden effects and noise; the diagnosis
//! must name the effect and recover its parameter within 3 reported standard deviations,
//! give `none` on a log without effect, and `unexplained`, with the angle named, on a log
//! whose effect its catalogue leaves out.

use dmech_lie::rng::Rng;
use robots::diagnose::model::{Catalogue, ParamSpec};
use robots::diagnose::{
    diagnose, ChannelSpec, DiagnoseOptions, FitScalar, Indicator, MeasuredLog, Plant,
};

const G: f64 = 9.81;
/// The true length, damping and input gain.
const L: f64 = 0.5;
const C: f64 = 0.3;
const B: f64 = 4.0;
const H: f64 = 0.01;
/// Sensor noise: angle and rate.
const NOISE: [f64; 2] = [0.002, 0.01];

struct Pendulum {
    catalogue: Catalogue,
    channels: Vec<ChannelSpec>,
    inputs: Vec<String>,
}

impl Pendulum {
    fn new() -> Self {
        let mut cat = Catalogue::default();
        let offset = cat.param(ParamSpec::linear("offset_rad", 0.0, 0.01, (-0.3, 0.3)));
        let gain = cat.param(ParamSpec::linear("gain", 1.0, 0.1, (0.3, 3.0)));
        let damping = cat.param(ParamSpec::linear("extra_damping", 0.0, 0.1, (0.0, 10.0)));
        let length = cat.param(ParamSpec::positive("L", L, 0.1, (0.1, 2.0)));
        cat.effect("angle_offset", vec![offset]);
        cat.effect("input_gain", vec![gain]);
        cat.effect("extra_damping", vec![damping]);
        cat.calibration = vec![length];
        Pendulum {
            catalogue: cat,
            channels: vec![
                ChannelSpec::new("angle", "rad", 10.0),
                ChannelSpec::new("rate", "rad/s", 100.0),
            ],
            inputs: vec!["u".into()],
        }
    }

    /// `(θ̇, ω̇)` with parameters `[offset, gain, extra damping, L]`.
    fn rate<T: FitScalar>(theta: &[T], x: [T; 2], u: f64) -> [T; 2] {
        let (gain, extra, len) = (theta[1], theta[2], theta[3]);
        let acc = -(x[0].sin() * G) / len - x[1] * (extra + C) + gain * (B * u);
        [x[1], acc]
    }

    fn step<T: FitScalar>(theta: &[T], x: [T; 2], u: f64, dt: f64) -> [T; 2] {
        let add = |a: [T; 2], k: [T; 2], s: f64| [a[0] + k[0] * s, a[1] + k[1] * s];
        let k1 = Self::rate(theta, x, u);
        let k2 = Self::rate(theta, add(x, k1, dt / 2.0), u);
        let k3 = Self::rate(theta, add(x, k2, dt / 2.0), u);
        let k4 = Self::rate(theta, add(x, k3, dt), u);
        [0, 1].map(|i| x[i] + (k1[i] + k2[i] * 2.0 + k3[i] * 2.0 + k4[i]) * (dt / 6.0))
    }
}

impl Plant for Pendulum {
    fn channels(&self) -> &[ChannelSpec] {
        &self.channels
    }
    fn inputs(&self) -> &[String] {
        &self.inputs
    }
    fn catalogue(&self) -> &Catalogue {
        &self.catalogue
    }
    fn state_dim(&self) -> usize {
        2
    }
    fn additive(&self) -> &[(usize, usize)] {
        &[]
    }
    fn history(&self, _h: f64) -> usize {
        0
    }
    fn initial_state(&self, log: &MeasuredLog, start: usize, _len: usize) -> Vec<f64> {
        vec![
            log.value(start, 0).unwrap_or(0.0),
            log.value(start, 1).unwrap_or(0.0),
        ]
    }
    fn predict<T: FitScalar>(
        &self,
        log: &MeasuredLog,
        start: usize,
        len: usize,
        z0: &[T],
        theta: &[T],
    ) -> Option<Vec<T>> {
        let mut x = [z0[0], z0[1]];
        let mut out = Vec::with_capacity(2 * len);
        for k in start..start + len {
            out.push(x[0] + theta[0]);
            out.push(x[1]);
            for _ in 0..2 {
                x = Self::step(theta, x, log.input(k)[0], log.h / 2.0);
            }
        }
        out.iter().all(|v| v.re().is_finite()).then_some(out)
    }
    fn conditions(&self, log: &MeasuredLog) -> Vec<Indicator> {
        vec![Indicator {
            name: "input positive".into(),
            flags: (0..log.len())
                .map(|k| Some(log.input(k)[0] > 0.0))
                .collect(),
        }]
    }
}

/// A 20 s log of the true pendulum (parameters `[offset, gain, extra damping, L]`) under a
/// random multisine input, with a hidden quadratic drag `drag θ̇|θ̇|` that no catalogue
/// effect has.
fn simulate(theta: [f64; 4], drag: f64, seed: u64) -> MeasuredLog {
    let mut rng = Rng::new(seed);
    let comps: Vec<(f64, f64, f64)> = (0..4)
        .map(|_| {
            (
                rng.range(0.2, 0.6),
                rng.range(0.5, 4.0),
                rng.range(0.0, 6.3),
            )
        })
        .collect();
    let mut log = MeasuredLog::empty(H, 1, 2);
    let mut x = [0.0f64, 0.0];
    for k in 0..2000 {
        let t = k as f64 * H;
        let u: f64 = comps.iter().map(|(a, w, p)| a * (w * t + p).sin()).sum();
        let row = [
            x[0] + theta[0] + NOISE[0] * rng.normal(),
            x[1] + NOISE[1] * rng.normal(),
        ];
        log.push_row(t, &[u], &row);
        for _ in 0..20 {
            let mut y = Pendulum::step(&theta, x, u, H / 20.0);
            y[1] -= drag * x[1] * x[1].abs() * H / 20.0;
            x = y;
        }
    }
    log.channels_present_from_data();
    log
}

fn opts() -> DiagnoseOptions {
    DiagnoseOptions {
        threads: 1,
        ..Default::default()
    }
}

/// One case: hide `truth[i] = value`, diagnose, return `(cause, estimate, σ)`.
fn run(i: usize, value: f64, seed: u64) -> (String, f64, f64) {
    let plant = Pendulum::new();
    let mut theta = [0.0, 1.0, 0.0, L];
    theta[i] = value;
    let d = diagnose(&plant, &simulate(theta, 0.0, seed), &opts(), &|_| {}).unwrap();
    (d.cause.clone(), d.chosen.fit.theta[i], d.chosen.fit.std[i])
}

#[test]
fn each_toy_effect_is_found_with_its_parameter() {
    let mut rng = Rng::new(424242);
    for (i, name, value) in [
        (0, "angle_offset", rng.range(0.01, 0.03)),
        (1, "input_gain", 1.0 + rng.range(0.1, 0.3)),
        (2, "extra_damping", rng.range(0.2, 0.5)),
    ] {
        let (cause, est, sd) = run(i, value, rng.next_u64());
        println!("{name}: named {cause}, true {value:.5} est {est:.5} ± {sd:.1e}");
        assert_eq!(cause, name);
        assert!(
            (est - value).abs() <= 3.0 * sd,
            "{name}: {est} ± {sd} vs {value}"
        );
    }
}

#[test]
fn a_toy_log_without_effect_is_none() {
    let plant = Pendulum::new();
    let d = diagnose(
        &plant,
        &simulate([0.0, 1.0, 0.0, L], 0.0, 7),
        &opts(),
        &|_| {},
    )
    .unwrap();
    assert_eq!(d.cause, "none", "{}", d.verdict);
}

/// Quadratic drag is no effect of the toy catalogue (extra viscous damping is its nearest
/// relative, and cannot follow `θ̇|θ̇|`): the verdict is `unexplained` and the rate fails.
#[test]
fn a_toy_effect_outside_the_catalogue_is_unexplained() {
    let plant = Pendulum::new();
    let d = diagnose(
        &plant,
        &simulate([0.0, 1.0, 0.0, L], 0.6, 11),
        &opts(),
        &|_| {},
    )
    .unwrap();
    println!("{}", d.verdict);
    assert_eq!(d.cause, "unexplained", "{}", d.verdict);
    assert!(d.tests_after.iter().any(|t| t.channel == 1 && !t.passes()));
}

/// A wrong length in the model is a calibration, not an effect: with `L` calibrated the
/// log is explained and `L` comes back within 3σ.
#[test]
fn a_toy_length_is_calibrated() {
    let plant = Pendulum::new();
    let log = simulate([0.0, 1.0, 0.0, 0.6], 0.0, 13);
    let o = DiagnoseOptions {
        calibrate: vec!["L".into()],
        ..opts()
    };
    let d = diagnose(&plant, &log, &o, &|l| eprintln!("{l}")).unwrap();
    let (est, sd) = (d.chosen.fit.theta[3], d.chosen.fit.std[3]);
    println!("{}; L = {est} ± {sd}", d.verdict);
    assert_eq!(d.cause, "calibration", "{}", d.verdict);
    assert!((est - 0.6).abs() <= 3.0 * sd, "L = {est} ± {sd}");
}
