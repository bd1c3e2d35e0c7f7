//! The car planned through the toolkit alone: the built-in problems solve from the generic
//! (kinematic) start, with every constraint holding on the returned plan.

use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Status};
use robots::car::plan::{plan, CarBounds};
use robots::car::problems::CarProblem;
use robots::car::Car;

fn solve(problem: &CarProblem, h: f64) -> robots::car::plan::CarOutcome {
    let opts = IpOptions {
        verbose: std::env::var("CAR_VERBOSE").is_ok(),
        ..IpOptions::default()
    };
    plan(
        &Car::default(),
        problem,
        CarBounds::default(),
        h,
        Discretisation::FirstOrder,
        opts,
    )
    .unwrap()
}

/// The solver's tolerance is 1e-8 on the scaled problem; the issue asks for 1e-9 on every
/// residual, which the interior point's last steps reach (measured 1e-12 and below).
#[test]
fn parallel_park_and_lane_change_solve_from_the_kinematic_start() {
    for problem in [CarProblem::parallel_park(), CarProblem::lane_change()] {
        let o = solve(&problem, 0.02);
        println!(
            "{}: {:?} after {} iterations, J = {:.6}, max violation {:.2e}, {:.2} s",
            problem.name, o.status, o.iterations, o.objective, o.max_violation, o.solve_time_s
        );
        assert_eq!(o.status, Status::Solved, "{}", problem.name);
        assert!(
            o.max_violation <= 1e-9,
            "{}: {:e}",
            problem.name,
            o.max_violation
        );
    }
}

/// The solver issue's stall on the car's own model: the steering-angle bound lowered below
/// the unconstrained plan's peak until it is active over much of the manoeuvre; every plan
/// solves with the default options (the steered car of
/// `dmech-ocp/tests/solver/steered_car_bounds.rs` stalled at 500 iterations with a bound active on
/// many stages).
#[test]
fn parallel_park_solves_with_the_steering_bound_active() {
    let problem = CarProblem::parallel_park();
    let plan_with = |steer_angle: f64| {
        plan(
            &Car::default(),
            &problem,
            CarBounds {
                steer_angle,
                ..CarBounds::default()
            },
            0.02,
            Discretisation::FirstOrder,
            IpOptions::default(),
        )
        .unwrap()
    };
    let peak = |o: &robots::car::plan::CarOutcome| {
        o.trajectory
            .stages
            .iter()
            .map(|s| s.shape[0].abs())
            .fold(0.0, f64::max)
    };
    let free = plan_with(CarBounds::default().steer_angle);
    assert_eq!(free.status, Status::Solved);
    let phi_free = peak(&free);
    let mut j_prev = free.objective;
    for fraction in [0.8, 0.6, 0.4] {
        let bound = fraction * phi_free;
        let o = plan_with(bound);
        let active = o
            .trajectory
            .stages
            .iter()
            .filter(|s| s.shape[0].abs() > bound - 1e-5)
            .count();
        println!(
            "steering bound {bound:.3} rad ({fraction} of the free peak {phi_free:.3}): {:?} after {} iterations, J = {:.6}, active at {active} of {} stages, max violation {:.1e}, peak {:.4}",
            o.status,
            o.iterations,
            o.objective,
            o.trajectory.stages.len(),
            o.max_violation,
            peak(&o)
        );
        assert_eq!(o.status, Status::Solved, "bound {bound}");
        assert!(
            o.max_violation <= 1e-9,
            "bound {bound}: {:e}",
            o.max_violation
        );
        // A bound below the free peak binds: somewhere within the solver's tolerance of it
        // (complementarity 1e-6 over multipliers of order one).
        assert!(active > 0, "bound {bound} inactive");
        // A tighter bound shrinks the feasible set: the optimum cannot fall (beyond the
        // solver's relative tolerance).
        assert!(
            o.objective >= j_prev * (1.0 - 1e-6),
            "J fell: {} < {j_prev}",
            o.objective
        );
        j_prev = o.objective;
    }
}

/// "Arrive at rest" is rest under the midpoint scheme too: both built-in plans, replayed
/// through the integrator they were planned with and continued for 2 s with zero inputs
/// (no steering torque, no drive voltage), stay where they ended to 1e-9 m; the replay
/// follows the plan to the solver's tolerance through the motion's sensitivity. The rest
/// is the momentum's at the last node (`transcription::conditions_for_scheme`): the plan
/// arrives with zero velocity (its Legendre transform) while its last interval still moves,
/// where rest reached a step early would leave that interval at rest to round-off.
#[test]
fn midpoint_plans_stay_at_rest_after_their_end() {
    use dmech_ocp::toolkit::replay::replay;
    for problem in [CarProblem::parallel_park(), CarProblem::lane_change()] {
        let h = 0.02;
        let o = plan(
            &Car::default(),
            &problem,
            CarBounds::default(),
            h,
            Discretisation::Midpoint,
            IpOptions::default(),
        )
        .unwrap();
        assert_eq!(o.status, Status::Solved, "{}", problem.name);
        let r = replay(
            &Car::default(),
            h,
            Discretisation::Midpoint,
            &o.trajectory,
            100,
        )
        .unwrap();
        println!(
            "{}: replay {:.1e} from the plan, {:.1e} of drift in 2 s after it",
            problem.name, r.plan_deviation, r.drift_after
        );
        assert!(
            r.drift_after <= 1e-9,
            "{}: moved on by {:.2e}",
            problem.name,
            r.drift_after
        );
        assert!(
            r.plan_deviation <= 1e-6,
            "{}: replay off by {:.2e}",
            problem.name,
            r.plan_deviation
        );
        let n = o.trajectory.stages.len() - 1;
        let arriving = o.trajectory.stages[n].velocity.amax();
        let last_interval = o.trajectory.stages[n - 1].velocity.amax();
        println!(
            "{}: arriving velocity {arriving:.1e}, last interval's {last_interval:.1e}",
            problem.name
        );
        assert!(
            arriving <= 1e-9,
            "{}: arrives with {arriving:.2e}",
            problem.name
        );
        assert!(
            last_interval > 1e-6,
            "{}: the last interval is at rest ({last_interval:.2e})",
            problem.name
        );
    }
}
