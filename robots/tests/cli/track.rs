//! `wip track` through the real binary and the closed loop through the library: the
//! feedforward reproduces a trajectory of the plant exactly, the noisy loop along a short
//! plan stays up, and bad inputs fail with one line.

use crate::common::{fails_with_one_line, read_json, scratch, succeeds, wip};
use robots::wip::simulate::Trajectory;
use robots::wip::track::closed_loop::{track, TrackConfig};
use robots::wip::track::lq::{LqController, SAMPLE};
use robots::wip::track::mpc::MpcController;
use robots::wip::track::observer::SensorModel;
use robots::wip::track::simulated_robot::SUBSTEPS;
use robots::wip::{ReducedState, Wip, WipParams};
use std::path::PathBuf;

fn hook_plan() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/track_hook_h20.csv")
}

/// A reference that IS a trajectory of the plant (its own RK4 with the same substeps,
/// driven by a small voltage pattern for 0.6 s): with ideal sensors the feedforward alone
/// reproduces it, so every error and the feedback stay at rounding level (the same
/// arithmetic runs twice; 1e-9 allows for the sums differing in the last bits as the
/// feedback, itself rounding, is added).
#[test]
fn feedforward_reproduces_a_plant_trajectory() {
    let p = WipParams::default();
    let wip = Wip::new(p);
    let n = 120;
    let mut sched = robots::wip::simulate::InputSchedule {
        t: vec![],
        u: vec![],
    };
    for k in 0..=n {
        let t = k as f64 * SAMPLE;
        sched.t.push(t);
        sched
            .u
            .push([0.2 * (7.0 * t).sin(), 0.15 * (5.0 * t).sin()]);
    }
    let fine = robots::wip::simulate::simulate(
        &wip,
        dmech::Integrator::Rk4,
        SAMPLE / SUBSTEPS as f64,
        &ReducedState::zeros(),
        &sched,
        n * SUBSTEPS,
    )
    .unwrap();
    let mut plan = Trajectory::default();
    for k in 0..=n {
        plan.t.push(fine.t[k * SUBSTEPS]);
        plan.x.push(fine.x[k * SUBSTEPS]);
        plan.u.push(sched.u[k]);
    }
    let lq = LqController::design(&p).unwrap();
    let cfg = TrackConfig {
        plant: p,
        nominal: p,
        sensors: SensorModel::ideal(),
        seed: 0,
        push: None,
    };
    let run = track(&plan, &lq, &cfg, |_| {}).unwrap();
    let f = run.figures();
    assert!(!f.fell);
    assert!(f.position_error_max_m < 1e-9, "{}", f.position_error_max_m);
    assert!(f.feedback_voltage_max < 1e-6, "{}", f.feedback_voltage_max);
    // The MPC along the same reference: every error is zero, the inputs' rate is within its
    // bound, so the QP's solution is zero to clarabel's tolerance (1e-8 on gaps).
    let mpc = MpcController::design(&p, &plan).unwrap();
    let run = track(&plan, &mpc, &cfg, |_| {}).unwrap();
    let f = run.figures();
    assert!(!f.fell && f.qp_fallbacks == 0);
    assert!(f.position_error_max_m < 1e-6, "{}", f.position_error_max_m);
    assert!(f.feedback_voltage_max < 1e-5, "{}", f.feedback_voltage_max);
}

/// Along a short planned path with the paper's sensor rates, delays, losses and noise,
/// three seeds: the WIP stays up and the errors stay within the paper's hardware figures
/// on the (harder) eight: 24 mm and 12.1°.
#[test]
fn noisy_loop_tracks_a_short_plan() {
    let dir = scratch("track-noisy");
    for (controller, seed) in [
        ("lq", "1"),
        ("lq", "2"),
        ("lq", "3"),
        ("mpc", "1"),
        ("nmpc", "1"),
    ] {
        let out_dir = dir.join(format!("{controller}-{seed}"));
        succeeds(
            wip()
                .arg("track")
                .arg(hook_plan())
                .args(["--controller", controller, "--seed", seed, "--out"])
                .arg(&out_dir),
        );
        let j = read_json(out_dir.join("tracking.json"));
        assert_eq!(j["fell"], false);
        assert_eq!(j["controller"], controller);
        for key in ["qp_solve_ms_median", "qp_solve_ms_max", "qp_wall_ms_max"] {
            assert_eq!(j[key].is_number(), controller != "lq", "{key}: {j}");
        }
        assert!(j["position_error_max_m"].as_f64().unwrap() < 0.024, "{j}");
        assert!(
            j["heading_error_max_rad"].as_f64().unwrap() < 12.1f64.to_radians(),
            "{j}"
        );
        for f in [
            "tracking.csv",
            "tracking_path.svg",
            "tracking_errors.svg",
            "tracking_tilt.svg",
            "tracking_feedback.svg",
        ] {
            assert!(out_dir.join(f).exists(), "{f}");
        }
    }
}

/// The delay sweep runs every delay for both controllers and names the largest one
/// without a fall; along the short plan with the nominal plant nothing falls.
#[test]
fn delay_sweep_reports_each_delay() {
    let dir = scratch("track-sweep");
    for controller in ["lq", "mpc"] {
        let out_dir = dir.join(controller);
        succeeds(
            wip()
                .arg("track")
                .arg(hook_plan())
                .args([
                    "--controller",
                    controller,
                    "--delay-sweep",
                    "--monte-carlo",
                    "2",
                ])
                .arg("--out")
                .arg(&out_dir),
        );
        let j: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out_dir.join("delay_sweep.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(j["controller"], controller);
        assert_eq!(j["sweep"].as_array().unwrap().len(), 5);
        let largest = j["largest_mean_delay_without_fall_s"].as_f64().unwrap();
        assert!((largest - 16.0 * 0.063).abs() < 1e-12, "{j}");
    }
}

#[test]
fn bad_plans_fail_with_one_line() {
    let dir = scratch("track-bad");
    std::fs::write(
        dir.join("short.csv"),
        "t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL\n0,0,0,0,0,0,0,0,0,0,0,0\n",
    )
    .unwrap();
    std::fs::write(dir.join("nocol.csv"), "t,x\n0,0\n1,1\n").unwrap();
    fails_with_one_line(&["track", "missing.csv"], &dir, "missing.csv");
    fails_with_one_line(&["track", "short.csv"], &dir, "two rows");
    fails_with_one_line(&["track", "nocol.csv"], &dir, "no column 'y'");
}
