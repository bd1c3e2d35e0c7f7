//! The car planned through the toolkit alone: the built-in problems solve from the generic
//! (kinematic) start, with every constraint holding on the returned plan.

use dmech::Discretisation;
use dmech_ocp::ipm::{IpOptions, Status};
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
