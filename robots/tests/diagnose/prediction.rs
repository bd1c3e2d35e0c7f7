//! The prediction model of `wip diagnose` against the truth it must explain: for every
//! effect of the catalogue (and none), a closed-loop log of the TRUE model (dynamic current,
//! `dmech`'s generic path, fine steps) is predicted window by window from the true states
//! with the true parameters. The prediction's model error, `RMS(prediction − clean
//! reading)`, must stay below half the sensor's noise in every channel: the recovery tests
//! require the refitted error within 1.2 of the noise floor, i.e. a model error below
//! `sqrt(1.2² − 1) = 0.66` of the noise, and half leaves the rest to the fit.
//!
//! This checks the reductions of the prediction (the algebraic current with the exact
//! voltage lag and the inertia `J_e`, the stick-slip law's switching times located within a
//! step, the tilt filter's innovation form, the lost motion's quasi-static form) where the
//! recovery tests only see their sum.

use robots::diagnose::Plant;
use robots::wip::diagnose::effects::{Effect, Layout};
use robots::wip::diagnose::generate::{draw_effect, generate, Rng, RunSettings};
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::WipParams;

#[test]
fn prediction_from_the_true_state_follows_the_truth() {
    let p = WipParams::default();
    let plant = WipPlant::new(p);
    let cat = plant.catalogue();
    let layout = Layout::new(cat, &p);
    let settings = RunSettings {
        duration: 4.0,
        ..Default::default()
    };
    let mut rng = Rng::new(20261126);
    let mut failures = Vec::new();
    for effect in std::iter::once(None).chain(Effect::ALL.map(Some)) {
        let hidden: Vec<(Effect, Vec<f64>)> = effect
            .map(|e| vec![(e, draw_effect(e, &p, &mut rng))])
            .unwrap_or_default();
        let seed = rng.next_u64();
        let g = generate(&p, &hidden, seed, &settings).expect("the robot stays up");
        let theta = layout.theta_with(cat, &hidden);
        let h = g.log.h;
        let window = (0.5 / h).round() as usize;
        let first = plant.history(h);
        let mut sums = [(0.0, 0usize); 9];
        let mut start = first;
        while start + window <= g.log.len() {
            let y = plant
                .predict(&g.log, start, window, &g.states[start], &theta)
                .expect("the prediction runs");
            for j in 0..window {
                for c in Channel::ALL {
                    let i = c.index();
                    if g.log.value(start + j, i).is_some() {
                        let d = plant.channels()[i].residual(y[j * 9 + i], g.clean[start + j][i]);
                        sums[i].0 += d * d;
                        sums[i].1 += 1;
                    }
                }
            }
            start += window;
        }
        let name = effect.map_or("none", |e| e.name());
        let mut line = format!("{name:<24}");
        for c in Channel::ALL {
            let (ss, n) = sums[c.index()];
            let ratio = (ss / n as f64).sqrt() / settings.noise.sigma(c);
            line += &format!(" {} {ratio:.3}", c.name());
            if ratio > 0.5 {
                failures.push(format!(
                    "{name}: {} model error {ratio:.3} of the noise",
                    c.name()
                ));
            }
        }
        println!("{line}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
