//! The WIP's continuous model: the generic path (dmech, from ℓ, A and forcing) against
//! the hand-derived closed form and the independent reference vectors.

use dmech::continuous::{acceleration, coordinate_rate};
use dmech::PrincipalKinematicSystem;
use dmech_lie::lcg::Lcg;
use nalgebra::SVector;
use robots::wip::closed_form;
use robots::wip::state::{from_reduced, reduced_acceleration};
use robots::wip::{Wip, WipParams};

/// `Ẋ` by the generic path.
pub fn generic_xdot(w: &Wip, x: &SVector<f64, 9>, u: &SVector<f64, 2>) -> SVector<f64, 9> {
    let (g, s, v) = from_reduced(&w.params, x, [0.3, -0.2, 0.1, 0.05]);
    let xi = -(w.connection(&s) * v);
    let gd = coordinate_rate::<_, f64, 3>(&g, &xi);
    let a = acceleration::<Wip, f64, 3, 5, 2>(w, &s, &v, u).unwrap();
    let ar = reduced_acceleration(&w.params, &a);
    SVector::<f64, 9>::from_column_slice(&[
        gd[0], gd[1], gd[2], v[0], ar[0], ar[1], ar[2], ar[3], ar[4],
    ])
}

fn rel_err(a: &SVector<f64, 9>, b: &SVector<f64, 9>) -> f64 {
    let scale = b.amax().max(1e-300);
    (a - b).amax() / scale
}

#[test]
fn reference_vectors() {
    // `Ẋ = f(X, u)` of the continuous model at eight states and inputs (default parameters),
    // computed by an independent implementation of the model of docs/wip.md.
    let text = include_str!("../data/reference-vectors.json");
    let json: serde_json::Value = serde_json::from_str(text).unwrap();
    let w = Wip::default();
    let mut worst: f64 = 0.0;
    for vec in json["vectors"].as_array().unwrap() {
        let get = |k: &str| -> Vec<f64> {
            vec[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|z| z.as_f64().unwrap())
                .collect()
        };
        let x = SVector::<f64, 9>::from_column_slice(&get("X"));
        let u = SVector::<f64, 2>::from_column_slice(&get("u"));
        let want = SVector::<f64, 9>::from_column_slice(&get("Xdot"));
        let gen = generic_xdot(&w, &x, &u);
        let cf = closed_form::state_derivative(&w.params, &x, &u).unwrap();
        println!(
            "generic {:.3e} closed {:.3e}",
            rel_err(&gen, &want),
            rel_err(&cf, &want)
        );
        worst = worst.max(rel_err(&gen, &want)).max(rel_err(&cf, &want));
    }
    assert!(worst < 1e-10, "worst relative error {worst:e}");
    let _ = WipParams::default();
}

/// The generic model equals the hand-derived closed form at 1,000 random states and inputs,
/// to 1e-10 relative (both are ~60 flops deep in f64 from the same parameters; the mass
/// matrix has condition ≈ 1e4, so ε·κ ≈ 2e-12 bounds the difference).
#[test]
fn generic_equals_closed_form_at_random_states() {
    let w = Wip::default();
    let mut rng = Lcg(7);
    let mut worst: f64 = 0.0;
    for _ in 0..1000 {
        let x = SVector::<f64, 9>::from_fn(|i, _| match i {
            0 | 1 => rng.range(-3.0, 3.0),
            2 => rng.range(-6.0, 6.0),
            3 => rng.range(-1.2, 1.2),
            4 => rng.range(-4.0, 4.0),
            5 => rng.range(-1.0, 1.0),
            6 => rng.range(-3.0, 3.0),
            _ => rng.range(-3.0, 3.0),
        });
        let u = SVector::<f64, 2>::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let a = generic_xdot(&w, &x, &u);
        let b = closed_form::state_derivative(&w.params, &x, &u).unwrap();
        worst = worst.max(rel_err(&a, &b));
    }
    println!("worst relative difference over 1000 states: {worst:.3e}");
    assert!(worst < 1e-10);
}

/// The Euler–Lagrange equation of qR, from the generic path, is the motor circuit
/// L_m i̇R + k_e n_wm (φ̇R − α̇) = uR − R_m iR (and the same for qL).
#[test]
fn motor_circuit_from_generic_path() {
    let w = Wip::default();
    let p = w.params;
    let mut rng = Lcg(11);
    for _ in 0..200 {
        let s = SVector::<f64, 5>::from_fn(|_, _| rng.range(-1.0, 1.0));
        let v = SVector::<f64, 5>::from_fn(|_, _| rng.range(-3.0, 3.0));
        let u = SVector::<f64, 2>::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let a = acceleration::<Wip, f64, 3, 5, 2>(&w, &s, &v, &u).unwrap();
        for (side, (iv, phiv)) in [(3usize, 1usize), (4, 2)].into_iter().enumerate() {
            let lhs = p.L_m * a[iv] + p.k_e * p.n_wm * (v[phiv] - v[0]);
            let rhs = u[side] - p.R_m * v[iv];
            // terms are O(10) V; ε-level relative agreement after a 5×5 solve (κ ≈ 1e4).
            assert!(
                (lhs - rhs).abs() < 1e-10 * (1.0 + rhs.abs()),
                "{lhs} vs {rhs}"
            );
        }
    }
}

/// Upright rest with zero input is an equilibrium, and its linearisation has exactly one
/// eigenvalue with positive real part, and it is real.
#[test]
fn upright_equilibrium_has_one_unstable_real_eigenvalue() {
    let w = Wip::default();
    let zero = SVector::<f64, 9>::zeros();
    let u0 = SVector::<f64, 2>::zeros();
    let f0 = generic_xdot(&w, &zero, &u0);
    assert!(f0.amax() == 0.0, "rest is an equilibrium: {f0}");
    // Linearise the 6 non-cyclic states (α, v_α, v_d, v_θ, iR, iL) by dual numbers.
    use num_dual::DualSVec64;
    type D = DualSVec64<6>;
    let (_, jac) = dmech_lie::dual::value_and_jacobian(
        |z: &SVector<D, 6>| {
            let p = w.params;
            let vr = (z[2] + z[3] * p.d) / p.r;
            let vl = (z[2] - z[3] * p.d) / p.r;
            let s =
                SVector::<D, 5>::new(z[0], D::from(0.0), D::from(0.0), D::from(0.0), D::from(0.0));
            let v = SVector::<D, 5>::new(z[1], vr, vl, z[4], z[5]);
            let a = acceleration::<Wip, D, 3, 5, 2>(&w, &s, &v, &SVector::zeros()).unwrap();
            SVector::<D, 6>::new(
                z[1],
                a[0],
                (a[1] + a[2]) * (p.r / 2.0),
                (a[1] - a[2]) * (p.r / (2.0 * p.d)),
                a[3],
                a[4],
            )
        },
        &SVector::<f64, 6>::zeros(),
    );
    let eig = jac.complex_eigenvalues();
    let mut ev: Vec<_> = eig.iter().collect();
    ev.sort_by(|a, b| b.re.total_cmp(&a.re));
    println!("eigenvalues of the upright linearisation (α, v_α, v_d, v_θ, iR, iL):");
    for e in &ev {
        println!("  {:+.6e} {:+.6e}i", e.re, e.im);
    }
    let unstable: Vec<_> = ev.iter().filter(|e| e.re > 0.0).collect();
    assert_eq!(unstable.len(), 1, "exactly one unstable eigenvalue");
    assert!(
        unstable[0].im.abs() < 1e-9 * unstable[0].re,
        "and it is real"
    );
}

/// Parameters can be dual numbers: the derivative of the momentum-matching residual with
/// respect to the body mass, by a dual-number parameter, equals central differences
/// (step 1e-6 relative: truncation ~1e-12, round-off ~1e-10 of the residual's scale).
#[test]
fn derivatives_with_respect_to_parameters() {
    use dmech::variational::momentum_matching_residual;
    use dmech::{Discretisation, ForcingQuadrature};
    use num_dual::DualSVec64;
    type P = DualSVec64<1>;
    let base = WipParams::default();
    let mut pd = base.map(P::from);
    pd.m_b = P::from(base.m_b).derivative(0);
    let wd = Wip::new(pd);
    let s0 = SVector::<f64, 5>::new(0.1, 0.3, -0.2, 0.01, 0.02);
    let v0 = SVector::<f64, 5>::new(0.4, 5.0, 3.0, 0.2, -0.1);
    let s1 = s0 + v0 * 0.005;
    let v1 = SVector::<f64, 5>::new(0.5, 5.2, 2.9, 0.25, -0.05);
    let u = SVector::<f64, 2>::new(1.0, -0.5);
    let l = |x: &SVector<f64, 5>| x.map(P::from);
    let r = momentum_matching_residual::<Wip<P>, P, 3, 5, 2>(
        &wd,
        0.005,
        Discretisation::FirstOrder,
        ForcingQuadrature::Right,
        &l(&s0),
        &l(&v0),
        &u.map(P::from),
        &l(&s1),
        &l(&v1),
        &u.map(P::from),
    );
    let fd = |m_b: f64| {
        let w = Wip::new(WipParams { m_b, ..base });
        momentum_matching_residual::<Wip, f64, 3, 5, 2>(
            &w,
            0.005,
            Discretisation::FirstOrder,
            ForcingQuadrature::Right,
            &s0,
            &v0,
            &u,
            &s1,
            &v1,
            &u,
        )
    };
    let dm = 1e-6 * base.m_b;
    let want = (fd(base.m_b + dm) - fd(base.m_b - dm)) / (2.0 * dm);
    let got = r.map(|z| z.eps.0.map(|e| e[0]).unwrap_or(0.0));
    let scale = want.amax();
    println!("d residual / d m_b: dual {got:?} vs central differences {want:?}");
    assert!((got - want).amax() < 1e-6 * scale, "{got} vs {want}");
}

/// The closed form `wip diagnose` differentiates equals the generic path with every
/// extension a `Wip` can carry (radius offsets, `J_e`, a changed payload) and an external
/// shape force, at 500 random states; and its first derivatives (dual numbers through
/// both) agree too. Tolerance as above: ε·κ with κ ≈ 1e4 (the negative `J_e` lowers the
/// wheel inertia by under 1 %, so κ barely moves).
#[test]
fn closed_form_with_extensions_equals_generic_path() {
    use dmech::continuous::acceleration_with_force;
    use num_dual::{Derivative, DualSVec64};
    use robots::wip::closed_form::shape_acceleration;
    type D2 = DualSVec64<2>;
    let mut rng = Lcg(23);
    let mut worst: f64 = 0.0;
    let mut worst_d: f64 = 0.0;
    for _ in 0..500 {
        let mut p = robots::wip::WipParams::default();
        p.m_b *= rng.range(0.8, 1.3);
        p.l *= rng.range(0.8, 1.3);
        p.d_v *= rng.range(0.5, 4.0);
        let je = (p.k_e * p.n_wm).powi(2) * p.L_m / (p.R_m * p.R_m);
        let offsets = [rng.range(-2e-3, 2e-3), rng.range(-2e-3, 2e-3)];
        let s = SVector::<f64, 5>::new(
            rng.range(-1.0, 1.0),
            rng.range(-9.0, 9.0),
            rng.range(-9.0, 9.0),
            0.0,
            0.0,
        );
        let v = SVector::<f64, 5>::from_fn(|_, _| rng.range(-3.0, 3.0));
        let u = SVector::<f64, 2>::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let f = SVector::<f64, 5>::new(
            rng.range(-0.05, 0.05),
            rng.range(-0.01, 0.01),
            rng.range(-0.01, 0.01),
            0.0,
            0.0,
        );
        // Two dual directions: the tilt and the payload mass.
        let mut pd = p.map(D2::from);
        pd.m_b = D2::from(p.m_b).derivative(1);
        let mut w = Wip::new(pd);
        w.wheel_radius_offsets = offsets.map(D2::from);
        w.quasi_static_inertia = D2::from(je);
        let sd = s.map(D2::from);
        let mut sd = sd;
        sd[0] = D2::from(s[0]).derivative(0);
        let vd = v.map(D2::from);
        let ud = u.map(D2::from);
        let fd = f.map(D2::from);
        let a = acceleration_with_force::<Wip<D2>, D2, 3, 5, 2>(&w, &sd, &vd, &ud, &fd).unwrap();
        let b = shape_acceleration(
            &w,
            sd[0],
            [vd[0], vd[1], vd[2]],
            [vd[3], vd[4]],
            [fd[0], fd[1], fd[2]],
        )
        .unwrap();
        for j in 0..3 {
            let scale = 1.0 + a[j].re.abs();
            worst = worst.max((a[j].re - b[j].re).abs() / scale);
            let (da, db) = match (&a[j].eps, &b[j].eps) {
                (Derivative(Some(x)), Derivative(Some(y))) => (*x, *y),
                _ => panic!("both paths carry derivatives"),
            };
            for k in 0..2 {
                worst_d = worst_d.max((da[k] - db[k]).abs() / (1.0 + da[k].abs()));
            }
        }
    }
    println!("worst relative difference: values {worst:.3e}, derivatives {worst_d:.3e}");
    assert!(worst < 1e-10 && worst_d < 1e-10);
}

/// The algebraic-current model (`NS = 3`, its own ℓ, A and forcing) through the generic
/// path equals (a) the full model's mechanical accelerations with the currents at their
/// steady state `i = (u − k_e n_wm (φ̇ − α̇))/R_m` (the mass matrix has no current–mechanics
/// block, so `L_m` does not enter them), and (b) the hand-derived closed form with those
/// currents, at 500 random states and inputs. Tolerance as above, ε·κ with κ ≈ 1e4.
#[test]
fn algebraic_current_model_equals_full_model_at_steady_current() {
    use robots::wip::algebraic_current::WipAlgebraicCurrent;
    use robots::wip::closed_form::shape_acceleration;
    let full = Wip::default();
    let alg = WipAlgebraicCurrent::new(full);
    let p = full.params;
    let mut rng = Lcg(31);
    let mut worst: f64 = 0.0;
    for _ in 0..500 {
        let s3 = SVector::<f64, 3>::new(
            rng.range(-1.0, 1.0),
            rng.range(-9.0, 9.0),
            rng.range(-9.0, 9.0),
        );
        let v3 = SVector::<f64, 3>::from_fn(|_, _| rng.range(-3.0, 3.0));
        let u = SVector::<f64, 2>::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let i = [
            p.steady_current(u[0], v3[1] - v3[0]),
            p.steady_current(u[1], v3[2] - v3[0]),
        ];
        // Same formula, multiplication by 1/R_m instead of division: a few ulps apart.
        let ia = alg.currents(&v3, &u);
        for (x, y) in ia.iter().zip(&i) {
            assert!(
                (x - y).abs() <= 4.0 * f64::EPSILON * (1.0 + y.abs()),
                "{x} vs {y}"
            );
        }
        let a = acceleration::<WipAlgebraicCurrent, f64, 3, 3, 2>(&alg, &s3, &v3, &u).unwrap();
        let s5 = SVector::<f64, 5>::new(s3[0], s3[1], s3[2], rng.range(-1.0, 1.0), 0.3);
        let v5 = SVector::<f64, 5>::new(v3[0], v3[1], v3[2], i[0], i[1]);
        let b = acceleration::<Wip, f64, 3, 5, 2>(&full, &s5, &v5, &u).unwrap();
        let c = shape_acceleration(&full, s3[0], [v3[0], v3[1], v3[2]], i, [0.0; 3]).unwrap();
        for j in 0..3 {
            let scale = 1.0 + a[j].abs();
            worst = worst
                .max((a[j] - b[j]).abs() / scale)
                .max((a[j] - c[j]).abs() / scale);
        }
        // The full model's current rows are at rest there: i̇ = 0 is the steady state.
        assert!(b[3].abs() < 1e-9 * (1.0 + b[1].abs()) && b[4].abs() < 1e-9 * (1.0 + b[2].abs()));
        assert_eq!(
            alg.connection(&s3),
            full.connection(&s5).fixed_columns::<3>(0)
        );
    }
    println!("worst relative difference: {worst:.3e}");
    assert!(worst < 1e-10, "worst relative difference {worst:e}");
}

/// A WIP with its mass, centre-of-mass height, viscous friction and rotor inertia drawn
/// around the defaults, random wheel-radius offsets and the quasi-static inertia `J_e` on:
/// every term the closed forms carry.
fn perturbed_wip(rng: &mut Lcg) -> Wip {
    let mut p = WipParams::default();
    p.m_b *= rng.range(0.8, 1.3);
    p.l *= rng.range(0.8, 1.3);
    p.d_v *= rng.range(0.5, 4.0);
    p.I_m *= rng.range(0.5, 2.0);
    let mut w = Wip::new(p);
    w.wheel_radius_offsets = [rng.range(-2e-3, 2e-3), rng.range(-2e-3, 2e-3)];
    w.quasi_static_inertia = (p.k_e * p.n_wm).powi(2) * p.L_m / (p.R_m * p.R_m);
    w
}

/// The closed form each WIP model supplies to the transcriptions
/// (`PrincipalKinematicSystem::closed_form_acceleration`: the full model with its motor
/// circuits, the algebraic-current model at its steady currents) equals the generic path,
/// values and Jacobians in `s`, `v` and `u` (three vector-dual passes), at 300 random
/// states, inputs and parameters with wheel-radius offsets and a nonzero `J_e`. Tolerance
/// as above: ε·κ with κ ≈ 1e4 (the derivatives go through the same factorisation).
#[test]
fn closed_form_acceleration_of_both_models_equals_generic_path() {
    use dmech_lie::dual::{jacobian_part, seeded};
    use num_dual::DualSVec64;
    use robots::wip::algebraic_current::WipAlgebraicCurrent;

    /// Worst relative difference of value and Jacobians in (s, v, u).
    fn compare<S, const NS: usize>(
        sys: &S,
        s: &SVector<f64, NS>,
        v: &SVector<f64, NS>,
        u: &SVector<f64, 2>,
    ) -> f64
    where
        S: PrincipalKinematicSystem<3, NS, 2, Param = f64>,
    {
        let c = |x: &SVector<f64, NS>| x.map(DualSVec64::<NS>::from_re);
        let cu = |x: &SVector<f64, 2>| x.map(DualSVec64::<NS>::from_re);
        let c2 = |x: &SVector<f64, NS>| x.map(DualSVec64::<2>::from_re);
        let generic = [
            acceleration::<S, _, 3, NS, 2>(sys, &seeded(s), &c(v), &cu(u)).unwrap(),
            acceleration::<S, _, 3, NS, 2>(sys, &c(s), &seeded(v), &cu(u)).unwrap(),
        ];
        let closed = [
            sys.closed_form_acceleration(&seeded(s), &c(v), &cu(u))
                .unwrap(),
            sys.closed_form_acceleration(&c(s), &seeded(v), &cu(u))
                .unwrap(),
        ];
        let gu = acceleration::<S, _, 3, NS, 2>(sys, &c2(s), &c2(v), &seeded(u)).unwrap();
        let fu = sys
            .closed_form_acceleration(&c2(s), &c2(v), &seeded(u))
            .unwrap();
        let rel = |a: f64, b: f64| (a - b).abs() / (1.0 + b.abs());
        let mut worst = 0.0f64;
        for (g, f) in generic.iter().zip(&closed) {
            let (jg, jf) = (jacobian_part(g), jacobian_part(f));
            for i in 0..NS {
                worst = worst.max(rel(f[i].re, g[i].re));
                for j in 0..NS {
                    worst = worst.max(rel(jf[(i, j)], jg[(i, j)]));
                }
            }
        }
        let (jg, jf) = (jacobian_part(&gu), jacobian_part(&fu));
        for i in 0..NS {
            for j in 0..2 {
                worst = worst.max(rel(jf[(i, j)], jg[(i, j)]));
            }
        }
        worst
    }

    let mut rng = Lcg(47);
    let mut worst: f64 = 0.0;
    for _ in 0..300 {
        let full = perturbed_wip(&mut rng);
        let s = SVector::<f64, 5>::new(
            rng.range(-1.0, 1.0),
            rng.range(-9.0, 9.0),
            rng.range(-9.0, 9.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let v = SVector::<f64, 5>::from_fn(|_, _| rng.range(-3.0, 3.0));
        let u = SVector::<f64, 2>::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        worst = worst.max(compare(&full, &s, &v, &u));
        let alg = WipAlgebraicCurrent::new(full);
        let (s3, v3) = (
            s.fixed_rows::<3>(0).into_owned(),
            v.fixed_rows::<3>(0).into_owned(),
        );
        worst = worst.max(compare(&alg, &s3, &v3, &u));
    }
    println!("worst relative difference: {worst:.3e}");
    assert!(worst < 1e-10, "worst relative difference {worst:e}");
}

/// The closed-form partials of ℓ each WIP model supplies
/// (`PrincipalKinematicSystem::closed_form_lagrangian_gradient`) equal the dual-number
/// partials of its `reduced_lagrangian`, values and Jacobians in `(s, v, ξ)` (one
/// vector-dual pass of 13 or 9 lanes), at 300 random points and parameters with a nonzero
/// `J_e`. Both are a few dozen flops from the same numbers: 1e-12 relative bounds their
/// round-off with margin (no solve amplifies it here).
#[test]
fn closed_form_lagrangian_gradient_of_both_models_equals_dual_partials() {
    use dmech::partials::{dl_ds, dl_dv, dl_dxi};
    use dmech_lie::dual::jacobian_part;
    use num_dual::{Derivative, DualSVec64};
    use robots::wip::algebraic_current::WipAlgebraicCurrent;

    fn compare<S, const NS: usize, const N: usize>(sys: &S, z: &SVector<f64, N>) -> f64
    where
        S: PrincipalKinematicSystem<3, NS, 2, Param = f64>,
    {
        assert_eq!(N, 2 * NS + 3);
        let seeded = SVector::<DualSVec64<N>, N>::from_fn(|i, _| {
            let mut e = SVector::<f64, N>::zeros();
            e[i] = 1.0;
            DualSVec64::new(z[i], Derivative::some(e))
        });
        let s = SVector::<DualSVec64<N>, NS>::from_fn(|i, _| seeded[i]);
        let v = SVector::<DualSVec64<N>, NS>::from_fn(|i, _| seeded[NS + i]);
        let xi = SVector::<DualSVec64<N>, 3>::from_fn(|i, _| seeded[2 * NS + i]);
        let (ls, lv, lxi) = sys.closed_form_lagrangian_gradient(&s, &v, &xi).unwrap();
        let refs = (
            dl_ds::<S, _, 3, NS, 2>(sys, &s, &v, &xi),
            dl_dv::<S, _, 3, NS, 2>(sys, &s, &v, &xi),
            dl_dxi::<S, _, 3, NS, 2>(sys, &s, &v, &xi),
        );
        let rel = |a: f64, b: f64| (a - b).abs() / (1.0 + b.abs());
        let mut worst = 0.0f64;
        let mut check = |got: &[DualSVec64<N>], want: &[DualSVec64<N>]| {
            for (g, w) in got.iter().zip(want) {
                worst = worst.max(rel(g.re, w.re));
                let (gj, wj) = (
                    jacobian_part(&SVector::<_, 1>::new(*g)),
                    jacobian_part(&SVector::<_, 1>::new(*w)),
                );
                for j in 0..N {
                    worst = worst.max(rel(gj[j], wj[j]));
                }
            }
        };
        check(ls.as_slice(), refs.0.as_slice());
        check(lv.as_slice(), refs.1.as_slice());
        check(lxi.as_slice(), refs.2.as_slice());
        worst
    }

    let mut rng = Lcg(53);
    let mut worst: f64 = 0.0;
    for _ in 0..300 {
        let full = perturbed_wip(&mut rng);
        let z13 = SVector::<f64, 13>::from_fn(|_, _| rng.range(-3.0, 3.0));
        worst = worst.max(compare::<_, 5, 13>(&full, &z13));
        let z9 = SVector::<f64, 9>::from_fn(|_, _| rng.range(-3.0, 3.0));
        worst = worst.max(compare::<_, 3, 9>(&WipAlgebraicCurrent::new(full), &z9));
    }
    println!("worst relative difference: {worst:.3e}");
    assert!(worst < 1e-12, "worst relative difference {worst:e}");
}
