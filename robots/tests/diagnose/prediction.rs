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
use robots::wip::diagnose::prediction::MAX_SUBSTEP;
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

/// The plant's window key (`Plant::window_key`) with a reversal lockout: wherever two grid
/// values of `lockout_s` give a window the same key, the window's predictions under them
/// are the same bit for bit, in values and in dual derivatives with respect to the state
/// (what the lockout scan shares between them). And the key tells values apart: some
/// windows have several keys over the grid, and some keys are shared.
#[test]
fn windows_with_equal_lockout_keys_predict_alike() {
    use num_dual::DualSVec64;
    let p = WipParams::default();
    let plant = WipPlant::new(p);
    let cat = plant.catalogue();
    let layout = Layout::new(cat, &p);
    let settings = RunSettings {
        duration: 6.0,
        ..Default::default()
    };
    let truth = vec![(Effect::ReversalLockout, vec![0.0637])];
    let g = generate(&p, &truth, 11, &settings).expect("the robot stays up");
    let lockout = cat
        .params
        .iter()
        .position(|s| s.name == "lockout_s")
        .expect("the catalogue has the lockout");
    let grid = cat.params[lockout].start_grid.clone();
    assert!(grid.len() > 2, "the lockout has a scan grid");
    let h = g.log.h;
    let window = (0.5 / h).round() as usize;
    let (mut shared, mut split) = (0usize, 0usize);
    let mut start = plant.history(h);
    while start + window <= g.log.len() {
        let z = &g.states[start];
        let zd: Vec<DualSVec64<2>> = z
            .iter()
            .enumerate()
            .map(|(i, &v)| match i {
                3 => DualSVec64::from(v).derivative(0),
                6 => DualSVec64::from(v).derivative(1),
                _ => DualSVec64::from(v),
            })
            .collect();
        let mut seen: Vec<(Vec<f64>, Vec<f64>, Vec<DualSVec64<2>>)> = Vec::new();
        for &t in &grid {
            let mut theta = layout.theta_with(cat, &[]);
            theta[lockout] = t;
            let key = plant.window_key(&g.log, start, window, &theta);
            let y = plant.predict(&g.log, start, window, z, &theta);
            let thd: Vec<DualSVec64<2>> = theta.iter().map(|&v| DualSVec64::from(v)).collect();
            let yd = plant.predict(&g.log, start, window, &zd, &thd);
            let (y, yd) = (y.expect("predicts"), yd.expect("predicts"));
            match seen.iter().find(|(k, _, _)| *k == key) {
                Some((_, y0, yd0)) => {
                    shared += 1;
                    assert!(
                        y0.iter().zip(&y).all(|(a, b)| a.to_bits() == b.to_bits()),
                        "window at {start}: T = {t} has a shared key and other values"
                    );
                    let bits = |d: &DualSVec64<2>| {
                        let e = d
                            .eps
                            .unwrap_generic(nalgebra::Const::<2>, nalgebra::Const::<1>);
                        [d.re.to_bits(), e[0].to_bits(), e[1].to_bits()]
                    };
                    assert!(
                        yd0.iter().zip(&yd).all(|(a, b)| bits(a) == bits(b)),
                        "window at {start}: T = {t} has a shared key and other derivatives"
                    );
                }
                None => seen.push((key, y, yd)),
            }
        }
        split += usize::from(seen.len() > 1);
        start += window;
    }
    assert!(shared > 0, "no window shares a key between grid values");
    assert!(split > 0, "no window tells grid values apart");
}

/// The prediction's derivative with respect to the input delay, in dual numbers, against
/// one-sided finite differences, at delays of 0, 1 and 3 whole samples (where the step's
/// split at the driver's switch leaves a piece of no length, which must still carry the
/// derivative) and at 2.4 samples. Per reading of each window, from the true states of a
/// log with a 12-ms delay, the forward difference `D(δ) = (y(τ + δ) − y(τ))/δ` differs from
/// the derivative by `y''δ/2 + O(δ²)`, and `D(2δ) − D(δ) = y''δ/2 + O(δ²)` too: the
/// tolerance is twice that estimate (for the `O(δ²)` terms) plus the rounding of the
/// differences, `4 ε n max(|y|, 1)/δ` with `n` the Runge–Kutta steps from the window's start
/// (each rounds at `ε`, accumulated linearly). `δ = 0.1 µs`: the gear friction's
/// `tanh(d_0 w)` bends the prediction in the delay on the scale of microseconds wherever a
/// wheel's relative speed crosses zero, so at 5 µs `D(2δ) − D(δ)` is not yet the
/// truncation error (it underestimated it 50-fold); from 1 µs down `D(δ)` approaches the
/// dual derivative linearly in `δ`, as it should. The old prediction, which skipped the
/// piece of no length, missed the derivative by the rate times one (`O(1)` relative); its
/// error was `10²–10⁴` tolerances.
#[test]
fn delay_derivative_matches_finite_differences() {
    use num_dual::DualSVec64;
    let p = WipParams::default();
    let plant = WipPlant::new(p);
    let cat = plant.catalogue();
    let layout = Layout::new(cat, &p);
    let settings = RunSettings {
        duration: 3.0,
        ..Default::default()
    };
    let truth = vec![(Effect::InputDelay, vec![0.012])];
    let g = generate(&p, &truth, 7, &settings).expect("the robot stays up");
    let h = g.log.h;
    let delay = cat
        .params
        .iter()
        .position(|s| s.name == "delay_s")
        .expect("the catalogue has the delay");
    let window = (0.5 / h).round() as usize;
    let delta = 1e-7;
    let mut failures = Vec::new();
    for samples in [0.0, 1.0, 3.0, 2.4] {
        let tau = samples * h;
        let theta_at = |d: f64| {
            let mut th = layout.theta_with(cat, &truth);
            th[delay] = d;
            th
        };
        let (mut worst, mut worst_at) = (0.0f64, String::new());
        let mut start = plant.history(h);
        while start + window <= g.log.len() {
            let z = &g.states[start];
            let y = |d: f64| {
                plant
                    .predict(&g.log, start, window, z, &theta_at(d))
                    .expect("predicts")
            };
            let (y0, y1, y2) = (y(tau), y(tau + delta), y(tau + 2.0 * delta));
            let zd: Vec<DualSVec64<1>> = z.iter().map(|&v| DualSVec64::from(v)).collect();
            let thd: Vec<DualSVec64<1>> = theta_at(tau)
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    let d = DualSVec64::from(v);
                    if i == delay {
                        d.derivative(0)
                    } else {
                        d
                    }
                })
                .collect();
            let yd = plant
                .predict(&g.log, start, window, &zd, &thd)
                .expect("predicts");
            for (i, (&a, &b)) in y0.iter().zip(&y1).enumerate() {
                let c = y2[i];
                if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                    continue;
                }
                let d1 = (b - a) / delta;
                let d2 = (c - a) / (2.0 * delta);
                let dual = yd[i]
                    .eps
                    .unwrap_generic(nalgebra::Const::<1>, nalgebra::Const::<1>)[0];
                let err = (dual - d1).abs();
                let steps = ((i / 9 + 1) as f64 / MAX_SUBSTEP).ceil() + 2.0;
                let tol =
                    2.0 * (d2 - d1).abs() + 4.0 * f64::EPSILON * steps * a.abs().max(1.0) / delta;
                if err / tol > worst {
                    (worst, worst_at) = (
                        err / tol,
                        format!(
                            "reading {} of row {}: dual {dual:.6e}, D(δ) {d1:.6e}, D(2δ) {d2:.6e}",
                            i % 9,
                            start + i / 9
                        ),
                    );
                }
                if err > tol {
                    failures.push(format!(
                        "delay {samples} samples, reading {} of row {}: dual {dual:.6e}, D(δ) {d1:.6e}, D(2δ) {d2:.6e}",
                        i % 9,
                        start + i / 9
                    ));
                }
            }
            start += window;
        }
        println!(
            "delay {samples} samples: worst |dual − D(δ)| / tolerance {worst:.3} ({worst_at})"
        );
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
