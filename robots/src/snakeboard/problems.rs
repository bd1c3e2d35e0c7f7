//! The snakeboard's planning problems: the built-in `forward`, `sideways` and `turn`, and
//! pose files of the car's format (`docs/snakeboard.md`).

use crate::io::{JsonError, JsonObject};
use crate::pose_path::Pose;
use serde::Deserialize;

/// Rest to rest from `start` to `end` in `duration` seconds.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnakeboardProblem {
    pub name: String,
    pub start: Pose,
    pub end: Pose,
    pub duration: f64,
}

/// The built-in problems' names.
pub const BUILTIN: [&str; 3] = ["forward", "sideways", "turn"];

impl SnakeboardProblem {
    /// From rest to rest 1 m ahead, the heading unchanged, in 8 s.
    pub fn forward() -> Self {
        SnakeboardProblem {
            name: "forward".into(),
            start: [0.0, 0.0, 0.0],
            end: [1.0, 0.0, 0.0],
            duration: 8.0,
        }
    }
    /// From rest to rest 0.3 m to the left, the heading unchanged, in 10 s: the board
    /// cannot slip sideways, so it must weave.
    pub fn sideways() -> Self {
        SnakeboardProblem {
            name: "sideways".into(),
            start: [0.0, 0.0, 0.0],
            end: [0.0, 0.3, 0.0],
            duration: 10.0,
        }
    }
    /// From rest to rest a quarter turn to the left, 0.6 m ahead and 0.6 m to the left, in
    /// 8 s.
    pub fn turn() -> Self {
        SnakeboardProblem {
            name: "turn".into(),
            start: [0.0, 0.0, 0.0],
            end: [0.6, 0.6, std::f64::consts::FRAC_PI_2],
            duration: 8.0,
        }
    }
    /// A built-in problem by name.
    pub fn builtin(name: &str) -> Option<Self> {
        match name {
            "forward" => Some(Self::forward()),
            "sideways" => Some(Self::sideways()),
            "turn" => Some(Self::turn()),
            _ => None,
        }
    }

    /// Read a pose file's text: an object with `name`, `start`, `end` and `duration`.
    /// Anything but an object, an unknown key, a `null`, a value of the wrong type, a
    /// duration that is not positive are errors naming the key.
    pub fn from_json_str(text: &str) -> Result<Self, JsonError> {
        let p: SnakeboardProblem =
            JsonObject::parse(text, &["name", "start", "end", "duration"])?.typed()?;
        if !(p.duration > 0.0 && p.duration.is_finite()) {
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
        let hint = " (built-in problems: forward, sideways, turn)";
        let text = crate::io::read_text_limited(path, &what, crate::io::MAX_JSON_BYTES, hint)
            .map_err(|e| match e {
                crate::io::ReadError::Io { what, source } => crate::io::ReadError::Io {
                    what: format!("{what}{hint}"),
                    source,
                },
                other => other,
            })?;
        Self::from_json_str(&text).map_err(|source| crate::io::ReadError::Json { what, source })
    }
}
