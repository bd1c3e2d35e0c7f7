//! Runs of the variational integrators without input, and what the tests read from them:
//! the distance between configurations, observed orders, the return error of a reversed
//! run and its bound, the energy error's envelope over a long run.

use dmech::continuous::{ContinuousModel, RungeKutta};
use dmech::{
    energy, Discretisation, JacobianPolicy, NewtonCache, PrincipalKinematicSystem,
    VariationalIntegrator, ViState,
};
use dmech_lie::LieGroup;
use nalgebra::SVector;

/// `n` steps of `vi` from the continuous state `x0` (the start's discrete Legendre
/// transform included), no input. Returns every node.
pub fn run<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    vi: &VariationalIntegrator,
    x0: &ViState<S::Group<f64>, NS>,
    n: usize,
) -> Vec<ViState<S::Group<f64>, NS>>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let u = SVector::<f64, NU>::zeros();
    let mut x = ViState {
        g: x0.g,
        s: x0.s,
        v: vi.start(sys, &x0.s, &x0.v, &u).expect("start"),
    };
    let mut path = vec![x];
    for _ in 0..n {
        x = vi.step(sys, &x, &u, &u).expect("step").0;
        path.push(x);
    }
    path
}

/// The distance between two configurations: `|log(a⁻¹b)| + |s_a − s_b|`.
pub fn config_distance<G: LieGroup<DOF, Scalar = f64>, const DOF: usize, const NS: usize>(
    a: &ViState<G, NS>,
    b: &ViState<G, NS>,
) -> f64 {
    a.g.inverse().compose(&b.g).log().norm() + (a.s - b.s).norm()
}

/// `n` steps forward, the velocity of the last interval flipped, `n` steps back: the
/// distance from the start. (The reversed run starts at node `n` with `−v_{n−1}`.)
pub fn return_error<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    vi: &VariationalIntegrator,
    x0: &ViState<S::Group<f64>, NS>,
    n: usize,
) -> f64
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let u = SVector::<f64, NU>::zeros();
    let forward = run::<S, DOF, NS, NU>(sys, vi, x0, n);
    let mut x = ViState {
        g: forward[n].g,
        s: forward[n].s,
        v: -forward[n - 1].v,
    };
    for _ in 0..n {
        x = vi.step(sys, &x, &u, &u).expect("backward step").0;
    }
    config_distance(&forward[0], &x)
}

/// The largest relative energy error in each tenth of `n` steps. The midpoint scheme's
/// energy is read at the interval midpoint `(s_k + ½h v_k, v_k)`, where `v_k` is a
/// second-order velocity; the first-order scheme's at `(s_k, v_k)`.
pub fn energy_envelope<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    disc: Discretisation,
    h: f64,
    n: usize,
    x0: &ViState<S::Group<f64>, NS>,
) -> [f64; 10]
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let u = SVector::<f64, NU>::zeros();
    let e0 = energy::<_, f64, DOF, NS, NU>(sys, &x0.s, &x0.v);
    let vi = VariationalIntegrator::new(h)
        .with_discretisation(disc)
        .with_jacobian(JacobianPolicy::ReuseAcrossSteps);
    let mut x = ViState {
        g: x0.g,
        s: x0.s,
        v: vi.start(sys, &x0.s, &x0.v, &u).expect("start"),
    };
    let mut envelope = [0.0f64; 10];
    let mut cache = NewtonCache::default();
    for k in 0..n {
        x = vi
            .step_cached(sys, &x, &u, &u, &x.v, &mut cache)
            .expect("step")
            .0;
        let s = disc.evaluation_point(h, &x.s, &x.v);
        let e = energy::<_, f64, DOF, NS, NU>(sys, &s, &x.v);
        let tenth = &mut envelope[k * 10 / n];
        *tenth = tenth.max(((e - e0) / e0).abs());
    }
    envelope
}

/// Growth of the energy error over a run: last tenth's envelope over the first's. A bounded
/// error gives ≈ 1; a drift at rate ρ on top of a bounded error `a` gives
/// `(a + ρT)/(a + ρT/10)`, which exceeds 2 exactly when the drift over the run exceeds
/// 1.25 a; a random walk from zero gives √10 ≈ 3.2, a linear drift from zero 10.
pub fn envelope_growth(envelope: &[f64; 10]) -> f64 {
    envelope[9] / envelope[0]
}

/// Observed orders of `disc` over the halving sequence `h = T/16 … T/128`, T = 1 s,
/// unforced, against RK4 at T/2048 (its error, ~(h_ref ω)⁴, below 1e-10 for the test
/// systems, under a thousandth of the smallest variational error): `log₂` of successive
/// configuration errors' ratios.
pub fn observed_orders<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    x0: &ViState<S::Group<f64>, NS>,
    disc: Discretisation,
) -> Vec<f64>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let (t_end, n_ref) = (1.0, 2048);
    let u = SVector::<f64, NU>::zeros();
    let mut reference = *x0;
    for _ in 0..n_ref {
        reference =
            ContinuousModel::step(sys, RungeKutta::Rk4, t_end / n_ref as f64, &reference, &u)
                .expect("RK4 reference");
    }
    let errors: Vec<f64> = [16usize, 32, 64, 128]
        .iter()
        .map(|&n| {
            let vi = VariationalIntegrator::new(t_end / n as f64).with_discretisation(disc);
            config_distance(
                &reference,
                run::<S, DOF, NS, NU>(sys, &vi, x0, n).last().unwrap(),
            )
        })
        .collect();
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// The midpoint scheme's return to its start after `n` steps of `h` forward and `n` back
/// ([`return_error`]), its bound, and the first-order scheme's return. The bound: Newton
/// stops each step within `τ = tol·(1 + |v|)`, a perturbation of `v` of that size moves the
/// returned configuration by `K τ` where `K` (the run's sensitivity to its start velocity)
/// is measured by finite differences; 2n such perturbations add up to at most `2n K τ`,
/// taken ×4 for the other round-off.
pub fn reversibility<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    x0: &ViState<S::Group<f64>, NS>,
    h: f64,
    n: usize,
) -> (f64, f64, f64)
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::Midpoint);
    let forward = run::<S, DOF, NS, NU>(sys, &vi, x0, n);
    let v_max = forward.iter().map(|x| x.v.amax()).fold(0.0, f64::max);
    let delta = 1e-7;
    let mut perturbed = *x0;
    perturbed.v[0] += delta;
    let moved = config_distance(
        &forward[n],
        run::<S, DOF, NS, NU>(sys, &vi, &perturbed, n)
            .last()
            .unwrap(),
    );
    let sensitivity = (moved / delta).max(1.0);
    let bound = 4.0 * 2.0 * n as f64 * sensitivity * vi.newton_tol * (1.0 + v_max);
    let err = return_error::<S, DOF, NS, NU>(sys, &vi, x0, n);
    let first_order = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
    let err_first = return_error::<S, DOF, NS, NU>(sys, &first_order, x0, n);
    (err, bound, err_first)
}
