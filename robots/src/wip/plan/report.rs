//! What `wip plan` reports about a solved plan: the trajectory in the paper's reduced
//! state, the figures of `summary.json` measured on that trajectory, and the plots.

use crate::plot::{Plot, Series};
use crate::wip::plan::problems::PlanProblem;
use crate::wip::plan::{PlanBounds, PlanOutcome};
use crate::wip::simulate::Trajectory;
use crate::wip::state::to_reduced;
use crate::wip::Wip;
use dmech_lie::Se2;

/// The planned trajectory as `trajectory.csv` rows (`u` of the last row repeats).
pub fn reduced_trajectory(wip: &Wip, o: &PlanOutcome) -> Trajectory {
    let t = &o.trajectory;
    let n = t.g.len();
    Trajectory {
        t: match &o.times {
            Some(times) => times.clone(),
            None => (0..n).map(|k| k as f64 * t.h).collect(),
        },
        x: (0..n)
            .map(|k| {
                let g = Se2::new(t.g[k][0], t.g[k][1], t.g[k][2]);
                to_reduced(&wip.params, &g, &t.s[k], &t.v[k])
            })
            .collect(),
        u: t.u.iter().map(|u| [u[0], u[1]]).collect(),
    }
}

/// Peaks of the planned trajectory (summary.json's `peaks`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Peaks {
    pub abs_alpha: f64,
    pub abs_i: f64,
    pub abs_v_theta: f64,
    pub abs_u: f64,
    pub abs_du: f64,
    pub speed: f64,
}

pub fn peaks(traj: &Trajectory) -> Peaks {
    let mut p = Peaks::default();
    for (k, x) in traj.x.iter().enumerate() {
        p.abs_alpha = p.abs_alpha.max(x[3].abs());
        p.speed = p.speed.max(x[5].abs());
        p.abs_v_theta = p.abs_v_theta.max(x[6].abs());
        p.abs_i = p.abs_i.max(x[7].abs()).max(x[8].abs());
        let u = traj.u[k];
        p.abs_u = p.abs_u.max(u[0].abs()).max(u[1].abs());
        let prev = if k == 0 { [0.0, 0.0] } else { traj.u[k - 1] };
        p.abs_du = p
            .abs_du
            .max((u[0] - prev[0]).abs())
            .max((u[1] - prev[1]).abs());
    }
    p
}

/// Largest distance between a waypoint and the planned position at its stage.
pub fn waypoint_error_max(problem: &PlanProblem, traj: &Trajectory) -> f64 {
    problem
        .points
        .iter()
        .zip(&problem.stages)
        .map(|(p, &k)| ((traj.x[k][0] - p[0]).powi(2) + (traj.x[k][1] - p[1]).powi(2)).sqrt())
        .fold(0.0, f64::max)
}

/// Everything `summary.json` holds, as JSON.
#[allow(clippy::too_many_arguments)]
pub fn summary_json(
    benchmark: &str,
    integrator: &str,
    current: &str,
    problem: &PlanProblem,
    o: &PlanOutcome,
    traj: &Trajectory,
    bounds: &PlanBounds,
    setup_time_s: f64,
) -> String {
    let p = peaks(traj);
    let num = |v: f64| {
        if v.is_finite() {
            serde_json::json!(v)
        } else {
            serde_json::Value::Null
        }
    };
    let v = serde_json::json!({
        "benchmark": benchmark,
        "integrator": integrator,
        "current": current,
        "h": problem.h,
        "N": problem.n,
        "status": o.status.code(),
        "iterations": o.iterations,
        "solve_time_s": o.timings.total,
        "setup_time_s": setup_time_s,
        "objective": num(o.objective),
        "max_violation": num(o.max_violation),
        "u_max": bounds.u_max,
        "peaks": {
            "abs_alpha": p.abs_alpha, "abs_i": p.abs_i, "abs_v_theta": p.abs_v_theta,
            "abs_u": p.abs_u, "abs_du": p.abs_du, "speed": p.speed
        },
        "waypoint_error_max": num(waypoint_error_max(problem, traj)),
        "time_breakdown_s": {
            "derivatives": o.timings.derivatives,
            "kkt": o.timings.kkt,
            "kkt_riccati": o.timings.riccati,
            "kkt_factorizations": o.timings.factorizations,
            "second_order_corrections": o.timings.second_order_corrections,
            "line_search": o.timings.line_search
        }
    });
    serde_json::to_string_pretty(&v).expect("JSON of numbers and strings") + "\n"
}

/// The plots: `(file name, SVG)`.
pub fn plots(
    problem: &PlanProblem,
    traj: &Trajectory,
    bounds: &PlanBounds,
) -> Vec<(String, String)> {
    let t = &traj.t;
    let col = |i: usize| traj.x.iter().map(|x| x[i]).collect::<Vec<f64>>();
    let (xs, ys) = (col(0), col(1));
    let ur: Vec<f64> = traj.u.iter().map(|u| u[0]).collect();
    let ul: Vec<f64> = traj.u.iter().map(|u| u[1]).collect();
    let rate = |u: &[f64]| -> Vec<f64> {
        (0..u.len())
            .map(|k| (u[k] - if k == 0 { 0.0 } else { u[k - 1] }) / problem.h)
            .collect()
    };
    let (dur, dul) = (rate(&ur), rate(&ul));
    let (ir, il) = (col(7), col(8));
    let alpha_deg: Vec<f64> = col(3).iter().map(|a| a.to_degrees()).collect();
    let vth_deg: Vec<f64> = col(6).iter().map(|a| a.to_degrees()).collect();
    let two = |title: &'static str,
               ylabel: &'static str,
               a: (&'static str, Vec<f64>),
               b: Option<(&'static str, Vec<f64>)>,
               bound: f64|
     -> String {
        let mut series = vec![Series {
            label: a.0,
            x: t,
            y: &a.1,
            color: "#1f77b4",
        }];
        if let Some(b) = &b {
            series.push(Series {
                label: b.0,
                x: t,
                y: &b.1,
                color: "#ff7f0e",
            });
        }
        Plot {
            title,
            xlabel: "t [s]",
            ylabel,
            series,
            bounds: vec![-bound, bound],
            markers: vec![],
            equal_axes: false,
        }
        .to_svg()
    };
    let path = Plot {
        title: "path (waypoints: circles)",
        xlabel: "x [m]",
        ylabel: "y [m]",
        series: vec![Series {
            label: "planned",
            x: &xs,
            y: &ys,
            color: "#1f77b4",
        }],
        bounds: vec![],
        markers: problem.points.iter().map(|p| (p[0], p[1])).collect(),
        equal_axes: true,
    }
    .to_svg();
    vec![
        ("path.svg".into(), path),
        (
            "voltages.svg".into(),
            two(
                "voltages",
                "u [V]",
                ("uR", ur.clone()),
                Some(("uL", ul.clone())),
                bounds.u_max,
            ),
        ),
        (
            "voltage_rates.svg".into(),
            two(
                "voltage rates",
                "du/dt [V/s]",
                ("uR", dur),
                Some(("uL", dul)),
                bounds.du_max_per_s,
            ),
        ),
        (
            "currents.svg".into(),
            two(
                "currents",
                "i [A]",
                ("iR", ir),
                Some(("iL", il)),
                bounds.i_max,
            ),
        ),
        (
            "tilt.svg".into(),
            two(
                "tilt",
                "alpha [deg]",
                ("alpha", alpha_deg),
                None,
                bounds.alpha_max.to_degrees(),
            ),
        ),
        (
            "heading_rate.svg".into(),
            two(
                "heading rate",
                "v_theta [deg/s]",
                ("v_theta", vth_deg),
                None,
                bounds.v_theta_max.to_degrees(),
            ),
        ),
    ]
}
