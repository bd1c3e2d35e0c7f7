//! `wip generate` and `wip diagnose` from the command line: malformed logs rejected with
//! exit status 1 and one line naming the problem; a generated log diagnosed end to end,
//! with every output file written and `diagnosis.json` carrying the keys of docs/formats.md.

use crate::common::{read_json, scratch, succeeds, wip};

/// A well-formed log of `n` rows (tilt, rate and one current channel), as text.
fn good_rows(n: usize) -> String {
    let mut s = String::from("# robot: test\nt,uR,uL,alpha,v_alpha,iR\n");
    for k in 0..n {
        s += &format!("{},{},{},0.01,0.0,0.1\n", k as f64 * 0.005, 0.1, 0.1);
    }
    s
}

/// Runs `wip diagnose` on `text`; returns (exit code, stderr).
fn diagnose_text(name: &str, text: &str) -> (i32, String) {
    let dir = scratch(name);
    let file = dir.join("log.csv");
    std::fs::write(&file, text).unwrap();
    let out = wip()
        .args(["diagnose", file.to_str().unwrap(), "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn malformed_logs_exit_1_with_one_line() {
    let good = good_rows(400);
    let mut lines: Vec<&str> = good.lines().collect();
    let text_in_number = {
        let bad = lines[10].replacen("0.01", "0.0x1", 1);
        lines[10] = &bad;
        lines.join("\n")
    };
    let mut lines: Vec<String> = good.lines().map(String::from).collect();
    lines[20] = lines[19].clone(); // t repeats: not increasing
    let non_increasing = lines.join("\n");
    let missing_column = good.replace("t,uR,uL,", "t,uR,");
    let missing_column: String = missing_column
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i < 2 {
                l.to_string()
            } else {
                // Drop the uL field of every data row.
                let f: Vec<&str> = l.split(',').collect();
                [f[0], f[1], f[3], f[4], f[5]].join(",")
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let all_nan = good
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i < 2 {
                l.to_string()
            } else {
                let f: Vec<&str> = l.split(',').collect();
                [f[0], f[1], f[2], f[3], f[4], "NaN"].join(",")
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let cases: [(&str, String, &str); 5] = [
        ("missing_column", missing_column, "uL"),
        ("text_in_number", text_in_number, "line 11"),
        ("non_increasing", non_increasing, "line 21"),
        ("empty", String::new(), "empty"),
        ("all_nan", all_nan, "iR"),
    ];
    for (name, text, must_name) in cases {
        let (code, err) = diagnose_text(name, &text);
        println!("{name}: exit {code}: {}", err.trim_end());
        assert_eq!(code, 1, "{name}: exit status");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{name}: one line, got {err:?}"
        );
        assert!(
            err.contains(must_name),
            "{name}: the message names '{must_name}': {err}"
        );
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

#[test]
fn text_in_a_number_names_line_and_column() {
    let good = good_rows(50);
    let mut lines: Vec<&str> = good.lines().collect();
    lines[7] = "0.025,0.1,0.1,0.01,zero,0.1"; // file line 8, column v_alpha
    let (code, err) = diagnose_text("column", &lines.join("\n"));
    assert_eq!(code, 1);
    assert!(err.contains("line 8") && err.contains("v_alpha"), "{err}");
}

/// `wip generate` hides a tilt-sensor offset in a 12 s closed-loop log; `wip diagnose`
/// names it and writes every file. (The recovery over seeds and effects is
/// `tests/diagnose/recovery.rs`; this checks the command-line surfaces.)
#[test]
fn generate_then_diagnose_end_to_end() {
    let dir = scratch("e2e");
    succeeds(
        wip()
            .args([
                "generate",
                "--effect",
                "tilt_offset",
                "--seed",
                "4",
                "--duration",
                "12",
                "--out",
            ])
            .arg(&dir),
    );
    let truth = read_json(dir.join("truth.json"));
    let b_true = truth["effects"][0]["parameters"]["b_rad"].as_f64().unwrap();
    // One corrupt reading (a logging fault): flagged and not fitted, never a NaN result.
    let text = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let col = lines[header].split(',').position(|c| c == "alpha").unwrap();
    let mut f: Vec<String> = lines[header + 100].split(',').map(String::from).collect();
    f[col] = "1e300".into();
    lines[header + 100] = f.join(",");
    std::fs::write(dir.join("log.csv"), lines.join("\n") + "\n").unwrap();
    let out = wip()
        .args(["diagnose", dir.join("log.csv").to_str().unwrap(), "--out"])
        .arg(dir.join("d"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("tilt_offset"),
        "progress names the candidates: {stderr}"
    );
    let text = std::fs::read_to_string(dir.join("d/diagnosis.json")).unwrap();
    assert!(!text.contains("null"), "every number finite: {text}");
    let d: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(d["cause"], "tilt_offset");
    let flagged = d["flagged_readings"].as_array().unwrap();
    assert_eq!(flagged.len(), 1, "{flagged:?}");
    assert!(flagged[0].as_str().unwrap().contains("alpha"));
    // The refitted model is a parameter file `--params` reads.
    let refit = std::fs::read_to_string(dir.join("d/params_refit.json")).unwrap();
    robots::wip::WipParams::from_json_str(&refit).unwrap();
    let b = d["parameters"]["b_rad"].as_f64().unwrap();
    let sd = d["uncertainty"]["b_rad"].as_f64().unwrap();
    assert!(
        (b - b_true).abs() <= 3.0 * sd,
        "b = {b} ± {sd}, true {b_true}"
    );
    for key in ["error_before", "error_after", "gain"] {
        assert!(d[key].as_f64().is_some(), "{key}");
    }
    let gain = 1.0 - d["error_after"].as_f64().unwrap() / d["error_before"].as_f64().unwrap();
    assert!((gain - d["gain"].as_f64().unwrap()).abs() < 1e-12);
    let cands = d["candidates"].as_array().unwrap();
    assert!(
        cands.len() >= 9,
        "every effect and the nominal model are listed"
    );
    assert_eq!(cands[0]["effect"], "tilt_offset", "best first");
    // Why a candidate may not be named (parameters outside their physical range, or not
    // determined by the log): in the file, and on the candidate's progress line.
    let reasons = |c: &serde_json::Value, key: &str| c[key].as_array().unwrap().len();
    assert_eq!(
        reasons(&cands[0], "implausible") + reasons(&cands[0], "undetermined"),
        0
    );
    for c in cands {
        let name = c["effect"].as_str().unwrap();
        let blocked = reasons(c, "implausible") + reasons(c, "undetermined") > 0;
        let lines: Vec<&str> = stderr
            .lines()
            .filter(|l| l.split_whitespace().next() == Some(name) && l.contains(" error "))
            .collect();
        if let Some(line) = lines.last() {
            assert_eq!(line.contains("(not nameable: "), blocked, "{name}: {line}");
        }
    }
    let report = std::fs::read_to_string(dir.join("d/report.md")).unwrap();
    assert!(report.contains("tilt_offset") && report.contains("noise floor"));
    for ch in ["alpha", "v_alpha", "phiR_rel", "iR", "x"] {
        let svg = std::fs::read_to_string(dir.join(format!("d/residual_{ch}.svg"))).unwrap();
        assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"), "{ch}");
    }
    // residuals.csv holds the residuals behind the report: each channel's RMS after the
    // refit over the noise is the `rms_over_noise` of diagnosis.json (to the file's six
    // significant digits).
    let table = std::fs::read_to_string(dir.join("d/residuals.csv")).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for t in d["residual_tests"]["after"].as_array().unwrap() {
        let ch = t["channel"].as_str().unwrap();
        let col = header
            .iter()
            .position(|h| *h == format!("{ch}_after"))
            .unwrap_or_else(|| panic!("column {ch}_after in {header:?}"));
        let r: Vec<f64> = rows
            .iter()
            .filter(|row| !row[col].is_empty())
            .map(|row| row[col].parse().unwrap())
            .collect();
        assert_eq!(r.len() as u64, t["n"].as_u64().unwrap(), "{ch}");
        let rms = (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt();
        let ratio = rms / d["noise"][ch].as_f64().unwrap();
        let want = t["rms_over_noise"].as_f64().unwrap();
        assert!(
            (ratio / want - 1.0).abs() < 1e-5,
            "{ch}: {ratio} against {want}"
        );
    }
}

/// A log whose readings never change carries no information: a clear error (exit 1), not
/// a diagnosis with a score of `ln 0` printed as `null`.
#[test]
fn a_constant_log_is_a_clear_error() {
    let mut s = String::from("t,uR,uL,alpha,v_alpha,phiR_rel\n");
    for k in 0..400 {
        s += &format!("{},0,0,0,0,0\n", k as f64 * 0.01);
    }
    let (code, err) = diagnose_text("zeros", &s);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("constant"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// With every effect excluded and the calibration on, no candidate may be named (on
/// `balboa_01` the calibration moves `m_b` and `I_byy` outside their physical ranges): the
/// diagnosis falls back to the base model and says what is left. This aborted with a panic
/// ("at least the base model") on the real Balboa log.
#[test]
fn every_effect_excluded_falls_back_to_the_base_model() {
    let dir = scratch("exclude_all");
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/balboa");
    // The catalogue's effects and the generic reading hypotheses.
    let all = robots::wip::diagnose::effects::Effect::all()
        .map(|e| e.name())
        .collect::<Vec<_>>()
        .join(",");
    let out = wip()
        .args([
            "diagnose",
            "--quiet",
            "--calibrate",
            "--exclude",
            &all,
            "--params",
        ])
        .arg(data.join("balboa_params.json"))
        .arg(data.join("balboa_01.csv"))
        .arg("--out")
        .arg(dir.join("d"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let d = read_json(dir.join("d/diagnosis.json"));
    assert!(
        d["effects"].as_array().unwrap().is_empty(),
        "{}",
        d["effects"]
    );
    assert!(
        d["cause"] == "unexplained" || d["cause"] == "none",
        "{}",
        d["cause"]
    );
    assert!(d["error_after"].as_f64().unwrap() <= d["error_before"].as_f64().unwrap());
}

/// `wip generate --effect NAME=V[,V]` hides the effect at the magnitudes given (written to
/// `truth.json` as given), and refuses with a usage error (exit status 2, the subcommand's
/// usage) an unknown name, a wrong number of values, a value that is not a finite number,
/// and one outside the parameter's plausible range.
#[test]
fn generate_sets_a_hidden_effect_magnitude() {
    let dir = scratch("effect-magnitude");
    succeeds(
        wip()
            .args([
                "generate",
                "--effect",
                "input_delay=0.015+floor_slope=0.02,-0.03",
                "--duration",
                "2",
                "--out",
            ])
            .arg(&dir),
    );
    let truth = read_json(dir.join("truth.json"));
    let effects = truth["effects"].as_array().unwrap();
    assert_eq!(effects[0]["effect"], "input_delay");
    assert_eq!(effects[0]["parameters"]["delay_s"].as_f64(), Some(0.015));
    assert_eq!(effects[1]["effect"], "floor_slope");
    assert_eq!(effects[1]["parameters"]["slope_x_rad"].as_f64(), Some(0.02));
    assert_eq!(
        effects[1]["parameters"]["slope_y_rad"].as_f64(),
        Some(-0.03)
    );
    // The generic reading hypotheses take magnitudes too.
    succeeds(
        wip()
            .args(["generate", "--effect"])
            .arg("reading_offset:v_alpha=0.03+reading_scale:phiR_rel=1.03")
            .args(["--duration", "2", "--out"])
            .arg(dir.join("readings")),
    );
    let truth = read_json(dir.join("readings/truth.json"));
    let effects = truth["effects"].as_array().unwrap();
    assert_eq!(effects[0]["effect"], "reading_offset:v_alpha");
    assert_eq!(effects[1]["effect"], "reading_scale:phiR_rel");
    assert_eq!(
        effects[1]["parameters"]["phiR_rel_scale"].as_f64(),
        Some(1.03)
    );
    for (spec, expect) in [
        ("input_dealy=0.015", "unknown effect 'input_dealy'"),
        (
            "input_delay=0.01,0.02",
            "has 1 parameter(s) (delay_s), got 2",
        ),
        (
            "floor_slope=0.02",
            "has 2 parameter(s) (slope_x_rad, slope_y_rad), got 1",
        ),
        ("input_delay=", "'' is not a finite number"),
        ("input_delay=NaN", "'NaN' is not a finite number"),
        ("input_delay=inf", "'inf' is not a finite number"),
        (
            "input_delay=0.5",
            "delay_s = 0.5 is outside its physically plausible range [0, 0.1]",
        ),
        (
            "input_delay=-0.005",
            "outside its physically plausible range",
        ),
        (
            "reading_scale:phiR_rel=1.5",
            "outside its physically plausible range",
        ),
    ] {
        let out = wip()
            .args(["generate", "--effect", spec, "--duration", "1", "--out"])
            .arg(dir.join("refused"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{spec}: {err}");
        assert!(
            err.contains(expect),
            "{spec}: '{err}' should say '{expect}'"
        );
        assert!(err.contains("Usage: wip generate"), "{spec}: {err}");
        assert!(!dir.join("refused").exists(), "{spec}: nothing written");
    }
}
