//! One property suite, written once and run by every group: axioms, exp/log, Ad/ad,
//! dexp/dexp⁻¹ against dual-number and central-difference derivatives, and the Jacobians
//! of compose/inverse/act. Random elements always include the hard points: the identity,
//! tangents of norm 1e-8 and 1e-4, ordinary ones, and rotations within 1e-6 of π.
//!
//! Tolerances (derived, not tuned):
//! - `TOL_ALG = 1e-10`: each map is a fixed sequence of ≲ 200 flops on entries bounded by
//!   |ξ| ≤ 2π (rotation) and ≤ 4 (translation), so the forward error is ≲ 200·ε·4² ≈ 7e-12;
//!   composites of up to four maps stay below 1e-10. Near θ = π the quaternion log goes
//!   through atan2 (condition ≈ 1) and the SE(2)/SE(3) `V⁻¹` has entries ≤ π/2, so the
//!   same bound holds there.
//! - `TOL_FD = 1e-6`: central differences with step `h = 1e-5` carry `h²/6·|f'''| ≲ 2e-10·M`
//!   truncation plus `ε·|f|/h ≈ 1e-10` round-off; third derivatives of these maps grow
//!   at most like `1/cos²(θ/4)` towards θ = π (a factor ≈ 2), so 1e-6 holds with margin.
//! - `TOL_SERIES = 1e-12`: the bar for derivatives at and near zero.

use dmech_lie::{GroupAction, LieGroup, Rn, Se2, Se3, So2, So3};
use nalgebra::{SMatrix, SVector};
use num_dual::{jacobian, Dual2SVec64, DualSVec64};
use proptest::prelude::*;

const TOL_ALG: f64 = 1e-10;
const TOL_FD: f64 = 1e-6;
const TOL_SERIES: f64 = 1e-12;
const PI: f64 = std::f64::consts::PI;

type D<const N: usize> = DualSVec64<N>;

/// Which tangent components are rotational (to place samples near θ = π).
trait Sampled<const DOF: usize, const DIM: usize>: GroupAction<DOF, DIM, Scalar = f64> {
    const ROT: &'static [usize];
}
impl Sampled<1, 2> for So2<f64> {
    const ROT: &'static [usize] = &[0];
}
impl Sampled<3, 2> for Se2<f64> {
    const ROT: &'static [usize] = &[2];
}
impl Sampled<3, 3> for So3<f64> {
    const ROT: &'static [usize] = &[0, 1, 2];
}
impl Sampled<6, 3> for Se3<f64> {
    const ROT: &'static [usize] = &[3, 4, 5];
}
impl Sampled<4, 4> for Rn<f64, 4> {
    const ROT: &'static [usize] = &[];
}

/// A tangent from a raw direction and a "kind": 0 zero, 1 1e-8, 2 1e-4, 3 ordinary,
/// 4 rotation part of norm π − 1e-6 (translation ordinary).
fn tangent<G: Sampled<DOF, DIM>, const DOF: usize, const DIM: usize>(
    dir: &[f64],
    kind: u8,
) -> SVector<f64, DOF> {
    let v = SVector::<f64, DOF>::from_column_slice(&dir[..DOF]);
    match kind {
        0 => SVector::zeros(),
        1 => v * 1e-8,
        2 => v * 1e-4,
        3 => {
            // Ordinary: up to 2 per component, rotation norm capped at 3 (< π, inside the
            // injectivity radius where log ∘ exp is the identity).
            let mut v = v * 2.0;
            let n: f64 = G::ROT.iter().map(|&i| v[i] * v[i]).sum::<f64>().sqrt();
            if n > 3.0 {
                for &i in G::ROT {
                    v[i] *= 3.0 / n;
                }
            }
            v
        }
        _ => {
            let mut v = v;
            let n: f64 = G::ROT.iter().map(|&i| v[i] * v[i]).sum::<f64>().sqrt();
            if n > 1e-3 {
                for &i in G::ROT {
                    v[i] *= (PI - 1e-6) / n;
                }
            }
            v
        }
    }
}

fn max_abs<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> f64 {
    m.iter().fold(0.0, |a, x| a.max(x.abs()))
}

/// Compare two elements by their action on a few points (insensitive to q vs −q).
fn same_element<G: GroupAction<DOF, DIM, Scalar = f64>, const DOF: usize, const DIM: usize>(
    a: &G,
    b: &G,
) -> f64 {
    let mut err: f64 = 0.0;
    for k in 0..=DIM {
        let mut p = SVector::<f64, DIM>::zeros();
        if k < DIM {
            p[k] = 1.0;
        }
        err = err.max(max_abs(&(a.act(&p) - b.act(&p))));
    }
    err
}

/// Matrix exponential by scaling and squaring of the Taylor series (reference, f64 only).
fn expm<const N: usize>(a: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let s = (max_abs(a) * N as f64).log2().ceil().max(0.0) as i32 + 1;
    let b = a / 2f64.powi(s);
    let mut term = SMatrix::<f64, N, N>::identity();
    let mut sum = term;
    for k in 1..20 {
        term = term * b / k as f64;
        sum += term;
    }
    for _ in 0..s {
        sum = sum * sum;
    }
    sum
}

/// `Σ_k c_k ad_ξ^k` evaluated in any scalar (the reference series for dexp and dexp⁻¹).
fn ad_series<G: LieGroup<DOF>, const DOF: usize>(
    xi: &SVector<G::Scalar, DOF>,
    coeffs: &[f64],
) -> SMatrix<G::Scalar, DOF, DOF> {
    let ad = G::ad(xi);
    let mut pow = SMatrix::<G::Scalar, DOF, DOF>::identity();
    let mut sum = SMatrix::<G::Scalar, DOF, DOF>::zeros();
    for &c in coeffs {
        sum += pow * G::Scalar::from(c);
        pow *= ad;
    }
    sum
}
/// `dexp_ξ = Σ ad^k/(k+1)!`, to ad⁷ (next term ≤ |ξ|⁸/9! < 1e-37 at |ξ| = 1e-4).
const DEXP_SERIES: [f64; 8] = [
    1.0,
    0.5,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
];
/// `dexp⁻¹_ξ = Σ B_k ad^k / k!`, to ad⁶.
const DEXPINV_SERIES: [f64; 7] = [1.0, -0.5, 1.0 / 12.0, 0.0, -1.0 / 720.0, 0.0, 1.0 / 30240.0];

fn check_group<G, const DOF: usize, const DIM: usize>(
    d1: &[f64],
    d2: &[f64],
    d3: &[f64],
    k1: u8,
    k2: u8,
    pt: &[f64],
) where
    G: Sampled<DOF, DIM>,
    G::With<DualSVec64<DOF>>: GroupAction<DOF, DIM>,
    G::With<DualSVec64<DIM>>: GroupAction<DOF, DIM>,
    G::With<Dual2SVec64<DOF>>: GroupAction<DOF, DIM>,
{
    let x1 = tangent::<G, DOF, DIM>(d1, k1);
    let x2 = tangent::<G, DOF, DIM>(d2, k2);
    let x3 = tangent::<G, DOF, DIM>(d3, 3);
    let (a, b, c) = (G::exp(&x1), G::exp(&x2), G::exp(&x3));
    let p = SVector::<f64, DIM>::from_column_slice(&pt[..DIM]);
    let e = G::identity();

    // Group axioms.
    assert!(same_element(&a.compose(&b).compose(&c), &a.compose(&b.compose(&c))) < TOL_ALG);
    assert!(same_element(&a.compose(&e), &a) < TOL_ALG);
    assert!(same_element(&e.compose(&a), &a) < TOL_ALG);
    assert!(same_element(&a.compose(&a.inverse()), &e) < TOL_ALG);
    assert!(max_abs(&(a.compose(&b).act(&p) - a.act(&b.act(&p)))) < TOL_ALG);

    // exp ∘ log and log ∘ exp (inside the injectivity radius: |rotation| < π).
    assert!(same_element(&G::exp(&a.log()), &a) < TOL_ALG);
    assert!(max_abs(&(a.log() - x1)) < TOL_ALG, "log(exp ξ) = ξ");
    assert!(
        same_element(&b.rplus(&a.rminus(&b)), &a) < TOL_ALG,
        "X ⊕ (Y ⊖ X) = Y"
    );

    // Ad: exp(Ad_g η) = g exp(η) g⁻¹, and Ad_{exp ξ} = exp(ad_ξ).
    let lhs = G::exp(&(a.adjoint() * x3));
    let rhs = a.compose(&c).compose(&a.inverse());
    assert!(same_element(&lhs, &rhs) < TOL_ALG, "Ad definition");
    let ad_exp = expm(&G::ad(&x1));
    assert!(
        max_abs(&(a.adjoint() - ad_exp)) < TOL_ALG * 10.0,
        "Ad_exp = exp(ad)"
    );

    // dexp⁻¹ · dexp = I and dexp⁻¹_ξ Ad_{exp ξ} = dexp⁻¹_{−ξ}.
    let i: SMatrix<f64, DOF, DOF> = SMatrix::identity();
    assert!(max_abs(&(G::dexp_inv(&x1) * G::dexp(&x1) - i)) < TOL_ALG);
    assert!(max_abs(&(G::dexp_inv(&x1) * a.adjoint() - G::dexp_inv(&(-x1)))) < TOL_ALG);
    assert!(max_abs(&(G::rjac(&x1) * G::rjac_inv(&x1) - i)) < TOL_ALG);

    // dexp against dual numbers: d/dδ log(exp(ξ+δ) exp(ξ)⁻¹) at δ = 0.
    let a_inv_d = <G::With<D<DOF>> as LieGroup<DOF>>::from_re(&a.inverse().re());
    let x1d = x1.map(D::<DOF>::from);
    let (_, jd) = jacobian(
        |dl: SVector<D<DOF>, DOF>| {
            <G::With<D<DOF>> as LieGroup<DOF>>::exp(&(x1d + dl))
                .compose(&a_inv_d)
                .log()
        },
        &SVector::<f64, DOF>::zeros(),
    );
    assert!(max_abs(&(jd - G::dexp(&x1))) < TOL_ALG, "dexp vs dual");
    // … and against central differences.
    let hstep = 1e-5;
    let mut jfd = SMatrix::<f64, DOF, DOF>::zeros();
    for k in 0..DOF {
        let mut dl = SVector::<f64, DOF>::zeros();
        dl[k] = hstep;
        let fp = G::exp(&(x1 + dl)).compose(&a.inverse()).log();
        let fm = G::exp(&(x1 - dl)).compose(&a.inverse()).log();
        jfd.set_column(k, &((fp - fm) / (2.0 * hstep)));
    }
    assert!(
        max_abs(&(jfd - G::dexp(&x1))) < TOL_FD,
        "dexp vs central differences"
    );

    // Jacobians of compose, inverse and act against dual numbers (right perturbations).
    let lift = |g: &G| <G::With<D<DOF>> as LieGroup<DOF>>::from_re(&g.re());
    let (ad_, bd_) = (lift(&a), lift(&b));
    let z = SVector::<f64, DOF>::zeros();
    let zinv = lift(&a.compose(&b).inverse());
    let (_, j_a) = jacobian(
        |dl: SVector<D<DOF>, DOF>| zinv.compose(&ad_.rplus(&dl).compose(&bd_)).log(),
        &z,
    );
    let (_, j_b) = jacobian(
        |dl: SVector<D<DOF>, DOF>| zinv.compose(&ad_.compose(&bd_.rplus(&dl))).log(),
        &z,
    );
    let (ja, jb) = a.compose_jacobians(&b);
    assert!(max_abs(&(j_a - ja)) < TOL_ALG, "compose J_X");
    assert!(max_abs(&(j_b - jb)) < TOL_ALG, "compose J_Y");
    let (_, j_inv) = jacobian(
        |dl: SVector<D<DOF>, DOF>| ad_.compose(&ad_.rplus(&dl).inverse()).log(),
        &z,
    );
    assert!(
        max_abs(&(j_inv - a.inverse_jacobian())) < TOL_ALG,
        "inverse J"
    );
    let pd = p.map(D::<DOF>::from);
    let (_, j_act_g) = jacobian(|dl: SVector<D<DOF>, DOF>| ad_.rplus(&dl).act(&pd), &z);
    let (jg, jp) = a.act_jacobians(&p);
    assert!(max_abs(&(j_act_g - jg)) < TOL_ALG, "act J_g");
    let ap = <G::With<D<DIM>> as LieGroup<DOF>>::from_re(&a.re());
    let (_, j_act_p) = jacobian(|q: SVector<D<DIM>, DIM>| ap.act(&q), &p);
    assert!(max_abs(&(j_act_p - jp)) < TOL_ALG, "act J_p");
}

/// At and near zero: derivatives of exp, log and dexp⁻¹ by dual numbers (first and second
/// order) are finite and equal the `ad` power series to 1e-12.
type W<G, U, const DOF: usize, const DIM: usize> = <G as LieGroup<DOF>>::With<U>;

fn check_near_zero<G, const DOF: usize, const DIM: usize>(dir: &[f64], eta: &[f64], scale: f64)
where
    G: Sampled<DOF, DIM>,
    G::With<DualSVec64<DOF>>: GroupAction<DOF, DIM>,
    G::With<DualSVec64<DIM>>: GroupAction<DOF, DIM>,
    G::With<Dual2SVec64<DOF>>: GroupAction<DOF, DIM>,
{
    let xi = SVector::<f64, DOF>::from_column_slice(&dir[..DOF]) * scale;
    let eta = SVector::<f64, DOF>::from_column_slice(&eta[..DOF]);

    // First derivatives of ξ ↦ dexp⁻¹_ξ η and ξ ↦ dexp_ξ η: closed form vs series.
    let etad = eta.map(D::<DOF>::from);
    let (v1, j1) = jacobian(
        |x: SVector<D<DOF>, DOF>| <W<G, D<DOF>, DOF, DIM> as LieGroup<DOF>>::dexp_inv(&x) * etad,
        &xi,
    );
    let (v2, j2) = jacobian(
        |x: SVector<D<DOF>, DOF>| {
            ad_series::<W<G, D<DOF>, DOF, DIM>, DOF>(&x, &DEXPINV_SERIES) * etad
        },
        &xi,
    );
    assert!(j1.iter().all(|x| x.is_finite()));
    assert!(max_abs(&(v1 - v2)) < TOL_SERIES && max_abs(&(j1 - j2)) < TOL_SERIES);
    let (_, j1) = jacobian(
        |x: SVector<D<DOF>, DOF>| <W<G, D<DOF>, DOF, DIM> as LieGroup<DOF>>::dexp(&x) * etad,
        &xi,
    );
    let (_, j2) = jacobian(
        |x: SVector<D<DOF>, DOF>| ad_series::<W<G, D<DOF>, DOF, DIM>, DOF>(&x, &DEXP_SERIES) * etad,
        &xi,
    );
    assert!(max_abs(&(j1 - j2)) < TOL_SERIES, "dexp' near zero");

    // d/dδ log(exp(ξ) exp(δ)) at δ = 0 is J_r(ξ)⁻¹ = dexp⁻¹_{−ξ}: through exp AND log.
    let g = <W<G, D<DOF>, DOF, DIM> as LieGroup<DOF>>::from_re(&G::exp(&xi).re());
    let (_, jl) = jacobian(
        |dl: SVector<D<DOF>, DOF>| {
            g.compose(&<W<G, D<DOF>, DOF, DIM> as LieGroup<DOF>>::exp(&dl))
                .log()
        },
        &SVector::zeros(),
    );
    let series = ad_series::<G, DOF>(&(-xi), &DEXPINV_SERIES);
    assert!(max_abs(&(jl - series)) < TOL_SERIES, "log∘exp derivative");

    // Second derivatives (Hessian of a scalar projection of dexp⁻¹) finite and = series.
    type H<const N: usize> = Dual2SVec64<N>;
    let etah = eta.map(H::<DOF>::from);
    let f_closed = |x: SVector<H<DOF>, DOF>| {
        (<W<G, H<DOF>, DOF, DIM> as LieGroup<DOF>>::dexp_inv(&x) * etah).sum()
    };
    let f_series = |x: SVector<H<DOF>, DOF>| {
        (ad_series::<W<G, H<DOF>, DOF, DIM>, DOF>(&x, &DEXPINV_SERIES) * etah).sum()
    };
    let (_, _, h1) = num_dual::hessian(f_closed, &xi);
    let (_, _, h2) = num_dual::hessian(f_series, &xi);
    assert!(h1.iter().all(|x| x.is_finite()));
    assert!(
        max_abs(&(h1 - h2)) < TOL_SERIES,
        "Hessian of dexp⁻¹ near zero"
    );
    // And the Hessian of the exp map's action, through exp's series branch.
    let f_exp = |x: SVector<H<DOF>, DOF>| {
        let p = SVector::<H<DOF>, DIM>::from_element(H::<DOF>::from(0.7));
        <W<G, H<DOF>, DOF, DIM> as LieGroup<DOF>>::exp(&x)
            .act(&p)
            .sum()
    };
    let (_, _, h3) = num_dual::hessian(f_exp, &xi);
    assert!(h3.iter().all(|x| x.is_finite()), "Hessian of exp finite");
}

fn dir() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-1.0..1.0f64, 6)
}
fn kind() -> impl Strategy<Value = u8> {
    0u8..5
}
fn near_zero_scale() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(1e-8), Just(1e-6), Just(1e-4)]
}

macro_rules! group_suite {
    ($name:ident, $g:ty, $dof:literal, $dim:literal) => {
        mod $name {
            use super::*;
            proptest! {
                #![proptest_config(ProptestConfig::with_cases(256))]
                #[test]
                fn properties(d1 in dir(), d2 in dir(), d3 in dir(), k1 in kind(), k2 in kind(),
                              pt in prop::collection::vec(-2.0..2.0f64, 4)) {
                    check_group::<$g, $dof, $dim>(&d1, &d2, &d3, k1, k2, &pt);
                }
                #[test]
                fn derivatives_near_zero(d in dir(), eta in dir(), s in near_zero_scale()) {
                    check_near_zero::<$g, $dof, $dim>(&d, &eta, s);
                }
            }
        }
    };
}

group_suite!(so2, So2<f64>, 1, 2);
group_suite!(se2, Se2<f64>, 3, 2);
group_suite!(so3, So3<f64>, 3, 3);
group_suite!(se3, Se3<f64>, 6, 3);
group_suite!(r4, Rn<f64, 4>, 4, 4);

/// At exactly ξ = 0 the dual derivative of exp is the identity (not NaN, not zero).
#[test]
fn exp_derivative_at_exact_zero_is_identity() {
    let z = SVector::<f64, 6>::zeros();
    let (_, j) = jacobian(
        |x: SVector<D<6>, 6>| {
            let g = Se3::exp(&x);
            let mut v = SVector::<D<6>, 6>::zeros();
            v.fixed_rows_mut::<3>(0).copy_from(&g.translation);
            v.fixed_rows_mut::<3>(3)
                .copy_from(&(g.rotation.v * D::<6>::from(2.0)));
            v
        },
        &z,
    );
    assert_eq!(j, SMatrix::<f64, 6, 6>::identity());
    let (_, j) = jacobian(
        |x: SVector<D<3>, 3>| {
            let g = Se2::exp(&x);
            SVector::<D<3>, 3>::new(g.x, g.y, g.theta)
        },
        &SVector::zeros(),
    );
    assert_eq!(j, SMatrix::<f64, 3, 3>::identity());
}
