//! The `wip` and `car` tools under hostile use, second round (issue 57): every reproduction
//! gives a clear one-line error (exit 1), a usage error (exit 2), or a correct result;
//! never a panic (101), an abort (134), a crash (139) or a hang. The closed loop's runs use
//! the short hook plan of `tests/data` (7 s at 20 ms) to stay fast.

use crate::common::{car, read_json, scratch, wip};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn hook_plan() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/track_hook_h20.csv")
}

/// Run `cmd` in `dir`, killed after `limit` (a hang is a failure, not a stuck CI job).
fn run_within(mut cmd: Command, dir: &Path, limit: Duration) -> Output {
    let mut child = cmd
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd:?} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn run(tool: fn() -> Command, args: &[&str], dir: &Path) -> Output {
    let mut c = tool();
    c.args(args);
    run_within(c, dir, Duration::from_secs(120))
}

/// Write a file of the test's directory.
fn write(dir: &Path, name: impl AsRef<Path>, contents: impl AsRef<[u8]>) {
    std::fs::write(dir.join(name), contents).unwrap();
}

/// `wip generate` of a log of `seconds` into `dir/out`.
fn generate(dir: &Path, seconds: &str, seed: &str, out: &str) {
    succeeds(
        wip,
        &[
            "generate",
            "--duration",
            seconds,
            "--seed",
            seed,
            "--out",
            out,
        ],
        dir,
    );
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Exit 1 with one line on stderr that mentions every one of `expect`.
#[track_caller]
fn refused(tool: fn() -> Command, args: &[&str], dir: &Path, expect: &[&str]) -> String {
    let out = run(tool, args, dir);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "args {args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    for e in expect {
        assert!(err.contains(e), "'{err}' should mention '{e}'");
    }
    err
}

/// Exit 0 (the run's summary on stdout).
#[track_caller]
fn succeeds(tool: fn() -> Command, args: &[&str], dir: &Path) -> Output {
    let out = run(tool, args, dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "args {args:?}: {}",
        stderr(&out)
    );
    out
}

/// Exit 2 with the usage and a message mentioning `expect`.
#[track_caller]
fn usage_error(tool: fn() -> Command, args: &[&str], dir: &Path, expect: &str) {
    let out = run(tool, args, dir);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "args {args:?}: {err}");
    assert!(err.contains(expect) && err.contains("Usage:"), "{err}");
}

const X0: &str = "0,0,0,0.01,0,0,0,0,0";

/// A short waypoint problem (0.5 m in 4 s) and its plan at 20 ms into `o`.
const SHORT: &str = r#"{"name": "short", "points": [[0,0],[0.5,0]], "duration": 4,
    "start_heading": 0, "end_heading": 0}"#;
const SHORT_PLAN: [&str; 7] = [
    "plan",
    "short.json",
    "--step",
    "0.02",
    "--quiet",
    "--out",
    "o",
];
const CAR_X0: &str = "0,0,0,0,0,0,0,0,0";

/// Valid motor values that make the electrical mode faster than the plant's default RK4
/// substeps resolve: the plant takes more substeps and tracks (both controllers), where it
/// panicked in the closed form.
#[test]
fn track_with_a_fast_motor_circuit_takes_more_substeps() {
    let dir = scratch("fast-motor");
    write(&dir, "Lm.json", r#"{"L_m": 2e-4}"#);
    write(&dir, "Rm.json", r#"{"R_m": 3.0}"#);
    let plan = hook_plan();
    let plan = plan.to_str().unwrap();
    for (params, controller) in [("Lm.json", "lq"), ("Rm.json", "lq"), ("Lm.json", "mpc")] {
        let out_dir = format!("{params}-{controller}");
        succeeds(
            wip,
            &[
                "track",
                plan,
                "--params",
                params,
                "--controller",
                controller,
                "--out",
                &out_dir,
            ],
            &dir,
        );
        let j = read_json(dir.join(&out_dir).join("tracking.json"));
        assert_eq!(j["outcome"], "completed", "{j}");
        assert!(j["plant_substeps"].as_u64().unwrap() > 10, "{j}");
    }
}

/// `--param-error` is a relative error below 1 (bad usage otherwise); the plausible plant
/// of seed 16 at 0.3, which panicked, is simulated within RK4's bound; over 20 seeds at 0.3
/// no run diverges, and every fall is a fall (a finite state beyond 45°).
#[test]
fn monte_carlo_plants_are_checked_and_a_blow_up_is_not_a_fall() {
    let dir = scratch("mc");
    let plan = hook_plan();
    let plan = plan.to_str().unwrap();
    for rel in ["1.5", "1", "0", "-0.1"] {
        usage_error(
            wip,
            &["track", plan, "--monte-carlo", "2", "--param-error", rel],
            &dir,
            "(0, 1)",
        );
    }
    // A fall (exit 1) or not: a result either way, never a panic.
    let at_error_03 = |extra: &[&str], out: &str| {
        let mut args = vec!["track", plan, "--param-error", "0.3", "--out", out];
        args.extend_from_slice(extra);
        let o = run(wip, &args, &dir);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    };
    at_error_03(&["--plant-seed", "16"], "seed16");
    let j = read_json(dir.join("seed16/tracking.json"));
    assert_ne!(j["outcome"], "diverged", "{j}");
    assert!(j["feedback_voltage_max"].as_f64().unwrap() < 100.0, "{j}");
    at_error_03(&["--monte-carlo", "20"], "mc");
    let j = read_json(dir.join("mc/montecarlo.json"));
    assert_eq!(j["diverged"], 0, "{j}");
    assert_eq!(j["diverged_seeds"].as_array().unwrap().len(), 0, "{j}");
}

/// The closed loop through the library with a plant stepped beyond RK4's bound on purpose
/// (one substep of 5 ms): the simulation blows up, and the run says so; it is not a fall.
#[test]
fn a_plant_that_blows_up_is_diverged_not_fallen() {
    use robots::wip::track::closed_loop::{track_with_substeps, TrackConfig};
    use robots::wip::track::lq::LqController;
    use robots::wip::track::observer::SensorModel;
    use robots::wip::WipParams;
    let plan = robots::wip::track::report::read_plan(&hook_plan(), 1000, "").unwrap();
    let p = WipParams::default();
    let lq = LqController::design(&p).unwrap();
    let cfg = TrackConfig {
        plant: p,
        nominal: p,
        sensors: SensorModel::ideal(),
        seed: 1,
        push: None,
    };
    let run = track_with_substeps(&plan, &lq, &cfg, 1, |_| {});
    assert_eq!(run.outcome(), "diverged");
    assert!(run.fell_at.is_none());
    let f = run.figures();
    assert!(!f.fell && f.outcome == "diverged");
    // The checked count for the same plant: 10, and the run completes.
    let n = robots::wip::track::simulated_robot::substeps(&p, &plan.x[0], 0.005).unwrap();
    assert_eq!(n, 10);
    assert_eq!(
        track_with_substeps(&plan, &lq, &cfg, n, |_| {}).outcome(),
        "completed"
    );
}

/// `"accel": 1e20` put the waypoints at infinite times (a stage past the horizon: a panic
/// in the solver); now they are the cruise's times and the plan solves.
#[test]
fn a_huge_acceleration_plans() {
    let dir = scratch("accel");
    for accel in ["1e15", "1e20"] {
        write(
            &dir,
            "acc.json",
            format!(
                r#"{{"name": "acc", "points": [[0,0],[0.25,0],[0.5,0]], "duration": 5,
                    "accel": {accel}, "start_heading": 0, "end_heading": 0}}"#
            ),
        );
        let out = run(
            wip,
            &[
                "plan", "acc.json", "--step", "0.02", "--quiet", "--out", "p",
            ],
            &dir,
        );
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "accel {accel}: {}",
            stderr(&out)
        );
        assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
        let j = read_json(dir.join("p/summary.json"));
        assert_eq!(j["N"], 250, "{j}");
    }
}

/// `g`, `d_v` or `d_c` of 1e308: every scheme refuses the file at once (RK hung in the
/// eigenvalues of a non-finite linearisation); `g = 1e12` is refused by the midpoint
/// scheme too (it turned the fall over and kept the tilt at 0.01 rad).
#[test]
fn absurd_parameters_are_refused_by_every_scheme_without_hanging() {
    let dir = scratch("absurd");
    write(&dir, "u.csv", "t,uR,uL\n0,1,1\n0.5,1,1\n");
    let simulate = |params: &'static str, integrator: &'static str| {
        let args = [
            "simulate",
            "--x0",
            X0,
            "--inputs",
            "u.csv",
            "--params",
            params,
            "--integrator",
            integrator,
            "--out",
            "s",
        ];
        let mut c = wip();
        c.args(args);
        let out = run_within(c, &dir, Duration::from_secs(20));
        assert_eq!(out.status.code(), Some(1), "{params} {integrator}");
        assert_eq!(stderr(&out).trim_end().lines().count(), 1);
        stderr(&out)
    };
    for key in ["g", "d_v", "d_c"] {
        write(
            &dir,
            format!("{key}.json"),
            format!(r#"{{"{key}": 1e308}}"#),
        );
        for integrator in ["rk4", "rk1", "rk2", "varint", "midpoint"] {
            let params: &'static str = Box::leak(format!("{key}.json").into_boxed_str());
            let err = simulate(params, integrator);
            assert!(err.contains("not finite"), "{key} {integrator}: {err}");
        }
    }
    write(&dir, "g12.json", r#"{"g": 1e12}"#);
    for integrator in ["midpoint", "varint", "rk4"] {
        let err = simulate("g12.json", integrator);
        assert!(
            err.contains("simulate:") && err.contains("--step ≤"),
            "{err}"
        );
    }
    // The same rule refuses such a model in the other commands, before any work.
    refused(
        wip,
        &["plan", "eight", "--params", "g12.json", "--step", "0.02"],
        &dir,
        &["grows e-fold"],
    );
    refused(
        wip,
        &[
            "track",
            hook_plan().to_str().unwrap(),
            "--params",
            "g12.json",
        ],
        &dir,
        &["track: the plant"],
    );
}

/// The car has RK4's stability bound and a voltage limit: 1 V for 1 s with RK4 at 5 ms
/// gave x = −4.5e220 m, and 1e300 V x ≈ 6e305 m.
#[test]
fn car_simulate_checks_the_step_and_the_inputs() {
    let dir = scratch("car-sim");
    write(&dir, "one.csv", "t,tau_s,u_d\n0,0,1\n1,0,1\n");
    write(&dir, "huge.csv", "t,tau_s,u_d\n0,0,1e300\n1,0,1e300\n");
    write(&dir, "twist.csv", "t,tau_s,u_d\n0,50,0\n1,50,0\n");
    let args = |inputs: &'static str, extra: &[&'static str]| {
        let mut v = vec!["simulate", "--x0", CAR_X0, "--inputs", inputs];
        v.extend_from_slice(extra);
        v
    };
    refused(
        car,
        &args("one.csv", &["--integrator", "rk4"]),
        &dir,
        &["rk4", "beyond its stability bound", "--step ≤"],
    );
    succeeds(
        car,
        &args(
            "one.csv",
            &["--integrator", "rk4", "--step", "1e-4", "--out", "rk4"],
        ),
        &dir,
    );
    let text = std::fs::read_to_string(dir.join("rk4/trajectory.csv")).unwrap();
    let x: f64 = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!((x - 0.255).abs() < 0.005, "x(1 s) = {x}");
    refused(car, &args("huge.csv", &[]), &dir, &["u_d", "--max-voltage"]);
    refused(
        car,
        &args("twist.csv", &[]),
        &dir,
        &["tau_s", "--max-torque"],
    );
}

/// A row between two steps is refused with what the hold would do with it and a step that
/// honours every row (the 5-V pulse from 1 to 4 ms was dropped without a word).
#[test]
fn rows_between_steps_are_refused_with_the_fix() {
    let dir = scratch("pulse");
    write(
        &dir,
        "w.csv",
        "t,uR,uL\n0,0,0\n0.001,5,5\n0.004,0,0\n1,0,0\n",
    );
    write(
        &dir,
        "c.csv",
        "t,tau_s,u_d\n0,0,0\n0.001,0,5\n0.004,0,0\n1,0,0\n",
    );
    for (tool, x0, file) in [
        (wip as fn() -> Command, X0, "w.csv"),
        (car, CAR_X0, "c.csv"),
    ] {
        refused(
            tool,
            &["simulate", "--x0", x0, "--inputs", file],
            &dir,
            &[
                "data row 2",
                "whole number of steps",
                "drop it",
                "--step 0.001",
            ],
        );
    }
    // With that step the pulse is applied.
    succeeds(
        wip,
        &[
            "simulate", "--x0", X0, "--inputs", "w.csv", "--step", "0.001", "--out", "s",
        ],
        &dir,
    );
    let text = std::fs::read_to_string(dir.join("s/trajectory.csv")).unwrap();
    let row2: Vec<&str> = text.lines().nth(2).unwrap().split(',').collect();
    assert_eq!(row2[0], "0.001");
    assert_eq!(row2[10].parse::<f64>().unwrap(), 5.0);
}

/// A plan with rows cut out (a 2-s hole in t) is refused, naming the line.
#[test]
fn a_plan_with_a_hole_is_refused() {
    let dir = scratch("hole");
    let text = std::fs::read_to_string(hook_plan()).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let mut cut: Vec<&str> = lines[..header + 101].to_vec();
    cut.extend_from_slice(&lines[header + 201..]);
    write(&dir, "hole.csv", cut.join("\n") + "\n");
    refused(
        wip,
        &["track", "hole.csv"],
        &dir,
        &["hole.csv", "line", "rows are missing"],
    );
}

/// A plan stopped by the clock did not reach its end: `time_limit`, and no objective or
/// violation (they were the finest mesh's start: 0 and the start's violation).
#[test]
fn a_time_limited_bench_marks_its_figures_absent() {
    let dir = scratch("bench");
    let out = succeeds(
        wip,
        &[
            "bench",
            "--problems",
            "eight",
            "--integrators",
            "varint",
            "--currents",
            "dynamic",
            "--time-limit",
            "0.05",
            "--out",
            "b",
        ],
        &dir,
    );
    let j = read_json(dir.join("b/bench.json"));
    let r = &j["runs"][0];
    assert_eq!(r["status"], "time_limit", "{j}");
    assert!(
        r["objective"].is_null() && r["max_violation"].is_null(),
        "{j}"
    );
    assert!(r["iterations"].as_u64().is_some(), "{j}");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("time_limit"), "{table}");
}

/// JSON read as written: an array is not a parameter file (it set g and m_b by position),
/// a null is not "the default", and the car's pose file is an object too.
#[test]
fn json_arrays_nulls_and_wrong_types_are_refused_by_key() {
    let dir = scratch("json");
    write(&dir, "arr.json", "[1.0, 2.0]");
    write(&dir, "null.json", r#"{"m_b": null}"#);
    write(&dir, "text.json", r#"{"R_m": "1.5"}"#);
    for (file, expect) in [
        ("arr.json", ["expected a JSON object", "an array"]),
        ("null.json", ["'m_b'", "null"]),
        ("text.json", ["'R_m'", "must be a number"]),
    ] {
        let expect = [&[file][..], &expect].concat();
        refused(wip, &["params", "--params", file], &dir, &expect);
    }
    write(
        &dir,
        "wp.json",
        r#"{"points": [[0,0],[0.5,0]], "duration": 4, "accel": null, "start_heading": 0, "end_heading": 0}"#,
    );
    refused(
        wip,
        &["plan", "wp.json", "--step", "0.02"],
        &dir,
        &["'accel'", "null"],
    );
    write(
        &dir,
        "pose.json",
        r#"["arr", [0,0,0], [], [1,0,0], 5, false]"#,
    );
    refused(
        car,
        &["plan", "pose.json"],
        &dir,
        &["pose.json", "expected a JSON object"],
    );
    write(
        &dir,
        "pose2.json",
        r#"{"name": "p", "start": [0,0,0], "end": [1,0], "duration": 5}"#,
    );
    refused(car, &["plan", "pose2.json"], &dir, &["'end'", "pose"]);
}

/// A log with an extra text column: the column is not read, a warning names it, the
/// diagnosis runs (it was refused: "'ok' is not a finite number").
#[test]
fn an_unknown_text_column_of_a_log_is_ignored_with_a_warning() {
    let dir = scratch("textcol");
    generate(&dir, "2", "2", "g");
    let text = std::fs::read_to_string(dir.join("g/log.csv")).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        if line.starts_with('#') {
            out += line;
        } else if i == 0 || line.starts_with("t,") {
            out += &format!("{line},note");
        } else {
            out += &format!("{line},ok");
        }
        out.push('\n');
    }
    write(&dir, "note.csv", out);
    let res = succeeds(wip, &["diagnose", "note.csv", "--out", "d"], &dir);
    let err = stderr(&res);
    assert!(err.contains("unknown column 'note' ignored"), "{err}");
    assert!(dir.join("d/diagnosis.json").exists());
}

/// The car's messages: one step is too few (not "not a whole number of steps (1.0000)"),
/// the start equal to the goal and a turn in place are what they are (not "use a smaller
/// step" at 1 ms), and headings wrap (3.0 → −3.0 is a small turn, not 6 rad).
#[test]
fn the_cars_messages_say_what_is_wrong_and_headings_wrap() {
    let dir = scratch("car-msgs");
    let pose = |name: &str, start: &str, end: &str, duration: &str| {
        write(
            &dir,
            format!("{name}.json"),
            format!(
                r#"{{"name": "{name}", "start": {start}, "end": {end}, "duration": {duration}}}"#
            ),
        );
    };
    pose("one", "[0,0,0]", "[1,0,0]", "0.1");
    pose("same", "[0,0,0]", "[0,0,0]", "2");
    pose("turn", "[0,0,0]", "[0,0,1.5]", "2");
    pose("wrap", "[0,0,3.0]", "[-1,0,-3.0]", "4");
    refused(
        car,
        &["plan", "one.json", "--step", "0.1"],
        &dir,
        &["1 step(s)", "at least 2", "--step 0.05"],
    );
    refused(
        car,
        &["plan", "same.json", "--step", "0.001"],
        &dir,
        &["same pose", "nothing to plan"],
    );
    refused(
        car,
        &["plan", "turn.json", "--step", "0.001"],
        &dir,
        &["cannot turn in place", "waypoint"],
    );
    succeeds(car, &["plan", "wrap.json", "--quiet", "--out", "w"], &dir);
    let text = std::fs::read_to_string(dir.join("w/trajectory.csv")).unwrap();
    let theta: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(3).unwrap().parse().unwrap())
        .collect();
    let turned = theta.iter().map(|t| (t - 3.0).abs()).fold(0.0, f64::max);
    assert!(
        turned < 1.0,
        "the heading went as far as {turned} rad from the start's"
    );
    let end = theta.last().unwrap();
    assert!(
        (end - (-3.0 + std::f64::consts::TAU)).abs() < 1e-6,
        "end heading {end}"
    );
}

/// Every file in a directory that a run of either tool wrote: its manifest and its files.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn manifest(dir: &Path) -> Vec<String> {
    let mut v = robots::io::manifest(dir);
    v.sort();
    v
}

/// An output folder holds one run's set: a car plan into a wip plan's folder leaves no wip
/// SVG, a plain track after a Monte Carlo no montecarlo.json, a diagnosis with fewer
/// channels no residual plot of the earlier one; a file no run wrote stays.
#[test]
fn an_output_folder_holds_one_runs_set() {
    let dir = scratch("sets");
    let out = dir.join("o");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    write(&dir, "short.json", SHORT);
    succeeds(wip, &SHORT_PLAN, &dir);
    assert!(out.join("tilt.svg").exists());
    succeeds(car, &["plan", "lane-change", "--quiet", "--out", "o"], &dir);
    let car_set = [
        "drive.svg",
        "path.svg",
        "steering.svg",
        "summary.json",
        "trajectory.csv",
    ];
    assert_eq!(manifest(&out), car_set);
    let mut expect: Vec<String> = car_set.iter().map(|s| s.to_string()).collect();
    expect.extend([".manifest".to_string(), "notes.txt".to_string()]);
    expect.sort();
    assert_eq!(listing(&out), expect);

    let plan = hook_plan();
    let plan = plan.to_str().unwrap();
    succeeds(
        wip,
        &["track", plan, "--monte-carlo", "2", "--out", "t"],
        &dir,
    );
    assert!(dir.join("t/montecarlo.json").exists());
    succeeds(wip, &["track", plan, "--ideal", "--out", "t"], &dir);
    assert!(!dir.join("t/montecarlo.json").exists());
    assert!(dir.join("t/tracking.json").exists());

    // Diagnoses of a log with x, y and theta, then of the same log without them.
    generate(&dir, "2", "3", "g");
    let text = std::fs::read_to_string(dir.join("g/log.csv")).unwrap();
    let header = text.lines().find(|l| l.starts_with("t,")).unwrap();
    let keep: Vec<usize> = header
        .split(',')
        .enumerate()
        .filter(|(_, c)| !["x", "y", "theta"].contains(c))
        .map(|(i, _)| i)
        .collect();
    let fewer: String = text
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                l.to_string() + "\n"
            } else {
                let f: Vec<&str> = l.split(',').collect();
                keep.iter().map(|&i| f[i]).collect::<Vec<_>>().join(",") + "\n"
            }
        })
        .collect();
    write(&dir, "fewer.csv", fewer);
    succeeds(
        wip,
        &["diagnose", "g/log.csv", "--quiet", "--out", "d"],
        &dir,
    );
    assert!(dir.join("d/residual_x.svg").exists());
    succeeds(
        wip,
        &["diagnose", "fewer.csv", "--quiet", "--out", "d"],
        &dir,
    );
    assert!(!dir.join("d/residual_x.svg").exists());
    assert!(dir.join("d/residual_alpha.svg").exists());
    assert!(!listing(&dir.join("d"))
        .iter()
        .any(|n| n.starts_with(".staging") || n == ".commit"));
}

/// SIGINT and SIGTERM during the work: the staging directory goes, the previous set stays
/// as it was, the process dies of the signal. A staging directory of a process that no
/// longer exists is removed by the next run.
#[test]
fn an_interrupted_run_leaves_the_previous_set_and_no_staging() {
    let dir = scratch("signals");
    succeeds(
        wip,
        &["plan", "zigzag", "--step", "0.02", "--quiet", "--out", "o"],
        &dir,
    );
    let before = std::fs::read(dir.join("o/trajectory.csv")).unwrap();
    for sig in [libc::SIGINT, libc::SIGTERM] {
        let mut child = wip()
            .args(["plan", "eight", "--step", "0.0025", "--quiet", "--out", "o"])
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait until the run has its staging directory (the solve then takes seconds).
        let staging = dir.join(format!("o/.staging-{}", child.id()));
        let start = Instant::now();
        while !staging.exists() && start.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(staging.exists());
        std::thread::sleep(Duration::from_millis(200));
        unsafe { libc::kill(child.id() as i32, sig) };
        let status = child.wait().unwrap();
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(status.signal(), Some(sig), "{status:?}");
        assert!(!staging.exists(), "signal {sig}: staging left");
        assert_eq!(std::fs::read(dir.join("o/trajectory.csv")).unwrap(), before);
    }
    // A crash leaves a staging directory: the next run removes it.
    let dead = {
        let mut c = Command::new("true").spawn().unwrap();
        c.wait().unwrap();
        c.id()
    };
    let stale = dir.join(format!("o/.staging-{dead}"));
    std::fs::create_dir_all(&stale).unwrap();
    std::fs::write(stale.join("trajectory.csv"), "half").unwrap();
    succeeds(
        wip,
        &["plan", "zigzag", "--step", "0.02", "--quiet", "--out", "o"],
        &dir,
    );
    assert!(!stale.exists());
}

/// An interrupt while the set is being put in place (each file's move slowed down) waits
/// for it: the folder then holds the new run's set, whole, and nothing of the old one;
/// the eight's trajectory was found beside the zigzag's plots.
#[test]
fn an_interrupt_during_the_commit_waits_for_the_set() {
    let dir = scratch("commit");
    write(&dir, "short.json", SHORT);
    succeeds(car, &["plan", "lane-change", "--quiet", "--out", "o"], &dir);
    let mut child = wip()
        .args(SHORT_PLAN)
        .env("ROBOTS_TEST_COMMIT_PAUSE_MS", "150")
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let journal = dir.join("o/.commit");
    let start = Instant::now();
    while !journal.exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(journal.exists(), "the commit never started");
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let status = child.wait().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(libc::SIGINT), "{status:?}");
    assert!(!journal.exists());
    let set = manifest(&dir.join("o"));
    assert!(set.contains(&"tilt.svg".to_string()), "{set:?}");
    for f in ["drive.svg", "steering.svg"] {
        assert!(
            !dir.join("o").join(f).exists(),
            "{f} of the car's plan is left"
        );
    }
    let summary = read_json(dir.join("o/summary.json"));
    assert_eq!(summary["benchmark"], "short");
}

/// Every reader has a size limit, checked from the file's size first: a 400 MB log (a
/// sparse file here) is refused at once, and so are oversized inputs, plans and
/// parameter files; a log with more rows than `--max-rows` at the first row too many.
#[test]
fn every_reader_refuses_a_file_too_large_at_once() {
    let dir = scratch("sizes");
    let sparse = |name: &str, bytes: u64, head: &str| {
        let f = std::fs::File::create(dir.join(name)).unwrap();
        use std::io::Write;
        (&f).write_all(head.as_bytes()).unwrap();
        f.set_len(bytes).unwrap();
    };
    sparse("big.csv", 400_000_000, "t,uR,uL,alpha\n");
    sparse("big_inputs.csv", 1_000_000_000, "t,uR,uL\n");
    sparse("big_plan.csv", 1_000_000_000, "t,x\n");
    sparse("big.json", 20_000_000, "{");
    type Case<'a> = (fn() -> Command, &'a [&'a str], &'a [&'a str]);
    let cases: [Case; 5] = [
        (
            wip,
            &["diagnose", "big.csv"],
            &["big.csv", "bytes", "--max-rows"],
        ),
        (
            wip,
            &["simulate", "--x0", X0, "--inputs", "big_inputs.csv"],
            &["big_inputs.csv", "bytes", "--max-steps"],
        ),
        (
            wip,
            &["track", "big_plan.csv"],
            &["big_plan.csv", "bytes", "--max-samples"],
        ),
        (
            wip,
            &["params", "--params", "big.json"],
            &["big.json", "bytes"],
        ),
        (car, &["plan", "big.json"], &["big.json", "bytes"]),
    ];
    for (tool, args, expect) in cases {
        refused(tool, args, &dir, expect);
    }
    let mut log = String::from("t,uR,uL,alpha\n");
    for k in 0..3000 {
        log += &format!("{},0,0,{}\n", k as f64 * 0.01, 1e-3 * (k as f64).sin());
    }
    write(&dir, "rows.csv", log);
    refused(
        wip,
        &["diagnose", "rows.csv", "--max-rows", "1000"],
        &dir,
        &["more than 1000 data rows", "--max-rows"],
    );
}

/// `generate` and `diagnose` check their models too: a fast motor circuit gets more RK4
/// substeps in `generate` (it failed with "the true model failed: NonFinite"), and a
/// friction whose wheel mode the predictions' substeps cannot follow is refused by
/// `diagnose` (it returned a diagnosis of blown-up predictions).
#[test]
fn generate_and_diagnose_check_their_models() {
    let dir = scratch("models");
    write(&dir, "fast.json", r#"{"L_m": 2e-4, "R_m": 3.0}"#);
    succeeds(
        wip,
        &[
            "generate",
            "--duration",
            "2",
            "--params",
            "fast.json",
            "--out",
            "g",
        ],
        &dir,
    );
    write(&dir, "dv.json", r#"{"d_v": 10}"#);
    refused(
        wip,
        &["diagnose", "g/log.csv", "--params", "dv.json"],
        &dir,
        &[
            "diagnose: the model",
            "beyond its stability bound",
            "a log step ≤",
        ],
    );
}
