//! The MPC's QPs of a real `wip track --controller mpc` run, written to a file, and our
//! interior point timed on such a file (the Rust side of `scripts/peers/mpc_qp/`).
//!
//! ```text
//! mpc_qps dump PLAN_DIR OUT.qps [--seed N] [--from K] [--count N] [--stride S]
//! mpc_qps time FILE.qps [--rounds R] [--start-mu MU] > ours.json
//! ```
//! `dump` runs the closed loop along `PLAN_DIR/trajectory.csv` (nominal plant, the paper's
//! sensors, seed `N`, default 1), records every sample's QP and writes those of samples
//! `K, K+S, …` (`count` of them; default all) in `dmech_ocp::qp`'s text form, and prints the
//! loop's own per-sample QP times (median, 99th percentile, largest; thread CPU and wall
//! clock). `time` solves every QP of a file with the MPC's settings (`mpc::qp_settings`;
//! another cold start's `μ0` by `--start-mu`) `R` times (default 5) cold, and once more
//! warm from the previous QP's solution shifted by a stage (meaningful for a file of
//! consecutive samples, stride 1), and prints per QP the median time (s) over the rounds,
//! the iterations and `δu_0`.

use dmech_ocp::qp::{QpSolver, QpStatus};
use robots::wip::track::closed_loop::{track, TrackConfig};
use robots::wip::track::monte_carlo::quantile;
use robots::wip::track::mpc::{qp_settings, MpcController, MpcQp};
use robots::wip::track::observer::SensorModel;
use robots::wip::track::report::read_plan;
use robots::wip::WipParams;
use std::path::PathBuf;
use std::time::Instant;

fn flag(args: &[String], name: &str, default: usize) -> usize {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |v| v.parse().expect("a whole number"))
}

/// The number after `name`, if given.
fn number(args: &[String], name: &str) -> Option<f64> {
    let at = args.iter().position(|a| a == name)?;
    Some(args.get(at + 1)?.parse().expect("a number"))
}

fn dump(args: &[String]) {
    let (dir, out) = (PathBuf::from(&args[0]), PathBuf::from(&args[1]));
    let (seed, from) = (flag(args, "--seed", 1), flag(args, "--from", 0));
    let (count, stride) = (flag(args, "--count", usize::MAX), flag(args, "--stride", 1));
    let plan = read_plan(&dir.join("trajectory.csv"), 1_000_000, "").expect("a plan");
    let p = WipParams::default();
    let mpc = MpcController::design(&p, &plan)
        .expect("an MPC design")
        .recording();
    let cfg = TrackConfig {
        plant: p,
        nominal: p,
        sensors: SensorModel::paper(),
        seed: seed as u64,
        push: None,
    };
    let run = track(&plan, &mpc, &cfg, |_| {}).expect("a closed loop");
    let mut text = String::new();
    let calls = mpc.recorded();
    let mut written = 0;
    for c in calls.iter().skip(from).step_by(stride.max(1)).take(count) {
        text += &mpc
            .stage_qp(c.k, &c.e0, c.u_prev)
            .expect("a valid QP")
            .to_text();
        written += 1;
    }
    std::fs::write(&out, text).expect("the file written");
    eprintln!(
        "{written} QPs of {} samples (seed {seed}, fell: {}) written to {}",
        calls.len(),
        run.fell_at.is_some(),
        out.display()
    );
    // The loop's own per-sample QP times (the QP built and solved as the MPC does).
    let ms = |v: &[f64], q: f64| 1e3 * quantile(v, q);
    for (what, v) in [("CPU", &run.qp_solve_s), ("wall", &run.qp_wall_s)] {
        eprintln!(
            "per-sample QP time in the loop, {what}: median {:.4} ms, p99 {:.4} ms, largest {:.4} ms",
            ms(v, 0.5),
            ms(v, 0.99),
            ms(v, 1.0)
        );
    }
}

fn time(args: &[String]) {
    let text = std::fs::read_to_string(&args[0]).expect("a QP file");
    let qps = MpcQp::all_from_text(&text).expect("QPs in the text form");
    let rounds = flag(args, "--rounds", 5).max(1);
    // The MPC's settings, or another start.
    let mut settings = qp_settings();
    if let Some(mu0) = number(args, "--start-mu") {
        settings.start_mu = mu0;
    }
    let mut solver = QpSolver::new(settings);
    // Set-up as the MPC does it, each time: the QP built (validated) from its parts.
    let parts = |qp: &MpcQp| (*qp.x0(), qp.stages().to_vec(), qp.terminal().clone());
    let mut cold = Vec::new();
    for qp in &qps {
        let mut times = Vec::with_capacity(rounds);
        let mut last = None;
        for _ in 0..rounds {
            let (x0, stages, terminal) = parts(qp);
            let t0 = Instant::now();
            let qp = MpcQp::new(x0, stages, terminal).expect("a valid QP");
            let sol = solver.solve(&qp);
            times.push(t0.elapsed().as_secs_f64());
            last = Some(sol);
        }
        times.sort_by(f64::total_cmp);
        cold.push((times[rounds / 2], last.expect("one round at least")));
    }
    let mut warm = Vec::new();
    let mut previous: Option<dmech_ocp::qp::QpSolution<10, 2, 5>> = None;
    for qp in &qps {
        let (x0, stages, terminal) = parts(qp);
        let t0 = Instant::now();
        let qp = MpcQp::new(x0, stages, terminal).expect("a valid QP");
        let sol = match &previous {
            Some(p) => solver.solve_warm(&qp, &p.shifted()),
            None => solver.solve(&qp),
        };
        warm.push((t0.elapsed().as_secs_f64(), sol.clone()));
        previous = Some(sol);
    }
    let record = |runs: &[(f64, dmech_ocp::qp::QpSolution<10, 2, 5>)]| {
        serde_json::json!({
            "time_s": runs.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
            "iterations": runs.iter().map(|(_, s)| s.info.iterations).collect::<Vec<_>>(),
            "solved": runs.iter().map(|(_, s)| s.status == QpStatus::Solved).collect::<Vec<_>>(),
            "u0": runs.iter().map(|(_, s)| [s.u[0][0], s.u[0][1]]).collect::<Vec<_>>(),
            "objective": runs.iter().map(|(_, s)| s.info.objective).collect::<Vec<_>>(),
        })
    };
    let out = serde_json::json!({
        "qps": qps.len(),
        "rounds": rounds,
        "cold": record(&cold),
        "warm": record(&warm),
    });
    println!("{out}");
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("dump") if args.len() >= 3 => dump(&args[1..]),
        Some("time") if args.len() >= 2 => time(&args[1..]),
        _ => {
            eprintln!(
                "usage: mpc_qps dump PLAN_DIR OUT.qps [--seed N] [--from K] [--count N] \
                 [--stride S] | mpc_qps time FILE.qps [--rounds R] [--start-mu MU]"
            );
            std::process::exit(2);
        }
    }
}
