//! The generic integrators on systems with known answers (no WIP code involved).

use dmech::continuous::{acceleration, ContinuousModel, ContinuousState, RungeKutta};
use dmech::{energy, Discretisation, VariationalIntegrator, ViState};
use dmech_lie::{LieGroup, Se2};
use dmech_tests::{DifferentialDrive, VariableRadiusRobot};
use nalgebra::{SVector, Vector3};

/// Unforced differential drive: the exact solution is a circle, `g(t_k) = g₀ exp(t_k ξ)` with
/// constant wheel rates. The discrete momentum-matching equation is solved exactly by
/// constant v (dexp⁻¹(hξ) − dexp⁻¹(−hξ) = −h ad_ξ, and Aᵀ ad_ξᵀ μ = 0 here), so the VI
/// reproduces the circle to round-off at any step size.
#[test]
fn differential_drive_drives_the_exact_circle() {
    let sys = DifferentialDrive {
        m: 2.0,
        j: 0.05,
        i: 0.002,
        r: 0.05,
        d: 0.15,
    };
    let v0 = SVector::<f64, 2>::new(12.0, 7.0);
    let xi = -(dmech::PrincipalKinematicSystem::connection(&sys, &SVector::<f64, 2>::zeros()) * v0);
    let g0 = Se2::new(0.3, -0.2, 0.4);
    let empty = SVector::<f64, 0>::zeros();
    // The continuous model: zero acceleration.
    let a = acceleration(&sys, &SVector::zeros(), &v0, &empty).unwrap();
    assert!(a.amax() < 1e-13, "{a}");
    for h in [0.1, 0.01] {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
        let mut x = ViState {
            g: g0,
            s: SVector::zeros(),
            v: v0,
        };
        let mut worst: f64 = 0.0;
        for k in 1..=1000 {
            x = vi.step(&sys, &x, &empty, &empty).unwrap().0;
            let exact = g0.compose(&Se2::exp(&(xi * (k as f64 * h))));
            let err = (x.g.x - exact.x)
                .abs()
                .max((x.g.y - exact.y).abs())
                .max((x.g.theta - exact.theta).abs());
            worst = worst.max(err);
            assert!((x.v - v0).amax() < 1e-12);
        }
        println!("h = {h}: worst deviation from the exact circle over 1000 steps {worst:.2e}");
        // 1000 compositions, each rounding ~ε·(‖p‖ + 1) with ‖p‖ ≲ 3: a random walk well below 1e-11.
        assert!(worst < 1e-11);
    }
}

/// A shape-dependent connection: the continuous model conserves the energy (RK4 at a
/// small step, error O(h⁴)), which fails if the `Ȧ` terms of the generic equations were
/// wrong; and the VI converges to it with order 1.
#[test]
fn shape_dependent_connection_energy_and_convergence() {
    let sys = VariableRadiusRobot {
        m: 3.0,
        c: 0.08,
        j: 0.06,
        i: 0.003,
        i_psi: 0.01,
        k_psi: 2.0,
        r0: 0.05,
        eps: 0.3,
        d: 0.15,
    };
    let empty = SVector::<f64, 0>::zeros();
    let s0 = Vector3::new(0.0, 0.0, 0.6);
    let v0 = Vector3::new(9.0, 4.0, 1.5);
    let g0 = Se2::new(0.0, 0.0, 0.0);
    let e0 = energy(&sys, &s0, &v0);
    let t_end: f64 = 2.0;

    let h_ref = 1e-4;
    let mut y = ContinuousState {
        g: g0,
        s: s0,
        v: v0,
    };
    let mut e_err: f64 = 0.0;
    for _ in 0..(t_end / h_ref).round() as usize {
        y = ContinuousModel::step(&sys, RungeKutta::Rk4, h_ref, &y, &empty).unwrap();
        e_err = e_err.max((energy(&sys, &y.s, &y.v) - e0).abs());
    }
    println!("continuous model, RK4 h = {h_ref}: max |E − E0| = {e_err:.2e} (E0 = {e0:.4})");
    // RK4's local error ~ (h ω)⁵ E with ω ≲ 30 rad/s here: (3e-3)⁵ ≈ 2e-13 per step, 2e4 steps.
    assert!(e_err < 1e-8 * e0);

    let hs = [0.02, 0.01, 0.005, 0.0025];
    let mut errs = Vec::new();
    for &h in &hs {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
        let mut x = ViState {
            g: g0,
            s: s0,
            v: v0,
        };
        for _ in 0..(t_end / h).round() as usize {
            x = vi.step(&sys, &x, &empty, &empty).unwrap().0;
        }
        let err = (x.g.x - y.g.x)
            .abs()
            .max((x.g.y - y.g.y).abs())
            .max((x.g.theta - y.g.theta).abs())
            .max((x.s - y.s).amax());
        errs.push(err);
    }
    let order = (errs[0] / errs[3]).ln() / (hs[0] / hs[3]).ln();
    println!("VI configuration errors {errs:?}, order {order:.3}");
    assert!((order - 1.0).abs() < 0.2, "order {order}");
}

/// `dmech::partials::pulled_back_partials_factored` (`∂ℓ/∂ξ` contracted with `dexp⁻ᵀ`
/// first, then `−Aᵀ`) against the momentum written with `D = −dexp⁻¹ A` formed:
/// `∂ℓ/∂v + c ∂ℓ/∂s + Dᵀ ∂ℓ/∂ξ`, on random blocks. The same sums in another order: each
/// entry sums at most 11 terms whose magnitudes add to less than 0.5 + 0.025 + 9·0.125 <
/// 1.7, so either order errs by at most 11·ε·1.7.
#[test]
fn factored_momentum_equals_the_one_through_d() {
    use dmech::partials::pulled_back_partials_factored;
    use dmech_tests::random_system::Lcg;
    use nalgebra::SMatrix;
    let mut rng = Lcg(0x5EED);
    for _ in 0..100 {
        let ls = SVector::<f64, 4>::from_fn(|_, _| rng.uniform());
        let lv = SVector::<f64, 4>::from_fn(|_, _| rng.uniform());
        let lxi = SVector::<f64, 3>::from_fn(|_, _| rng.uniform());
        let dinv = SMatrix::<f64, 3, 3>::from_fn(|_, _| rng.uniform());
        let a = SMatrix::<f64, 3, 4>::from_fn(|_, _| rng.uniform());
        for c in [0.0, -0.05] {
            let got = pulled_back_partials_factored((ls, lv, lxi), c, &dinv, &a);
            let d = -(dinv * a);
            let want = lv + ls * c + d.transpose() * lxi;
            assert!((got - want).amax() <= 2.0 * 11.0 * 1.7 * f64::EPSILON);
        }
    }
}
