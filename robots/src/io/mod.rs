//! File input and output shared by the tools: output sets written whole (staged, then put
//! in place under a journal and named by a manifest), the readers' size limits, the CSV and
//! JSON readers, input schedules, and progress and result lines that never panic on a
//! closed or full stream.

use serde::de::DeserializeOwned;
use std::io::Read as _;
use std::os::fd::AsRawFd as _;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// A line on stderr (progress, warnings). Best-effort: a closed or full stderr
/// (`2>/dev/full`, `2>&1 | head -1`) loses the line instead of panicking as `eprintln!`
/// does, so the run still finishes and writes its files.
#[macro_export]
macro_rules! progress {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

/// A line on stdout (the short result summary). Best-effort, as [`progress!`]: the results
/// are in the files and the exit status tells success.
#[macro_export]
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

mod inputs;
mod json;
mod output;
mod read;
mod table;

pub use inputs::*;
pub use json::*;
pub use output::*;
pub use read::*;
pub use table::*;

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("wip-io-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_missing_file_and_a_malformed_one_are_different_errors() {
        let dir = scratch("read");
        let missing = read_inputs(&dir.join("missing.csv"), 100, "");
        assert!(
            matches!(&missing, Err(ReadError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound),
            "{missing:?}"
        );
        std::fs::write(dir.join("bad.csv"), "t,uR,uL\n0,1,x\n").unwrap();
        let bad = read_inputs(&dir.join("bad.csv"), 100, "");
        assert!(
            matches!(
                &bad,
                Err(ReadError::Inputs(InputError::Csv(CsvError::NotANumber {
                    line: 2,
                    column: 3,
                    ..
                })))
            ),
            "{bad:?}"
        );
        // Too many rows: refused by size before parsing, or by the row count.
        let long: String = std::iter::once("t,uR,uL\n".to_string())
            .chain((0..2000).map(|k| format!("{k},0,0\n")))
            .collect();
        std::fs::write(dir.join("long.csv"), &long).unwrap();
        let e = read_inputs(&dir.join("long.csv"), 100, " (--max-steps)").unwrap_err();
        assert!(
            matches!(
                &e,
                ReadError::Inputs(InputError::Csv(CsvError::TooManyRows { limit: 100, .. }))
            ),
            "{e:?}"
        );
        let e = read_inputs(&dir.join("long.csv"), 1, " (--max-steps)").unwrap_err();
        assert!(matches!(&e, ReadError::TooLarge { .. }), "{e:?}");
        assert!(e.to_string().contains("--max-steps"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn rows_between_steps_are_refused_with_a_step_that_fits() {
        let s = parse_inputs("t,uR,uL\n0,0,0\n0.001,5,5\n0.004,0,0\n1,0,0\n", "f").unwrap();
        let e = s.steps_on_grid(0.005, "f", "--step").unwrap_err();
        assert!(
            matches!(&e, InputError::OffGrid { row: 2, fate, fix, .. } if fate.contains("drop") && fix.contains("--step 0.001")),
            "{e}"
        );
        assert_eq!(s.steps_on_grid(0.001, "f", "--step").unwrap(), 1000);
        let late = parse_inputs("t,uR,uL\n0,0,0\n0.007,5,5\n1,0,0\n", "f").unwrap();
        let e = late.steps_on_grid(0.005, "f", "--step").unwrap_err();
        assert!(
            e.to_string().contains("apply it from t = 0.01 s, late"),
            "{e}"
        );
    }

    #[test]
    fn unread_columns_may_hold_text() {
        let text = "t,a,note\n0,1,ok\n1,2,fine\n";
        assert!(parse_csv(text, "f", true).is_err());
        let csv = parse_csv_with(
            text,
            "f",
            CsvOptions {
                allow_missing: true,
                columns: Some(&["t", "a"]),
                ..CsvOptions::default()
            },
        )
        .unwrap();
        assert_eq!(csv.rows[1][1], 2.0);
        assert!(csv.rows[1][2].is_nan());
    }

    #[test]
    fn json_objects_refuse_arrays_nulls_and_wrong_types_by_key() {
        let known = ["a", "b"];
        let e = JsonObject::parse("[1.0, 2.0]", &known).unwrap_err();
        assert_eq!(e, JsonError::NotAnObject { found: "an array" });
        let e = JsonObject::parse(r#"{"a": null}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::WrongType { key, .. } if key == "a"),
            "{e}"
        );
        let e = JsonObject::parse(r#"{"b": [1, null]}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::WrongType { key, .. } if key == "b[1]"),
            "{e}"
        );
        let e = JsonObject::parse(r#"{"c": 1}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::UnknownKey { key, .. } if key == "c"),
            "{e}"
        );
        let o = JsonObject::parse(r#"{"a": "x"}"#, &known).unwrap();
        let e = o.number("a").unwrap_err();
        assert!(e.to_string().starts_with("'a' must be a number"), "{e}");
        assert!(matches!(
            o.require::<f64>("b", "a number"),
            Err(JsonError::MissingKey { .. })
        ));
    }
}
