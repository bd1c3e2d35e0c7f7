//! `params_refit.json`: the refitted model in the parameter-file format that
//! `wip plan/simulate --params` read (a JSON object of the model's keys, SI). The robot's
//! own parameters that the diagnosis moved (a calibration, the friction and payload
//! effects) go into it; the other effects (sensor offset and filter, floor slope, delay,
//! voltage gain, dead zone, unequal wheels, stick-slip, backlash) are not parameters of the
//! paper's model and are listed for the report instead.

use super::effects::{Effect, CALIBRATED};
use super::plant::WipPlant;
use crate::diagnose::{Diagnosis, Plant};
use crate::wip::WipParams;

/// The parameters of the refitted model, and the named effects the file cannot hold.
pub fn refit_params(plant: &WipPlant, d: &Diagnosis) -> (WipParams, Vec<Effect>) {
    let mut q = plant.params;
    if d.cause == "none" || d.cause == "unexplained" {
        return (q, Vec::new());
    }
    let cat = plant.catalogue();
    for (key, v) in q.named_mut() {
        if CALIBRATED.contains(&key) {
            if let Some(i) = cat.param_index(key) {
                *v = d.chosen.fit.theta[i];
            }
        }
    }
    let left_out = d
        .effects
        .iter()
        .filter_map(|&e| Effect::at(e))
        .filter(|e| !matches!(e, Effect::Friction | Effect::Payload))
        .collect();
    (q, left_out)
}

/// The parameter file's text: every key of [`WipParams`], nothing else.
pub fn params_file_json(p: &WipParams) -> String {
    p.to_json()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file reads back as the same parameters (the keys are exactly the model's).
    #[test]
    fn params_file_reads_back() {
        let p = WipParams {
            d_c: 0.0123,
            m_b: 0.345,
            ..Default::default()
        };
        let q = WipParams::from_json_str(&params_file_json(&p)).unwrap();
        assert_eq!(p, q);
    }
}
