//! `params_refit.json`: the refitted model in the parameter-file format that
//! `wip plan/simulate --params` read (a JSON object of the model's keys, SI). Effects that
//! are parameters of the model (friction, payload) go into it; the others (sensor offset,
//! floor slope, delay, voltage gain, dead zone, unequal wheels) are not parameters of the
//! paper's model and are listed for the report instead.

use super::effects::Effect;
use super::selection::Diagnosis;
use crate::wip::WipParams;

/// The parameters of the refitted model, and the named effects the file cannot hold.
pub fn refit_params(d: &Diagnosis, p: &WipParams) -> (WipParams, Vec<Effect>) {
    let mut q = *p;
    let mut left_out = Vec::new();
    if d.cause == "none" || d.cause == "unexplained" {
        return (q, left_out);
    }
    let mut at = 0;
    for &e in &d.chosen.fit.candidate.effects {
        let th = &d.chosen.fit.theta[at..at + e.n_params()];
        at += e.n_params();
        match e {
            Effect::Friction => {
                q.d_v = th[0];
                q.d_c = th[1];
            }
            Effect::Payload => {
                q.m_b = th[0];
                q.l = th[1];
            }
            _ => left_out.push(e),
        }
    }
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
