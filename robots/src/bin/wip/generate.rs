//! `wip generate`: a synthetic measured log from a closed-loop run with hidden effects.

use crate::common::{load_params, usage_error, Failure};
use robots::diagnose::Plant;
use robots::io::OutputSet;
use robots::say;
use robots::wip::diagnose::effects::Effect;
use robots::wip::diagnose::generate::{draw_effect, generate, truth_substeps, Rng, RunSettings};
use robots::wip::diagnose::WipPlant;
use std::path::PathBuf;

/// Generate a synthetic measured log: a closed-loop run of a model with hidden effects.
///
/// Simulates a closed-loop run (LQR designed on the nominal model, sums of sinusoids as speed
/// and turn references) of the model with hidden effects, with sensor noise (tilt 0.003 rad,
/// rate 0.02 rad/s, encoders 3600 counts/rev, currents 0.02 A, pose 1 mm / 0.005 rad at 50
/// Hz), and writes it as a measured log DIR/log.csv that `wip diagnose` reads, and the
/// hidden truth as DIR/truth.json. The effects' magnitudes are drawn from the seed in the
/// ranges of docs/diagnose.md.
#[derive(clap::Args)]
pub struct GenerateArgs {
    /// An effect of the catalogue, two different ones joined by '+', or none
    #[arg(long, value_name = "NAME[+NAME]", default_value = "none")]
    effect: String,
    /// Random seed
    #[arg(long, value_name = "N", default_value = "1")]
    seed: u64,
    /// Length of the log in seconds, in [1, 3600]
    #[arg(long, value_name = "SECONDS", default_value = "30", allow_negative_numbers = true, value_parser = duration)]
    duration: f64,
    /// JSON parameter file of the model (docs/formats.md)
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
}

fn duration(s: &str) -> Result<f64, String> {
    let v = crate::common::positive_number(s)?;
    if (1.0..=3600.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("the duration must be in [1, 3600] s, got {v}"))
    }
}

/// The effects named by `--effect`: known names, none repeated.
fn parse_effects(spec: &str) -> Result<Vec<Effect>, Failure> {
    if spec == "none" {
        return Ok(Vec::new());
    }
    let mut effects: Vec<Effect> = Vec::new();
    for name in spec.split('+').map(str::trim) {
        let e = Effect::from_name(name).ok_or_else(|| {
            usage_error(
                "generate",
                format!(
                    "unknown effect '{name}' (expected one of: {})",
                    Effect::ALL.map(|e| e.name()).join(", ")
                ),
            )
        })?;
        if effects.contains(&e) {
            return Err(usage_error(
                "generate",
                format!("--effect names '{name}' twice: each effect is applied once"),
            ));
        }
        effects.push(e);
    }
    Ok(effects)
}

pub fn run(a: GenerateArgs) -> Result<(), Failure> {
    let names = parse_effects(&a.effect)?;
    let p = load_params(a.params.as_deref())?;
    let mut files = OutputSet::create(&a.out)?;
    // The magnitudes come from their own stream so that the run (reference, noise) does not
    // change with the effect.
    let mut rng = Rng::new(a.seed.wrapping_add(1000));
    let effects: Vec<(Effect, Vec<f64>)> = names
        .iter()
        .map(|&e| (e, draw_effect(e, &p, &mut rng)))
        .collect();
    let mut settings = RunSettings {
        duration: a.duration,
        ..Default::default()
    };
    settings.substeps = truth_substeps(&p, &effects, &settings)?;
    let g = generate(&p, &effects, a.seed, &settings)?;
    let plant = WipPlant::new(p);
    files.write(
        "log.csv",
        g.log.to_csv(plant.channels(), plant.inputs()).as_bytes(),
    )?;
    let truth: Vec<serde_json::Value> = effects
        .iter()
        .map(|(e, theta)| {
            let mut m = serde_json::Map::new();
            for (n, v) in e.parameter_names().iter().zip(theta) {
                m.insert((*n).to_string(), serde_json::json!(v));
            }
            serde_json::json!({ "effect": e.name(), "parameters": m })
        })
        .collect();
    let json = serde_json::to_string_pretty(&serde_json::json!({
        "seed": a.seed, "duration_s": a.duration, "h": settings.h, "effects": truth
    }))
    .map_err(|e| format!("truth.json: {e}"))?;
    files.write("truth.json", (json + "\n").as_bytes())?;
    files.commit()?;
    say!(
        "generated {} rows ({} s) with {}; wrote {}/{{log.csv, truth.json}}",
        g.log.len(),
        a.duration,
        if effects.is_empty() {
            "no hidden effect".to_string()
        } else {
            a.effect.clone()
        },
        a.out.display()
    );
    Ok(())
}
