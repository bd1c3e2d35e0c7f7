//! "Arrive at rest" means rest under the midpoint scheme, at its second order: a midpoint
//! plan of the steered car without damping (so nothing but the plan's end holds it) and of
//! a momentum system (the rolling disk whose yaw is free, through `WithMomentum`), replayed
//! through the integrator and continued for 2 s with zero input, stay where they ended; the
//! midpoint plan's objective converges to the Runge–Kutta plan's at second order; and the
//! node velocity the plan reports at its end (the discrete Legendre transform,
//! `VariationalIntegrator::node_velocity`) is the motion's `v(t_N)` to second order.

use crate::steered_car_bounds::{hermite_path, ParkDiagonal};
use dmech::continuous::{ContinuousModel, RungeKutta};
use dmech::{Discretisation, VariationalIntegrator, ViState};
use dmech_lie::{Real, Se2};
use dmech_ocp::solver::{IpOptions, Solver, Status};
use dmech_ocp::toolkit::plan::{plan, PlanSettings, PlanStart};
use dmech_ocp::toolkit::replay::replay;
use dmech_ocp::transcription::{
    Condition, PlannedTrajectory, PlanningProblem, Quantity, RkTranscription, Stage, StartState,
    VarIntTranscription,
};
use dmech_tests::momentum_systems::{RollingDisk, RollingDiskWithYaw};
use dmech_tests::SteeredCar;
use nalgebra::{SVector, Vector2};

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

/// The plan's end: at rest in the robot's terms (the arriving velocity, by the Legendre
/// transform, zero to the solver's tolerance), with the last interval still moving: the
/// plan reaches rest at `t_N`, not a step early.
fn assert_arrives_moving_into_rest<const NP: usize, const NS: usize, const NU: usize>(
    plan: &PlannedTrajectory<NP, NS, NU>,
) {
    let n = plan.stages.len() - 1;
    let arriving = plan.stages[n].velocity.amax();
    let last_interval = plan.stages[n - 1].velocity.amax();
    println!("end: arriving velocity {arriving:.1e}, last interval's {last_interval:.1e}");
    // The Legendre transform's Newton stops at 1e-13 relative; the terminal rows hold to
    // the solver's violation tolerance over a mass of order one.
    assert!(arriving <= 1e-9, "arrives with {arriving:.2e}");
    // Rest reached a step early would leave the last interval at rest to round-off.
    assert!(
        last_interval > 1e-6,
        "the last interval is at rest ({last_interval:.2e}): the plan stopped a step early"
    );
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
    assert_arrives_moving_into_rest(&plan);
}

/// The rolling disk with its yaw free, `WithMomentum`: extended shape `(φ, σ)`, `σ̇ = p` the
/// yaw rate; inputs the heading torque (along the free direction) and the rolling torque.
fn disk() -> dmech::WithMomentum<RollingDiskWithYaw, 1, 1> {
    dmech::WithMomentum::new(RollingDiskWithYaw(RollingDisk {
        m: 1.2,
        r: 0.15,
        i: 0.01,
        j: 0.02,
    }))
}

/// A quarter turn of radius 0.6 m in 3 s, rest to rest, least squared torque.
struct QuarterTurn {
    n: usize,
}
const TURN_TIME: f64 = 3.0;
const TURN_RADIUS: f64 = 0.6;

impl PlanningProblem<3, 2, 2, 0> for QuarterTurn {
    fn horizon(&self) -> usize {
        self.n
    }
    fn start(&self) -> StartState<3, 2, 2> {
        StartState::at_rest(SVector::zeros(), SVector::zeros())
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, 2, 2>) -> T {
        stage.input.dot(&stage.input) * 0.5
    }
    fn constraints<T: Real>(&self, _k: usize, _: &Stage<T, 3, 2, 2>) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
        (SVector::zeros(), SVector::zeros())
    }
    fn conditions(&self) -> Vec<Condition> {
        let end = [TURN_RADIUS, TURN_RADIUS, std::f64::consts::FRAC_PI_2];
        let at_end = |quantity, value| Condition {
            stage: self.n,
            quantity,
            value,
        };
        let mut c: Vec<_> = (0..3).map(|i| at_end(Quantity::Pose(i), end[i])).collect();
        c.extend((0..2).map(|i| at_end(Quantity::Velocity(i), 0.0)));
        c
    }
}

/// The quarter circle sampled at `n + 1` stages, smoothly from rest to rest.
fn quarter_circle(n: usize) -> Vec<Se2<f64>> {
    (0..=n)
        .map(|k| {
            let tau = k as f64 / n as f64;
            let theta = std::f64::consts::FRAC_PI_2 * tau * tau * (3.0 - 2.0 * tau);
            Se2::new(
                TURN_RADIUS * theta.sin(),
                TURN_RADIUS * (1.0 - theta.cos()),
                theta,
            )
        })
        .collect()
}

/// The momentum system through the toolkit's one call (mesh sequencing from 40 ms):
/// replayed with 2 s of zero input after the plan, it stays at rest to 1e-9 m.
#[test]
fn a_momentum_system_planned_to_rest_stays_at_rest() {
    let sys = disk();
    let h = 0.02;
    let settings = PlanSettings {
        solver: IpOptions {
            verbose: false,
            ..tight()
        },
        ..PlanSettings::new(h, Discretisation::Midpoint)
    };
    let steps = |h: f64| (TURN_TIME / h).round() as usize;
    let path = |n: usize| quarter_circle(n);
    let start = PlanStart::Path {
        path: &path,
        regularisation: SVector::<f64, 2>::new(1e-4, 1e-4),
    };
    let p = plan(
        &sys,
        |h| Some(QuarterTurn { n: steps(h) }),
        &settings,
        &start,
    )
    .expect("the plan starts");
    println!(
        "disk quarter turn: {:?}, {} iterations, violation {:.1e}",
        p.status, p.iterations, p.max_violation
    );
    assert_eq!(p.status, Status::Solved);
    let rest_steps = (2.0 / h).round() as usize;
    let r = replay(&sys, h, Discretisation::Midpoint, &p.trajectory, rest_steps).expect("replay");
    println!(
        "replay: {:.1e} from the plan, {:.1e} of drift in 2 s after it",
        r.plan_deviation, r.drift_after
    );
    assert!(
        r.drift_after <= 1e-9,
        "the disk moved on by {:.2e} after the plan",
        r.drift_after
    );
    assert_arrives_moving_into_rest(&p.trajectory);
}

/// `h·J` of the midpoint plans at 20, 10, 5 ms against the RK4 plan's, observed order ≥ 1.9.
///
/// The reference: the RK4 plan's `h·J` at 2.5 and 1.25 ms, extrapolated (Richardson) for
/// its own second-order error, that of the held input (measured at 5, 2.5, 1.25 ms: the
/// differences 6.04e-9 then 1.51e-9, ratio 4.0); what is left, O(h³), is below 1e-11, a
/// thousandth of the midpoint's error at 5 ms (1.3e-8). The solves stop at a KKT error of
/// 1e-10 and a violation of 1e-12, which moves `h·J` by less than 1e-12. Together these
/// move an observed order by at most log₂(1 + 2e-3) ≈ 3e-3; the rest of the 0.1 allowed
/// below 2 is for the next term of the error's expansion, O(h³), at 20 ms.
#[test]
fn the_midpoint_objective_converges_at_second_order() {
    let car = SteeredCar::new(0.0, [0.0, 0.0]);
    let rk4 = |n_fine: usize| {
        let h_fine = DURATION / n_fine as f64;
        let rk = RkTranscription::new(&car, problem(n_fine), h_fine, RungeKutta::Rk4);
        // Started from the midpoint plan at the same step, whose states are those of the
        // continuous motion to O(h²).
        let (plan, _) = midpoint_plan(&car, n_fine);
        let (xs, ws) = rk.start_from_trajectory::<3>(&plan);
        let solver = Solver::new(&rk, tight());
        let r = solver.solve(solver.initial_iterate(xs, ws));
        assert_eq!(
            r.status,
            Status::Solved,
            "the RK4 reference at {n_fine} steps"
        );
        h_fine * r.objective
    };
    let (coarse, fine) = (rk4(2000), rk4(4000));
    let reference = (4.0 * fine - coarse) / 3.0;
    let errors: Vec<f64> = [250usize, 500, 1000]
        .iter()
        .map(|&n| (DURATION / n as f64 * midpoint_plan(&car, n).1 - reference).abs())
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    let shown: Vec<String> = errors.iter().map(|e| format!("{e:.3e}")).collect();
    println!(
        "h·J against RK4's {reference:.12} (2.5 ms: {coarse:.12}, 1.25 ms: {fine:.12}): \
         errors {shown:?}, orders {orders:.3?}"
    );
    assert!(orders.iter().all(|p| *p >= 1.9), "orders {orders:.3?}");
}

/// The node velocity of a midpoint run (the Legendre transform at the node from the interval
/// before it) against RK4's `v(T)` with the same held input: second order, where the
/// interval velocity `v_{N−1}` itself is first order. The steered car with a steering
/// spring and damping, so that every term of the momentum and of the force is in play;
/// the reference RK4 at T/4096 is off by (h ω)⁴ ≈ 1e-12, far below the variational errors.
#[test]
fn the_node_velocity_is_the_motions_at_second_order() {
    let car = SteeredCar::new(0.5, [0.02, 1e-3]);
    let u = Vector2::new(0.01, 0.03);
    let x0 = ViState {
        g: Se2::new(0.0, 0.0, 0.0),
        s: Vector2::new(0.2, 0.0),
        v: Vector2::new(-0.5, 4.0),
    };
    let t_end = 1.0;
    let mut reference = x0;
    let n_ref = 4096;
    for _ in 0..n_ref {
        reference =
            ContinuousModel::step(&car, RungeKutta::Rk4, t_end / n_ref as f64, &reference, &u)
                .expect("RK4");
    }
    let errors = |n: usize| {
        let vi = VariationalIntegrator::new(t_end / n as f64)
            .with_discretisation(Discretisation::Midpoint);
        let mut x = ViState {
            v: vi.start(&car, &x0.s, &x0.v, &u).expect("start"),
            ..x0
        };
        let mut before = x;
        for _ in 0..n {
            before = x;
            x = vi.step(&car, &x, &u, &u).expect("step").0;
        }
        let node = vi
            .node_velocity(&car, &before.s, &before.v, &u, &x.s)
            .expect("node velocity");
        ((node - reference.v).amax(), (before.v - reference.v).amax())
    };
    let runs: Vec<(f64, f64)> = [32usize, 64, 128, 256].iter().map(|&n| errors(n)).collect();
    let order = |e: &dyn Fn(&(f64, f64)) -> f64| -> Vec<f64> {
        runs.windows(2)
            .map(|w| (e(&w[0]) / e(&w[1])).log2())
            .collect()
    };
    let (node, interval) = (order(&|r| r.0), order(&|r| r.1));
    let shown: Vec<String> = runs
        .iter()
        .map(|(a, b)| format!("{a:.2e} / {b:.2e}"))
        .collect();
    println!("node / interval velocity errors {shown:?}: orders {node:.3?} / {interval:.3?}");
    // Orders of a smooth error expansion: 2 and 1, each within 0.3 (its next term over
    // these steps).
    assert!(
        node.iter().all(|p| (p - 2.0).abs() <= 0.3),
        "node {node:.3?}"
    );
    assert!(
        interval.iter().all(|p| (p - 1.0).abs() <= 0.3),
        "interval {interval:.3?}"
    );
    // The first-order scheme's node velocity is its interval's.
    let first = VariationalIntegrator::new(0.01);
    let v = Vector2::new(0.3, -2.0);
    let s = Vector2::new(0.1, 0.0);
    assert_eq!(
        first
            .with_discretisation(Discretisation::FirstOrder)
            .node_velocity(&car, &s, &v, &u, &(s + v * 0.01))
            .unwrap(),
        v
    );
}
