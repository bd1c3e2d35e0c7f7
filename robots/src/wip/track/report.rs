//! Reading the plan to track (a `trajectory.csv`), and the closed loop's result files:
//! `tracking.csv`, `tracking.json` and the plots.

use super::closed_loop::{TrackFigures, TrackRun};
use crate::io::{parse_csv_with, read_text_limited, CsvError, CsvOptions, ReadError};
use crate::plot::{Plot, Series};
use crate::wip::simulate::Trajectory;
use crate::wip::ReducedState;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The paper's hardware figures on the eight (position max / RMS in m, heading max / RMS
/// in rad), printed beside ours.
pub const PAPER_FIGURES: [f64; 4] = [0.024, 0.0083, 0.2112, 0.0559];

/// `DIR/trajectory.csv` or the file itself.
pub fn plan_path(arg: &Path) -> PathBuf {
    if arg.is_dir() {
        arg.join("trajectory.csv")
    } else {
        arg.to_path_buf()
    }
}

/// The bytes a row of a `trajectory.csv` is allowed (twelve numbers of `wip plan`'s
/// format take about 290), for the size limit of [`read_plan`].
pub const PLAN_ROW_BYTES: u64 = 512;

/// A step of the plan's grid longer than this many times its median step is a hole (rows
/// missing), not a plan: `wip plan --free-timing` varies its steps within [0.5, 2] of the
/// nominal one, a ratio of 4 at most.
pub const HOLE_RATIO: f64 = 5.0;

/// Why a plan to track was refused; the message names the file and the line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error(transparent)]
    Csv(#[from] CsvError),
    #[error("{what}: no column '{name}' (a trajectory.csv of wip plan)")]
    MissingColumn { what: String, name: String },
    #[error("{what}: line {line}: t = {t} does not continue a time grid starting at 0")]
    NotOnGrid { what: String, line: usize, t: f64 },
    #[error("{what}: a plan needs at least two rows")]
    TooFewRows { what: String },
    /// A step far longer than the plan's typical one: rows are missing.
    #[error(
        "{what}: line {line}: t jumps from {from} to {to} s, a step of {step:.4} s against the \
         plan's typical {typical:.4} s: rows are missing (a plan to track has no holes)"
    )]
    Hole {
        what: String,
        line: usize,
        from: f64,
        to: f64,
        step: f64,
        typical: f64,
    },
}

/// Read a `trajectory.csv` of at most `max_rows` rows (a larger file is refused from its
/// size before it is read; `hint` says how to raise the limit): see [`parse_plan`].
pub fn read_plan(path: &Path, max_rows: usize, hint: &str) -> Result<Trajectory, ReadError> {
    let what = path.display().to_string();
    let limit = crate::io::csv_byte_limit(max_rows, PLAN_ROW_BYTES);
    let text = read_text_limited(path, &format!("plan {what}"), limit, hint)?;
    Ok(parse_plan(&text, &what, max_rows, hint)?)
}

/// A `trajectory.csv`'s text as a plan: columns by name; at least two rows, strictly
/// increasing `t` from 0, and no hole (a step more than [`HOLE_RATIO`] times the median).
pub fn parse_plan(
    text: &str,
    what: &str,
    max_rows: usize,
    hint: &str,
) -> Result<Trajectory, PlanError> {
    const COLS: [&str; 12] = [
        "t", "x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL", "uR", "uL",
    ];
    let csv = parse_csv_with(text, what, CsvOptions::rows(max_rows, hint))?;
    let mut idx = [0usize; 12];
    for (i, c) in COLS.iter().enumerate() {
        idx[i] = csv.column(c).ok_or_else(|| PlanError::MissingColumn {
            what: what.to_string(),
            name: c.to_string(),
        })?;
    }
    let mut traj = Trajectory::default();
    for (row, &line) in csv.rows.iter().zip(&csv.lines) {
        let t = row[idx[0]];
        if traj.t.last().is_some_and(|&tp| t <= tp) || (traj.t.is_empty() && t.abs() > 1e-12) {
            return Err(PlanError::NotOnGrid {
                what: what.to_string(),
                line,
                t,
            });
        }
        traj.t.push(t);
        traj.x.push(ReducedState::from_fn(|i, _| row[idx[1 + i]]));
        traj.u.push([row[idx[10]], row[idx[11]]]);
    }
    if traj.t.len() < 2 {
        return Err(PlanError::TooFewRows {
            what: what.to_string(),
        });
    }
    let mut steps: Vec<f64> = traj.t.windows(2).map(|w| w[1] - w[0]).collect();
    let gaps = steps.clone();
    let mid = steps.len() / 2;
    let typical = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
    if let Some(k) = gaps.iter().position(|&s| s > HOLE_RATIO * typical) {
        return Err(PlanError::Hole {
            what: what.to_string(),
            line: csv.lines[k + 1],
            from: traj.t[k],
            to: traj.t[k + 1],
            step: gaps[k],
            typical,
        });
    }
    Ok(traj)
}

/// `tracking.csv`: per controller sample the true pose and tilt, the plan's pose, the
/// estimated pose, and the feedforward, feedback and applied voltages.
pub fn tracking_csv(run: &TrackRun) -> String {
    let mut s = String::from(
        "t,x,y,theta,alpha,x_ref,y_ref,theta_ref,alpha_ref,x_est,y_est,theta_est,\
         uR_ff,uL_ff,uR_fb,uL_fb,uR,uL\n",
    );
    for p in &run.samples {
        let row = tracking_row(p);
        let vals = &row[1..];
        let _ = write!(s, "{}", p.t);
        for v in vals {
            let _ = write!(s, ",{v:.9e}");
        }
        s.push('\n');
    }
    s
}

/// One row of `tracking.csv`: `t`, the true pose and tilt, the plan's, the estimated pose,
/// the feedforward, feedback and applied voltages.
pub fn tracking_row(p: &super::closed_loop::Sample) -> [f64; 18] {
    [
        p.t,
        p.x[0],
        p.x[1],
        p.x[2],
        p.x[3],
        p.reference[0],
        p.reference[1],
        p.reference[2],
        p.reference[3],
        p.estimate[0],
        p.estimate[1],
        p.estimate[2],
        p.u_ff[0],
        p.u_ff[1],
        p.u_fb[0],
        p.u_fb[1],
        p.u[0],
        p.u[1],
    ]
}

/// `tracking.json`: the figures of the run, the run's identity, and the paper's figures.
pub fn tracking_json(
    f: &TrackFigures,
    seed: u64,
    ideal: bool,
    controller: &str,
    fell_at: Option<f64>,
    duration: f64,
    plant_substeps: usize,
) -> String {
    let mut v = serde_json::to_value(f).expect("plain numbers");
    let o = v.as_object_mut().expect("an object");
    o.insert("seed".into(), seed.into());
    o.insert("ideal".into(), ideal.into());
    o.insert("controller".into(), controller.into());
    o.insert("duration_s".into(), duration.into());
    o.insert(
        "fell_at_s".into(),
        fell_at.map_or(serde_json::Value::Null, Into::into),
    );
    o.insert("plant_substeps".into(), plant_substeps.into());
    o.insert(
        "paper_hardware".into(),
        serde_json::json!({
            "position_error_max_m": PAPER_FIGURES[0],
            "position_error_rms_m": PAPER_FIGURES[1],
            "heading_error_max_rad": PAPER_FIGURES[2],
            "heading_error_rms_rad": PAPER_FIGURES[3],
        }),
    );
    serde_json::to_string_pretty(&v).expect("serialisable") + "\n"
}

/// The plots: planned vs actual path, x/y/θ errors, tilt, feedback voltage.
pub fn plots(run: &TrackRun) -> Vec<(String, String)> {
    let s = &run.samples;
    let t: Vec<f64> = s.iter().map(|p| p.t).collect();
    let col =
        |f: &dyn Fn(&super::closed_loop::Sample) -> f64| s.iter().map(f).collect::<Vec<f64>>();
    let (xs, ys) = (col(&|p| p.x[0]), col(&|p| p.x[1]));
    let (xr, yr) = (col(&|p| p.reference[0]), col(&|p| p.reference[1]));
    let ex = col(&|p| 1e3 * (p.x[0] - p.reference[0]));
    let ey = col(&|p| 1e3 * (p.x[1] - p.reference[1]));
    let eth = col(&|p| p.errors().1.to_degrees());
    let alpha = col(&|p| p.x[3].to_degrees());
    let alpha_r = col(&|p| p.reference[3].to_degrees());
    let (fr, fl) = (col(&|p| p.u_fb[0]), col(&|p| p.u_fb[1]));
    let series =
        |label: &'static str, y: &[f64], color: &'static str| -> (String, Vec<f64>, &'static str) {
            (label.to_string(), y.to_vec(), color)
        };
    let time_plot = |title: &str, ylabel: &str, curves: Vec<(String, Vec<f64>, &'static str)>| {
        Plot {
            title,
            xlabel: "t [s]",
            ylabel,
            series: curves
                .iter()
                .map(|(l, y, c)| Series {
                    label: l,
                    x: &t,
                    y,
                    color: c,
                })
                .collect(),
            bounds: vec![],
            markers: vec![],
            equal_axes: false,
        }
        .to_svg()
    };
    let path = Plot {
        title: "path: planned and actual",
        xlabel: "x [m]",
        ylabel: "y [m]",
        series: vec![
            Series {
                label: "planned",
                x: &xr,
                y: &yr,
                color: "#1f77b4",
            },
            Series {
                label: "actual",
                x: &xs,
                y: &ys,
                color: "#ff7f0e",
            },
        ],
        bounds: vec![],
        markers: vec![],
        equal_axes: true,
    }
    .to_svg();
    vec![
        ("tracking_path.svg".into(), path),
        (
            "tracking_errors.svg".into(),
            time_plot(
                "tracking errors (x, y in mm; theta in deg)",
                "error",
                vec![
                    series("x [mm]", &ex, "#1f77b4"),
                    series("y [mm]", &ey, "#ff7f0e"),
                    series("theta [deg]", &eth, "#2ca02c"),
                ],
            ),
        ),
        (
            "tracking_tilt.svg".into(),
            time_plot(
                "tilt",
                "alpha [deg]",
                vec![
                    series("actual", &alpha, "#ff7f0e"),
                    series("planned", &alpha_r, "#1f77b4"),
                ],
            ),
        ),
        (
            "tracking_feedback.svg".into(),
            time_plot(
                "feedback voltage",
                "u_fb [V]",
                vec![series("uR", &fr, "#1f77b4"), series("uL", &fl, "#ff7f0e")],
            ),
        ),
    ]
}
