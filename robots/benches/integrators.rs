//! One variational-integrator step of the WIP, and 20 s (4,000 steps at h = 5 ms) with the
//! VI (first-order and midpoint) and with RK4 on the continuous model. Scenario: default parameters, released at a
//! tilt of 0.05 rad with time-varying voltages: the robot falls and swings about its axle,
//! so every step does real Newton work.
use criterion::{criterion_group, criterion_main, Criterion};
use dmech::{Discretisation, Integrator, JacobianPolicy, VariationalIntegrator, ViState};
use nalgebra::SVector;
use robots::wip::simulate::{simulate, InputSchedule, Stepping};
use robots::wip::state::from_reduced;
use robots::wip::{ReducedState, Wip};
use std::hint::black_box;

fn scenario() -> (Wip, ReducedState, InputSchedule) {
    let w = Wip::default();
    let x0 = ReducedState::from_column_slice(&[0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let t: Vec<f64> = (0..=200).map(|k| k as f64 * 0.1).collect();
    let u = t
        .iter()
        .map(|&t| [2.0 * (1.3 * t).sin(), 1.5 * (0.7 * t).cos()])
        .collect();
    (w, x0, InputSchedule { t, u })
}

fn bench(c: &mut Criterion) {
    let (w, x0, inputs) = scenario();
    let (g, s, v) = from_reduced(&w.params, &x0, [0.0; 4]);
    let vi = VariationalIntegrator::new(0.005).with_discretisation(Discretisation::FirstOrder);
    let x = ViState {
        g,
        s,
        v: v + SVector::<f64, 5>::new(0.5, 3.0, 2.0, 0.2, 0.1),
    };
    let u = SVector::<f64, 2>::new(1.0, -0.5);
    c.bench_function("vi step", |b| {
        b.iter(|| vi.step(&w, black_box(&x), &u, &u).unwrap())
    });

    // RK4 is unstable on this stiff model at h = 5 ms (h·R_m/L_m = 18.75 > 2.79), so it runs
    // at h = 0.5 ms (40,000 steps), the largest round step it is stable at.
    let mut grp = c.benchmark_group("20 s simulation");
    grp.sample_size(10);
    for (name, integ, h, n) in [
        (
            "varint h=5ms, exact Jacobian at every Newton iterate",
            Stepping {
                jacobian: JacobianPolicy::Exact,
                ..Stepping::from(Integrator::FirstOrder)
            },
            0.005,
            4000,
        ),
        (
            "varint h=5ms, exact Jacobian reused across steps (default)",
            Stepping::from(Integrator::FirstOrder),
            0.005,
            4000,
        ),
        (
            "midpoint h=5ms, exact Jacobian reused across steps",
            Stepping::from(Integrator::Midpoint),
            0.005,
            4000,
        ),
        (
            "rk4 h=0.5ms",
            Stepping::from(Integrator::Rk4),
            0.0005,
            40000,
        ),
    ] {
        grp.bench_function(name, |b| {
            b.iter(|| simulate(&w, integ, h, black_box(&x0), &inputs, n).unwrap())
        });
    }
    grp.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
