//! "Arrive at rest" means rest: a midpoint plan of the steered car without damping (so
//! nothing but the plan's end state holds it), replayed through the integrator and continued
//! for 2 s with zero input, stays where it ended; and the midpoint plan's objective converges
//! to the Runge–Kutta plan's at a fine step (at first order: below).

use crate::steered_car_bounds::{hermite_path, ParkDiagonal};
use dmech::continuous::RungeKutta;
use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Solver, Status};
use dmech_ocp::toolkit::replay::replay;
use dmech_ocp::transcription::{PlannedTrajectory, RkTranscription, VarIntTranscription};
use dmech_tests::SteeredCar;
use nalgebra::SVector;

const DURATION: f64 = 5.0;

fn problem(n: usize) -> ParkDiagonal {
    ParkDiagonal {
        n,
        drive_torque: 0.05,
        quartic: 0.0,
        steer_price: 0.0,
        declares_constant: true,
    }
}

fn tight() -> IpOptions {
    IpOptions {
        tol: 1e-10,
        constr_viol_tol: 1e-12,
        ..IpOptions::default()
    }
}

/// The midpoint plan at `n` steps: its trajectory and objective.
fn midpoint_plan(car: &SteeredCar, n: usize) -> (PlannedTrajectory<3, 2, 2>, f64) {
    let h = DURATION / n as f64;
    let tr = VarIntTranscription::new(car, problem(n), h, Discretisation::Midpoint);
    let (xs, ws) = tr
        .start_from_path(
            &hermite_path(n),
            &SVector::zeros(),
            &SVector::<f64, 2>::new(1e-4, 1e-6),
        )
        .expect("a kinematic start");
    let solver = Solver::new(&tr, tight());
    let r = solver.solve(solver.initial_iterate(xs, ws));
    assert_eq!(r.status, Status::Solved, "midpoint plan at {n} steps");
    (tr.trajectory(&r.iterate), r.objective)
}

#[test]
fn a_midpoint_plan_that_ends_at_rest_stays_at_rest() {
    let car = SteeredCar::new(0.0, [0.0, 0.0]);
    let n = 250;
    let h = DURATION / n as f64;
    let (plan, _) = midpoint_plan(&car, n);
    let rest_steps = (2.0 / h).round() as usize;
    let r = replay(&car, h, Discretisation::Midpoint, &plan, rest_steps).expect("replay");
    println!(
        "replay: {:.1e} from the plan, {:.1e} of drift in 2 s after it",
        r.plan_deviation, r.drift_after
    );
    assert!(
        r.drift_after <= 1e-9,
        "the car moved on by {:.2e} after the plan",
        r.drift_after
    );
    // The replay follows the plan to the solver's tolerance (1e-12) times the motion's
    // sensitivity over 250 steps.
    assert!(
        r.plan_deviation <= 1e-7,
        "replay off the plan by {:.2e}",
        r.plan_deviation
    );
}

/// `h·J` of the midpoint plans at 20, 10, 5 ms against the RK4 plan at 2.5 ms (whose own
/// error, O(h⁴) of a smooth optimum, is far below the midpoint's at 5 ms). The order is one,
/// not two: rest with zero input afterwards needs the last interval at rest with zero input
/// (`v_{N−1} = 0`, `u_{N−1} = 0`, `dmech_ocp::transcription::conditions_for_scheme`), so the
/// plan reaches its end one step early, an O(h) change of the horizon. The second-order
/// condition is the end's discrete Legendre transform `p_N⁺ = 0`, which leaves `v_{N−1}`
/// free (docs/ocp.md); this test holds the first order the transcription has.
#[test]
fn the_midpoint_objective_converges() {
    let car = SteeredCar::new(0.0, [0.0, 0.0]);
    let n_fine = 2000;
    let h_fine = DURATION / n_fine as f64;
    let rk = RkTranscription::new(&car, problem(n_fine), h_fine, RungeKutta::Rk4);
    let (xs, ws) = {
        // The RK transcription starts from the midpoint plan at the same step, whose states
        // are those of the continuous motion to O(h).
        let (plan, _) = midpoint_plan(&car, n_fine);
        rk.start_from_trajectory::<3>(&plan)
    };
    let solver = Solver::new(&rk, tight());
    let r = solver.solve(solver.initial_iterate(xs, ws));
    assert_eq!(r.status, Status::Solved, "the RK4 reference");
    let reference = h_fine * r.objective;
    let errors: Vec<f64> = [250usize, 500, 1000]
        .iter()
        .map(|&n| (DURATION / n as f64 * midpoint_plan(&car, n).1 - reference).abs())
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    let shown: Vec<String> = errors.iter().map(|e| format!("{e:.3e}")).collect();
    println!("h·J against RK4's {reference:.9}: errors {shown:?}, orders {orders:.3?}");
    assert!(orders.iter().all(|p| *p >= 0.95), "orders {orders:.3?}");
}
