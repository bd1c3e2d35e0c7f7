//! What `wip diagnose` says about an effect it does not know: closed-loop logs of the TRUE
//! model with an effect hidden, diagnosed with that effect (and its nearest relatives) left
//! out of the catalogue. The verdict must be `unexplained` and the failing channels must
//! include a wheel channel. That the conditions the residual follows name where the effect
//! acts (the commanded voltage or the wheel speed near zero for a dead zone, the wheel
//! speed for stick-slip friction) is required too, in the conditions of the chosen
//! model's residual or of the nominal model's.

use robots::diagnose::{diagnose, DiagnoseOptions, Plant};
use robots::wip::diagnose::effects::Effect;
use robots::wip::diagnose::generate::{generate, Rng, RunSettings};
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::WipParams;

/// Stick-slip friction (static torque twice the Coulomb level, Stribeck speed 0.3 rad/s:
/// inside the generator's ranges) with every friction-like effect left out. The wheel
/// angles' level must be found to follow the wheel speed near zero: inside a window the
/// slow and fast rows hardly differ (paired `t` 1.3–1.7 on 11 windows), between windows
/// the level follows the fraction of slow rows (docs/diagnose.md §4d).
#[test]
fn hidden_stick_slip_is_unexplained_with_its_conditions() {
    let p = WipParams::default();
    hidden_is_unexplained(
        (Effect::StickSlip, vec![2.0 * p.d_c, 0.3]),
        20261127,
        &["stick_slip", "friction", "dead_zone", "gear_backlash"],
        &["wheel speed"],
    );
}

/// The dead-zone log, requiring the conditions to be named. The chosen
/// `voltage_gain + tilt_filter` leaves E 7.5 whose level varies from window to window
/// (9–276 × σ²) with no condition above the critical value; the nominal model's residual,
/// the signature of what the model lacks, follows the wheel speed near zero.
#[test]
fn hidden_dead_zone_names_its_conditions() {
    hidden_is_unexplained(
        (Effect::DeadZone, vec![0.35]),
        20261124,
        &["dead_zone", "friction", "stick_slip"],
        &["voltage", "near zero"],
    );
}

/// Generate a 10 s run with `hidden`, diagnose it with `exclude` left out, and require
/// `unexplained`, a wheel channel failing, no parameter outside its physical range, and
/// a condition whose words contain one of `where_` (after or before).
fn hidden_is_unexplained(
    hidden: (Effect, Vec<f64>),
    master: u64,
    exclude: &[&str],
    where_: &[&str],
) {
    let p = WipParams::default();
    let seed = Rng::new(master).next_u64();
    let settings = RunSettings {
        duration: 10.0,
        ..Default::default()
    };
    let g = generate(&p, &[hidden], seed, &settings).expect("the nominal LQR keeps the robot up");
    let opts = DiagnoseOptions {
        exclude: exclude.iter().map(|s| s.to_string()).collect(),
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
        .chain(&d.conditions_before)
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
            .chain(&d.conditions_before)
            .any(|c| where_.iter().any(|w| c.condition.contains(w))),
        "{conds:?}"
    );
    let implausible = d
        .chosen
        .fit
        .candidate
        .implausible(plant.catalogue(), &d.chosen.fit.theta);
    assert!(implausible.is_empty(), "{implausible:?}");
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
