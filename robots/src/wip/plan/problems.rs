//! The planning problems of `docs/problems.md` (`eight`, `zigzag`) and waypoint
//! files: the polyline, the boundary poses and the waypoint stages from the trapezoidal
//! speed profile.

use crate::io::{JsonError, JsonObject};
use std::path::Path;

/// A planning problem: waypoints (positions) at stages, full poses at both ends.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanProblem {
    pub name: String,
    pub h: f64,
    /// Number of steps: stages `0..=n`.
    pub n: usize,
    /// Polyline points `(x, y)`, first = start, last = end.
    pub points: Vec<[f64; 2]>,
    /// The stage at which each point is reached.
    pub stages: Vec<usize>,
    pub start_heading: f64,
    pub end_heading: f64,
}

impl PlanProblem {
    /// The same waypoints and timing at step `h`: the duration and the waypoints' times kept
    /// (to the nearest stage of the new mesh). `None` when two waypoints would share a stage
    /// or the mesh would have fewer than two steps.
    pub fn at_step(&self, h: f64) -> Option<PlanProblem> {
        let scale = self.h / h;
        let n = (self.n as f64 * scale).round() as usize;
        let stages: Vec<usize> = self
            .stages
            .iter()
            .map(|&k| ((k as f64 * scale).round() as usize).min(n))
            .collect();
        if n < 2 || stages.windows(2).any(|w| w[0] >= w[1]) {
            return None;
        }
        Some(PlanProblem {
            h,
            n,
            stages,
            ..self.clone()
        })
    }
}

/// Cumulative arc length of a polyline.
pub fn arc_lengths(points: &[[f64; 2]]) -> Vec<f64> {
    let mut s = vec![0.0];
    for w in points.windows(2) {
        let d = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
        s.push(s.last().unwrap() + d);
    }
    s
}

/// Times at which a trapezoidal speed profile (accelerate from rest at `a`, cruise at
/// `v_c`, brake at `a` to rest at `T`) passes the arc lengths `s_j`. `v_c` is the smaller
/// root of `T = S/v_c + v_c/a`; `None` if there is none (`T² < 4S/a`: too short a time).
pub fn trapezoid_times(s: &[f64], total_time: f64, a: f64) -> Option<Vec<f64>> {
    let total = *s.last()?;
    let disc = total_time * total_time - 4.0 * total / a;
    if disc < 0.0 || a <= 0.0 || total_time <= 0.0 {
        return None;
    }
    // The smaller root `a (T − √D)/2` in the form without cancellation: at a large `a` the
    // difference of `T` and `√D` loses every digit (and gave `v_c = 0`, waypoints at
    // infinite times).
    let vc = 2.0 * total / (total_time + disc.sqrt());
    let t1 = vc / a;
    let s1 = 0.5 * a * t1 * t1;
    let s2 = total - s1;
    Some(
        s.iter()
            .map(|&sj| {
                if sj <= s1 {
                    (2.0 * sj / a).sqrt()
                } else if sj <= s2 {
                    t1 + (sj - s1) / vc
                } else {
                    // Braking: s(t) = S − ½ a (T − t)².
                    total_time - (2.0 * (total - sj).max(0.0) / a).sqrt()
                }
            })
            .collect(),
    )
}

fn from_timing(
    name: &str,
    points: Vec<[f64; 2]>,
    total_time: f64,
    a: f64,
    h: f64,
    start_heading: f64,
    end_heading: f64,
) -> Result<PlanProblem, WaypointError> {
    let s = arc_lengths(&points);
    let no_profile = || WaypointError::NoProfile {
        name: name.to_string(),
        length: *s.last().unwrap_or(&0.0),
        duration: total_time,
        accel: a,
    };
    let times = trapezoid_times(&s, total_time, a).ok_or_else(no_profile)?;
    let n = (total_time / h).round() as usize;
    // Every waypoint at a stage of the horizon: a time that is not finite or lies outside
    // [0, T] (a profile the arithmetic cannot represent) would name a stage past the end.
    if times
        .iter()
        .any(|t| !t.is_finite() || *t < -1e-9 * total_time || *t > total_time * (1.0 + 1e-9))
    {
        return Err(no_profile());
    }
    let stages: Vec<usize> = times
        .iter()
        .map(|t| ((t / h).round() as usize).min(n))
        .collect();
    Ok(PlanProblem {
        name: name.to_string(),
        h,
        n,
        points,
        stages,
        start_heading,
        end_heading,
    })
}

/// The figure eight: eight segments of √2 m, T = 21.175 s, a = 0.2 m/s².
pub fn eight(h: f64) -> PlanProblem {
    let points = vec![
        [1.0, 0.5],
        [2.0, 1.5],
        [3.0, 2.5],
        [4.0, 1.5],
        [3.0, 0.5],
        [2.0, 1.5],
        [1.0, 2.5],
        [0.0, 1.5],
        [1.0, 0.5],
    ];
    let q = std::f64::consts::FRAC_PI_4;
    from_timing("eight", points, 21.175, 0.2, h, q, -q).expect("the benchmark is feasible")
}

/// The zig-zag: 18 segments of 0.35 m with 0.1 m lateral steps, T = 19.36 s, a = 0.1 m/s².
pub fn zigzag(h: f64) -> PlanProblem {
    let points = (0..19)
        .map(|j| [4.0 - 0.33541 * j as f64, 1.5 + 0.1 * (j % 2) as f64])
        .collect();
    let pi = std::f64::consts::PI;
    from_timing("zigzag", points, 19.36, 0.1, h, pi, pi).expect("the benchmark is feasible")
}

/// A benchmark of docs/problems.md by name (`eight`, `zigzag`) at step `h`.
pub fn by_name(name: &str, h: f64) -> Option<PlanProblem> {
    match name {
        "eight" => Some(eight(h)),
        "zigzag" => Some(zigzag(h)),
        _ => None,
    }
}

/// Why a waypoint file was refused; the message names the key or the point.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WaypointError {
    /// Not a JSON object of the format's keys, or a value of the wrong type.
    #[error("{0} (docs/formats.md, \"Waypoint file\")")]
    Json(#[from] JsonError),
    #[error("'points' needs at least 2 points, got {count}")]
    TooFewPoints { count: usize },
    #[error("points[{index}] repeats points[{previous}]")]
    Repeated { index: usize, previous: usize },
    #[error("'{key}' must be positive, got {value}")]
    NotPositive { key: &'static str, value: f64 },
    #[error(
        "{name}: no trapezoidal profile covers {length:.3} m in {duration} s at {accel} m/s² \
         (needs T² ≥ 4S/a)"
    )]
    NoProfile {
        name: String,
        length: f64,
        duration: f64,
        accel: f64,
    },
    #[error(
        "points[{first}] and points[{second}] fall on the same stage at h = {h}: use a smaller h"
    )]
    SameStage { first: usize, second: usize, h: f64 },
}

/// A waypoint file as written (docs/formats.md); its keys are checked by [`JsonObject`].
#[derive(serde::Deserialize)]
struct WaypointFile {
    name: Option<String>,
    points: Vec<[f64; 2]>,
    duration: f64,
    accel: Option<f64>,
    start_heading: f64,
    end_heading: f64,
}

/// The keys of a waypoint file.
const WAYPOINT_KEYS: [&str; 6] = [
    "name",
    "points",
    "duration",
    "accel",
    "start_heading",
    "end_heading",
];

/// Read a waypoint file (JSON, documented in `docs/formats.md`):
/// ```json
/// { "name": "square", "points": [[0,0],[1,0],[1,1]], "duration": 12.0, "accel": 0.2,
///   "start_heading": 0.0, "end_heading": 1.5708 }
/// ```
/// `name` and `accel` (default 0.2 m/s²) are optional; an unknown key, a `null` and a value
/// of the wrong type are errors naming the key. Every problem is named in the error.
pub fn from_json_str(text: &str, h: f64) -> Result<PlanProblem, WaypointError> {
    let file: WaypointFile = JsonObject::parse(text, &WAYPOINT_KEYS)?.typed()?;
    let name = file.name.unwrap_or_else(|| "waypoints".to_string());
    let points = file.points;
    let (duration, accel) = (file.duration, file.accel.unwrap_or(0.2));
    let (start_heading, end_heading) = (file.start_heading, file.end_heading);
    if points.len() < 2 {
        return Err(WaypointError::TooFewPoints {
            count: points.len(),
        });
    }
    let s = arc_lengths(&points);
    if let Some(i) = s.windows(2).position(|w| w[1] - w[0] < 1e-9) {
        return Err(WaypointError::Repeated {
            index: i + 1,
            previous: i,
        });
    }
    for (key, value) in [("duration", duration), ("accel", accel)] {
        if value <= 0.0 {
            return Err(WaypointError::NotPositive { key, value });
        }
    }
    let problem = from_timing(
        &name,
        points,
        duration,
        accel,
        h,
        start_heading,
        end_heading,
    )?;
    if let Some(w) = problem.stages.windows(2).position(|w| w[1] <= w[0]) {
        return Err(WaypointError::SameStage {
            first: w,
            second: w + 1,
            h,
        });
    }
    Ok(problem)
}

/// [`from_json_str`] for a file, with its path in the message.
pub fn from_file(path: &Path, h: f64) -> Result<PlanProblem, crate::io::ReadError> {
    let what = format!("waypoint file {}", path.display());
    let text = crate::io::read_text_limited(path, &what, crate::io::MAX_JSON_BYTES, "")?;
    from_json_str(&text, h).map_err(|e| crate::io::ReadError::Content(format!("{what}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_matches_the_spec() {
        let p = eight(0.005);
        assert_eq!(p.n, 4235);
        assert_eq!(
            p.stages,
            vec![0, 765, 1216, 1667, 2117, 2568, 3019, 3470, 4235]
        );
        let s = arc_lengths(&p.points);
        assert!((s.last().unwrap() - 8.0 * 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn zigzag_matches_the_spec() {
        let p = zigzag(0.005);
        assert_eq!(p.n, 3872);
        assert_eq!(
            p.stages,
            vec![
                0, 529, 748, 921, 1090, 1260, 1429, 1598, 1767, 1936, 2105, 2274, 2443, 2612, 2782,
                2951, 3124, 3343, 3872
            ]
        );
    }

    #[test]
    fn scale_series_sizes() {
        let ns: Vec<usize> = [0.02, 0.01, 0.005, 0.0025, 0.00125]
            .iter()
            .map(|&h| eight(h).n)
            .collect();
        assert_eq!(ns, vec![1059, 2118, 4235, 8470, 16940]);
    }

    /// The eight at 5 ms taken to 10 ms is the 10 ms benchmark: the same number of steps, and
    /// every waypoint within one stage (the timing rule rounds the exact times once, at_step
    /// rounds the 5 ms stages again). Waypoints that would share a stage give `None`.
    #[test]
    fn at_step_is_the_same_problem_on_another_mesh() {
        let (fine, coarse) = (eight(0.005), eight(0.01));
        let moved = fine.at_step(0.01).expect("the eight has room at 10 ms");
        assert_eq!(moved.n, coarse.n);
        assert_eq!(moved.h, 0.01);
        assert_eq!(moved.points, coarse.points);
        for (a, b) in moved.stages.iter().zip(&coarse.stages) {
            assert!(a.abs_diff(*b) <= 1, "stage {a} against {b}");
        }
        let mut close = fine.clone();
        close.stages[1] = close.stages[0] + 1;
        assert!(close.at_step(0.02).is_none());
    }

    #[test]
    fn cruise_speed_is_the_smaller_root() {
        // T = S/v + v/a at v_c = 0.62718 for the eight (docs/problems.md).
        let s = arc_lengths(&eight(0.005).points);
        let t = trapezoid_times(&s, 21.175, 0.2).unwrap();
        let seg = (t[2] - t[1], s[2] - s[1]); // a cruise segment
        assert!((seg.1 / seg.0 - 0.62718).abs() < 1e-5);
    }

    #[test]
    fn malformed_waypoint_files_are_named() {
        let bad = [
            ("[1,2]", "expected a JSON object"),
            (
                r#"{"points": [[0,0],[1,0]], "duration": 5, "start_heading": 0}"#,
                "missing key 'end_heading'",
            ),
            (
                r#"{"points": [[0,0]], "duration": 5, "start_heading": 0, "end_heading": 0}"#,
                "at least 2 points",
            ),
            (
                r#"{"points": [[0,0],[1,"a"]], "duration": 5, "start_heading": 0, "end_heading": 0}"#,
                "'points': invalid type: string \"a\", expected f64 at line 1 column 24",
            ),
            (
                r#"{"points": [[0,0],[0,0]], "duration": 5, "start_heading": 0, "end_heading": 0}"#,
                "repeats",
            ),
            (
                r#"{"points": [[0,0],[10,0]], "duration": 1, "start_heading": 0, "end_heading": 0}"#,
                "no trapezoidal profile",
            ),
            (
                r#"{"points": [[0,0],[1,0]], "duration": 5, "start_heading": 0, "end_heading": 0, "speed": 1}"#,
                "unknown key 'speed'",
            ),
            ("{", "EOF while parsing an object at line 1 column 1"),
            (
                r#"{"points": [[0,0],[1,0]], "duration": 5, "accel": null, "start_heading": 0, "end_heading": 0}"#,
                "'accel' must be a value, got null",
            ),
        ];
        for (text, msg) in bad {
            let e = from_json_str(text, 0.005).unwrap_err().to_string();
            assert!(e.contains(msg), "'{e}' should contain '{msg}'");
        }
        let ok = from_json_str(
            r#"{"points": [[0,0],[1,0],[1,1]], "duration": 12, "start_heading": 0, "end_heading": 1.5708}"#,
            0.005,
        )
        .unwrap();
        assert_eq!(ok.n, 2400);
        assert_eq!(ok.stages.len(), 3);
    }

    /// A huge acceleration is a constant speed with instant starts and stops: the
    /// waypoints' times are those of the cruise, all within the horizon (the cancelling form
    /// of the root put them at infinite times, past the last stage).
    #[test]
    fn a_huge_acceleration_keeps_the_waypoints_in_the_horizon() {
        for accel in [1e15, 1e20, 1e300] {
            let p = from_json_str(
                &format!(
                    r#"{{"points": [[0,0],[0.25,0],[0.5,0]], "duration": 5, "accel": {accel}, "start_heading": 0, "end_heading": 0}}"#
                ),
                0.02,
            )
            .unwrap();
            assert_eq!(p.stages, vec![0, 125, 250], "accel {accel}");
        }
    }
}
