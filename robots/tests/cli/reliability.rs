//! The `wip` tool under careless or hostile use: every reproduction of issue 24 gives a
//! clear one-line error (exit 1), a usage error with the subcommand's usage (exit 2), or a
//! correct result; never a panic (101) or an abort (134).

use crate::common::{fails_with_one_line, scratch, wip};

use std::io::Read;
use std::path::Path;
use std::process::{Output, Stdio};

fn run(args: &[&str], dir: &Path) -> Output {
    wip().args(args).current_dir(dir).output().unwrap()
}

/// Exit 2 with the usage of `wip <sub>` and a message that mentions `expect`.
fn usage_error(args: &[&str], dir: &Path, expect: &str) {
    let out = run(args, dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "args {args:?}: {err}");
    assert!(err.contains(expect), "'{err}' should mention '{expect}'");
    assert!(
        err.contains(&format!("Usage: wip {}", args[0])),
        "the subcommand's usage: {err}"
    );
}

/// A short waypoint problem: 0.5 m straight ahead in 4 s (200 stages at 20 ms).
const SHORT: &str = r#"{"name": "short", "points": [[0,0],[0.5,0]], "duration": 4.0,
    "start_heading": 0.0, "end_heading": 0.0}"#;

const X0: &str = "0,0,0,0.02,0,0,0,0,0";

#[test]
fn closed_or_full_stderr_and_stdout_do_not_crash_a_plan() {
    let dir = scratch("closed");
    std::fs::write(dir.join("short.json"), SHORT).unwrap();
    // 2>/dev/full and 1>/dev/full: every write fails with ENOSPC.
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let out = wip()
        .args(["plan", "short.json", "--step", "0.02", "--out", "full"])
        .current_dir(&dir)
        .stderr(full())
        .stdout(full())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(dir.join("full/summary.json").exists());
    // `2>&1 | head -2`: the reader goes away after two lines (EPIPE on the next write).
    let mut child = wip()
        .args(["plan", "short.json", "--step", "0.02", "--out", "pipe"])
        .current_dir(&dir)
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 16];
    child.stderr.take().unwrap().read_exact(&mut first).unwrap();
    drop(child.stdout.take());
    // stderr dropped at the end of the statement above: both pipes are closed now.
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    let summary = std::fs::read_to_string(dir.join("pipe/summary.json")).unwrap();
    assert!(summary.contains("\"status\": \"solved\""), "{summary}");
}

#[test]
fn closed_stderr_does_not_crash_diagnose() {
    let dir = scratch("diag");
    let out = run(
        &["generate", "--duration", "3", "--seed", "2", "--out", "g"],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut child = wip()
        .args(["diagnose", "g/log.csv", "--out", "d"])
        .current_dir(&dir)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut first = [0u8; 8];
    child.stderr.take().unwrap().read_exact(&mut first).unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(0));
    for f in ["diagnosis.json", "params_refit.json", "report.md"] {
        assert!(dir.join("d").join(f).exists(), "{f}");
    }
    // The refitted model is a parameter file that simulate reads.
    std::fs::write(dir.join("u.csv"), "t,uR,uL\n0,1,1\n0.5,1,1\n").unwrap();
    let out = run(
        &[
            "simulate",
            "--x0",
            X0,
            "--inputs",
            "u.csv",
            "--params",
            "d/params_refit.json",
            "--out",
            "s",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn bad_parameters_are_refused_before_any_work() {
    let dir = scratch("params");
    std::fs::write(dir.join("zero.json"), r#"{"R_m": 0}"#).unwrap();
    std::fs::write(dir.join("neg.json"), r#"{"R_m": -1.5}"#).unwrap();
    std::fs::write(dir.join("mass.json"), r#"{"m_w": 0.0}"#).unwrap();
    fails_with_one_line(
        &["generate", "--params", "zero.json", "--duration", "2"],
        &dir,
        "'R_m' must be finite and > 0, got 0",
    );
    fails_with_one_line(
        &["plan", "eight", "--params", "neg.json", "--step", "0.02"],
        &dir,
        "'R_m' must be finite and > 0, got -1.5",
    );
    fails_with_one_line(&["params", "--params", "mass.json"], &dir, "'m_w'");
}

#[test]
fn sizes_are_checked_up_front() {
    let dir = scratch("sizes");
    // Milliseconds typed as seconds: 2.4 million stages.
    std::fs::write(
        dir.join("ms.json"),
        SHORT.replace("\"duration\": 4.0", "\"duration\": 12000"),
    )
    .unwrap();
    fails_with_one_line(&["plan", "ms.json"], &dir, "--max-stages");
    // 21 million stages.
    fails_with_one_line(&["plan", "eight", "--h", "1e-6"], &dir, "--max-stages");
    // Inputs up to t = 1e9 s.
    std::fs::write(dir.join("long.csv"), "t,uR,uL\n0,1,1\n1e9,1,1\n").unwrap();
    fails_with_one_line(
        &["simulate", "--x0", X0, "--inputs", "long.csv"],
        &dir,
        "--max-steps",
    );
}

#[test]
fn simulate_refuses_nonsense_instead_of_printing_it() {
    let dir = scratch("sim");
    std::fs::write(dir.join("mega.csv"), "t,uR,uL\n0,1e6,1e6\n2,1e6,1e6\n").unwrap();
    std::fs::write(dir.join("u.csv"), "t,uR,uL\n0,1,1\n2,1,1\n").unwrap();
    std::fs::write(dir.join("short.csv"), "t,uR,uL\n0,1,1\n0.0124,1,1\n").unwrap();
    fails_with_one_line(
        &["simulate", "--x0", X0, "--inputs", "mega.csv"],
        &dir,
        "--max-voltage",
    );
    fails_with_one_line(
        &[
            "simulate",
            "--x0",
            X0,
            "--inputs",
            "u.csv",
            "--integrator",
            "rk1",
            "--h",
            "0.5",
        ],
        &dir,
        "beyond its stability bound",
    );
    fails_with_one_line(
        &["simulate", "--x0", X0, "--inputs", "short.csv"],
        &dir,
        "whole number of steps",
    );
    // The stability check leaves a resolving step alone: RK4 at 0.2 ms runs.
    let out = run(
        &[
            "simulate",
            "--x0",
            X0,
            "--inputs",
            "u.csv",
            "--integrator",
            "rk4",
            "--step",
            "0.0002",
            "--out",
            "rk4",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn csv_quirks_are_read_or_refused_clearly() {
    let dir = scratch("csv");
    // A UTF-8 byte-order mark, CRLF line ends and a quoted field read as plain CSV.
    std::fs::write(
        dir.join("bom.csv"),
        "\u{feff}t,uR,uL\r\n0,1,1\r\n\"0.5\",1,1\r\n",
    )
    .unwrap();
    let out = run(
        &["simulate", "--x0", X0, "--inputs", "bom.csv", "--out", "b"],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(dir.join("dup.csv"), "t,uR,uL,uR\n0,1,1,2\n0.5,1,1,2\n").unwrap();
    fails_with_one_line(
        &["simulate", "--x0", X0, "--inputs", "dup.csv"],
        &dir,
        "column 'uR' appears twice",
    );
}

#[test]
fn diagnose_options_and_degenerate_logs() {
    let dir = scratch("dlog");
    let mut log = String::from("t,uR,uL,alpha,v_alpha,phiR_rel,phiL_rel\n");
    for k in 0..300 {
        log += &format!("{},0,0,0,0,0,0\n", k as f64 * 0.01);
    }
    std::fs::write(dir.join("zero.csv"), &log).unwrap();
    fails_with_one_line(&["diagnose", "zero.csv"], &dir, "every reading is constant");
    let mut log = String::from("t,uR,uL,alpha,v_alpha\n");
    for k in 0..300 {
        let t = k as f64 * 0.01;
        log += &format!("{t},0,0,{},{}\n", 0.01 * t.sin(), 0.01 * t.cos());
    }
    std::fs::write(dir.join("moving.csv"), &log).unwrap();
    for w in ["-5", "0"] {
        usage_error(
            &["diagnose", "moving.csv", "--window", w],
            &dir,
            "must be positive",
        );
    }
    fails_with_one_line(
        &["diagnose", "moving.csv", "--window", "0.001"],
        &dir,
        "at least 10 samples",
    );
}

#[test]
fn a_reading_of_1e300_is_set_aside_not_fitted() {
    let dir = scratch("spike");
    let out = run(
        &["generate", "--duration", "4", "--seed", "5", "--out", "g"],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("g/log.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let col = lines[header].split(',').position(|c| c == "alpha").unwrap();
    let mut row: Vec<String> = lines[header + 200].split(',').map(String::from).collect();
    row[col] = "1e300".into();
    lines[header + 200] = row.join(",");
    std::fs::write(dir.join("spike.csv"), lines.join("\n")).unwrap();
    let out = run(&["diagnose", "spike.csv", "--out", "d"], &dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("1e300") && err.contains("is not fitted"),
        "{err}"
    );
    let json = std::fs::read_to_string(dir.join("d/diagnosis.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    for key in ["error_before", "error_after", "gain"] {
        assert!(v[key].as_f64().is_some_and(f64::is_finite), "{key}: {json}");
    }
}

#[test]
fn usage_errors_name_the_subcommand() {
    let dir = scratch("usage");
    usage_error(
        &["generate", "--effect", "floor_slope+floor_slope"],
        &dir,
        "twice",
    );
    usage_error(&["bench", "--time-limit", "-5"], &dir, "must be positive");
    usage_error(&["plan", "eight", "--integrator", "rk3"], &dir, "rk1");
    usage_error(&["plan", "eigth"], &dir, "unknown problem");
    usage_error(&["plan", "eight", "--u-max", "6"], &dir, "outside (0, 5]");
    usage_error(&["plan", "eight", "--u-max", "-1"], &dir, "outside (0, 5]");
    usage_error(&["simulate", "--frobnicate"], &dir, "--frobnicate");
}

#[test]
fn version_help_and_parameter_round_trip() {
    let dir = scratch("params-rt");
    let out = run(&["--version"], &dir);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("wip "));
    let out = run(&["plan", "--help"], &dir);
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && help.contains("--step") && help.contains("--max-stages"));
    assert!(!help.contains("--h "), "--h is a hidden alias: {help}");
    // `wip params > p.json && wip plan … --params p.json`
    let out = run(&["params"], &dir);
    assert!(out.status.success());
    std::fs::write(dir.join("p.json"), &out.stdout).unwrap();
    std::fs::write(dir.join("short.json"), SHORT).unwrap();
    let out = run(
        &[
            "plan",
            "short.json",
            "--step",
            "0.02",
            "--params",
            "p.json",
            "--quiet",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn an_unwritable_output_directory_is_found_before_the_solve() {
    let dir = scratch("unwritable");
    std::fs::write(dir.join("file"), "").unwrap();
    // One line on stderr: the plan's announcement and iteration table never started.
    fails_with_one_line(
        &["plan", "eight", "--out", "file/sub"],
        &dir,
        "cannot create output directory",
    );
    // No stray staging directory is left where the output could be written.
    let out = run(
        &[
            "simulate",
            "--x0",
            X0,
            "--inputs",
            "missing.csv",
            "--out",
            "o",
        ],
        &dir,
    );
    assert_eq!(out.status.code(), Some(1));
    let stray: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("staging"))
        .collect();
    assert!(stray.is_empty());
}

/// The exact curvature of an RK plan evaluates each stage in nested duals of kilobytes a
/// number: on the solver's worker threads (2 MiB stacks by default) it aborted with a
/// stack overflow (exit by SIGABRT). One iteration, on one thread and on two: the
/// iteration limit's exit 1, no signal.
#[test]
fn exact_curvature_of_an_rk_plan_does_not_overflow_the_stack() {
    let dir = scratch("rk-exact");
    std::fs::write(dir.join("short.json"), SHORT).unwrap();
    for threads in ["1", "2"] {
        let out = run(
            &[
                "plan",
                "short.json",
                "--step",
                "0.02",
                "--integrator",
                "rk1",
                "--hessian",
                "exact",
                "--max-iter",
                "1",
                "--threads",
                threads,
                "--quiet",
                "--out",
                "o",
            ],
            &dir,
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{threads} threads: {err}");
        assert!(
            err.contains("not solved within"),
            "{threads} threads: {err}"
        );
    }
}
