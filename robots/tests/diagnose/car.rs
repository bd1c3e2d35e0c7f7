//! The car's recovery matrix (`car generate` → `car diagnose` through the library): each
//! hidden effect of its catalogue, own and generic, in a log driven by the parallel-park
//! plan's commands, is named with its parameter within 3 reported standard deviations,
//! and a log without effect gives `none`. On the lane change, which never reverses, a
//! constant drive friction and a negative drive-voltage offset act alike: the verdict names
//! one and the other as indistinguishable. The car's prediction is `SystemPlant`'s,
//! derived from the car's `ℓ`, connection and forcing.

use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Status};
use robots::car::diagnose::{car_plant, generate};
use robots::car::plan::{plan, CarBounds};
use robots::car::problems::CarProblem;
use robots::car::{Car, CarParams};
use robots::diagnose::{diagnose, DiagnoseOptions, Plant};

fn planned(name: &str) -> dmech_ocp::transcription::PlannedTrajectory<3, 3, 2> {
    let problem = CarProblem::load(name).unwrap();
    let opts = IpOptions {
        verbose: false,
        ..IpOptions::default()
    };
    let o = plan(
        &Car::default(),
        &problem,
        CarBounds::default(),
        0.02,
        Discretisation::FirstOrder,
        opts,
    )
    .unwrap();
    assert_eq!(o.status, Status::Solved);
    o.trajectory
}

/// Hide `(effect, value)`, diagnose; `(cause, estimate, σ)` of the effect's parameter.
fn recover(
    traj: &dmech_ocp::transcription::PlannedTrajectory<3, 3, 2>,
    effect: Option<(&str, f64)>,
    seed: u64,
) -> (String, Vec<String>, f64, f64, f64) {
    let hidden: Vec<(String, f64)> = effect.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let (log, theta) = generate(CarParams::default(), traj, &hidden, seed).unwrap();
    let plant = car_plant(CarParams::default(), log.h);
    let opts = DiagnoseOptions {
        threads: 2,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let d = diagnose(&plant, &log, &opts, &|l| eprintln!("{l}")).unwrap();
    println!(
        "{:?}: {} ({:.1} s)",
        effect,
        d.verdict,
        t0.elapsed().as_secs_f64()
    );
    let Some((name, _)) = effect else {
        return (d.cause.clone(), d.alternatives.clone(), 0.0, 0.0, 0.0);
    };
    let cat = plant.catalogue();
    let i = cat.effects[cat.effect_index(name).unwrap()].params[0];
    (
        d.cause.clone(),
        d.alternatives.clone(),
        d.chosen.fit.theta[i],
        d.chosen.fit.std[i],
        theta[i],
    )
}

#[test]
fn the_car_recovery_matrix() {
    let traj = planned("parallel-park");
    let cases = [
        ("drive_friction", 0.005),
        ("steering_friction", 0.001),
        ("reading_offset:yaw_rate", 0.03),
        ("reading_offset:steer", 0.02),
        ("input_gain:u_d", 0.9),
        ("input_offset:u_d", 0.05),
        ("reading_scale:wheel", 1.03),
    ];
    let mut failures = Vec::new();
    for (k, (name, value)) in cases.into_iter().enumerate() {
        let (cause, _, est, sd, truth) = recover(&traj, Some((name, value)), 100 + k as u64);
        println!("{name}: named {cause}, true {truth} est {est} ± {sd}");
        if cause != name || (est - truth).abs() > 3.0 * sd {
            failures.push(format!(
                "{name}: named {cause}, {est} ± {sd} against {truth}"
            ));
        }
    }
    let (cause, ..) = recover(&traj, None, 99);
    if cause != "none" {
        failures.push(format!("no effect: named {cause}"));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn a_drive_friction_on_a_forward_only_manoeuvre_is_told_alike_to_a_voltage_offset() {
    let traj = planned("lane-change");
    let (cause, alternatives, ..) = recover(&traj, Some(("drive_friction", 0.004)), 5);
    let pair = ["drive_friction", "input_offset:u_d"];
    assert!(pair.contains(&cause.as_str()), "named {cause}");
    let other = pair.iter().find(|&&n| n != cause).unwrap();
    assert!(
        alternatives.iter().any(|a| a == other),
        "{cause} named without {other} as alternative: {alternatives:?}"
    );
}
