//! Partial derivatives of the reduced Lagrangian by dual numbers, and the momenta.
//!
//! Each partial (`∂ℓ/∂s`, `∂ℓ/∂v`, `∂ℓ/∂ξ`) is one vector-dual evaluation of `ℓ`, so a caller
//! pays only for the partials it needs. The functions are generic over the scalar, so
//! they can themselves be differentiated (nested duals) by the integrator's Newton
//! Jacobian and by the optimal-control transcription.

use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::SVector;
use num_dual::{Derivative, DualVec};

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

fn lift_vec<T: Real, const N: usize, const M: usize>(x: &SVector<T, M>) -> SVector<Dv<T, N>, M> {
    x.map(Dv::<T, N>::from_re)
}

/// `x` as vector duals seeded with the unit directions (the input of a gradient).
pub fn seeded<T: Real, const N: usize>(x: &SVector<T, N>) -> SVector<Dv<T, N>, N> {
    SVector::from_fn(|i, _| {
        let mut e = SVector::<T, N>::zeros();
        e[i] = T::one();
        DualVec::new(x[i], Derivative::some(e))
    })
}

/// The gradient part of a vector dual (zero if it carries none).
pub fn grad_part<T: Real, const N: usize>(f: &Dv<T, N>) -> SVector<T, N> {
    f.eps.0.unwrap_or_else(SVector::zeros)
}

/// Value and Jacobian of `f: Rᴺ → Rᴹ` by vector duals, generic over the scalar.
pub fn value_and_jacobian<T: Real, const N: usize, const M: usize>(
    f: impl Fn(&SVector<Dv<T, N>, N>) -> SVector<Dv<T, N>, M>,
    x: &SVector<T, N>,
) -> (SVector<T, M>, nalgebra::SMatrix<T, M, N>) {
    let y = f(&seeded(x));
    let val = y.map(|z| z.re);
    let jac = nalgebra::SMatrix::<T, M, N>::from_fn(|i, j| grad_part(&y[i])[j]);
    (val, jac)
}

/// `∂ℓ/∂s` at `(s, v, ξ)`.
pub fn dl_ds<S, T, const DOF: usize, const DIM: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, DIM, NS, NU>,
    T: Real,
    Dv<T, NS>: Lift<S::Param>,
{
    let (vd, xid) = (lift_vec::<T, NS, NS>(v), lift_vec::<T, NS, DOF>(xi));
    grad_part(&sys.reduced_lagrangian(&seeded(s), &vd, &xid))
}

/// `∂ℓ/∂v_s` at `(s, v, ξ)`.
pub fn dl_dv<S, T, const DOF: usize, const DIM: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, DIM, NS, NU>,
    T: Real,
    Dv<T, NS>: Lift<S::Param>,
{
    let (sd, xid) = (lift_vec::<T, NS, NS>(s), lift_vec::<T, NS, DOF>(xi));
    grad_part(&sys.reduced_lagrangian(&sd, &seeded(v), &xid))
}

/// `μ = ∂ℓ/∂ξ` at `(s, v, ξ)`: the body momentum.
pub fn dl_dxi<S, T, const DOF: usize, const DIM: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    xi: &SVector<T, DOF>,
) -> SVector<T, DOF>
where
    S: PrincipalKinematicSystem<DOF, DIM, NS, NU>,
    T: Real,
    Dv<T, DOF>: Lift<S::Param>,
{
    let (sd, vd) = (lift_vec::<T, DOF, NS>(s), lift_vec::<T, DOF, NS>(v));
    grad_part(&sys.reduced_lagrangian(&sd, &vd, &seeded(xi)))
}
