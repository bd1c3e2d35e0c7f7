//! The vector space `Rⁿ` as an (abelian) Lie group under addition.

use crate::{GroupAction, LieGroup, Real};
use nalgebra::{SMatrix, SVector};

/// `Rⁿ` under `+`: `exp` and `log` are the identity, `Ad = dexp = I`, `ad = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rn<T: Real, const N: usize>(pub SVector<T, N>);

impl<T: Real, const N: usize> LieGroup<N> for Rn<T, N> {
    type Scalar = T;
    type With<U: Real> = Rn<U, N>;

    fn identity() -> Self {
        Rn(SVector::zeros())
    }
    fn compose(&self, other: &Self) -> Self {
        Rn(self.0 + other.0)
    }
    fn inverse(&self) -> Self {
        Rn(-self.0)
    }
    fn exp(xi: &SVector<T, N>) -> Self {
        Rn(*xi)
    }
    fn log(&self) -> SVector<T, N> {
        self.0
    }
    fn adjoint(&self) -> SMatrix<T, N, N> {
        SMatrix::identity()
    }
    fn ad(_xi: &SVector<T, N>) -> SMatrix<T, N, N> {
        SMatrix::zeros()
    }
    fn dexp(_xi: &SVector<T, N>) -> SMatrix<T, N, N> {
        SMatrix::identity()
    }
    fn dexp_inv(_xi: &SVector<T, N>) -> SMatrix<T, N, N> {
        SMatrix::identity()
    }
    fn re(&self) -> Rn<f64, N> {
        Rn(self.0.map(|x| x.re()))
    }
    fn from_re(g: &Rn<f64, N>) -> Self {
        Rn(g.0.map(T::from))
    }
    fn coordinates(&self) -> Vec<T> {
        self.0.iter().copied().collect()
    }
    fn from_coordinates(c: &[T]) -> Option<Self> {
        (c.len() == N).then(|| Rn(SVector::from_column_slice(c)))
    }
}

impl<T: Real, const N: usize> GroupAction<N, N> for Rn<T, N> {
    fn act(&self, p: &SVector<T, N>) -> SVector<T, N> {
        p + self.0
    }
    fn act_jacobians(&self, _p: &SVector<T, N>) -> (SMatrix<T, N, N>, SMatrix<T, N, N>) {
        (SMatrix::identity(), SMatrix::identity())
    }
}
