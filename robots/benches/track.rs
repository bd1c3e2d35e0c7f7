//! A 30 s closed loop of `wip track` on one core: the eight planned at h = 20 ms (21.2 s),
//! then 8.8 s of balancing at its end point; LQ feedback, the paper's sensor model (noise,
//! 50-Hz poses arriving late), the nominal plant by RK4 with 10 substeps per 5-ms sample.
//! Real-time factor = 30 s / the measured time (docs/tracking.md).
use criterion::{criterion_group, criterion_main, Criterion};
use dmech_ocp::solver::IpOptions;
use robots::wip::plan::problems;
use robots::wip::plan::report::reduced_trajectory;
use robots::wip::plan::{plan, CurrentModel, PlanBounds};
use robots::wip::simulate::Trajectory;
use robots::wip::track::closed_loop::{track, TrackConfig};
use robots::wip::track::lq::LqController;
use robots::wip::track::observer::SensorModel;
use robots::wip::{Wip, WipParams};
use std::hint::black_box;

/// Closed-loop duration (s).
const DURATION: f64 = 30.0;

/// The eight at 20 ms, held at its final (rest) state up to [`DURATION`].
fn reference() -> Trajectory {
    let wip = Wip::default();
    let problem = problems::by_name("eight", 0.02).expect("built in");
    let opts = IpOptions {
        verbose: false,
        ..Default::default()
    };
    let o = plan(
        &wip,
        &problem,
        PlanBounds::default(),
        dmech::Integrator::FirstOrder,
        CurrentModel::Dynamic,
        opts,
    );
    assert!(
        matches!(o.status, dmech_ocp::solver::Status::Solved),
        "the eight at 20 ms: {:?}",
        o.status
    );
    let mut traj = reduced_trajectory(&wip, &o);
    let (x_end, t_end) = (*traj.x.last().unwrap(), *traj.t.last().unwrap());
    let mut t = t_end;
    while t < DURATION - 1e-9 {
        t = (t + 0.02).min(DURATION);
        traj.t.push(t);
        traj.x.push(x_end);
        traj.u.push([0.0, 0.0]);
    }
    traj
}

fn bench(c: &mut Criterion) {
    let traj = reference();
    let nominal = WipParams::default();
    let lq = LqController::design(&nominal).expect("the DARE solves");
    let cfg = TrackConfig {
        plant: nominal,
        nominal,
        sensors: SensorModel::paper(),
        seed: 1,
        push: None,
    };
    let run = track(&traj, &lq, &cfg, |_| {}).expect("the loop runs");
    assert!(run.fell_at.is_none(), "the benchmark's loop fell");
    let mut grp = c.benchmark_group("closed loop");
    grp.sample_size(10);
    grp.bench_function("30 s, LQ, paper sensors", |b| {
        b.iter(|| track(black_box(&traj), &lq, &cfg, |_| {}).unwrap())
    });
    grp.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
