//! What `wip diagnose` says about an effect it does not know: a closed-loop log of the TRUE
//! model with a dead zone in the drivers, diagnosed with the dead zone (and Coulomb
//! friction, its nearest relative) left out of the catalogue. The verdict must be
//! `unexplained`, the failing channels must include a wheel channel, and the conditions
//! that the residual follows must name the commanded voltage or the wheel speed near
//! zero: that is where a dead zone acts.

use robots::diagnose::{diagnose, DiagnoseOptions, Plant};
use robots::wip::diagnose::effects::Effect;
use robots::wip::diagnose::generate::{generate, Rng, RunSettings};
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::WipParams;

#[test]
fn a_hidden_dead_zone_is_unexplained_with_its_conditions() {
    let p = WipParams::default();
    let seed = Rng::new(20261124).next_u64();
    let settings = RunSettings {
        duration: 10.0,
        ..Default::default()
    };
    // 0.35 V: inside the generator's dead-zone range (0.2–0.5 V).
    let g = generate(&p, &[(Effect::DeadZone, vec![0.35])], seed, &settings)
        .expect("the nominal LQR keeps the robot up");
    let opts = DiagnoseOptions {
        exclude: vec!["dead_zone".into(), "friction".into()],
        ..Default::default()
    };
    let plant = WipPlant::new(p);
    let d = diagnose(&plant, &g.log, &opts, &|_| {}).unwrap();
    let name = |c: usize| Channel::ALL[c].name();
    let failing: Vec<&str> = d
        .tests_after
        .iter()
        .filter(|t| !t.passes())
        .map(|t| name(t.channel))
        .collect();
    let conds: Vec<String> = d
        .conditions
        .iter()
        .map(|c| {
            format!(
                "{} {} {} z {:.1}",
                name(c.channel),
                c.condition,
                c.measure,
                c.z
            )
        })
        .collect();
    println!(
        "seed {seed}: cause {} ({}), E {:.3} -> {:.3}; failing {failing:?}\n{}",
        d.cause,
        d.chosen.fit.candidate.name(plant.catalogue()),
        d.error_before,
        d.error_after,
        conds.join("\n")
    );
    assert_eq!(d.cause, "unexplained", "{}", d.verdict);
    assert!(
        failing
            .iter()
            .any(|c| c.starts_with("phi") || c.starts_with('i')),
        "a wheel channel fails: {failing:?}"
    );
    assert!(
        d.conditions
            .iter()
            .any(|c| c.condition.contains("voltage") || c.condition.contains("near zero")),
        "{conds:?}"
    );
}

/// The first case: a small systematic sensor error, 1.2 × the tilt's noise in RMS
/// (a 2 Hz sinusoid of amplitude `√(2·0.44)·σ_α` on the tilt reading, σ_α = 0.003 rad),
/// moves the overall error by a few percent only; over thousands of samples the
/// per-channel tests must see it: the verdict is not `none` and the tilt fails.
#[test]
fn a_small_systematic_error_over_a_long_log_is_not_none() {
    let p = WipParams::default();
    let seed = Rng::new(20261125).next_u64();
    let settings = RunSettings {
        duration: 10.0,
        ..Default::default()
    };
    let mut g = generate(&p, &[], seed, &settings).expect("the nominal LQR keeps the robot up");
    let a = (2.0f64 * 0.44).sqrt() * 0.003;
    let alpha = Channel::Alpha.index();
    for k in 0..g.log.len() {
        let t = g.log.t[k];
        g.log.row_mut(k)[alpha] += a * (std::f64::consts::TAU * 2.0 * t).sin();
    }
    let plant = WipPlant::new(p);
    let d = diagnose(&plant, &g.log, &DiagnoseOptions::default(), &|_| {}).unwrap();
    let alpha_test = d.tests_before.iter().find(|t| t.channel == alpha).unwrap();
    println!(
        "seed {seed}: cause {}, E {:.3} -> {:.3}; alpha {alpha_test:?}",
        d.cause, d.error_before, d.error_after
    );
    assert_ne!(d.cause, "none", "{}", d.verdict);
    assert!(!alpha_test.passes(), "{alpha_test:?}");
}
