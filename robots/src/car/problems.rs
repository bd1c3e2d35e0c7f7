//! The car's planning problems: the built-in `parallel-park` and `lane-change`, and pose
//! files (`docs/car.md`).

use crate::io::{JsonError, JsonObject};
use serde::Deserialize;

/// A pose `(x, y, θ)` of the rear-axle midpoint (m, m, rad).
pub use crate::pose_path::Pose;

/// Rest-to-rest from `start` through `waypoints` to `end` in `duration` seconds.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CarProblem {
    pub name: String,
    pub start: Pose,
    /// Intermediate poses, reached at times proportional to the path length.
    #[serde(default)]
    pub waypoints: Vec<Pose>,
    pub end: Pose,
    pub duration: f64,
    /// Drive backwards along the start path (the direction of motion, not the heading,
    /// follows the path's tangent).
    #[serde(default)]
    pub reverse: bool,
}

/// The most stages a car plan takes (about 2 kB each while solving).
pub const MAX_STAGES: f64 = 200_000.0;

/// A plan of more than [`MAX_STAGES`] stages.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{duration} s at {step} s is {stages:.0} stages, more than 200000: use a larger --step")]
pub struct TooManyStages {
    pub duration: f64,
    pub step: f64,
    pub stages: f64,
}

/// The car's width (m): the sideways offset of `parallel-park`.
pub const CAR_WIDTH: f64 = 0.2;

impl CarProblem {
    /// Reversing into a parking space one car width to the side and 0.8 m behind, in 6 s.
    pub fn parallel_park() -> Self {
        CarProblem {
            name: "parallel-park".into(),
            start: [0.0, 0.0, 0.0],
            waypoints: vec![],
            end: [-0.8, -CAR_WIDTH, 0.0],
            duration: 6.0,
            reverse: true,
        }
    }
    /// Forward from rest to rest 3 m ahead and one lane (0.35 m) to the left, in 5 s.
    pub fn lane_change() -> Self {
        CarProblem {
            name: "lane-change".into(),
            start: [0.0, 0.0, 0.0],
            waypoints: vec![],
            end: [3.0, 0.35, 0.0],
            duration: 5.0,
            reverse: false,
        }
    }
    /// A built-in problem by name.
    pub fn builtin(name: &str) -> Option<Self> {
        match name {
            "parallel-park" => Some(Self::parallel_park()),
            "lane-change" => Some(Self::lane_change()),
            _ => None,
        }
    }
    /// `Err` if a plan at `step` would have more than [`MAX_STAGES`] stages.
    pub fn check_stages(&self, step: f64) -> Result<(), TooManyStages> {
        let stages = self.duration / step;
        if stages > MAX_STAGES {
            return Err(TooManyStages {
                duration: self.duration,
                step,
                stages,
            });
        }
        Ok(())
    }

    /// All poses in order, each heading taken modulo 2π to within π of the one before
    /// (the start's as given): the car turns the short way between two poses, 3.0 → −3.0
    /// being a turn of 0.28 rad, not of 6 rad.
    pub fn poses(&self) -> Vec<Pose> {
        let mut p = vec![self.start];
        for q in self.waypoints.iter().chain(std::iter::once(&self.end)) {
            let before = p.last().expect("the start")[2];
            let d = q[2] - before;
            let turn = d - std::f64::consts::TAU * (d / std::f64::consts::TAU).round();
            p.push([q[0], q[1], before + turn]);
        }
        p
    }

    /// Read a pose file's text (docs/car.md): an object with `name`, `start`, `end`,
    /// `duration` and the optional `waypoints` and `reverse`. Anything but an object, an
    /// unknown key, a `null`, a value of the wrong type, a duration that is not positive are
    /// errors naming the key.
    pub fn from_json_str(text: &str) -> Result<Self, JsonError> {
        let p: CarProblem = JsonObject::parse(
            text,
            &["name", "start", "waypoints", "end", "duration", "reverse"],
        )?
        .typed()?;
        if p.duration <= 0.0 {
            return Err(JsonError::WrongType {
                key: "duration".into(),
                expected: "a positive number of seconds".into(),
                found: p.duration.to_string(),
            });
        }
        Ok(p)
    }

    /// A built-in problem by name, or else a pose file (of at most
    /// [`crate::io::MAX_JSON_BYTES`]).
    pub fn load(arg: &str) -> Result<Self, crate::io::ReadError> {
        if let Some(p) = Self::builtin(arg) {
            return Ok(p);
        }
        let path = std::path::Path::new(arg);
        let what = format!("pose file {}", path.display());
        let text = crate::io::read_text_limited(
            path,
            &what,
            crate::io::MAX_JSON_BYTES,
            " (built-in problems: parallel-park, lane-change)",
        )
        .map_err(|e| match e {
            crate::io::ReadError::Io { what, source } => crate::io::ReadError::Io {
                what: format!("{what} (built-in problems: parallel-park, lane-change)"),
                source,
            },
            other => other,
        })?;
        Self::from_json_str(&text).map_err(|source| crate::io::ReadError::Json { what, source })
    }
}
