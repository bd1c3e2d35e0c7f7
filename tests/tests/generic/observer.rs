//! The observer of `dmech_ocp::tracking::observer` on a random linear time-varying system
//! with nonlinear readings (no robot): with exact readings and an exact start its estimate
//! is the state to round-off; a pose that arrives late gives the estimate it would have
//! given on time.

use dmech_lie::rng::Rng;
use dmech_lie::Real;
use dmech_ocp::tracking::{
    LinearisedPlan, Observer, ObserverError, ObserverNoise, PlanView, Readings,
};
use nalgebra::{SMatrix, SVector};

const NX: usize = 5;
const NU: usize = 2;
const N: usize = 100;

type X = SVector<f64, NX>;
type U = SVector<f64, NU>;

/// Two on-board readings and a two-dimensional pose, each nonlinear in the state; together
/// with the dynamics they observe it.
struct TestReadings;

impl Readings<NX, 2, 2> for TestReadings {
    fn on_board<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, 2> {
        SVector::<T, 2>::new(x[2].sin() + x[3] * x[4], x[4] * (x[0] * 0.1).exp())
    }
    fn pose<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, 2> {
        SVector::<T, 2>::new(x[0], x[1] + x[2] * x[2] * 0.1)
    }
}

/// A random system `x_{k+1} = A_k x_k + B_k u_k` (`A_k` near the identity, as a
/// discretised flow), its plan from random inputs, and a plant run off the plan (another
/// start, other inputs): `(linearisation, plan states, plan inputs, plant states, plant
/// inputs)`.
struct Case {
    lin: LinearisedPlan<NX, NU>,
    plan_x: Vec<X>,
    plan_u: Vec<U>,
    x: Vec<X>,
    u: Vec<U>,
}

fn case(seed: u64) -> Case {
    let mut rng = Rng::new(seed);
    let mut lin = LinearisedPlan {
        a: Vec::new(),
        b: Vec::new(),
    };
    for _ in 0..N {
        let a = SMatrix::<f64, NX, NX>::identity()
            + SMatrix::<f64, NX, NX>::from_fn(|_, _| 0.1 * rng.range(-1.0, 1.0));
        lin.a.push(a);
        lin.b.push(SMatrix::<f64, NX, NU>::from_fn(|_, _| {
            0.1 * rng.range(-1.0, 1.0)
        }));
    }
    let plan_u: Vec<U> = (0..N)
        .map(|_| U::from_fn(|_, _| rng.range(-1.0, 1.0)))
        .collect();
    let u: Vec<U> = plan_u
        .iter()
        .map(|u| u + U::from_fn(|_, _| 0.1 * rng.range(-1.0, 1.0)))
        .collect();
    let mut plan_x = vec![X::from_fn(|_, _| rng.range(-1.0, 1.0))];
    let mut x = vec![plan_x[0] + X::from_fn(|_, _| 0.1 * rng.range(-1.0, 1.0))];
    for k in 0..N {
        plan_x.push(lin.a[k] * plan_x[k] + lin.b[k] * plan_u[k]);
        x.push(lin.a[k] * x[k] + lin.b[k] * u[k]);
    }
    Case {
        lin,
        plan_x,
        plan_u,
        x,
        u,
    }
}

fn noise() -> ObserverNoise<NX, 2, 2> {
    ObserverNoise {
        process: SMatrix::identity() * 1e-4,
        on_board: SMatrix::identity() * 1e-4,
        pose: SMatrix::identity() * 1e-6,
    }
}

fn observer<'a>(c: &'a Case, start: X, memory: usize) -> Observer<'a, TestReadings, NX, NU, 2, 2> {
    let plan = PlanView {
        linearised: &c.lin,
        states: &c.plan_x,
        inputs: &c.plan_u,
    };
    Observer::new(
        TestReadings,
        plan,
        noise(),
        start,
        SMatrix::identity() * 1e-2,
        memory,
    )
    .unwrap()
}

/// Exact readings (on-board every sample, a pose every third, on time) and the true start:
/// every innovation is round-off, so the estimate is the state to round-off at every
/// sample. The bound: each sample's prediction and updates are sums of `NX` products
/// (a rounding of `NX ε` of the state's size each), carried over at most `N` samples by
/// dynamics whose growth the corrections hold below 10 (the largest `|x|` is measured):
/// `10 N NX ε max|x|`.
#[test]
fn exact_readings_give_the_state() {
    for seed in 1..=5 {
        let c = case(seed);
        let mut obs = observer(&c, c.x[0], 20);
        let scale = c.x.iter().map(|x| x.amax()).fold(1.0, f64::max);
        let bound = 10.0 * (N * NX) as f64 * f64::EPSILON * scale;
        let mut worst: f64 = 0.0;
        for k in 0..=N {
            obs.read(&TestReadings.on_board(&c.x[k])).unwrap();
            if k % 3 == 0 {
                assert!(obs.pose(k, &TestReadings.pose(&c.x[k])).unwrap());
            }
            worst = worst.max((obs.estimate() - c.x[k]).amax());
            if k < N {
                obs.advance(&c.u[k]).unwrap();
            }
        }
        println!("seed {seed}: largest estimate error {worst:.2e} (bound {bound:.2e})");
        assert!(worst <= bound, "seed {seed}: {worst:.2e} > {bound:.2e}");
        // The plan's end: no input past it.
        assert_eq!(
            obs.advance(&c.u[0]),
            Err(ObserverError::PastThePlan {
                sample: N,
                stages: N
            })
        );
    }
}

/// Noisy readings from a wrong start; the same poses given on time to one observer and
/// 0–8 samples late, some out of order, to another. Wherever the late one has every pose
/// measured so far, its estimate and covariance are the on-time one's to round-off
/// (`NX ε` of their size per operation over the replayed samples: `N NX ε` relative), while
/// without the late poses the estimate is far off (so the comparison can fail).
#[test]
fn a_late_pose_gives_the_on_time_estimate() {
    let c = case(11);
    let mut rng = Rng::new(99);
    let start = c.plan_x[0];
    let (mut on_time, mut late, mut blind) = (
        observer(&c, start, 20),
        observer(&c, start, 20),
        observer(&c, start, 20),
    );
    let poses: Vec<(usize, usize, SVector<f64, 2>)> = (0..N - 10)
        .step_by(3)
        .map(|m| {
            let noisy =
                TestReadings.pose(&c.x[m]) + SVector::<f64, 2>::from_fn(|_, _| 1e-3 * rng.normal());
            (m, m + (rng.uniform() * 9.0) as usize, noisy)
        })
        .collect();
    let tol = (N * NX) as f64 * f64::EPSILON;
    let mut compared = 0;
    let mut largest_blind: f64 = 0.0;
    for k in 0..=N {
        let y =
            TestReadings.on_board(&c.x[k]) + SVector::<f64, 2>::from_fn(|_, _| 1e-2 * rng.normal());
        for o in [&mut on_time, &mut late, &mut blind] {
            o.read(&y).unwrap();
        }
        for (m, arrive, p) in &poses {
            if *m == k {
                assert!(on_time.pose(*m, p).unwrap());
            }
            if *arrive == k {
                assert!(late.pose(*m, p).unwrap());
            }
        }
        let complete = poses.iter().all(|(m, arrive, _)| *m > k || *arrive <= k);
        if complete {
            compared += 1;
            let scale = on_time.estimate().amax().max(1.0);
            let dx = (late.estimate() - on_time.estimate()).amax();
            assert!(dx <= tol * scale, "sample {k}: {dx:.2e}");
            let cov_scale = on_time.covariance().amax();
            let dp = (late.covariance() - on_time.covariance()).amax();
            assert!(dp <= tol * cov_scale, "sample {k}: covariance {dp:.2e}");
            largest_blind = largest_blind.max((blind.estimate() - on_time.estimate()).amax());
        }
        if k < N {
            for o in [&mut on_time, &mut late, &mut blind] {
                o.advance(&c.u[k]).unwrap();
            }
        }
    }
    println!("{compared} samples compared; without the poses off by {largest_blind:.2e}");
    assert!(compared >= N / 10, "{compared} samples compared");
    assert!(
        largest_blind > 1e3 * tol,
        "the poses change nothing: {largest_blind:.2e}"
    );
    // A pose older than the memory is dropped; one from the future is refused.
    let old = TestReadings.pose(&c.x[0]);
    assert_eq!(late.pose(N - 20, &old), Ok(false));
    assert_eq!(
        late.pose(N + 1, &old),
        Err(ObserverError::FromTheFuture {
            measured: N + 1,
            now: N
        })
    );
}
