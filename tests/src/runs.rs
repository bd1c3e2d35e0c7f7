//! Runs of the variational integrators without input, and what the tests read from them:
//! the distance between configurations, the return error of a reversed run, the energy
//! error's envelope over a long run.

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
