//! The benchmarks' objectives against the independent solutions of the same problems
//! (CasADi 3.8 + IPOPT 3.14, tolerance 1e-6, exact Hessian; `docs/problems.md`).
//!
//! The tolerance: each objective is within its duality gap `Σ z t` above the optimum to
//! first order (`PlanOutcome::duality_gap`), the reference is quoted to four decimals
//! (±0.5e-4), and IPOPT's and FATROP's solutions of the first-order scheme agree to
//! 1e-11, so the reference's own error is its rounding. The sums of a few thousand stage
//! costs add `N ε |J|` of round-off, negligible beside the rest.

use dmech::Integrator;
use dmech_ocp::solver::{IpOptions, Status};
use robots::wip::plan::problems;
use robots::wip::plan::{plan, CurrentModel, PlanBounds};
use robots::wip::Wip;

/// The quoted references' rounding: four decimals.
const REFERENCE_ROUNDING: f64 = 0.5e-4;

fn check(problem: &str, integrator: Integrator, reference: f64) {
    let p = problems::by_name(problem, 0.005).expect("a built-in problem");
    let opts = IpOptions {
        verbose: false,
        ..Default::default()
    };
    let o = plan(
        &Wip::default(),
        &p,
        PlanBounds::default(),
        integrator,
        CurrentModel::Dynamic,
        opts,
    );
    assert_eq!(o.status, Status::Solved, "{problem} {integrator}");
    let round_off = p.n as f64 * f64::EPSILON * reference.abs();
    let tolerance = o.duality_gap + REFERENCE_ROUNDING + round_off;
    println!(
        "{problem} {integrator}: J = {:.6} against {reference} (tolerance {tolerance:.1e}, gap {:.1e})",
        o.objective, o.duality_gap
    );
    assert!(
        (o.objective - reference).abs() <= tolerance,
        "{problem} {integrator}: J = {} against {reference} ± {tolerance:.1e}",
        o.objective
    );
}

#[test]
fn the_eight_matches_the_independent_first_order_solution() {
    check("eight", Integrator::FirstOrder, 4877.1583);
}

#[test]
fn the_eight_matches_the_independent_rk1_solution() {
    check("eight", Integrator::Rk1, 4876.4865);
}

#[test]
fn the_zigzag_matches_the_independent_first_order_solution() {
    check("zigzag", Integrator::FirstOrder, 2320.0254);
}
