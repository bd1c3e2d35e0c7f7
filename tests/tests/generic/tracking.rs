//! A plan tracked in closed loop through `dmech_ocp::tracking`, on a robot the project does
//! not ship: the steered car's parking plan, run on a plant with 10 % heavier body, 10 %
//! more yaw inertia and lighter wheels, from a start 2 cm to the side. Open loop the plant
//! misses the parking pose by centimetres; the plan's LQ gains bring it in. And the
//! linearisation's `A_k`, `B_k` against finite differences of the plant's own step.

use crate::steered_car_bounds::{hermite_path, ParkDiagonal};
use dmech::Discretisation;
use dmech_ocp::solver::{IpOptions, Solver, Status};
use dmech_ocp::tracking::{linearise_along, lq_gains, plant_step, track};
use dmech_ocp::transcription::VarIntTranscription;
use dmech_ocp::transcription::{Condition, PlanningProblem, Stage, StartState};
use dmech_tests::random_system::RandomSystemSpec;
use dmech_tests::SteeredCar;
use nalgebra::{SMatrix, SVector};

const N: usize = 250;
const H: f64 = 5.0 / N as f64;

fn park() -> ParkDiagonal {
    ParkDiagonal {
        n: N,
        drive_torque: 0.05,
        quartic: 0.0,
        steer_price: 0.0,
        declares_constant: true,
    }
}

fn mismatched() -> SteeredCar {
    let mut car = SteeredCar::new(0.0, [0.02, 1e-3]);
    car.m *= 1.1;
    car.j *= 1.1;
    car.i_w *= 0.9;
    car
}

type Plan = (Vec<SVector<f64, 9>>, Vec<SVector<f64, 4>>);

/// The nominal car's midpoint parking plan, solved.
fn planned(car: &SteeredCar) -> Plan {
    let tr = VarIntTranscription::new(car, park(), H, Discretisation::Midpoint);
    let (xs, ws) = tr
        .start_from_path(
            &hermite_path(N),
            &SVector::zeros(),
            &SVector::<f64, 2>::new(1e-4, 1e-6),
        )
        .unwrap();
    let solver = Solver::new(&tr, IpOptions::default());
    let r = solver.solve(solver.initial_iterate(xs, ws));
    assert_eq!(r.status, Status::Solved);
    (r.iterate.x, r.iterate.w)
}

#[test]
fn lq_tracking_brings_a_mismatched_plant_to_the_parking_pose() {
    let car = SteeredCar::new(0.0, [0.02, 1e-3]);
    let tr = VarIntTranscription::new(&car, park(), H, Discretisation::Midpoint);
    let (px, pw) = &planned(&car);

    let lin = linearise_along(&tr, px, pw).unwrap();
    // Weights: position and heading errors of 1 cm and 0.05 rad cost as a torque at its
    // bound (0.05 N m); shape, velocity and previous input lightly.
    let mut q = SMatrix::<f64, 9, 9>::from_diagonal_element(1e-2);
    for (i, scale) in [(0, 0.01), (1, 0.01), (2, 0.05)] {
        q[(i, i)] = 1.0 / (scale * scale);
    }
    let r_w = SMatrix::<f64, 2, 2>::from_diagonal_element(1.0 / (0.05 * 0.05));
    let gains = lq_gains(&lin, &q, &(q * 10.0), &r_w).unwrap();

    let plant_car = mismatched();
    let plant = VarIntTranscription::new(&plant_car, park(), H, Discretisation::Midpoint);
    let mut x0 = px[0];
    x0[1] += 0.02;
    let end_error = |xs: &[SVector<f64, 9>]| {
        let (a, b) = (xs[N], px[N]);
        (a[0] - b[0]).hypot(a[1] - b[1])
    };
    let open = track(&plant, &x0, px, pw, None).unwrap();
    let closed = track(&plant, &x0, px, pw, Some(&gains)).unwrap();
    let (e_open, e_closed) = (end_error(&open), end_error(&closed));
    let worst = closed
        .iter()
        .zip(px)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max);
    println!(
        "end position error: open loop {:.1} mm, LQ {:.2} mm (worst along the plan {:.1} mm)",
        1e3 * e_open,
        1e3 * e_closed,
        1e3 * worst
    );
    assert!(
        e_open > 0.01,
        "the mismatch should matter open loop: {e_open:.2e}"
    );
    assert!(
        e_closed < 0.1 * e_open,
        "LQ {e_closed:.2e} against open loop {e_open:.2e}"
    );
    assert!(
        worst <= 0.021,
        "the closed loop strayed {worst:.3} m from the plan"
    );
}

/// `A_k`, `B_k` against central differences of the nominal plant's step at a few stages
/// of the solved plan (where the stage equality holds, so the step through `(x̄, ū)` is the
/// plan's). Step 1e-6: truncation ~1e-12, round-off ~1e-10, and the plant's Newton stops at
/// a residual of 1e-12 (quadratically converged, so in practice far below): 1e-6 relative.
#[test]
fn the_linearisation_is_the_steps_derivative() {
    let car = SteeredCar::new(0.0, [0.02, 1e-3]);
    let tr = VarIntTranscription::new(&car, park(), H, Discretisation::Midpoint);
    let (xs, ws) = planned(&car);
    let lin = linearise_along(&tr, &xs, &ws).unwrap();
    let step = |k: usize, x: &SVector<f64, 9>, u: &SVector<f64, 2>| {
        let guess = ws[k].fixed_rows::<2>(0).into_owned();
        plant_step::<_, 9, 4, 2, 2, 3>(&tr, k, x, u, &guess)
            .unwrap()
            .0
    };
    let d = 1e-6;
    for k in [0, 60, 125, 249] {
        let (x, u) = (xs[k], ws[k].fixed_rows::<2>(2).into_owned());
        for j in 0..9 {
            let mut e = SVector::<f64, 9>::zeros();
            e[j] = d;
            let fd = (step(k, &(x + e), &u) - step(k, &(x - e), &u)) / (2.0 * d);
            let err = (fd - lin.a[k].column(j)).amax();
            assert!(
                err <= 1e-6 * (1.0 + lin.a[k].column(j).amax()),
                "A_{k} column {j}: {err:.2e}"
            );
        }
        for j in 0..2 {
            let mut e = SVector::<f64, 2>::zeros();
            e[j] = d;
            let fd = (step(k, &x, &(u + e)) - step(k, &x, &(u - e))) / (2.0 * d);
            let err = (fd - lin.b[k].column(j)).amax();
            assert!(
                err <= 1e-6 * (1.0 + lin.b[k].column(j).amax()),
                "B_{k} column {j}: {err:.2e}"
            );
        }
    }
}

/// A reference of a random system (SE(2), two shape variables, a shape-dependent inertia
/// and connection, damping) under smooth inputs, tracked by LQ: on the nominal system it is
/// reproduced to Newton's tolerance, and on a plant drawn from the same seed with 10 % more
/// shape dependence and 50 % more damping the largest pose error is below the open loop's,
/// for every seed. Only below: these systems move their pose through the connection alone,
/// and along a reference that turns the shape slowly the linearisation barely controls it
/// (measured: 3.8 → 2.8 mm for seed 0; the steered car above, 77 → 0.6 mm).
#[test]
fn lq_tracks_random_systems_under_model_error() {
    use dmech_tests::random_system::{RandomSystem, Se2Family};
    let (n, h) = (200, 0.02);
    for seed in 0..4 {
        let nominal = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.5, 0.2));
        let plant_sys = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.55, 0.3));
        let tr = VarIntTranscription::new(&nominal, Reference(n), h, Discretisation::Midpoint);
        let plant = VarIntTranscription::new(&plant_sys, Reference(n), h, Discretisation::Midpoint);
        let (px, pw) = reference_of(&tr, n, h);
        let lin = linearise_along(&tr, &px, &pw).unwrap();
        let mut q = SMatrix::<f64, 9, 9>::from_diagonal_element(1.0);
        for i in 0..3 {
            q[(i, i)] = 1e4;
        }
        let gains = lq_gains(&lin, &q, &(q * 10.0), &SMatrix::<f64, 2, 2>::identity()).unwrap();
        let pose_error = |xs: &[SVector<f64, 9>]| {
            (0..=n)
                .map(|k| (xs[k].fixed_rows::<3>(0) - px[k].fixed_rows::<3>(0)).norm())
                .fold(0.0, f64::max)
        };
        // The nominal system from the reference's start: no error for the feedback to act
        // on, so the reference to the plant step's Newton tolerance (1e-12 per step).
        let exact = pose_error(&track(&tr, &px[0], &px, &pw, Some(&gains)).unwrap());
        assert!(
            exact <= 1e-9,
            "seed {seed}: the nominal closed loop left the reference by {exact:.2e}"
        );
        let open = pose_error(&track(&plant, &px[0], &px, &pw, None).unwrap());
        let closed = pose_error(&track(&plant, &px[0], &px, &pw, Some(&gains)).unwrap());
        println!("seed {seed}: largest pose error open loop {open:.3e}, LQ {closed:.3e}");
        assert!(
            closed < open,
            "seed {seed}: LQ {closed:.2e} against open loop {open:.2e}"
        );
    }
}

/// A horizon and a start, nothing to optimise: the transcription's stage functions for a
/// random system's reference.
pub(crate) struct Reference(pub usize);

impl PlanningProblem<3, 2, 2, 1> for Reference {
    fn horizon(&self) -> usize {
        self.0
    }
    fn start(&self) -> StartState<3, 2, 2> {
        StartState::at_rest(SVector::zeros(), SVector::zeros())
    }
    fn cost<T: dmech_lie::Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> T {
        st.input.dot(&st.input)
    }
    fn constraints<T: dmech_lie::Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> SVector<T, 1> {
        SVector::<T, 1>::new(st.input[0])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 1>, SVector<f64, 1>) {
        (
            SVector::repeat(f64::NEG_INFINITY),
            SVector::repeat(f64::INFINITY),
        )
    }
    fn conditions(&self) -> Vec<Condition> {
        Vec::new()
    }
}

/// The random systems' spec with these shape dependence and damping.
pub(crate) fn spec(shape_dependence: f64, damping: f64) -> RandomSystemSpec {
    RandomSystemSpec {
        damping,
        cyclic_first: false,
        shape_dependence,
    }
}

/// The reference: the transcribed system under the smooth inputs `(0.5 sin t,
/// 0.3 cos 1.3t)` from rest, `n` steps of `h`: the states and decisions.
pub(crate) fn reference_of<P>(
    tr: &P,
    n: usize,
    h: f64,
) -> (Vec<SVector<f64, 9>>, Vec<SVector<f64, 4>>)
where
    P: dmech_ocp::nlp::StageProblem<9, 4, 2, 2, 1>,
{
    let (mut px, mut pw) = (vec![SVector::<f64, 9>::zeros()], Vec::new());
    for k in 0..n {
        let t = k as f64 * h;
        let u = SVector::<f64, 2>::new(0.5 * t.sin(), 0.3 * (1.3 * t).cos());
        let guess = pw.last().map_or(SVector::zeros(), |w: &SVector<f64, 4>| {
            w.fixed_rows::<2>(0).into_owned()
        });
        let (next, w) = plant_step::<_, 9, 4, 2, 2, 1>(tr, k, &px[k], &u, &guess).unwrap();
        px.push(next);
        pw.push(w);
    }
    (px, pw)
}
