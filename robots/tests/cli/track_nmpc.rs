//! `wip track --controller nmpc` through the binary on the paper's plans: with ideal sensors
//! the nonlinear MPC tracks the eight and the zigzag within the LQ controller's documented
//! errors (docs/tracking.md, "Results": 0.61 mm on the eight, 0.46 mm on the zigzag), every
//! sample with its own move (no LQ fallback), its solve times reported.

use crate::common::{read_json, scratch, succeeds, wip};

#[test]
fn nmpc_tracks_the_plans_within_the_lq_errors() {
    let dir = scratch("track-nmpc");
    // The LQ's largest position error with ideal sensors, documented per plan.
    for (problem, lq_bound) in [("eight", 0.61e-3), ("zigzag", 0.46e-3)] {
        let plan = dir.join(format!("plan-{problem}"));
        succeeds(wip().args(["plan", problem, "--out"]).arg(&plan));
        let track = dir.join(format!("track-{problem}"));
        succeeds(
            wip()
                .arg("track")
                .arg(&plan)
                .args(["--ideal", "--controller", "nmpc", "--out"])
                .arg(&track),
        );
        let j = read_json(track.join("tracking.json"));
        assert_eq!(j["outcome"], "completed", "{j}");
        assert_eq!(j["controller"], "nmpc");
        assert_eq!(j["qp_fallbacks"], 0, "{j}");
        let error = j["position_error_max_m"].as_f64().unwrap();
        assert!(
            error <= lq_bound,
            "{problem}: {error} m against the LQ's {lq_bound} m"
        );
        for key in [
            "qp_solve_ms_median",
            "qp_solve_ms_p99",
            "qp_solve_ms_max",
            "qp_wall_ms_median",
            "qp_wall_ms_p99",
            "qp_wall_ms_max",
        ] {
            assert!(j[key].as_f64().unwrap() > 0.0, "{key}: {j}");
        }
    }
}
