//! `car generate` and `car diagnose` through the binary (docs/car.md, "Diagnosis"): a log
//! with a hidden drive friction is diagnosed `drive_friction` with the torque within 3
//! reported standard deviations and the output files written; the log's columns and
//! truth.json are what docs/car.md says; bad effects and bad flags are one line. (The whole
//! recovery matrix runs through the library in `tests/diagnose/car.rs`.)

use crate::common::{car, read_json, scratch, succeeds};

#[test]
fn a_generated_drive_friction_is_diagnosed() {
    let dir = scratch("car-diagnose-friction");
    succeeds(
        car()
            .args([
                "generate",
                "parallel-park",
                "--effect",
                "drive_friction=0.004",
            ])
            .args(["--seed", "5", "--out"])
            .arg(&dir),
    );
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    assert_eq!(
        log.lines().next().unwrap(),
        "t,tau_s,u_d,x,y,theta,steer,wheel,yaw_rate"
    );
    assert_eq!(log.lines().count(), 1 + 301, "the plan's 301 stages");
    let truth = read_json(dir.join("truth.json"));
    assert_eq!(truth["params"]["f_d"], 0.004, "{truth}");
    let out = dir.join("diagnosis");
    succeeds(
        car()
            .args(["diagnose", "--quiet", "--threads", "2", "--out"])
            .arg(&out)
            .arg(dir.join("log.csv")),
    );
    let d = read_json(out.join("diagnosis.json"));
    assert_eq!(d["cause"], "drive_friction", "{d}");
    let est = d["parameters"]["f_d"].as_f64().expect("f_d named");
    let sd = d["uncertainty"]["f_d"].as_f64().expect("f_d's σ");
    assert!((est - 0.004).abs() <= 3.0 * sd, "{est} ± {sd}");
    for f in ["report.md", "residuals.csv", "residual_wheel.svg"] {
        assert!(out.join(f).is_file(), "{f}");
    }
}

#[test]
fn bad_effects_and_flags_are_one_line() {
    let dir = scratch("car-diagnose-bad");
    for (args, code, expect) in [
        (
            vec!["generate", "parallel-park", "--effect", "payload=1"],
            1,
            "unknown effect 'payload'",
        ),
        (
            vec!["generate", "parallel-park", "--effect", "drive_friction"],
            2,
            "NAME=VALUE",
        ),
        (
            vec![
                "generate",
                "parallel-park",
                "--effect",
                "drive_friction=nan",
            ],
            2,
            "finite",
        ),
        (vec!["diagnose", "missing.csv"], 1, "missing.csv"),
    ] {
        let out = car().args(&args).current_dir(&dir).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(
            err.contains(expect),
            "{args:?}: '{err}' should mention '{expect}'"
        );
        assert!(!err.contains("panicked"), "{err}");
        if code == 1 {
            assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        }
    }
}
