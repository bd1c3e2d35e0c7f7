//! `car track` on the car's sensors (encoders, gyro, late poses) through the framework's
//! observer: no failure for either problem and controller, the estimate and the end within
//! bounds set by the sensors' accuracy, the ideal sensors on the plan's own car, the delay
//! sweep's file, and the options' usage errors.

use crate::car::{run_car, run_track as run};
use crate::common::{car, read_json, rows, scratch};

/// The paper's pose noise, σ of a position reading, m.
const SIGMA_POSITION: f64 = 5e-4;
/// The exact-state loop's worst end error over 100 seeds of ±10 % (docs/car.md), m.
const EXACT_END_WORST: f64 = 1.31e-3;

/// The default (the paper's sensors) on both problems, LQ and MPC, three plants each: every
/// run completes, every pose arrives within the observer's memory, the estimate from the
/// first pose on stays within 6 σ of a position reading of the truth, and the end error
/// within the exact-state loop's worst plus that estimate error.
#[test]
fn car_tracks_on_its_sensors() {
    for (problem, stages) in [("parallel-park", 300), ("lane-change", 250)] {
        for controller in ["lq", "mpc"] {
            let name = format!("sensors-{problem}-{controller}");
            let (json, dir) = run(
                &[
                    "track",
                    problem,
                    "--controller",
                    controller,
                    "--monte-carlo",
                    "3",
                ],
                &name,
            );
            assert_eq!(json["sensors"], "paper", "{json}");
            let fused = json["poses"]["fused"].as_u64().unwrap();
            assert_eq!(json["poses"]["dropped"], 0);
            // 50-Hz poses over 20-ms samples, 2 % lost, the last few still in flight.
            assert!(
                fused as usize > 3 * stages * 9 / 10,
                "{name}: {fused} poses fused"
            );
            let estimate = json["max_estimate_error_m"]["worst"].as_f64().unwrap();
            assert!(
                estimate < 6.0 * SIGMA_POSITION,
                "{name}: estimate off by {estimate:.2e}"
            );
            let end = json["end_position_error_m"]["worst"].as_f64().unwrap();
            assert!(
                end < EXACT_END_WORST + 6.0 * SIGMA_POSITION,
                "{name}: end error {end:.2e}"
            );
            let r = rows(&std::fs::read_to_string(dir.join("tracking.csv")).unwrap());
            assert_eq!(r.len(), stages + 1);
            for svg in ["tracking_path.svg", "tracking_error.svg"] {
                assert!(dir.join(svg).exists(), "{name}: {svg}");
            }
        }
    }
}

/// `--ideal` reads the state exactly and stays within 1 mm; with `--sensors ideal` the
/// plan's own car on the plan is estimated from exact readings through the observer and
/// stays within 1 mm too.
#[test]
fn ideal_car_tracks_within_a_millimetre() {
    for problem in ["parallel-park", "lane-change"] {
        let (exact, _) = run(&["track", problem, "--ideal"], &format!("ideal-{problem}"));
        assert_eq!(exact["sensors"], "exact");
        assert!(exact.get("poses").is_none());
        assert!(exact["max_position_error_m"]["worst"].as_f64().unwrap() <= 1e-3);
        let (sensed, _) = run(
            &["track", problem, "--ideal", "--sensors", "ideal"],
            &format!("ideal-sensors-{problem}"),
        );
        assert_eq!(sensed["sensors"], "ideal");
        assert!(
            sensed["max_position_error_m"]["worst"].as_f64().unwrap() <= 1e-3,
            "{sensed}"
        );
    }
}

/// `--delay-sweep`: five mean delays from the paper's 0.063 s to 16 times it, each row with
/// its runs and finite error figures.
#[test]
fn car_delay_sweep_writes_its_table() {
    let dir = run_car(
        &[
            "track",
            "lane-change",
            "--delay-sweep",
            "--monte-carlo",
            "2",
        ],
        "car-delay-sweep",
    );
    let json = read_json(dir.join("delay_sweep.json"));
    let sweep = json["sweep"].as_array().unwrap();
    assert_eq!(sweep.len(), 5);
    for (row, factor) in sweep.iter().zip([1.0, 2.0, 4.0, 8.0, 16.0]) {
        let delay = row["mean_delay_s"].as_f64().unwrap();
        assert!((delay - 0.063 * factor).abs() < 1e-12, "{row}");
        assert_eq!(row["runs"], 2);
        let end = row["end_position_error_m"]["median"].as_f64().unwrap();
        assert!(end.is_finite() && end >= 0.0, "{row}");
    }
}

/// Usage errors: an unknown sensor set, and the sweep with a sensor choice of its own.
#[test]
fn car_sensor_options_are_checked() {
    for args in [
        &["track", "lane-change", "--sensors", "perfect"][..],
        &[
            "track",
            "lane-change",
            "--delay-sweep",
            "--sensors",
            "exact",
        ][..],
        &["track", "lane-change", "--delay-sweep", "--ideal"][..],
    ] {
        let dir = scratch("car-sensor-usage");
        let out = car().args(args).arg("--out").arg(&dir).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
    }
}
