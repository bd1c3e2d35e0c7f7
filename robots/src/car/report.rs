//! The car's result files: trajectory.csv, summary.json and the plots (`docs/car.md`).

use super::model::{NS, NU};
use super::plan::{CarBounds, CarOutcome};
use super::problems::CarProblem;
use crate::io::{result_csv, NonFiniteValue};
use crate::plot::{Plot, Series};
use nalgebra::SVector;

/// One row per stage: time, pose, shape, the velocity leaving the stage, the input held
/// from it.
#[derive(Clone, Debug, Default)]
pub struct CarTrajectory {
    pub t: Vec<f64>,
    pub pose: Vec<[f64; 3]>,
    pub shape: Vec<SVector<f64, NS>>,
    pub velocity: Vec<SVector<f64, NS>>,
    pub input: Vec<SVector<f64, NU>>,
}

/// The columns of trajectory.csv.
pub const CSV_HEADER: &str = "t,x,y,theta,phi,psi,q,v_phi,v_psi,i,tau_s,u_d";

impl CarTrajectory {
    /// A plan's trajectory (the last row with the velocity the car arrives with, zero
    /// to the solver's tolerance, and the last input repeated).
    pub fn from_plan(o: &CarOutcome) -> Self {
        let mut t = CarTrajectory::default();
        for (k, stage) in o.trajectory.stages.iter().enumerate() {
            t.t.push(k as f64 * o.h);
            t.pose.push([stage.pose[0], stage.pose[1], stage.pose[2]]);
            t.shape.push(stage.shape);
            t.velocity.push(stage.velocity);
            t.input.push(stage.input);
        }
        t
    }

    /// Row `k` of trajectory.csv, in the columns of [`CSV_HEADER`].
    pub fn row(&self, k: usize) -> Vec<f64> {
        std::iter::once(self.t[k])
            .chain(self.pose[k].iter().copied())
            .chain(self.shape[k].iter().copied())
            .chain(self.velocity[k].iter().copied())
            .chain(self.input[k].iter().copied())
            .collect()
    }

    /// trajectory.csv; an error naming the time and column of a non-finite value.
    pub fn csv(&self) -> Result<String, NonFiniteValue> {
        result_csv(CSV_HEADER, (0..self.t.len()).map(|k| self.row(k)))
    }

    /// The largest distance between a problem pose and the trajectory's pose at its stage.
    pub fn pose_error_max(&self, stages: &[usize], problem: &CarProblem) -> f64 {
        problem
            .poses()
            .iter()
            .zip(stages)
            .map(|(p, &k)| {
                let q = self.pose[k];
                (p[0] - q[0]).hypot(p[1] - q[1]).max((p[2] - q[2]).abs())
            })
            .fold(0.0, f64::max)
    }
}

/// summary.json of `car plan`: the same fields as `wip plan`'s where they apply.
pub fn summary_json(
    problem: &CarProblem,
    integrator: &str,
    o: &CarOutcome,
    pose_error: f64,
) -> String {
    let num = |v: f64| {
        if v.is_finite() {
            serde_json::json!(v)
        } else {
            serde_json::Value::Null
        }
    };
    let summary = serde_json::json!({
        "problem": problem.name,
        "integrator": integrator,
        "h": o.h,
        "N": o.trajectory.stages.len() - 1,
        "status": o.status.code(),
        "iterations": o.iterations,
        "solve_time_s": num(o.solve_time_s),
        "objective": num(o.objective),
        "max_violation": num(o.max_violation),
        "pose_error_max": num(pose_error),
    });
    serde_json::to_string_pretty(&summary).expect("a JSON value serialises") + "\n"
}

/// path.svg, steering.svg, drive.svg.
pub fn plots(problem: &CarProblem, t: &CarTrajectory, b: &CarBounds) -> Vec<(String, String)> {
    let xs: Vec<f64> = t.pose.iter().map(|p| p[0]).collect();
    let ys: Vec<f64> = t.pose.iter().map(|p| p[1]).collect();
    let path = Plot {
        title: "rear-axle path (problem poses: circles)",
        xlabel: "x [m]",
        ylabel: "y [m]",
        series: vec![Series {
            label: "planned",
            x: &xs,
            y: &ys,
            color: "#1f77b4",
        }],
        bounds: vec![],
        markers: problem.poses().iter().map(|p| (p[0], p[1])).collect(),
        equal_axes: true,
    }
    .to_svg();
    let phi: Vec<f64> = t.shape.iter().map(|s| s[0]).collect();
    let steering = Plot {
        title: "steering angle",
        xlabel: "t [s]",
        ylabel: "phi [rad]",
        series: vec![Series {
            label: "phi",
            x: &t.t,
            y: &phi,
            color: "#2ca02c",
        }],
        bounds: vec![-b.steer_angle, b.steer_angle],
        markers: vec![],
        equal_axes: false,
    }
    .to_svg();
    let u: Vec<f64> = t.input.iter().map(|u| u[1]).collect();
    let i: Vec<f64> = t.velocity.iter().map(|v| v[2]).collect();
    let drive = Plot {
        title: "drive voltage and current",
        xlabel: "t [s]",
        ylabel: "u_d [V], i [A]",
        series: vec![
            Series {
                label: "u_d",
                x: &t.t,
                y: &u,
                color: "#d62728",
            },
            Series {
                label: "i",
                x: &t.t,
                y: &i,
                color: "#9467bd",
            },
        ],
        bounds: vec![-b.current, b.current],
        markers: vec![],
        equal_axes: false,
    }
    .to_svg();
    vec![
        ("path.svg".into(), path),
        ("steering.svg".into(), steering),
        ("drive.svg".into(), drive),
    ]
}

/// tracking_path.svg (the plan's and the plant's paths) and tracking_error.svg (the
/// position error over time) of `car track`.
pub fn tracking_plots(t: &super::track::CarTracking) -> Vec<(String, String)> {
    let (px, py): (Vec<f64>, Vec<f64>) = t.planned.iter().map(|p| (p[0], p[1])).unzip();
    let (ax, ay): (Vec<f64>, Vec<f64>) = t.actual.iter().map(|p| (p[0], p[1])).unzip();
    let path = Plot {
        title: "rear-axle path: planned and tracked",
        xlabel: "x [m]",
        ylabel: "y [m]",
        series: vec![
            Series {
                label: "planned",
                x: &px,
                y: &py,
                color: "#1f77b4",
            },
            Series {
                label: "tracked",
                x: &ax,
                y: &ay,
                color: "#d62728",
            },
        ],
        bounds: vec![],
        markers: vec![],
        equal_axes: true,
    }
    .to_svg();
    let e_mm: Vec<f64> = t.position_errors().iter().map(|e| 1e3 * e).collect();
    let error = Plot {
        title: "position error",
        xlabel: "t [s]",
        ylabel: "error [mm]",
        series: vec![Series {
            label: "error",
            x: &t.t,
            y: &e_mm,
            color: "#d62728",
        }],
        bounds: vec![],
        markers: vec![],
        equal_axes: false,
    }
    .to_svg();
    vec![
        ("tracking_path.svg".into(), path),
        ("tracking_error.svg".into(), error),
    ]
}

/// tracking.csv of `car track`: `t,x_plan,y_plan,theta_plan,x,y,theta,position_error,
/// tau_s,u_d` (the last row repeats the last input); an error naming the time and column
/// of a non-finite value.
pub fn tracking_csv(t: &super::track::CarTracking) -> Result<String, NonFiniteValue> {
    let errors = t.position_errors();
    result_csv(
        "t,x_plan,y_plan,theta_plan,x,y,theta,position_error,tau_s,u_d",
        errors.iter().enumerate().map(|(k, &error)| {
            let (p, q) = (t.planned[k], t.actual[k]);
            let u = t
                .input
                .get(k)
                .or(t.input.last())
                .copied()
                .unwrap_or([0.0, 0.0]);
            vec![
                t.t[k], p[0], p[1], p[2], q[0], q[1], q[2], error, u[0], u[1],
            ]
        }),
    )
}
