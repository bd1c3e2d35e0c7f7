//! The rover diagnosed from generated logs: a hidden wheel friction, a gyro offset and a
//! weak right motor are each named with their parameter within 3 reported standard
//! deviations, a log without
//! effect gives `none`, and the crate builds none of the dmech tools' dependencies.
//!
//! A log is the model's own simulation (`SystemPlant::simulate`, ten Runge–Kutta steps per
//! sample, against the diagnosis's two) under random multisine commands, with Gaussian
//! noise on every reading.

use diagnose_own_robot::{param, Rover};
use dmech_diagnose::{diagnose, DiagnoseOptions, MeasuredLog, ObservedSystem, Plant, SystemPlant};
use dmech_lie::rng::Rng;

/// The sample step, s, and the log's length in samples (20 s).
const H: f64 = 0.02;
const ROWS: usize = 1000;
/// Reading noise: pose x, y (m), heading (rad), encoders (rad), gyro (rad/s).
const NOISE: [f64; 6] = [1e-3, 1e-3, 5e-3, 2e-3, 2e-3, 1e-2];

/// A log of the rover under parameters `theta` (the catalogue's order), noise from `seed`.
fn generate(theta: &[f64], seed: u64) -> MeasuredLog {
    let truth = SystemPlant::new(Rover::new(), 10);
    let mut rng = Rng::new(seed);
    let sines: Vec<[f64; 4]> = (0..3)
        .map(|_| {
            [
                rng.range(0.2, 0.5),
                rng.range(0.3, 3.0),
                rng.range(0.0, 6.3),
                rng.range(0.0, 6.3),
            ]
        })
        .collect();
    let mut log = MeasuredLog::empty(H, 2, NOISE.len());
    for k in 0..ROWS {
        let t = k as f64 * H;
        let u = |side: usize| -> f64 {
            sines
                .iter()
                .map(|s| s[0] * (s[1] * t + s[2 + side]).sin())
                .sum::<f64>()
        };
        log.push_row(t, &[u(0), u(1)], &[0.0; 6]);
    }
    log.channels_present_from_data();
    let y = truth
        .simulate(&log, &[0.0; 7], theta)
        .expect("the rover simulates");
    for k in 0..ROWS {
        for (c, v) in log.row_mut(k).iter_mut().enumerate() {
            *v = y[k * NOISE.len() + c] + NOISE[c] * rng.normal();
        }
    }
    log
}

/// The catalogue's nominal parameters with `(index, value)` changed.
fn with(changes: &[(usize, f64)]) -> Vec<f64> {
    let mut theta = Rover::new().catalogue().nominal();
    for &(i, v) in changes {
        theta[i] = v;
    }
    theta
}

fn run(log: &MeasuredLog) -> dmech_diagnose::Diagnosis {
    let plant = SystemPlant::new(Rover::new(), 2);
    let opts = DiagnoseOptions {
        threads: 2,
        ..Default::default()
    };
    diagnose(&plant, log, &opts, &|line| eprintln!("{line}")).expect("the log is diagnosable")
}

/// The estimate of parameter `i` is within 3 of its standard deviations of `truth`.
fn within_3_sigma(d: &dmech_diagnose::Diagnosis, i: usize, truth: f64) {
    let (est, sd) = (d.chosen.fit.theta[i], d.chosen.fit.std[i]);
    println!("parameter {i}: true {truth}, estimate {est} ± {sd}");
    assert!(
        (est - truth).abs() <= 3.0 * sd,
        "parameter {i}: {est} ± {sd} against {truth}"
    );
}

#[test]
fn a_hidden_wheel_friction_is_named_with_its_torque() {
    let f_c = 0.02;
    let d = run(&generate(&with(&[(param::COULOMB, f_c)]), 11));
    println!("{}", d.verdict);
    assert_eq!(d.cause, "wheel_friction", "{}", d.verdict);
    within_3_sigma(&d, param::COULOMB, f_c);
}

#[test]
fn a_gyro_offset_is_named_by_the_generic_reading_hypothesis() {
    let plant = SystemPlant::new(Rover::new(), 2);
    let offset = plant
        .catalogue()
        .param_index(&dmech_diagnose::ReadingFamily::Offset.param_name("gyro"))
        .expect("the gyro declares an offset");
    let d = run(&generate(&with(&[(offset, 0.03)]), 12));
    println!("{}", d.verdict);
    assert_eq!(d.cause, "reading_offset:gyro", "{}", d.verdict);
    within_3_sigma(&d, offset, 0.03);
}

#[test]
fn a_weak_right_motor_is_named_by_the_generic_input_hypothesis() {
    let plant = SystemPlant::new(Rover::new(), 2);
    let gain = plant
        .catalogue()
        .param_index(&dmech_diagnose::ActuatorFamily::Gain.param_name("u_r"))
        .expect("every input declares a gain");
    let d = run(&generate(&with(&[(gain, 0.9)]), 14));
    println!("{}", d.verdict);
    assert_eq!(d.cause, "input_gain:u_r", "{}", d.verdict);
    within_3_sigma(&d, gain, 0.9);
}

#[test]
fn a_log_without_effect_is_none() {
    let d = run(&generate(&with(&[]), 13));
    println!("{}", d.verdict);
    assert_eq!(d.cause, "none", "{}", d.verdict);
}

/// What a user's crate builds to diagnose its robot: none of the dmech tools' dependencies.
#[test]
fn the_crate_builds_none_of_the_tools_dependencies() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
    let out = std::process::Command::new(cargo)
        .args([
            "tree",
            "--offline",
            "-e",
            "normal",
            "--prefix",
            "none",
            "--manifest-path",
        ])
        .arg(manifest)
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    assert!(tree.contains("dmech-diagnose"), "{tree}");
    for tool_dependency in ["clap ", "serde ", "csv ", "clarabel ", "robots "] {
        assert!(
            !tree.lines().any(|l| l.starts_with(tool_dependency)),
            "{tool_dependency}in the tree:\n{tree}"
        );
    }
}
