//! `diagnose`'s output files for any plant: `diagnosis.json` (docs/formats.md), `report.md`
//! and residual plots before and after the refit, one per channel.

use crate::plot::{Plot, Series};
use dmech_diagnose::conditions::Condition;
use dmech_diagnose::diagnosis::Diagnosis;
use dmech_diagnose::log::{ChannelSpec, MeasuredLog};
use dmech_diagnose::model::Catalogue;
use dmech_diagnose::session::Scored;
use dmech_diagnose::Plant;
use serde_json::{json, Map, Value};
use std::fmt::Write as _;

/// The candidate's effect parameters, by name, from a full vector of values.
fn params_json(cat: &Catalogue, s: &Scored, values: &[f64]) -> Value {
    let mut m = Map::new();
    for p in s.fit.candidate.effect_params(cat) {
        m.insert(cat.params[p].name.clone(), json!(values[p]));
    }
    Value::Object(m)
}

/// The calibration: every combination of the system's own parameters with its relative
/// standard deviation, and the calibrated parameters (the chosen model's values).
fn calibration_json(cat: &Catalogue, d: &Diagnosis) -> Value {
    let Some(c) = &d.calibration else {
        return Value::Null;
    };
    let ident = &c.identifiability;
    let combinations: Vec<Value> = ident
        .combinations
        .iter()
        .map(|k| {
            let mut w = Map::new();
            for (&p, &x) in ident.params.iter().zip(&k.weights) {
                w.insert(cat.params[p].name.clone(), json!(x));
            }
            json!({
                "name": k.name,
                "relative_std": if k.std.is_finite() { json!(k.std) } else { json!("infinite") },
                "determined": k.determined,
                "exponents": Value::Object(w),
            })
        })
        .collect();
    let mut values = Map::new();
    let mut nominal = Map::new();
    let mut std = Map::new();
    for &p in &ident.params {
        let name = cat.params[p].name.clone();
        values.insert(name.clone(), json!(d.chosen.fit.theta[p]));
        nominal.insert(name.clone(), json!(cat.params[p].nominal));
        std.insert(name, json!(d.chosen.fit.std[p]));
    }
    json!({
        "combinations": combinations,
        "nominal": Value::Object(nominal),
        "parameters": Value::Object(values),
        "uncertainty_within_determined": Value::Object(std),
        "error": c.fit.error,
    })
}

/// What a tool prints when a diagnosis is done: the cause, the error before and after, the
/// gain and the time, then each named effect's parameter with its standard deviation.
pub fn summary_lines<P: Plant>(plant: &P, d: &Diagnosis) -> Vec<String> {
    let mut lines = vec![format!(
        "cause: {}; error {:.3} -> {:.3} (1 = noise floor), gain {:.3}; {:.1} s",
        d.cause, d.error_before, d.error_after, d.gain, d.elapsed_s
    )];
    let cat = plant.catalogue();
    if !d.effects.is_empty() {
        for i in d.chosen.fit.candidate.effect_params(cat) {
            lines.push(format!(
                "  {} = {:.6e} ± {:.1e}",
                cat.params[i].name, d.chosen.fit.theta[i], d.chosen.fit.std[i]
            ));
        }
    }
    lines
}

/// `diagnosis.json` (docs/formats.md).
pub fn diagnosis_json<P: Plant>(plant: &P, d: &Diagnosis) -> Value {
    let cat = plant.catalogue();
    let chans = plant.channels();
    let named = d.cause != "none" && d.cause != "unexplained";
    let (parameters, uncertainty) = if named {
        (
            params_json(cat, &d.chosen, &d.chosen.fit.theta),
            params_json(cat, &d.chosen, &d.chosen.fit.std),
        )
    } else {
        (json!({}), json!({}))
    };
    let candidates: Vec<Value> = d
        .candidates
        .iter()
        .map(|c| {
            json!({
                "effect": c.fit.candidate.name(cat),
                "score": c.score,
                "parameters": params_json(cat, c, &c.fit.theta),
                "uncertainty": params_json(cat, c, &c.fit.std),
                "error": c.error,
                "fitted": c.fitted,
                "plausible": c.implausible.is_empty(),
                "implausible": c.implausible,
                "undetermined": c.undetermined,
            })
        })
        .collect();
    let mut noise = Map::new();
    for (c, spec) in chans.iter().enumerate() {
        let s = d.sigma_final[c];
        if s.is_finite() {
            noise.insert(spec.name.clone(), json!(s));
        }
    }
    let tests = |ts: &[super::adequacy::ChannelTest]| -> Vec<Value> {
        ts.iter()
            .map(|t| {
                json!({
                    "channel": chans[t.channel].name,
                    "n": t.n,
                    "z_mean": t.z_mean,
                    "z_level": t.z_level,
                    "z_white": t.z_white,
                    "rms_over_noise": t.ratio,
                    "critical": t.critical,
                    "passes": t.passes(),
                })
            })
            .collect()
    };
    let mut out = json!({
        "cause": d.cause,
        "effects": d.effects.iter().map(|&e| cat.effects[e].name.clone()).collect::<Vec<_>>(),
        "alternatives": d.alternatives,
        "parameters": parameters,
        "uncertainty": uncertainty,
        "error_before": d.error_before,
        "error_after": d.error_after,
        "gain": d.gain,
        "noise": Value::Object(noise),
        "windows": d.windows.len(),
        "elapsed_s": d.elapsed_s,
        "candidates": candidates,
        "residual_tests": {
            "false_alarm": super::adequacy::FALSE_ALARM,
            "before": tests(&d.tests_before),
            "after": tests(&d.tests_after),
        },
        "flagged_readings": d.flagged,
        "conditions": conditions_json(chans, &d.conditions),
        "conditions_before": conditions_json(chans, &d.conditions_before),
    });
    if d.calibration.is_some() {
        out["calibration"] = calibration_json(cat, d);
    }
    out
}

/// `report.md`; `refit_note` says what the plant's refitted parameter file holds.
pub fn report_md<P: Plant>(
    plant: &P,
    d: &Diagnosis,
    log: &MeasuredLog,
    source: &str,
    refit_note: &str,
) -> String {
    let cat = plant.catalogue();
    let chans = plant.channels();
    let mut s = String::new();
    let _ = writeln!(s, "# Model validation: {source}\n");
    let _ = writeln!(s, "**Verdict.** {}\n", d.verdict);
    let _ = writeln!(
        s,
        "Log: {} rows, step {} s ({:.1} s); {} prediction windows of {:.2} s; diagnosed in {:.1} s.\n",
        log.len(),
        log.h,
        log.h * (log.len().saturating_sub(1)) as f64,
        d.windows.len(),
        d.windows.first().map_or(0.0, |w| w.1 as f64 * log.h),
        d.elapsed_s
    );
    for w in &log.warnings {
        let _ = writeln!(s, "- warning: {w}");
    }
    let _ = writeln!(s, "## The error measure\n");
    let _ = writeln!(
        s,
        "The log is cut into windows; in each, the model is simulated from an initial state fitted to the readings (the robot is open-loop unstable: a replay of the whole log would diverge). \
The residual of channel `c` is prediction − reading; its noise level `σ_c` is estimated from first differences of the residual within windows (`σ² = mean(Δr²)/2`: white noise passes, a slowly varying model error does not). \
The error of a model is `E = sqrt(mean_c (RMS_c/σ_c)²)` over the measured channels: **1 is the noise floor**. `gain = 1 − E_after/E_before`.\n"
    );
    let _ = writeln!(
        s,
        "| | error |\n|---|---|\n| nominal model (before) | {:.3} |\n| refitted model (after) | {:.3} |\n| gain | {:.3} |\n",
        d.error_before, d.error_after, d.gain
    );
    let _ = writeln!(s, "## Where the nominal model disagrees\n");
    let _ = writeln!(s, "| channel | σ (noise) | RMS/σ before | RMS/σ after | worst 1 s of the log (before) |\n|---|---|---|---|---|");
    for (i, c) in chans.iter().enumerate() {
        if !d.channel_before[i].is_finite() {
            continue;
        }
        let worst = worst_second(&d.residuals_before, i, log.h, d.sigma_final[i]);
        let _ = writeln!(
            s,
            "| {} | {:.3e} {} | {:.2} | {:.2} | {} |",
            c.name, d.sigma_final[i], c.unit, d.channel_before[i], d.channel_after[i], worst
        );
    }
    let _ = writeln!(
        s,
        "\nResidual plots (before and after): `residual_<channel>.svg`.\n"
    );
    let _ = writeln!(s, "## Is anything left?\n");
    let _ = writeln!(
        s,
        "Per channel, three statistics that are standard normal when the residual is white noise (docs/diagnose.md): the mean `z_M = mean(r)√n/σ`, the level `z_L = (mean(r²)/σ² − 1)√n` and the lag-one autocorrelation `z_W = ρ₁√n`. A channel passes when `|z_M|`, `z_L` and `z_W` are at most the critical value, set by a false-alarm rate of {} per log shared over all tests.\n",
        super::adequacy::FALSE_ALARM
    );
    let _ = writeln!(
        s,
        "| channel | n | z_M before | z_L before | z_W before | z_M after | z_L after | z_W after | critical | after |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for a in &d.tests_after {
        if let Some(b) = d.tests_before.iter().find(|b| b.channel == a.channel) {
            let _ = writeln!(
                s,
                "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {} |",
                chans[a.channel].name,
                a.n,
                b.z_mean,
                b.z_level,
                b.z_white,
                a.z_mean,
                a.z_level,
                a.z_white,
                a.critical,
                if a.passes() {
                    "noise".to_string()
                } else {
                    format!("fails: {}", a.failures().join(", "))
                }
            );
        }
    }
    let _ = writeln!(s);
    if !d.conditions.is_empty() {
        let _ = writeln!(s, "## Where the model fails\n");
        let _ = writeln!(
            s,
            "The operating conditions that the remaining residual follows, in the channels that fail their tests: `(r/σ)²` (level) or `r/σ` (mean) inside and outside the condition, and `z`, a t statistic (paired over windows, or for the level between windows) on the normal scale (docs/diagnose.md §4d). This is where an effect is missing.\n"
        );
        conditions_md(&mut s, chans, &d.conditions);
    }
    if d.cause == "unexplained" && !d.conditions_before.is_empty() {
        let _ = writeln!(s, "## Where the nominal model fails\n");
        let _ = writeln!(
            s,
            "The same for the nominal model's residual: the signature of what the model lacks, whichever candidate was chosen.\n"
        );
        conditions_md(&mut s, chans, &d.conditions_before);
    }
    if !d.flagged.is_empty() {
        let _ = writeln!(s, "Readings outside their channel's range, not fitted:\n");
        for f in &d.flagged {
            let _ = writeln!(s, "- {f}");
        }
        let _ = writeln!(s);
    }
    calibration_md(&mut s, cat, d);
    let _ = writeln!(s, "## Fitted parameters\n");
    if d.effects.is_empty() {
        let _ = writeln!(s, "None: no effect is named.\n");
    } else {
        let _ = writeln!(s, "| parameter | value | uncertainty (1σ) |\n|---|---|---|");
        for p in d.chosen.fit.candidate.effect_params(cat) {
            let _ = writeln!(
                s,
                "| `{}` | {:.6e} | {:.2e} |",
                cat.params[p].name, d.chosen.fit.theta[p], d.chosen.fit.std[p]
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Candidates\n");
    if !refit_note.is_empty() {
        let _ = writeln!(s, "{refit_note}\n");
    }
    let _ = writeln!(
        s,
        "Selection by the Bayesian information criterion `m ln(RSS/m) + k ln m` over the `m` weighted residuals (`k` effect parameters; the window states are common to all candidates); lower is better. \
Every effect is screened by one linearisation at the nominal model; the promising ones are fitted to convergence (`fitted`).\n"
    );
    let _ = writeln!(
        s,
        "| candidate | score | error | fitted | parameters | physically plausible | determined by the log |\n|---|---|---|---|---|---|---|"
    );
    for c in &d.candidates {
        let ps: Vec<String> = c
            .fit
            .candidate
            .effect_params(cat)
            .iter()
            .map(|&p| {
                format!(
                    "{} = {:.4e} ± {:.1e}",
                    cat.params[p].name, c.fit.theta[p], c.fit.std[p]
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "| {} | {:.1} | {:.3} | {} | {} | {} | {} |",
            c.fit.candidate.name(cat),
            c.score,
            c.error,
            if c.fitted { "yes" } else { "screened" },
            ps.join(", "),
            yes_or_why_not(&c.implausible),
            yes_or_why_not(&c.undetermined),
        );
    }
    s
}

/// A table cell: `yes` when nothing stands against, else `no:` and the reasons.
fn yes_or_why_not(reasons: &[String]) -> String {
    if reasons.is_empty() {
        "yes".to_string()
    } else {
        format!("no: {}", reasons.join("; "))
    }
}

/// The calibration's combinations and calibrated parameters, if any.
fn calibration_md(s: &mut String, cat: &Catalogue, d: &Diagnosis) {
    let Some(c) = &d.calibration else {
        return;
    };
    let _ = writeln!(s, "## Calibration of the system's own parameters\n");
    let _ = writeln!(
        s,
        "The Fisher information of the parameters' logarithms at the nominal fit, decomposed: each combination `Π θ_j^(w_j)` is determined by the log to the relative standard deviation shown; those at most {} are calibrated, the others stay at the parameter file's values (docs/diagnose.md). The calibrated model alone has error {:.3}.\n",
        super::identify::DETERMINED,
        c.fit.error
    );
    let _ = writeln!(s, "| combination | relative σ | |\n|---|---|---|");
    for k in &c.identifiability.combinations {
        let _ = writeln!(
            s,
            "| `{}` | {:.2e} | {} |",
            k.name,
            k.std,
            if k.determined { "calibrated" } else { "left" }
        );
    }
    let _ = writeln!(
        s,
        "\n| parameter | file | calibrated | σ (within the determined combinations) |\n|---|---|---|---|"
    );
    for &p in &c.identifiability.params {
        let _ = writeln!(
            s,
            "| `{}` | {:.4e} | {:.4e} | {:.2e} |",
            cat.params[p].name, cat.params[p].nominal, d.chosen.fit.theta[p], d.chosen.fit.std[p]
        );
    }
    let _ = writeln!(s);
}

/// The one-second stretch where `|r|/σ` is largest on average, as text.
fn worst_second(r: &super::noise::Residuals, c: usize, h: f64, sigma: f64) -> String {
    let n = ((1.0 / h).round() as usize).max(1);
    let mut best = (0.0, 0usize);
    let mut k = 0;
    while k + n <= r.rows() {
        let vals: Vec<f64> = (k..k + n)
            .map(|j| r.get(j, c))
            .filter(|v| !v.is_nan())
            .collect();
        if !vals.is_empty() {
            let ms = (vals.iter().map(|v| v * v).sum::<f64>() / vals.len() as f64).sqrt() / sigma;
            if ms > best.0 {
                best = (ms, k);
            }
        }
        k += n / 2;
    }
    format!(
        "{:.1}–{:.1} s: RMS/σ {:.2}",
        best.1 as f64 * h,
        (best.1 + n) as f64 * h,
        best.0
    )
}

/// The residuals as a table (`residuals.csv`): per row of the log, `t` and for each channel
/// with a finite result its residual before (nominal) and after (refitted), prediction −
/// reading; empty where the channel was not read or the row is outside every window.
pub fn residuals_csv<P: Plant>(plant: &P, d: &Diagnosis, log: &MeasuredLog) -> String {
    let chans: Vec<usize> = (0..plant.channels().len())
        .filter(|&i| d.channel_before[i].is_finite())
        .collect();
    let mut s = String::from("t");
    for &i in &chans {
        let n = &plant.channels()[i].name;
        s += &format!(",{n}_before,{n}_after");
    }
    s.push('\n');
    let cell = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{v:.6e}")
        }
    };
    for (k, t) in log.t.iter().enumerate() {
        s += &format!("{t}");
        for &i in &chans {
            s += &format!(
                ",{},{}",
                cell(d.residuals_before.get(k, i)),
                cell(d.residuals_after.get(k, i))
            );
        }
        s.push('\n');
    }
    s
}

/// Residual plots, one per channel: before (nominal) and after (refitted).
pub fn residual_plots<P: Plant>(
    plant: &P,
    d: &Diagnosis,
    log: &MeasuredLog,
) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (i, c) in plant.channels().iter().enumerate() {
        if !d.channel_before[i].is_finite() {
            continue;
        }
        let pick = |r: &super::noise::Residuals| -> (Vec<f64>, Vec<f64>) {
            r.channel(i).map(|(k, v)| (log.t[k], v)).unzip()
        };
        let (tb, yb) = pick(&d.residuals_before);
        let (ta, ya) = pick(&d.residuals_after);
        let title = format!(
            "residual of {} (prediction − reading), noise σ = {:.2e} {}",
            c.name, d.sigma_final[i], c.unit
        );
        let ylabel = format!("{} [{}]", c.name, c.unit);
        let s = d.sigma_final[i];
        let plot = Plot {
            title: &title,
            xlabel: "t [s]",
            ylabel: &ylabel,
            series: vec![
                Series {
                    label: "before (nominal)",
                    x: &tb,
                    y: &yb,
                    color: "#d62728",
                },
                Series {
                    label: "after (refitted)",
                    x: &ta,
                    y: &ya,
                    color: "#1f77b4",
                },
            ],
            bounds: if s.is_finite() {
                vec![-3.0 * s, 3.0 * s]
            } else {
                vec![]
            },
            markers: vec![],
            equal_axes: false,
        };
        out.push((format!("residual_{}.svg", c.name), plot.to_svg()));
    }
    out
}

fn conditions_json(chans: &[ChannelSpec], conds: &[Condition]) -> Vec<Value> {
    conds
        .iter()
        .map(|c| {
            json!({
                "channel": chans[c.channel].name,
                "condition": c.condition,
                "measure": c.measure,
                "inside": c.inside,
                "outside": c.outside,
                "z": c.z,
            })
        })
        .collect()
}

/// A table of conditions (at most 20, strongest first).
fn conditions_md(s: &mut String, chans: &[ChannelSpec], conds: &[Condition]) {
    let _ = writeln!(
        s,
        "| channel | condition | measure | inside | outside | z |\n|---|---|---|---|---|---|"
    );
    for c in conds.iter().take(20) {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} | {:.1} |",
            chans[c.channel].name, c.condition, c.measure, c.inside, c.outside, c.z
        );
    }
    let _ = writeln!(s);
}
