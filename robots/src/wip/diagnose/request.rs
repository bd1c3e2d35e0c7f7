//! `wip generate` and `wip diagnose` as library calls: what the command line and the Python
//! package (`dmech.wip.generate`, `dmech.wip.diagnose`) share, so that both give the same
//! log from the same seed and the same verdict on the same log.

use super::effects::{Effect, CALIBRATED};
use super::generate::{draw_effect, generate, truth_substeps, GenerateError, Rng, RunSettings};
use super::refit::refit_params;
use super::WipPlant;
use crate::diagnose::report::{diagnosis_json, report_md, residuals_csv};
use crate::diagnose::{diagnose, DiagnoseError, DiagnoseOptions, Diagnosis, MeasuredLog, Plant};
use crate::wip::WipParams;

/// A refused `--effect` list.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EffectListError {
    #[error("unknown effect '{name}' (expected one of: {known})")]
    Unknown { name: String, known: String },
    #[error("--effect names '{0}' twice: each effect is applied once")]
    Repeated(String),
    #[error(
        "--effect {effect}={given}: {effect} has {expected} parameter(s) ({names}), got {count}"
    )]
    Count {
        effect: String,
        given: String,
        expected: usize,
        names: String,
        count: usize,
    },
    #[error("--effect {effect}: '{value}' is not a finite number")]
    NotANumber { effect: String, value: String },
    #[error("--effect {effect}: {param} = {value} is outside its physically plausible range [{lo}, {hi}]")]
    OutOfRange {
        effect: String,
        param: String,
        value: f64,
        lo: f64,
        hi: f64,
    },
}

/// An effect of an `--effect` list, with its magnitudes if given (`NAME=V[,V]`), else
/// drawn from the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectRequest {
    pub effect: Effect,
    /// The effect's parameters in the order of [`Effect::parameter_names`].
    pub values: Option<Vec<f64>>,
}

/// The effects named by an `--effect` list: `none`, or known names joined by `+`, none
/// repeated, each with its parameters after `=` (comma-separated, as many as the effect
/// has, finite) or without (drawn).
pub fn parse_effects(spec: &str) -> Result<Vec<EffectRequest>, EffectListError> {
    if spec == "none" {
        return Ok(Vec::new());
    }
    let mut effects: Vec<EffectRequest> = Vec::new();
    for item in spec.split('+').map(str::trim) {
        let (name, given) = match item.split_once('=') {
            Some((n, v)) => (n.trim(), Some(v.trim())),
            None => (item, None),
        };
        let e = Effect::from_name(name).ok_or_else(|| EffectListError::Unknown {
            name: name.to_string(),
            known: Effect::all()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(", "),
        })?;
        if effects.iter().any(|r| r.effect == e) {
            return Err(EffectListError::Repeated(name.to_string()));
        }
        let values = given
            .map(|g| {
                let parts: Vec<&str> = g.split(',').map(str::trim).collect();
                if parts.len() != e.n_params() {
                    return Err(EffectListError::Count {
                        effect: name.to_string(),
                        given: g.to_string(),
                        expected: e.n_params(),
                        names: e.parameter_names().join(", "),
                        count: parts.len(),
                    });
                }
                parts
                    .into_iter()
                    .map(|v| {
                        v.parse::<f64>()
                            .ok()
                            .filter(|x| x.is_finite())
                            .ok_or_else(|| EffectListError::NotANumber {
                                effect: name.to_string(),
                                value: v.to_string(),
                            })
                    })
                    .collect::<Result<Vec<f64>, _>>()
            })
            .transpose()?;
        effects.push(EffectRequest { effect: e, values });
    }
    Ok(effects)
}

/// Each given magnitude within its parameter's physically plausible range in the catalogue
/// of the robot `p` (docs/diagnose.md §3): a log with an effect the diagnosis could never
/// name is refused.
pub fn check_magnitudes(requests: &[EffectRequest], p: &WipParams) -> Result<(), EffectListError> {
    // The plant's catalogue: the WIP's effects and its generic reading hypotheses.
    let plant = WipPlant::new(*p);
    let cat = plant.catalogue();
    for r in requests {
        let Some(values) = &r.values else { continue };
        for (name, &v) in r.effect.parameter_names().iter().zip(values) {
            let spec = &cat.params[cat.param_index(name).expect("the effect's parameter")];
            let (lo, hi) = spec.plausible;
            if !(lo..=hi).contains(&v) {
                return Err(EffectListError::OutOfRange {
                    effect: r.effect.name().to_string(),
                    param: (*name).to_string(),
                    value: v,
                    lo,
                    hi,
                });
            }
        }
    }
    Ok(())
}

/// A generated log with its hidden truth.
pub struct GeneratedRun {
    /// The measured log (`log.csv`).
    pub log: MeasuredLog,
    /// The hidden effects with the parameters drawn for them.
    pub effects: Vec<(Effect, Vec<f64>)>,
    /// The run's settings (step, duration, substeps).
    pub settings: RunSettings,
}

impl GeneratedRun {
    /// `log.csv`'s text.
    pub fn log_csv(&self, plant: &WipPlant) -> String {
        self.log.to_csv(plant.channels(), plant.inputs())
    }

    /// `truth.json`: the seed, the duration, the step and each effect's parameters.
    pub fn truth_json(&self, seed: u64) -> serde_json::Value {
        let truth: Vec<serde_json::Value> = self
            .effects
            .iter()
            .map(|(e, theta)| {
                let mut m = serde_json::Map::new();
                for (n, v) in e.parameter_names().iter().zip(theta) {
                    m.insert((*n).to_string(), serde_json::json!(v));
                }
                serde_json::json!({ "effect": e.name(), "parameters": m })
            })
            .collect();
        serde_json::json!({
            "seed": seed, "duration_s": self.settings.duration, "h": self.settings.h,
            "effects": truth
        })
    }
}

/// Why no log was generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GenerateRunError {
    /// The robot with its effects cannot be simulated (its substeps).
    #[error(transparent)]
    Model(#[from] crate::check::CheckError),
    #[error(transparent)]
    Run(#[from] GenerateError),
    #[error(transparent)]
    Effect(#[from] EffectListError),
}

/// A closed-loop log of `duration` seconds of the robot `p` with the hidden `effects`, their
/// magnitudes as given or drawn from `seed` in the ranges of docs/diagnose.md (`wip
/// generate`).
pub fn generate_run(
    p: &WipParams,
    effects: &[EffectRequest],
    seed: u64,
    duration: f64,
) -> Result<GeneratedRun, GenerateRunError> {
    check_magnitudes(effects, p)?;
    // The magnitudes come from their own stream so that the run (reference, noise) does not
    // change with the effect. A given magnitude still takes its draw, so that the other
    // effects' magnitudes do not change with it.
    let mut rng = Rng::new(seed.wrapping_add(1000));
    let effects: Vec<(Effect, Vec<f64>)> = effects
        .iter()
        .map(|r| {
            let drawn = draw_effect(r.effect, p, &mut rng);
            (r.effect, r.values.clone().unwrap_or(drawn))
        })
        .collect();
    let mut settings = RunSettings {
        duration,
        ..Default::default()
    };
    settings.substeps = truth_substeps(p, &effects, &settings)?;
    let g = generate(p, &effects, seed, &settings)?;
    Ok(GeneratedRun {
        log: g.log,
        effects,
        settings,
    })
}

/// The parameter-file keys a calibration moves: `"default"` for every key of
/// [`CALIBRATED`], else a comma-separated list.
pub fn calibration_keys(spec: &str) -> Vec<String> {
    if spec == "default" {
        CALIBRATED.iter().map(|s| s.to_string()).collect()
    } else {
        name_list(spec)
    }
}

/// A comma-separated list of names, blanks dropped.
pub fn name_list(s: &str) -> Vec<String> {
    s.split(',')
        .map(|x| x.trim().to_string())
        .filter(|x| !x.is_empty())
        .collect()
}

/// What `wip diagnose` writes, in memory.
pub struct DiagnosisFiles {
    /// The diagnosis itself.
    pub diagnosis: Diagnosis,
    /// `diagnosis.json`.
    pub json: serde_json::Value,
    /// `report.md`.
    pub report_md: String,
    /// `residuals.csv`.
    pub residuals_csv: String,
    /// `params_refit.json`'s parameters.
    pub refit: WipParams,
    /// The named effects `params_refit.json` cannot hold.
    pub left_out: Vec<Effect>,
}

/// What the report says of `params_refit.json`.
pub const REFIT_NOTE: &str = "`params_refit.json` holds the refitted model in the parameter-file format (`--params`): the robot's own parameters that the diagnosis moved (a calibration, friction, payload) go in; the other effects (sensor offset and filter, floor slope, delay, voltage gain, dead zone, unequal wheels, stick-slip, backlash, reversal lockout, the readings' offsets and scales) are not parameters of the model and are only reported here.";

/// Why a diagnosis gave no result.
#[derive(Debug, thiserror::Error)]
pub enum DiagnosisRunError {
    #[error(transparent)]
    Check(#[from] crate::check::CheckError),
    #[error(transparent)]
    Diagnose(#[from] DiagnoseError),
    #[error("params_refit.json: {0}")]
    Refit(String),
}

/// Diagnose `log` (read from `source`, the name the report gives it) against the plant's
/// nominal model: the diagnosis and the contents of every file `wip diagnose` writes but the
/// plots. `progress` receives the progress lines.
pub fn diagnose_log(
    plant: &WipPlant,
    log: &MeasuredLog,
    opts: &DiagnoseOptions,
    source: &str,
    progress: &dyn Fn(&str),
) -> Result<DiagnosisFiles, DiagnosisRunError> {
    plant.check_model(log.h)?;
    let d = diagnose(plant, log, opts, progress)?;
    let json = diagnosis_json(plant, &d);
    let report_md = report_md(plant, &d, log, source, REFIT_NOTE);
    let residuals_csv = residuals_csv(plant, &d, log);
    let (refit, left_out) = refit_params(plant, &d);
    refit
        .validate()
        .map_err(|e| DiagnosisRunError::Refit(e.to_string()))?;
    Ok(DiagnosisFiles {
        diagnosis: d,
        json,
        report_md,
        residuals_csv,
        refit,
        left_out,
    })
}
