//! Dual-number helpers for derivatives by `num-dual`, generic over the scalar: seeding a
//! pass, lifting constants into it, and reading gradients and Jacobians back.

use crate::Real;
use nalgebra::{SMatrix, SVector};
use num_dual::{Derivative, DualVec};

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// `x` as vector duals with no derivative part (constants of a gradient pass).
pub fn lift_vec<T: Real, const N: usize, const M: usize>(
    x: &SVector<T, M>,
) -> SVector<Dv<T, N>, M> {
    x.map(Dv::<T, N>::from_re)
}

/// `x` as vector duals seeded with the unit directions (the input of a gradient).
pub fn seeded<T: Real, const N: usize>(x: &SVector<T, N>) -> SVector<Dv<T, N>, N> {
    seeded_from::<T, N, N>(x, 0)
}

/// `x` as vector duals of width `N`, entry `i` seeded with the unit direction `first + i`:
/// several inputs of one pass seeded side by side. Panics if `first + M > N`.
pub fn seeded_from<T: Real, const N: usize, const M: usize>(
    x: &SVector<T, M>,
    first: usize,
) -> SVector<Dv<T, N>, M> {
    assert!(first + M <= N, "directions {first}..{} of {N}", first + M);
    SVector::from_fn(|i, _| {
        let mut e = SVector::<T, N>::zeros();
        e[first + i] = T::one();
        DualVec::new(x[i], Derivative::some(e))
    })
}

/// The gradient part of a vector dual (zero if it carries none).
pub fn grad_part<T: Real, const N: usize>(f: &Dv<T, N>) -> SVector<T, N> {
    f.eps.0.unwrap_or_else(SVector::zeros)
}

/// The Jacobian `∂y/∂x` of a vector-dual pass seeded in `x`, row by row (reading each
/// row's gradient in place: building it entry by entry through [`grad_part`] copies the
/// whole gradient per entry, which was 3 % of a plan).
pub fn jacobian_part<T: Real, const M: usize, const N: usize>(
    y: &SVector<Dv<T, N>, M>,
) -> SMatrix<T, M, N> {
    let mut jac = SMatrix::<T, M, N>::zeros();
    for i in 0..M {
        if let Some(g) = &y[i].eps.0 {
            jac.row_mut(i).copy_from(&g.transpose());
        }
    }
    jac
}

/// `(y, ∂y/∂x, ∂y/∂w)` from two vector-dual evaluations of the same `y(x, w)`, one seeded
/// in `x` and one in `w` (the value is taken from the first).
#[allow(clippy::type_complexity)]
pub fn split_passes<const M: usize, const NX: usize, const NW: usize>(
    yx: &SVector<Dv<f64, NX>, M>,
    yw: &SVector<Dv<f64, NW>, M>,
) -> (SVector<f64, M>, SMatrix<f64, M, NX>, SMatrix<f64, M, NW>) {
    (yx.map(|d| d.re), jacobian_part(yx), jacobian_part(yw))
}

/// Value and Jacobian of `f: Rᴺ → Rᴹ` by vector duals, generic over the scalar.
pub fn value_and_jacobian<T: Real, const N: usize, const M: usize>(
    f: impl Fn(&SVector<Dv<T, N>, N>) -> SVector<Dv<T, N>, M>,
    x: &SVector<T, N>,
) -> (SVector<T, M>, SMatrix<T, M, N>) {
    let y = f(&seeded(x));
    let val = y.map(|z| z.re);
    let jac = jacobian_part(&y);
    (val, jac)
}
