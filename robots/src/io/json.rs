//! The JSON reader of the parameter, waypoint and pose files: keys checked, types refused
//! by key.

use super::*;

/// Why a JSON input was refused. Every variant but `Syntax` names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JsonError {
    /// Not JSON (serde's message, with the line and column).
    #[error("not valid JSON: {0}")]
    Syntax(String),
    /// The file is JSON, but not an object.
    #[error("expected a JSON object {{ \"key\": value, … }}, got {found}")]
    NotAnObject { found: &'static str },
    /// A key the format does not have.
    #[error("unknown key '{key}' (expected {known})")]
    UnknownKey { key: String, known: String },
    /// A required key is absent.
    #[error("missing key '{key}'")]
    MissingKey { key: String },
    /// A value the format's type does not take (serde's reason, and where in the file).
    #[error("'{key}': {reason} at {at}")]
    Invalid {
        key: String,
        reason: String,
        at: String,
    },
    /// A value of the wrong type, or `null` (never read as "the default"); `key` is the
    /// path to it (`points[1][0]`).
    #[error("'{key}' must be {expected}, got {found}")]
    WrongType {
        key: String,
        expected: String,
        found: String,
    },
}

/// The JSON type of a value, for messages.
fn json_type(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// The first `null` inside `v`, as a key path below `path`.
fn find_null(v: &serde_json::Value, path: &str) -> Option<String> {
    match v {
        serde_json::Value::Null => Some(path.to_string()),
        serde_json::Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| find_null(x, &format!("{path}[{i}]"))),
        serde_json::Value::Object(m) => m
            .iter()
            .find_map(|(k, x)| find_null(x, &format!("{path}.{k}"))),
        _ => None,
    }
}

/// The top-level key of the JSON object `text` whose value holds byte offset `pos` (for
/// an error serde locates there).
fn key_at(text: &str, pos: usize) -> Option<String> {
    let (mut depth, mut in_string, mut escaped) = (0usize, false, false);
    let (mut start, mut last_string, mut key) = (0usize, None::<(usize, usize)>, None);
    for (i, c) in text.char_indices() {
        if i >= pos {
            break;
        }
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => {
                    in_string = false;
                    last_string = Some((start, i));
                }
                _ => {}
            }
            continue;
        }
        match c {
            '"' => {
                in_string = true;
                start = i + 1;
            }
            '{' | '[' => depth += 1,
            '}' | ']' => depth = depth.saturating_sub(1),
            ':' if depth == 1 => key = last_string.map(|(a, b)| text[a..b].to_string()),
            _ => {}
        }
    }
    key
}

/// A JSON object read from a file: its keys checked against the format's, and typed
/// access to each that names the key in every error.
#[derive(Debug)]
pub struct JsonObject {
    map: serde_json::Map<String, serde_json::Value>,
    text: String,
}

impl JsonObject {
    /// Parse `text` (a byte-order mark allowed) as an object whose keys are among `known`,
    /// with no `null` anywhere in it.
    pub fn parse(text: &str, known: &[&str]) -> Result<Self, JsonError> {
        let v: serde_json::Value = serde_json::from_str(text.trim_start_matches('\u{feff}'))
            .map_err(|e| JsonError::Syntax(e.to_string()))?;
        let serde_json::Value::Object(map) = v else {
            return Err(JsonError::NotAnObject {
                found: json_type(&v),
            });
        };
        if let Some(key) = map.keys().find(|k| !known.contains(&k.as_str())) {
            return Err(JsonError::UnknownKey {
                key: key.clone(),
                known: known.join(", "),
            });
        }
        for (k, v) in &map {
            if let Some(path) = find_null(v, k) {
                return Err(JsonError::WrongType {
                    key: path,
                    expected: "a value".into(),
                    found: "null (leave the key out for its default)".into(),
                });
            }
        }
        Ok(JsonObject {
            map,
            text: text.trim_start_matches('\u{feff}').to_string(),
        })
    }

    /// The whole object as a `T` (a struct of the format's fields), read from the text so
    /// that an error says where: a value of the wrong type names its key, the line and the
    /// column; a missing field is [`JsonError::MissingKey`].
    pub fn typed<T: DeserializeOwned>(&self) -> Result<T, JsonError> {
        serde_json::from_str(&self.text).map_err(|e| {
            let message = e.to_string();
            let reason = message
                .rsplit_once(" at line ")
                .map_or(message.as_str(), |(r, _)| r);
            if let Some(k) = reason
                .strip_prefix("missing field `")
                .and_then(|r| r.strip_suffix('`'))
            {
                return JsonError::MissingKey { key: k.to_string() };
            }
            let line_start: usize = self
                .text
                .split_inclusive('\n')
                .take(e.line().saturating_sub(1))
                .map(str::len)
                .sum();
            JsonError::Invalid {
                key: key_at(&self.text, line_start + e.column()).unwrap_or_default(),
                reason: reason.to_string(),
                at: format!("line {} column {}", e.line(), e.column()),
            }
        })
    }

    /// The value of `key` as a `T` (`expected` describes `T` in the message), or `None`
    /// if the key is absent.
    pub fn get<T: DeserializeOwned>(
        &self,
        key: &str,
        expected: &str,
    ) -> Result<Option<T>, JsonError> {
        let Some(v) = self.map.get(key) else {
            return Ok(None);
        };
        serde_json::from_value(v.clone()).map(Some).map_err(|e| {
            let mut shown = v.to_string();
            if shown.chars().count() > 60 {
                shown = shown.chars().take(57).collect::<String>() + "…";
            }
            JsonError::WrongType {
                key: key.to_string(),
                expected: expected.to_string(),
                found: format!("{shown} ({e})"),
            }
        })
    }

    /// The value of a key the format requires.
    pub fn require<T: DeserializeOwned>(&self, key: &str, expected: &str) -> Result<T, JsonError> {
        self.get(key, expected)?
            .ok_or_else(|| JsonError::MissingKey {
                key: key.to_string(),
            })
    }

    /// A finite number, if the key is given.
    pub fn number(&self, key: &str) -> Result<Option<f64>, JsonError> {
        match self.get::<f64>(key, "a number")? {
            Some(v) if !v.is_finite() => Err(JsonError::WrongType {
                key: key.to_string(),
                expected: "a finite number".into(),
                found: v.to_string(),
            }),
            v => Ok(v),
        }
    }
}
