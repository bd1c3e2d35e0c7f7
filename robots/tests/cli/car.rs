//! `car plan` and `car simulate`: the built-in problems solve from the generic start, and
//! every constraint holds on the written trajectory.csv (re-measured from the file).

use crate::common::{car, read_json, rows, scratch};

#[test]
fn car_plans_the_built_in_problems() {
    for (problem, integrator, end) in [
        ("parallel-park", "first-order", [-0.8, -0.2, 0.0]),
        ("lane-change", "midpoint", [3.0, 0.35, 0.0]),
    ] {
        let dir = scratch(&format!("car-{problem}"));
        let out = car()
            .args([
                "plan",
                problem,
                "--integrator",
                integrator,
                "--quiet",
                "--out",
            ])
            .arg(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "car plan {problem}: {stderr}");
        let summary = read_json(dir.join("summary.json"));
        assert_eq!(summary["status"], "solved");
        assert_eq!(summary["integrator"], integrator);
        assert!(
            summary["max_violation"].as_f64().unwrap() <= 1e-9,
            "{summary}"
        );
        let r = rows(&std::fs::read_to_string(dir.join("trajectory.csv")).unwrap());
        // Columns t,x,y,theta,phi,psi,q,v_phi,v_psi,i,tau_s,u_d; bounds of docs/car.md, to
        // the solver's constraint tolerance (an interior point stays inside them).
        let tol = 1e-8;
        let h = 0.02;
        let mut u_prev = 0.0;
        for row in &r[..r.len() - 1] {
            assert!(row[4].abs() <= 0.6 + tol, "steering angle {row:?}");
            assert!(row[7].abs() <= 2.0 + tol, "steering rate {row:?}");
            assert!(row[9].abs() <= 2.0 + tol, "current {row:?}");
            assert!(row[10].abs() <= 0.05 + tol, "steering torque {row:?}");
            assert!(row[11].abs() <= 6.0 + tol, "voltage {row:?}");
            assert!(
                (row[11] - u_prev).abs() <= 20.0 * h + tol,
                "voltage rate {row:?}"
            );
            u_prev = row[11];
        }
        let last = r.last().unwrap();
        for i in 0..3 {
            assert!((last[1 + i] - end[i]).abs() < 1e-9, "end pose {last:?}");
        }
        assert!(
            last[7..10].iter().all(|v| v.abs() < 1e-9),
            "at rest: {last:?}"
        );
        for svg in ["path.svg", "steering.svg", "drive.svg"] {
            assert!(std::fs::read_to_string(dir.join(svg))
                .unwrap()
                .starts_with("<svg"));
        }
    }
}

/// A constant drive voltage from rest, no steering torque: straight ahead, the heading and
/// the lateral position stay zero, the speed builds up.
#[test]
fn car_simulates_a_straight_start() {
    let dir = scratch("car-simulate");
    std::fs::write(dir.join("in.csv"), "t,tau_s,u_d\n0,0,2\n1.0,0,2\n").unwrap();
    let out = car()
        .args([
            "simulate",
            "--x0",
            "0,0,0,0,0,0,0,0,0",
            "--inputs",
            "in.csv",
            "--out",
            ".",
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = rows(&std::fs::read_to_string(dir.join("trajectory.csv")).unwrap());
    assert_eq!(r.len(), 201);
    let last = r.last().unwrap();
    assert!(last[1] > 0.05, "moved forward: {last:?}");
    assert!(last[2].abs() < 1e-12 && last[3].abs() < 1e-12, "{last:?}");
}

/// `car track`: the ideal plant follows the plan to round-off; under the default mismatch
/// (±10 % on every mass, inertia and motor constant) from 2 cm to the side, LQ ends within
/// a tenth of the open loop's miss; a Monte Carlo reports its percentiles.
#[test]
fn car_tracks_its_plans_in_closed_loop() {
    let end_error = |args: &[&str], name: &str| run_track(args, name).0;
    for problem in ["parallel-park", "lane-change"] {
        let ideal = end_error(
            &["track", problem, "--ideal"],
            &format!("track-ideal-{problem}"),
        );
        assert!(
            ideal["max_position_error_m"]["worst"].as_f64().unwrap() < 1e-3,
            "{ideal}"
        );
        let lq = end_error(&["track", problem], &format!("track-lq-{problem}"));
        let open = end_error(
            &["track", problem, "--controller", "open-loop"],
            &format!("track-open-{problem}"),
        );
        let (e_lq, e_open) = (
            lq["end_position_error_m"]["worst"].as_f64().unwrap(),
            open["end_position_error_m"]["worst"].as_f64().unwrap(),
        );
        assert!(
            e_lq < 0.1 * e_open,
            "{problem}: LQ {e_lq:.2e} against open loop {e_open:.2e}"
        );
        let mc = end_error(
            &["track", problem, "--monte-carlo", "20"],
            &format!("track-mc-{problem}"),
        );
        assert_eq!(mc["runs"], 20);
        assert_eq!(mc["seeds"].as_array().unwrap().len(), 20);
        let p95 = mc["end_position_error_m"]["p95"].as_f64().unwrap();
        assert!(p95 < 5e-3, "{problem}: p95 end error {p95:.2e}");
    }
}

/// `car track --controller mpc`: no failure, every QP solved, the plan's own car on the
/// plan within 1 mm, the mismatched car's end error far below the open loop's, and the
/// QPs' figures in tracking.json; a horizon of no stage is a usage error. (The moves
/// within the bounds: `tests/tests/generic/tracking_mpc.rs`.)
#[test]
fn car_tracks_its_plans_by_mpc() {
    let run = run_track;
    for (problem, stages) in [("parallel-park", 300), ("lane-change", 250)] {
        let mpc = ["track", problem, "--controller", "mpc"];
        let (ideal, _) = run(
            &[&mpc[..], &["--ideal"]].concat(),
            &format!("mpc-ideal-{problem}"),
        );
        assert_eq!(ideal["controller"], "mpc");
        assert!(
            ideal["max_position_error_m"]["worst"].as_f64().unwrap() <= 1e-3,
            "{ideal}"
        );
        let (mc, dir) = run(
            &[&mpc[..], &["--monte-carlo", "3"]].concat(),
            &format!("mpc-mc-{problem}"),
        );
        let (open, _) = run(
            &["track", problem, "--controller", "open-loop"],
            &format!("mpc-open-{problem}"),
        );
        assert_eq!(mc["horizon"], 10);
        assert_eq!(mc["qp"]["samples"], 3 * stages);
        assert_eq!(mc["qp"]["not_solved"], 0);
        assert!(mc["qp"]["cpu_s"]["median"].as_f64().unwrap() > 0.0);
        let (e_mpc, e_open) = (
            mc["end_position_error_m"]["worst"].as_f64().unwrap(),
            open["end_position_error_m"]["worst"].as_f64().unwrap(),
        );
        assert!(
            e_mpc < 0.1 * e_open,
            "{problem}: MPC {e_mpc:.2e} against open loop {e_open:.2e}"
        );
        // One row per stage and the end.
        let r = rows(&std::fs::read_to_string(dir.join("tracking.csv")).unwrap());
        assert_eq!(r.len(), stages + 1);
    }
    let dir = scratch("mpc-horizon-zero");
    let out = car()
        .args([
            "track",
            "lane-change",
            "--controller",
            "mpc",
            "--horizon",
            "0",
        ])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

/// `car ARGS --out DIR` (DIR a scratch directory named `name`), which must succeed:
/// tracking.json and DIR.
pub(crate) fn run_track(args: &[&str], name: &str) -> (serde_json::Value, std::path::PathBuf) {
    let dir = run_car(args, name);
    (read_json(dir.join("tracking.json")), dir)
}

/// `car ARGS --out DIR` (DIR a scratch directory named `name`), which must succeed: DIR.
pub(crate) fn run_car(args: &[&str], name: &str) -> std::path::PathBuf {
    let dir = scratch(name);
    let out = car().args(args).arg("--out").arg(&dir).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}
