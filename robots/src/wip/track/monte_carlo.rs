//! Monte Carlo of the closed loop: many seeds, each with its own random error on every
//! mass, inertia and motor parameter of the plant (the controller keeps the nominal
//! design), run in parallel on `std::thread`s; and the delay-scaled sensor model of the
//! delay sweep.

use super::closed_loop::{track_with_substeps, Controller, TrackConfig, TrackError, TrackFigures};
use super::lq::SAMPLE;
use super::observer::SensorModel;
use super::simulated_robot::substeps;
use crate::wip::simulate::Trajectory;
use crate::wip::WipParams;
use dmech_lie::rng::Rng;

/// The parameters perturbed: every mass, inertia and motor parameter.
pub const PERTURBED: [&str; 13] = [
    "m_b", "I_bxx", "I_byy", "I_bzz", "m_w", "I_wxx", "I_wyy", "I_wzz", "I_m", "I_g", "k_e", "L_m",
    "R_m",
];

/// The plant of seed `seed`: each of [`PERTURBED`] times `1 + U(−rel, rel)` (`rel < 1`
/// keeps every one positive).
pub fn perturbed(nominal: &WipParams, rel: f64, seed: u64) -> WipParams {
    let mut p = *nominal;
    // A stream apart from the sensors' (which use `seed` itself).
    let mut rng = Rng::new(seed ^ 0x5e_ed0f_9a7a);
    for (name, v) in p.named_mut() {
        if PERTURBED.contains(&name) {
            *v *= 1.0 + rng.range(-rel, rel);
        }
    }
    p
}

/// The paper's sensor model with every delay (minimum, scale, maximum) scaled so that the
/// mean delay is `mean` seconds (the paper's 63 ms at factor 1).
pub fn with_mean_delay(mean: f64) -> SensorModel {
    let s = SensorModel::paper();
    SensorModel {
        delay: s.delay.scaled(mean / 0.063),
        ..s
    }
}

/// One Monte Carlo run's result.
#[derive(Clone, Debug)]
pub struct McRun {
    pub seed: u64,
    pub figures: TrackFigures,
    /// When the plant's simulation diverged (its figures are then not a result).
    pub diverged_at: Option<f64>,
}

/// Run seeds `1..=n` on `threads` threads with `controller`: plant parameter error `rel`,
/// sensors `sensors`. Every seed's plant is checked (its RK4 substeps chosen) before any
/// runs: a plant that cannot be simulated is the error, naming its seed.
pub fn monte_carlo(
    plan: &Trajectory,
    controller: Controller<'_>,
    nominal: &WipParams,
    sensors: &SensorModel,
    rel: f64,
    n: u64,
    threads: usize,
) -> Result<Vec<McRun>, TrackError> {
    let plants: Vec<(WipParams, usize)> = (1..=n)
        .map(|seed| {
            let p = perturbed(nominal, rel, seed);
            substeps(&p, &plan.x[0], SAMPLE)
                .map(|k| (p, k))
                .map_err(|e| TrackError::Seed {
                    seed,
                    source: Box::new(e),
                })
        })
        .collect::<Result<_, _>>()?;
    let next = std::sync::atomic::AtomicU64::new(1);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| loop {
                let seed = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if seed > n {
                    break;
                }
                let (plant, k) = plants[(seed - 1) as usize];
                let cfg = TrackConfig {
                    plant,
                    nominal: *nominal,
                    sensors: sensors.clone(),
                    seed,
                    push: None,
                };
                let run = track_with_substeps(plan, controller, &cfg, k, |_| {});
                let r = McRun {
                    seed,
                    diverged_at: run.diverged.as_ref().map(|(t, _)| *t),
                    figures: run.figures(),
                };
                results.lock().expect("no panics while held").push(r);
            });
        }
    });
    let mut out = results.into_inner().expect("no panics while held");
    out.sort_by_key(|r| r.seed);
    Ok(out)
}

/// The `q`-quantile (0..1) of `v` by linear interpolation between order statistics.
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    let pos = q * (s.len() - 1) as f64;
    let (i, w) = (pos.floor() as usize, pos.fract());
    if i + 1 < s.len() {
        s[i] * (1.0 - w) + s[i + 1] * w
    } else {
        s[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_sample() {
        let v = [3.0, 1.0, 2.0, 5.0, 4.0];
        assert_eq!(quantile(&v, 0.5), 3.0);
        assert_eq!(quantile(&v, 0.95), 4.8);
    }

    #[test]
    fn perturbation_stays_within_its_bound_and_spares_geometry() {
        let p = WipParams::default();
        let q = perturbed(&p, 0.1, 3);
        assert!((q.m_b / p.m_b - 1.0).abs() <= 0.1 && q.m_b != p.m_b);
        assert_eq!((q.r, q.d, q.l, q.g), (p.r, p.d, p.l, p.g));
    }
}
