//! Partial derivatives of the reduced Lagrangian by dual numbers, and the momenta.
//!
//! Each partial (`∂ℓ/∂s`, `∂ℓ/∂v`, `∂ℓ/∂ξ`) is one vector-dual evaluation of `ℓ`, so a caller
//! pays only for the partials it needs. The functions are generic over the scalar, so
//! they can themselves be differentiated (nested duals) by the integrator's Newton
//! Jacobian and by the optimal-control transcription.

use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::dual::{grad_part, lift_vec, seeded};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use num_dual::{Derivative, Dual, DualVec};

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// `∇_ν ℓ(s + c ν, v + ν, ξ + D ν)` at `ν = 0`: the momentum paired with a shape variation
/// `ν`, one vector-dual evaluation of `ℓ` (not one per partial). `c = 0` leaves `s` fixed.
/// With `c = −h`, `D = −dexp⁻¹(hξ)A` it is the discrete momentum leaving a node; with
/// `c = 0`, `D = −A` the continuous `P − Aᵀμ`. A system's closed-form partials
/// ([`PrincipalKinematicSystem::closed_form_lagrangian_gradient`]) replace the dual
/// evaluation of `ℓ` (for a Lagrangian of a few dozen terms, a third of the `f64`
/// residual's cost, and more through the nested duals of the midpoint scheme's Jacobian).
pub fn pulled_back_gradient<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    c: f64,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
    d: &SMatrix<T, DOF, NS>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
{
    if let Some(partials) = sys.closed_form_lagrangian_gradient(s, v, xi) {
        return pulled_back_partials(partials, c, d);
    }
    // The inputs as vector duals in ν, built directly (their ν-derivatives are `c eᵢ`,
    // `eᵢ` and the rows of `D`): no dual arithmetic before ℓ itself.
    let unit = |i: usize, scale: T| {
        let mut e = SVector::<T, NS>::zeros();
        e[i] = scale;
        Derivative::some(e)
    };
    let sd = SVector::<Dv<T, NS>, NS>::from_fn(|i, _| {
        if c == 0.0 {
            Dv::<T, NS>::from_re(s[i])
        } else {
            DualVec::new(s[i], unit(i, T::from(c)))
        }
    });
    let vd = SVector::<Dv<T, NS>, NS>::from_fn(|i, _| DualVec::new(v[i], unit(i, T::one())));
    let xid = SVector::<Dv<T, NS>, DOF>::from_fn(|i, _| {
        DualVec::new(xi[i], Derivative::some(d.row(i).transpose()))
    });
    grad_part(&sys.reduced_lagrangian(&sd, &vd, &xid))
}

/// `∂ℓ/∂v + c ∂ℓ/∂s + Dᵀ ∂ℓ/∂ξ` from the partials `(∂ℓ/∂s, ∂ℓ/∂v, ∂ℓ/∂ξ)` of a system
/// that has them in closed form: the momentum [`pulled_back_gradient`] takes from `ℓ`.
fn pulled_back_partials<T: Real, const DOF: usize, const NS: usize>(
    (ls, lv, lxi): (SVector<T, NS>, SVector<T, NS>, SVector<T, DOF>),
    c: f64,
    d: &SMatrix<T, DOF, NS>,
) -> SVector<T, NS> {
    SVector::from_fn(|j, _| {
        let mut p = lv[j];
        if c != 0.0 {
            p += ls[j] * T::from(c);
        }
        for i in 0..DOF {
            p += d[(i, j)] * lxi[i];
        }
        p
    })
}

/// `pulled_back_partials` with `D = −dexp⁻¹ A` given by its factors: the momentum
/// `∂ℓ/∂v + c ∂ℓ/∂s − Aᵀ (dexp⁻ᵀ ∂ℓ/∂ξ)`. Contracting `∂ℓ/∂ξ` first takes `DOF (DOF + NS)`
/// products of duals where forming `D` takes `DOF NS (DOF + 1)`: with `DOF = 3`, `NS = 5`
/// the product `dexp⁻¹ A` is a sixth of the equality partials' instructions.
pub fn pulled_back_partials_factored<T: Real, const DOF: usize, const NS: usize>(
    (ls, lv, lxi): (SVector<T, NS>, SVector<T, NS>, SVector<T, DOF>),
    c: f64,
    dexp_inv: &SMatrix<T, DOF, DOF>,
    a: &SMatrix<T, DOF, NS>,
) -> SVector<T, NS> {
    // −dexp⁻ᵀ ∂ℓ/∂ξ, so that the momentum is `pulled_back_partials` with `A` for `D`.
    let neg_mu = SVector::<T, DOF>::from_fn(|i, _| {
        let mut m = dexp_inv[(0, i)] * lxi[0];
        for r in 1..DOF {
            m += dexp_inv[(r, i)] * lxi[r];
        }
        -m
    });
    pulled_back_partials((ls, lv, neg_mu), c, a)
}

/// `νᵀ` [`pulled_back_gradient`]: `d/dε ℓ(s + c εν, v + εν, ξ + εDν)` at `ε = 0`, one
/// evaluation of `ℓ` in a scalar dual along the fixed direction `ν` (where only the
/// contraction with `ν` is needed, `NS` times fewer derivative lanes than the gradient).
/// Its second derivatives in `(s, v, ξ, D)` are the curvature `∇²(νᵀP)` of a momentum.
pub fn pulled_back_directional<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    c: f64,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
    d: &SMatrix<T, DOF, NS>,
    nu: &SVector<f64, NS>,
) -> T
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dual<T>: Lift<S::Param>,
{
    let sd = SVector::<Dual<T>, NS>::from_fn(|i, _| {
        Dual::new(
            s[i],
            if c == 0.0 {
                T::zero()
            } else {
                T::from(c * nu[i])
            },
        )
    });
    let vd = SVector::<Dual<T>, NS>::from_fn(|i, _| Dual::new(v[i], T::from(nu[i])));
    let dnu = d * nu.map(T::from);
    let xid = SVector::<Dual<T>, DOF>::from_fn(|i, _| Dual::new(xi[i], dnu[i]));
    sys.reduced_lagrangian(&sd, &vd, &xid).eps
}

/// [`pulled_back_gradient`] for inputs that are first-order vector duals in `N` seeds `θ`
/// (value and `θ`-Jacobian of the momentum), by one hyper-dual evaluation of `ℓ`: the first
/// direction carries `θ`, the second the variation `ν`, so `∂²ℓ` comes out in one flat
/// `N × NS` block instead of nested duals (several times cheaper for the same numbers).
/// `ν` enters linearly, so the mixed part of `ξ + D ν` is `∂D/∂θ` exactly. A system with
/// closed-form partials ([`PrincipalKinematicSystem::closed_form_lagrangian_gradient`])
/// gives the momentum from them in first-order duals instead.
pub fn pulled_back_gradient_dual<
    S,
    const DOF: usize,
    const NS: usize,
    const NU: usize,
    const N: usize,
>(
    sys: &S,
    s: &SVector<Dv<f64, N>, NS>,
    c: f64,
    v: &SVector<Dv<f64, N>, NS>,
    xi: &SVector<Dv<f64, N>, DOF>,
    d: &SMatrix<Dv<f64, N>, DOF, NS>,
) -> SVector<Dv<f64, N>, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    // A system's closed-form partials, in first-order duals.
    if let Some(partials) = sys.closed_form_lagrangian_gradient(s, v, xi) {
        return pulled_back_partials(partials, c, d);
    }
    let lift = |x: &Dv<f64, N>, nu: Option<SMatrix<f64, 1, NS>>, mixed| {
        let mut h = Hd::<N, NS>::from_re(x.re);
        h.eps1 = x.eps;
        h.eps2 = Derivative::new(nu);
        h.eps1eps2 = Derivative::new(mixed);
        h
    };
    let unit = |i: usize, scale: f64| {
        let mut e = SMatrix::<f64, 1, NS>::zeros();
        e[i] = scale;
        e
    };
    let sh =
        SVector::<Hd<N, NS>, NS>::from_fn(|i, _| lift(&s[i], (c != 0.0).then(|| unit(i, c)), None));
    let vh = SVector::<Hd<N, NS>, NS>::from_fn(|i, _| lift(&v[i], Some(unit(i, 1.0)), None));
    let xih = SVector::<Hd<N, NS>, DOF>::from_fn(|i, _| {
        let row = SMatrix::<f64, 1, NS>::from_fn(|_, j| d[(i, j)].re);
        let mixed = SMatrix::<f64, N, NS>::from_fn(|a, j| grad_part(&d[(i, j)])[a]);
        lift(&xi[i], Some(row), Some(mixed))
    });
    let l = sys.reduced_lagrangian(&sh, &vh, &xih);
    let (g, jt) = split_hd(&l);
    SVector::from_fn(|j, _| DualVec::new(g[j], Derivative::some(jt.row(j).transpose())))
}

/// `∂ℓ/∂s` at `(s, v, ξ)`.
pub fn dl_ds<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Real,
    Dv<T, NS>: Lift<S::Param>,
{
    let (vd, xid) = (lift_vec::<T, NS, NS>(v), lift_vec::<T, NS, DOF>(xi));
    grad_part(&sys.reduced_lagrangian(&seeded(s), &vd, &xid))
}

/// `∂ℓ/∂v_s` at `(s, v, ξ)`.
pub fn dl_dv<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Real,
    Dv<T, NS>: Lift<S::Param>,
{
    let (sd, xid) = (lift_vec::<T, NS, NS>(s), lift_vec::<T, NS, DOF>(xi));
    grad_part(&sys.reduced_lagrangian(&sd, &seeded(v), &xid))
}

/// `μ = ∂ℓ/∂ξ` at `(s, v, ξ)`: the body momentum.
pub fn dl_dxi<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, DOF>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Real,
    Dv<T, DOF>: Lift<S::Param>,
{
    let (sd, vd) = (lift_vec::<T, DOF, NS>(s), lift_vec::<T, DOF, NS>(v));
    grad_part(&sys.reduced_lagrangian(&sd, &vd, &seeded(xi)))
}

/// The momenta at `(s, v, ξ = −A v)` and their Jacobians with respect to `v` (through both
/// the `v` and the `ξ` slot), in `f64`.
#[derive(Clone, Copy, Debug)]
pub struct MomentaJacobian<const DOF: usize, const NS: usize> {
    /// `∂ℓ/∂v`.
    pub p: SVector<f64, NS>,
    /// `∂ℓ/∂s`.
    pub ls: SVector<f64, NS>,
    /// `μ = ∂ℓ/∂ξ`.
    pub mu: SVector<f64, DOF>,
    /// `d(∂ℓ/∂v)/dv`.
    pub dp: nalgebra::SMatrix<f64, NS, NS>,
    /// `d(∂ℓ/∂s)/dv`.
    pub dls: nalgebra::SMatrix<f64, NS, NS>,
    /// `dμ/dv`.
    pub dmu: nalgebra::SMatrix<f64, DOF, NS>,
}

type Hd<const M: usize, const N: usize> = num_dual::HyperDualSVec64<M, N>;

/// `x` with first-direction seeds `e_i` (and optionally the same second-direction seeds).
fn seed_hd<const M: usize, const N: usize>(
    x: &SVector<f64, M>,
    first: bool,
    second: bool,
) -> SVector<Hd<M, N>, M> {
    SVector::from_fn(|i, _| {
        let mut h = Hd::<M, N>::from_re(x[i]);
        if first {
            let mut e = SVector::<f64, M>::zeros();
            e[i] = 1.0;
            h.eps1 = Derivative::some(e);
        }
        if second {
            let mut e = nalgebra::SMatrix::<f64, 1, N>::zeros();
            e[i] = 1.0;
            h.eps2 = Derivative::some(e);
        }
        h
    })
}

fn add_second_seeds<const M: usize, const N: usize>(x: &mut SVector<Hd<M, N>, N>) {
    for i in 0..N {
        let mut e = nalgebra::SMatrix::<f64, 1, N>::zeros();
        e[i] = 1.0;
        x[i].eps2 = Derivative::some(e);
    }
}

fn split_hd<const M: usize, const N: usize>(
    f: &Hd<M, N>,
) -> (SVector<f64, N>, nalgebra::SMatrix<f64, N, M>) {
    let g = f
        .eps2
        .0
        .map(|e| e.transpose())
        .unwrap_or_else(SVector::zeros);
    let j = f
        .eps1eps2
        .0
        .map(|m| m.transpose())
        .unwrap_or_else(nalgebra::SMatrix::zeros);
    (g, j)
}

/// Three hyper-dual evaluations of `ℓ` (one per partial), each carrying the first partials
/// and their `v`-Jacobian in flat arrays: much cheaper than nesting vector duals.
pub fn momenta_and_jacobians<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<f64, NS>,
    v: &SVector<f64, NS>,
    a: &nalgebra::SMatrix<f64, DOF, NS>,
) -> MomentaJacobian<DOF, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    // ∂/∂v of ∂ℓ/∂v: v carries both seeds, ξ = −A v only the first.
    let v1 = seed_hd::<NS, NS>(v, true, false);
    let v12 = seed_hd::<NS, NS>(v, true, true);
    let ah = a.map(Hd::<NS, NS>::from_re);
    let xi1 = -(ah * v1);
    let s0 = s.map(Hd::<NS, NS>::from_re);
    let (p, dp) = split_hd(&sys.reduced_lagrangian(&s0, &v12, &xi1));
    // ∂/∂v of ∂ℓ/∂s: s carries the second seeds.
    let s2 = seed_hd::<NS, NS>(s, false, true);
    let (ls, dls) = split_hd(&sys.reduced_lagrangian(&s2, &v1, &xi1));
    // ∂/∂v of ∂ℓ/∂ξ: ξ = −A v (first) plus its own second seeds.
    let v1m = seed_hd::<NS, DOF>(v, true, false);
    let am = a.map(Hd::<NS, DOF>::from_re);
    let mut xim = -(am * v1m);
    add_second_seeds(&mut xim);
    let sm = s.map(Hd::<NS, DOF>::from_re);
    let (mu, dmu) = split_hd(&sys.reduced_lagrangian(&sm, &v1m, &xim));
    MomentaJacobian {
        p,
        ls,
        mu,
        dp,
        dls,
        dmu,
    }
}
