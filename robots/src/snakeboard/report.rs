//! The snakeboard's result files: trajectory.csv, summary.json and the plots
//! (`docs/snakeboard.md`).

use super::model::{Snakeboard, NA, NU};
use super::plan::{SnakeboardBounds, SnakeboardOutcome};
use super::problems::SnakeboardProblem;
use crate::io::{result_csv, NonFiniteValue};
use crate::plot::{Plot, Series};
use nalgebra::SVector;

/// One row per node: time, pose, the shape `(ψ, φ)`, the extended velocity
/// `(ψ̇, φ̇, p)`, the nonholonomic momentum `J`, the input.
#[derive(Clone, Debug, Default)]
pub struct SnakeboardTrajectory {
    pub t: Vec<f64>,
    pub pose: Vec<[f64; 3]>,
    pub shape: Vec<[f64; 2]>,
    pub velocity: Vec<SVector<f64, NA>>,
    pub input: Vec<SVector<f64, NU>>,
}

/// The columns of trajectory.csv.
pub const CSV_HEADER: &str = "t,x,y,theta,psi,phi,v_psi,v_phi,p,J,tau_psi,tau_phi";

impl SnakeboardTrajectory {
    /// A plan's trajectory. The plan's state leaves the rotor angle out (no equation reads
    /// it); the planned trajectory sums it back from the rotor rate,
    /// `ψ_{k+1} = ψ_k + h ψ̇_k`, from 0.
    pub fn from_plan(o: &SnakeboardOutcome) -> Self {
        let mut t = SnakeboardTrajectory::default();
        for (k, stage) in o.trajectory.stages.iter().enumerate() {
            t.t.push(k as f64 * o.h);
            t.pose.push([stage.pose[0], stage.pose[1], stage.pose[2]]);
            t.shape.push([stage.shape[0], stage.shape[1]]);
            t.velocity.push(stage.velocity);
            t.input.push(stage.input);
        }
        t
    }

    /// Row `k` of trajectory.csv, in the columns of [`CSV_HEADER`] (`J` the momentum).
    pub fn row(&self, board: &Snakeboard, k: usize) -> Vec<f64> {
        let (v, phi) = (&self.velocity[k], self.shape[k][1]);
        std::iter::once(self.t[k])
            .chain(self.pose[k].iter().copied())
            .chain(self.shape[k].iter().copied())
            .chain(v.iter().copied())
            .chain(std::iter::once(board.momentum(phi, v[0], v[2])))
            .chain(self.input[k].iter().copied())
            .collect()
    }

    /// trajectory.csv; an error naming the time and column of a non-finite value.
    pub fn csv(&self, board: &Snakeboard) -> Result<String, NonFiniteValue> {
        result_csv(CSV_HEADER, (0..self.t.len()).map(|k| self.row(board, k)))
    }

    /// The distance of the last pose from `end`: position and heading, the larger.
    pub fn end_error(&self, end: &[f64; 3]) -> f64 {
        let q = self.pose.last().expect("at least the start");
        (end[0] - q[0])
            .hypot(end[1] - q[1])
            .max((end[2] - q[2]).abs())
    }
}

/// summary.json of `snakeboard plan`: the fields of `car plan`'s, and the start.
pub fn summary_json(
    problem: &SnakeboardProblem,
    integrator: &str,
    start: &str,
    o: &SnakeboardOutcome,
    end_error: f64,
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
        "start": start,
        "h": o.h,
        "N": o.trajectory.stages.len() - 1,
        "status": o.status.code(),
        "iterations": o.iterations,
        "solve_time_s": num(o.solve_time_s),
        "objective": num(o.objective),
        "max_violation": num(o.max_violation),
        "end_error": num(end_error),
    });
    serde_json::to_string_pretty(&summary).expect("a JSON value serialises") + "\n"
}

/// path.svg, shape.svg (rotor and axle angles), torques.svg.
pub fn plots(
    problem: &SnakeboardProblem,
    t: &SnakeboardTrajectory,
    b: &SnakeboardBounds,
) -> Vec<(String, String)> {
    let xs: Vec<f64> = t.pose.iter().map(|p| p[0]).collect();
    let ys: Vec<f64> = t.pose.iter().map(|p| p[1]).collect();
    let path = Plot {
        title: "board centre's path (start and end: circles)",
        xlabel: "x [m]",
        ylabel: "y [m]",
        series: vec![Series {
            label: "planned",
            x: &xs,
            y: &ys,
            color: "#1f77b4",
        }],
        bounds: vec![],
        markers: vec![
            (problem.start[0], problem.start[1]),
            (problem.end[0], problem.end[1]),
        ],
        equal_axes: true,
    }
    .to_svg();
    let psi: Vec<f64> = t.shape.iter().map(|s| s[0]).collect();
    let phi: Vec<f64> = t.shape.iter().map(|s| s[1]).collect();
    let shape = Plot {
        title: "rotor and axle angles (the gait)",
        xlabel: "t [s]",
        ylabel: "angle [rad]",
        series: vec![
            Series {
                label: "psi (rotor)",
                x: &t.t,
                y: &psi,
                color: "#2ca02c",
            },
            Series {
                label: "phi (axles)",
                x: &t.t,
                y: &phi,
                color: "#ff7f0e",
            },
        ],
        bounds: vec![-b.axle_angle, b.axle_angle],
        markers: vec![],
        equal_axes: false,
    }
    .to_svg();
    let tau_psi: Vec<f64> = t.input.iter().map(|u| u[0]).collect();
    let tau_phi: Vec<f64> = t.input.iter().map(|u| u[1]).collect();
    let torques = Plot {
        title: "rotor and axle torques",
        xlabel: "t [s]",
        ylabel: "torque [N m]",
        series: vec![
            Series {
                label: "tau_psi",
                x: &t.t,
                y: &tau_psi,
                color: "#d62728",
            },
            Series {
                label: "tau_phi",
                x: &t.t,
                y: &tau_phi,
                color: "#9467bd",
            },
        ],
        bounds: vec![-b.rotor_torque, b.rotor_torque],
        markers: vec![],
        equal_axes: false,
    }
    .to_svg();
    vec![
        ("path.svg".into(), path),
        ("shape.svg".into(), shape),
        ("torques.svg".into(), torques),
    ]
}
