//! Systems whose constraints leave group directions free, through [`WithMomentum`]: the
//! Chaplygin sleigh against its closed form and its known end state, the vertical rolling
//! disk written two ways, and random systems of the class (constraint, discrete momentum
//! equation, orders, reversibility, energy).

use dmech::continuous::acceleration;
use dmech::partials::dl_dxi;
use dmech::{
    energy, Discretisation, NonholonomicSystem, PrincipalKinematicSystem, VariationalIntegrator,
    ViState, WithMomentum,
};
use dmech_lie::{LieGroup, Rn, Se2};
use dmech_tests::momentum_systems::{
    ChaplyginSleigh, RandomMomentumSystem, RollingDisk, RollingDiskOnPlane, RollingDiskWithYaw,
};
use dmech_tests::random_system::{
    GroupFamily, Lcg, RandomSystemSpec, Se2Family, Se3Family, So3Family,
};
use dmech_tests::runs::{energy_envelope, envelope_growth, observed_orders, reversibility, run};
use nalgebra::{SVector, Vector2};
use num_dual::Dual64;

const BOTH: [Discretisation; 2] = [Discretisation::FirstOrder, Discretisation::Midpoint];

fn sleigh() -> WithMomentum<ChaplyginSleigh, 0, 2> {
    WithMomentum::new(ChaplyginSleigh {
        m: 1.0,
        a: 0.3,
        j: 0.05,
    })
}

// ---------------------------------------------------------------------------------------
// The Chaplygin sleigh
// ---------------------------------------------------------------------------------------

/// The generic equations (the extended system's acceleration, `(v̇, ω̇)`) against the
/// sleigh's classical ones at random states, and the energy's time derivative along them:
/// both are sums of a few O(|v|²) products, so agreement is to a few ulps of that scale.
#[test]
fn the_sleigh_follows_its_closed_form_and_conserves_energy() {
    let sys = sleigh();
    let mut rng = Lcg(7);
    for _ in 0..50 {
        let p = Vector2::new(2.0 * rng.uniform(), 4.0 * rng.uniform());
        let sigma = Vector2::zeros();
        let a = acceleration::<_, f64, 3, 2, 0>(&sys, &sigma, &p, &SVector::zeros()).unwrap();
        let (vdot, wdot) = sys.system.closed_form_rates(p[0], p[1]);
        let scale = 1.0 + p.norm_squared();
        assert!(
            (a[0] - vdot).abs() + (a[1] - wdot).abs() <= 32.0 * f64::EPSILON * scale,
            "generic ({:.17}, {:.17}) against closed form ({vdot:.17}, {wdot:.17})",
            a[0],
            a[1]
        );
        let e = energy::<_, f64, 3, 2, 0>(&sys, &sigma, &p);
        let e_closed = sys.system.closed_form_energy(p[0], p[1]);
        assert!((e - e_closed).abs() <= 8.0 * f64::EPSILON * scale);
        // dE/dt along (σ̇, ṗ) = (p, a), by one dual number.
        let sd = SVector::<Dual64, 2>::from_fn(|i, _| Dual64::new(sigma[i], p[i]));
        let pd = SVector::<Dual64, 2>::from_fn(|i, _| Dual64::new(p[i], a[i]));
        let edot = energy::<_, Dual64, 3, 2, 0>(&sys, &sd, &pd).eps;
        assert!(
            edot.abs() <= 32.0 * f64::EPSILON * scale,
            "dE/dt = {edot:.2e}"
        );
    }
}

/// 10⁵ midpoint steps of 1 ms from a generic start: the yaw rate decays (at about
/// `m a v/(J + m a²) ≈ 1.7 /s` once the sleigh moves at its final speed, so far below 10⁻³
/// of its start within the run), and the sleigh ends moving straight at `√(2E/m)` of its
/// initial energy, to 1e-6; the energy envelope does not grow.
#[test]
fn the_sleigh_ends_straight_at_the_speed_of_its_energy() {
    let sys = sleigh();
    let (h, n) = (1e-3, 100_000);
    let x0 = ViState {
        g: Se2::new(0.0, 0.0, 0.0),
        s: Vector2::zeros(),
        v: Vector2::new(0.2, 2.0),
    };
    let e0 = energy::<_, f64, 3, 2, 0>(&sys, &x0.s, &x0.v);
    let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::Midpoint);
    let end = *run::<_, 3, 2, 0>(&sys, &vi, &x0, n).last().unwrap();
    let speed = (2.0 * e0 / sys.system.m).sqrt();
    println!(
        "sleigh: ω {:.2e} → {:.2e}, speed {:.12} against √(2E/m) = {speed:.12}",
        x0.v[1], end.v[1], end.v[0]
    );
    assert!(
        end.v[1].abs() < 1e-3 * x0.v[1].abs(),
        "yaw rate {:.2e}",
        end.v[1]
    );
    assert!(
        ((end.v[0] - speed) / speed).abs() < 1e-6,
        "speed {} against {speed}",
        end.v[0]
    );
    let env = energy_envelope::<_, 3, 2, 0>(&sys, Discretisation::Midpoint, h, n, &x0);
    println!("sleigh energy envelope per tenth: {}", sci(&env));
    assert!(
        env.iter().all(|e| *e <= env[0]),
        "the midpoint energy error grows after the transient: {}",
        sci(&env)
    );
}

// ---------------------------------------------------------------------------------------
// The rolling disk both ways
// ---------------------------------------------------------------------------------------

/// The disk as a principal-kinematic system on R² (heading a shape variable) and with its
/// yaw free on SE(2) (heading a group angle), under the same constant torques from the same
/// state: the two discretisations of each differ (the first evaluates the heading at a
/// node or a midpoint, the second moves along an arc), so the final poses differ by
/// O(h^p). Halving h must divide the difference by at least 2^p·0.8 (order p − 0.3) at
/// every step of the sequence, and the finest difference must be small.
#[test]
fn the_rolling_disk_two_ways_agrees_to_the_schemes_order() {
    let disk = RollingDisk {
        m: 1.2,
        r: 0.15,
        i: 0.01,
        j: 0.02,
    };
    let plane = RollingDiskOnPlane(disk);
    let yaw = WithMomentum::new(RollingDiskWithYaw(disk));
    let (theta0, theta_dot, phi_dot) = (0.3, 1.5, 8.0);
    let u = Vector2::new(0.02, -0.05);
    let t_end = 1.0;
    for (disc, p) in [
        (Discretisation::FirstOrder, 1.0),
        (Discretisation::Midpoint, 2.0),
    ] {
        let diffs: Vec<f64> = [32usize, 64, 128, 256]
            .iter()
            .map(|&n| {
                let h = t_end / n as f64;
                let vi = VariationalIntegrator::new(h).with_discretisation(disc);
                let mut a = ViState {
                    g: Rn(Vector2::zeros()),
                    s: Vector2::new(theta0, 0.0),
                    v: Vector2::new(theta_dot, phi_dot),
                };
                a.v = vi.start(&plane, &a.s, &a.v, &u).unwrap();
                let mut b = ViState {
                    g: Se2::new(0.0, 0.0, theta0),
                    s: Vector2::new(0.0, 0.0),
                    v: Vector2::new(phi_dot, theta_dot),
                };
                b.v = vi.start(&yaw, &b.s, &b.v, &u).unwrap();
                for _ in 0..n {
                    a = vi.step(&plane, &a, &u, &u).unwrap().0;
                    b = vi.step(&yaw, &b, &u, &u).unwrap().0;
                }
                (a.g.0 - b.g.translation()).norm()
                    + (a.s[0] - b.g.theta).abs()
                    + (a.s[1] - b.s[0]).abs()
            })
            .collect();
        let ratios: Vec<f64> = diffs.windows(2).map(|w| w[0] / w[1]).collect();
        println!(
            "disk two ways, {disc:?}: differences {}, ratios {ratios:.2?}",
            sci(&diffs)
        );
        assert!(
            ratios.iter().all(|r| *r >= 0.8 * 2f64.powf(p)),
            "{disc:?}: differences {} do not shrink at order {p}",
            sci(&diffs)
        );
    }
}

// ---------------------------------------------------------------------------------------
// Random systems of the class
// ---------------------------------------------------------------------------------------

fn conservative() -> RandomSystemSpec {
    RandomSystemSpec {
        damping: 0.0,
        cyclic_first: false,
        shape_dependence: 0.5,
    }
}

type Extended<F, const DOF: usize, const NS: usize, const NM: usize> =
    WithMomentum<RandomMomentumSystem<F, DOF, NS, NM>, NS, NM>;

fn draw<F, const DOF: usize, const NS: usize, const NM: usize>(
    seed: u64,
) -> Extended<F, DOF, NS, NM>
where
    F: GroupFamily<DOF>,
{
    WithMomentum::new(RandomMomentumSystem::<F, DOF, NS, NM>::draw(
        seed,
        conservative(),
    ))
}

/// A start drawn from the seed: pose near the identity, shapes, shape velocities and
/// free velocities O(1); `σ = 0`.
fn random_start<F, const DOF: usize, const NS: usize, const NM: usize, const NA: usize>(
    seed: u64,
) -> ViState<F::G<f64>, NA>
where
    F: GroupFamily<DOF>,
{
    let mut rng = Lcg(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x0DD_BA11);
    let pose = SVector::<f64, DOF>::from_fn(|_, _| rng.uniform());
    ViState {
        g: <F::G<f64> as LieGroup<DOF>>::exp(&pose),
        s: SVector::from_fn(|i, _| if i < NS { rng.uniform() } else { 0.0 }),
        v: SVector::from_fn(|_, _| 1.6 * rng.uniform()),
    }
}

/// The discrete constraint read with the system's own `A` and `E`:
/// `log(g_k⁻¹ g_{k+1})/h = −A(s_*) v_k + E(s_*) p_k` at the scheme's evaluation point, to
/// round-off (the bound of the principal-kinematic test), and the discrete momentum
/// equation of the free directions, written out from the system's `E` and `∂ℓ/∂ξ`:
///
/// ```text
/// E(s_k)ᵀ [dexp⁻¹(hξ_k)ᵀ μ_k − dexp⁻¹(−hξ_{k−1})ᵀ μ_{k−1}] = 0      (unforced)
/// ```
///
/// to Newton's tolerance on the velocity times the inertia scale, plus a few ulps of `|μ|`.
fn check_constraint_and_momentum<
    F,
    const DOF: usize,
    const NS: usize,
    const NM: usize,
    const NA: usize,
>(
    seed: u64,
) where
    F: GroupFamily<DOF>,
    Extended<F, DOF, NS, NM>:
        PrincipalKinematicSystem<DOF, NA, NS, Param = f64, Group<f64> = F::G<f64>>,
{
    let sys = draw::<F, DOF, NS, NM>(seed);
    let x0 = random_start::<F, DOF, NS, NM, NA>(seed);
    let h = 0.02;
    let split = |x: &SVector<f64, NA>| {
        (
            Extended::<F, DOF, NS, NM>::shape_part(x),
            Extended::<F, DOF, NS, NM>::momentum_part(x),
        )
    };
    for disc in BOTH {
        let vi = VariationalIntegrator::new(h).with_discretisation(disc);
        let path = run::<_, DOF, NA, NS>(&sys, &vi, &x0, 200);
        let xi_mu = |x: &ViState<F::G<f64>, NA>| {
            let se = disc.evaluation_point(h, &x.s, &x.v);
            let ((s, _), (v, p)) = (split(&se), split(&x.v));
            let xi = -(sys.system.connection(&s) * v) + sys.system.free_directions(&s) * p;
            let mu = dl_dxi::<_, f64, DOF, NA, NS>(&sys, &se, &x.v, &xi);
            (xi, mu)
        };
        for w in path.windows(3) {
            let (prev, a, b) = (&w[0], &w[1], &w[2]);
            let (xi, mu) = xi_mu(a);
            let observed = a.g.inverse().compose(&b.g).log() / h;
            let bound = 64.0 * f64::EPSILON * (1.0 + a.g.log().norm() + h * xi.norm()) / h;
            let err = (observed - xi).norm();
            assert!(
                err <= bound,
                "{} NS={NS} NM={NM} seed {seed} {disc:?}: constraint {err:.2e} > {bound:.2e}",
                F::NAME
            );
            let (xi_prev, mu_prev) = xi_mu(prev);
            let dinv = |z: SVector<f64, DOF>| <F::G<f64> as LieGroup<DOF>>::dexp_inv(&z);
            let e_k = sys.system.free_directions(&split(&a.s).0);
            let residual = e_k.transpose()
                * (dinv(xi * h).transpose() * mu - dinv(xi_prev * (-h)).transpose() * mu_prev);
            let tol = 10.0 * vi.newton_tol * (1.0 + a.v.amax()) + 16.0 * f64::EPSILON * mu.norm();
            assert!(
                residual.amax() <= tol,
                "{} NS={NS} NM={NM} seed {seed} {disc:?}: discrete momentum equation off by \
                 {:.2e} (bound {tol:.2e})",
                F::NAME,
                residual.amax()
            );
        }
    }
}

#[test]
fn random_systems_keep_the_constraint_and_the_discrete_momentum_equation() {
    for seed in 0..3 {
        check_constraint_and_momentum::<Se2Family, 3, 1, 1, 2>(seed);
        check_constraint_and_momentum::<Se2Family, 3, 2, 2, 4>(seed);
        check_constraint_and_momentum::<So3Family, 3, 1, 2, 3>(seed);
        check_constraint_and_momentum::<Se3Family, 6, 2, 1, 3>(seed);
    }
}

/// Observed orders ([`dmech_tests::runs::observed_orders`], the principal-kinematic
/// test's sequence and its argument for a deviation under 0.1 at the last pair).
fn check_orders<F, const DOF: usize, const NS: usize, const NM: usize, const NA: usize>(seed: u64)
where
    F: GroupFamily<DOF>,
    Extended<F, DOF, NS, NM>:
        PrincipalKinematicSystem<DOF, NA, NS, Param = f64, Group<f64> = F::G<f64>>,
{
    let sys = draw::<F, DOF, NS, NM>(seed);
    let x0 = random_start::<F, DOF, NS, NM, NA>(seed);
    for (disc, p) in BOTH.into_iter().zip([1.0, 2.0]) {
        let orders = observed_orders::<_, DOF, NA, NS>(&sys, &x0, disc);
        println!(
            "{} NS={NS} NM={NM} seed {seed} {disc:?}: observed orders {orders:.3?}",
            F::NAME
        );
        let last = *orders.last().unwrap();
        assert!(
            (last - p).abs() < 0.1,
            "{} NS={NS} NM={NM} seed {seed} {disc:?}: observed orders {orders:.3?}, expected {p}",
            F::NAME
        );
    }
}

#[test]
fn random_systems_converge_at_orders_one_and_two() {
    for seed in 0..2 {
        check_orders::<Se2Family, 3, 1, 1, 2>(seed);
        check_orders::<Se2Family, 3, 2, 2, 4>(seed);
        check_orders::<So3Family, 3, 1, 2, 3>(seed);
        check_orders::<Se3Family, 6, 2, 1, 3>(seed);
    }
}

/// The midpoint scheme is reversible on the extended system, within the bound of
/// [`dmech_tests::runs::reversibility`], and the first-order scheme misses by far more.
fn check_reversibility<F, const DOF: usize, const NS: usize, const NM: usize, const NA: usize>(
    seed: u64,
) where
    F: GroupFamily<DOF>,
    Extended<F, DOF, NS, NM>:
        PrincipalKinematicSystem<DOF, NA, NS, Param = f64, Group<f64> = F::G<f64>>,
{
    let sys = draw::<F, DOF, NS, NM>(seed);
    let x0 = random_start::<F, DOF, NS, NM, NA>(seed);
    let (err, bound, err_first) = reversibility::<_, DOF, NA, NS>(&sys, &x0, 0.02, 150);
    println!(
        "{} NS={NS} NM={NM} seed {seed}: back to {err:.1e} (bound {bound:.1e}); first order {err_first:.1e}",
        F::NAME
    );
    assert!(
        err <= bound,
        "{} seed {seed}: midpoint returns {err:.2e} > {bound:.2e}",
        F::NAME
    );
    assert!(
        err_first > 1e3 * bound,
        "{} seed {seed}: first order returned to {err_first:.2e}",
        F::NAME
    );
}

#[test]
fn the_midpoint_scheme_is_reversible_on_random_systems() {
    for seed in 0..3 {
        check_reversibility::<Se2Family, 3, 1, 1, 2>(seed);
        check_reversibility::<So3Family, 3, 1, 2, 3>(seed);
        check_reversibility::<Se3Family, 6, 2, 1, 3>(seed);
    }
}

/// Energy over 10⁵ steps of conservative random systems with one shape variable and one
/// free direction: the midpoint scheme's envelope does not grow (the growth statistic of
/// the principal-kinematic test: < 2 means a drift under 1.25× the bounded error).
#[test]
fn midpoint_energy_has_no_secular_trend_over_1e5_steps() {
    for seed in 0..2 {
        let sys = draw::<Se2Family, 3, 1, 1>(seed);
        let x0 = random_start::<Se2Family, 3, 1, 1, 2>(seed);
        let env = energy_envelope::<_, 3, 2, 1>(&sys, Discretisation::Midpoint, 0.02, 100_000, &x0);
        let first =
            energy_envelope::<_, 3, 2, 1>(&sys, Discretisation::FirstOrder, 0.02, 100_000, &x0);
        println!(
            "SE(2) NS=1 NM=1 seed {seed}: midpoint {:.2e} → {:.2e} (growth {:.2}); first order {:.2e} → {:.2e} (growth {:.2})",
            env[0], env[9], envelope_growth(&env), first[0], first[9], envelope_growth(&first)
        );
        assert!(
            envelope_growth(&env) < 2.0,
            "seed {seed}: midpoint energy drifts: {}",
            sci(&env)
        );
    }
}

/// Numbers in scientific notation, for the messages.
fn sci(xs: &[f64]) -> String {
    let parts: Vec<String> = xs.iter().map(|x| format!("{x:.2e}")).collect();
    format!("[{}]", parts.join(", "))
}
