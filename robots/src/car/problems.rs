//! The car's planning problems: the built-in `parallel-park` and `lane-change`, and pose
//! files (`docs/car.md`).

use serde::Deserialize;

/// A pose `(x, y, θ)` of the rear-axle midpoint (m, m, rad).
pub type Pose = [f64; 3];

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
    /// All poses in order.
    pub fn poses(&self) -> Vec<Pose> {
        let mut p = vec![self.start];
        p.extend(self.waypoints.iter().copied());
        p.push(self.end);
        p
    }
}
