//! The restart of a fit's outlying windows (`Fitter::restart_outliers`): on a log with
//! stick-slip friction, every window starts from its true state except one, put in the
//! wrong basin (its wheels spun up against the readings, so that they slip where the truth
//! sticks). The restart must find that window, and only it, and bring its cost back to
//! what the true state gives: at most the true state's cost plus three standard deviations
//! of a window's χ² cost (`3·sqrt(2 m_w)` for `m_w` residuals), since the restarted state
//! minimises the same cost the true state only samples.

use robots::diagnose::fit::{FitSetup, Fitter};
use robots::diagnose::Plant;
use robots::wip::diagnose::effects::{Effect, Layout};
use robots::wip::diagnose::generate::{generate, Rng, RunSettings, SensorNoise};
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::WipParams;

#[test]
fn a_window_in_the_wrong_basin_is_restarted_to_the_truth() {
    let p = WipParams::default();
    let plant = WipPlant::new(p);
    let cat = plant.catalogue();
    let hidden = vec![(Effect::StickSlip, vec![2.0 * p.d_c, 0.3])];
    let settings = RunSettings {
        duration: 4.0,
        ..Default::default()
    };
    let seed = Rng::new(20261126).next_u64();
    let g = generate(&p, &hidden, seed, &settings).expect("the robot stays up");
    let theta = Layout::new(cat, &p).theta_with(cat, &hidden);
    let noise = SensorNoise::default();
    let setup = FitSetup {
        first_row: plant.history(g.log.h),
        window: (0.5 / g.log.h).round() as usize,
        sigma: Channel::ALL.iter().map(|&c| noise.sigma(c)).collect(),
        threads: 2,
        max_iterations: 15,
    };
    let fitter = Fitter::new(&plant, &g.log, setup);
    let truth: Vec<Vec<f64>> = fitter
        .windows
        .iter()
        .map(|&(s, _)| g.states[s].to_vec())
        .collect();
    let (cost_true, m) = fitter.cost(&theta, &truth).expect("the truth simulates");

    // Nothing stands out at the truth.
    let mut z = truth.clone();
    assert_eq!(fitter.restart_outliers(&theta, &mut z), 0);

    let bad = fitter.windows.len() / 2;
    z[bad][7] += 3.0;
    z[bad][8] -= 3.0;
    let (cost_bad, _) = fitter.cost(&theta, &z).expect("the wrong state simulates");
    assert!(
        cost_bad > 10.0 * cost_true,
        "{cost_bad} against {cost_true}"
    );

    assert_eq!(fitter.restart_outliers(&theta, &mut z), 1);
    for (w, (a, b)) in z.iter().zip(&truth).enumerate() {
        if w != bad {
            assert_eq!(a, b, "window {w} moved");
        }
    }
    let (cost_after, _) = fitter.cost(&theta, &z).expect("the restart simulates");
    let m_window = m as f64 / fitter.windows.len() as f64;
    let bound = cost_true + 3.0 * (2.0 * m_window).sqrt();
    assert!(
        cost_after <= bound,
        "restarted cost {cost_after:.1} above {bound:.1} (truth {cost_true:.1})"
    );
}
