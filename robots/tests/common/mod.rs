//! What the command-line tests (`tests/cli/`) share: the `wip` and `car` binaries, a scratch
//! directory, and the check that a run fails with one clear line.

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn wip() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wip"))
}

pub fn car() -> Command {
    Command::new(env!("CARGO_BIN_EXE_car"))
}

pub fn snakeboard() -> Command {
    Command::new(env!("CARGO_BIN_EXE_snakeboard"))
}

/// A JSON file the tools wrote, parsed.
pub fn read_json(path: impl AsRef<Path>) -> serde_json::Value {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A fresh directory for one test: `name` keeps the tests of one file apart, the calling
/// file's name the files of one test binary (whose tests run at the same time in one
/// process, so the process id alone does not).
#[track_caller]
pub fn scratch(name: &str) -> PathBuf {
    let file = Path::new(std::panic::Location::caller().file());
    let stem = file.file_stem().unwrap_or_default().to_string_lossy();
    let d = std::env::temp_dir().join(format!("wip-test-{}-{stem}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Exit 1 with one line on stderr that mentions `expect`, and no panic.
pub fn fails_with_one_line(args: &[&str], dir: &Path, expect: &str) {
    let out = wip().args(args).current_dir(dir).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "args {args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.contains(expect), "'{err}' should mention '{expect}'");
    assert!(!err.contains("panicked"), "{err}");
}

/// The rows of a result CSV the tools wrote (the header skipped), every field a number.
pub fn rows(csv: &str) -> Vec<Vec<f64>> {
    csv.lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect()
}

/// Run a tool that must succeed; its stderr is the failure message otherwise.
#[track_caller]
pub fn succeeds(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}
