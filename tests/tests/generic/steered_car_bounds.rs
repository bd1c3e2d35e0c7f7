//! A steered car (torque inputs) planned rest to rest with a drive-torque bound active on
//! many stages, and a sweep of the bound: a reproduction of the solver's stall (SR1: 500
//! iterations at J = 0.1924 with the bound 0.035; the optimum is near 0.1608). On the traits
//! alone (`dmech_tests::SteeredCar`), so the solver meets a robot that is not in the project.
//!
//! The cost per stage is about 6e-4: the solver scales it (objective scaling); unscaled, SR1
//! stalled at 0.035 and the exact Hessian at 0.035 and 0.028.
//!
//! G = SE(2) (pose of the rear-axle midpoint), shape (steering angle φ, wheel angle ψ),
//! ξ = (r ψ̇ cos φ, 0, r ψ̇ sin φ / L) for the front wheel's rolling angle;
//! ℓ = ½ m (ξ₁² + (ξ₂ + b ξ₃)²) + ½ j ξ₃² + ½ i_s (ξ₃ + φ̇)² + ½ i_w ψ̇², forcing u − c ⊙ v.
//!
//! The same problem also checks the declaration of a constant cost curvature (its cost is
//! quadratic and its constraints affine): the iterates are those of the undeclared problem,
//! and a false declaration is reported.

use dmech::Discretisation;
use dmech_lie::{Real, Se2};
use dmech_ocp::solver::{Curvature, Failure, IpOptions, Solver, Status};
use dmech_ocp::transcription::{
    Condition, PlanningProblem, Quantity, Stage, StartState, VarIntTranscription,
};
use dmech_tests::SteeredCar;
use nalgebra::SVector;

/// The car: `dmech_tests::SteeredCar` without a steering spring, with the damping.
fn car() -> SteeredCar {
    SteeredCar::new(0.0, [0.02, 1e-3])
}

/// From rest at the origin to rest at (1, 1, 0) in `n` steps; cost Σ |u_k|² (plus
/// `quartic · u₂⁴` and `steer_price · φ` per stage), declaring its cost curvature constant
/// if `declares_constant`.
pub(crate) struct ParkDiagonal {
    pub(crate) n: usize,
    pub(crate) drive_torque: f64,
    pub(crate) quartic: f64,
    pub(crate) steer_price: f64,
    pub(crate) declares_constant: bool,
}
const STEER_TORQUE: f64 = 0.05;
const STEER_ANGLE: f64 = 0.6;
const END: [f64; 3] = [1.0, 1.0, 0.0];

impl PlanningProblem<3, 2, 2, 3> for ParkDiagonal {
    fn horizon(&self) -> usize {
        self.n
    }
    fn start(&self) -> StartState<3, 2, 2> {
        StartState::at_rest(SVector::zeros(), SVector::zeros())
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, 2, 2>) -> T {
        let u2 = stage.input[1] * stage.input[1];
        stage.input[0] * stage.input[0]
            + u2
            + u2 * u2 * self.quartic
            + stage.shape[0] * self.steer_price
    }
    fn constraints<T: Real>(&self, _k: usize, stage: &Stage<T, 3, 2, 2>) -> SVector<T, 3> {
        SVector::<T, 3>::new(stage.input[0], stage.input[1], stage.shape[0])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 3>, SVector<f64, 3>) {
        let hi = SVector::<f64, 3>::new(STEER_TORQUE, self.drive_torque, STEER_ANGLE);
        (-hi, hi)
    }
    fn conditions(&self) -> Vec<Condition> {
        let at_end = |quantity, value| Condition {
            stage: self.n,
            quantity,
            value,
        };
        let mut c: Vec<Condition> = (0..3).map(|i| at_end(Quantity::Pose(i), END[i])).collect();
        c.extend((0..2).map(|i| at_end(Quantity::Velocity(i), 0.0)));
        c
    }
    fn affine_in_configuration(&self) -> bool {
        true
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        self.declares_constant
    }
}

/// The start: a cubic Hermite path from the origin to `END` with unit tangents
/// along x at both ends, timed by 3τ² − 2τ³, the heading along the tangent.
pub(crate) fn hermite_path(n: usize) -> Vec<Se2<f64>> {
    (0..=n)
        .map(|k| {
            let tau = k as f64 / n as f64;
            let f = tau * tau * (3.0 - 2.0 * tau);
            // Hermite basis h10, h01, h11 (h00 multiplies the origin) and their derivatives.
            let (h10, h01, h11) = (
                f.powi(3) - 2.0 * f * f + f,
                -2.0 * f.powi(3) + 3.0 * f * f,
                f.powi(3) - f * f,
            );
            let (d10, d01, d11) = (
                3.0 * f * f - 4.0 * f + 1.0,
                -6.0 * f * f + 6.0 * f,
                3.0 * f * f - 2.0 * f,
            );
            let x = h01 * END[0] + h10 + h11;
            let y = h01 * END[1];
            let (dx, dy) = (d01 * END[0] + d10 + d11, d01 * END[1]);
            Se2::new(x, y, dy.atan2(dx))
        })
        .collect()
}

/// What a solve returned: status, iterations, objective, largest violation, duality gap.
type Outcome = (Status, usize, f64, f64, f64);

fn solve(drive_torque: f64, opts: IpOptions) -> Outcome {
    let problem = ParkDiagonal {
        n: 250,
        drive_torque,
        quartic: 0.0,
        steer_price: 0.0,
        declares_constant: false,
    };
    solve_problem(problem, opts)
}

fn solve_problem(problem: ParkDiagonal, opts: IpOptions) -> Outcome {
    let (n, h) = (problem.n, 5.0 / problem.n as f64);
    let disc = Discretisation::FirstOrder;
    let car = car();
    let problem = VarIntTranscription::new(&car, problem, h, disc);
    let (xs, ws) = problem
        .start_from_path(
            &hermite_path(n),
            &SVector::zeros(),
            &SVector::<f64, 2>::new(1e-4, 1e-6),
        )
        .expect("a kinematic start");
    let solver = Solver::new(&problem, opts);
    let r = solver.solve(solver.initial_iterate(xs, ws));
    (
        r.status,
        r.iterations,
        r.objective,
        r.max_violation,
        r.duality_gap,
    )
}

/// The bound sweep 0.05 → 0.028 with default options: every plan solved, constraints to the
/// solver's tolerance, and the optimum not lower for a tighter bound: each objective lies
/// within its duality gap `Σ z t` above its optimum (first order, `SolveResult::duality_gap`),
/// so a tighter bound's may fall below the looser one's by at most the looser one's gap.
#[test]
fn steered_car_bound_sweep_solves_with_default_options() {
    let (mut previous, mut previous_gap) = (0.0, 0.0);
    for tau in [0.05, 0.04, 0.035, 0.03, 0.028] {
        let (status, iterations, j, violation, gap) = solve(tau, IpOptions::default());
        println!("bound {tau}: {status:?} in {iterations} iterations, J = {j:.6}, violation {violation:.1e}");
        assert_eq!(status, Status::Solved, "bound {tau}");
        assert!(
            violation <= IpOptions::default().constr_viol_tol,
            "bound {tau}"
        );
        assert!(
            j >= previous - previous_gap,
            "bound {tau}: {j} < {previous} − {previous_gap:.1e}"
        );
        (previous, previous_gap) = (j, gap);
    }
}

/// At the bound where SR1 used to stall (0.035, J = 0.1924 against the optimum near
/// 0.1608), SR1 and the exact Hessian reach the same optimum: their objectives agree
/// within the sum of their duality gaps (each lies that far above it at most).
#[test]
fn steered_car_sr1_and_exact_hessian_agree_at_the_stalling_bound() {
    let exact = IpOptions {
        curvature: Curvature::Exact,
        ..Default::default()
    };
    let (status, _, j_exact, _, gap_exact) = solve(0.035, exact);
    let (status_sr1, _, j_sr1, _, gap_sr1) = solve(0.035, IpOptions::default());
    assert_eq!(status, Status::Solved);
    assert_eq!(status_sr1, Status::Solved);
    println!(
        "SR1 J = {j_sr1:.8} (gap {gap_sr1:.1e}), exact J = {j_exact:.8} (gap {gap_exact:.1e})"
    );
    assert!(
        (j_sr1 - j_exact).abs() <= gap_sr1 + gap_exact,
        "{j_sr1} against {j_exact}"
    );
}

/// Declaring the (quadratic, affine) problem's cost curvature constant changes nothing but
/// where the curvature and the state gradients (`∇_x ℓ`, here from a small price on the
/// steering angle, and `C_x`) are computed: the same iterations and the same objective, to
/// the bit.
#[test]
fn constant_curvature_declaration_leaves_the_solve_unchanged() {
    let park = |declares_constant| ParkDiagonal {
        n: 250,
        drive_torque: 0.035,
        quartic: 0.0,
        steer_price: 1e-3,
        declares_constant,
    };
    let computed = solve_problem(park(false), IpOptions::default());
    let declared = solve_problem(park(true), IpOptions::default());
    assert_eq!(computed.0, Status::Solved);
    assert_eq!(declared, computed);
}

/// A quartic cost declared constant in curvature is refused at the start.
#[test]
fn false_constant_curvature_declaration_is_reported() {
    let problem = ParkDiagonal {
        n: 250,
        drive_torque: 0.035,
        quartic: 1.0,
        steer_price: 0.0,
        declares_constant: true,
    };
    match solve_problem(problem, IpOptions::default()).0 {
        Status::Failed(Failure::CurvatureNotConstant { .. }) => {}
        other => panic!("a false declaration was not reported: {other:?}"),
    }
}
