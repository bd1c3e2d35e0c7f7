//! SO(2), planar rotations, stored as an unwrapped angle.

use crate::scalar::wrap_angle;
use crate::{GroupAction, LieGroup, Real};
use nalgebra::{SMatrix, SVector, Vector1, Vector2};

/// A planar rotation by `angle`. The angle is kept unwrapped (composition adds angles), so
/// that a heading integrated along a trajectory stays continuous; [`LieGroup::log`] wraps
/// it into (−π, π].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct So2<T: Real> {
    /// The rotation angle, rad (kept unwrapped).
    pub angle: T,
}

impl<T: Real> So2<T> {
    /// The rotation by `angle`.
    pub fn new(angle: T) -> Self {
        So2 { angle }
    }
    /// The rotation matrix `R(θ)`.
    pub fn matrix(&self) -> SMatrix<T, 2, 2> {
        let (s, c) = self.angle.sin_cos();
        SMatrix::<T, 2, 2>::new(c, -s, s, c)
    }
}

impl<T: Real> LieGroup<1> for So2<T> {
    type Scalar = T;
    type With<U: Real> = So2<U>;

    fn identity() -> Self {
        So2::new(T::zero())
    }
    fn compose(&self, other: &Self) -> Self {
        So2::new(self.angle + other.angle)
    }
    fn inverse(&self) -> Self {
        So2::new(-self.angle)
    }
    fn exp(xi: &Vector1<T>) -> Self {
        So2::new(xi[0])
    }
    fn log(&self) -> Vector1<T> {
        Vector1::new(wrap_angle(self.angle))
    }
    fn adjoint(&self) -> SMatrix<T, 1, 1> {
        SMatrix::identity()
    }
    fn ad(_xi: &Vector1<T>) -> SMatrix<T, 1, 1> {
        SMatrix::zeros()
    }
    fn dexp(_xi: &Vector1<T>) -> SMatrix<T, 1, 1> {
        SMatrix::identity()
    }
    fn dexp_inv(_xi: &Vector1<T>) -> SMatrix<T, 1, 1> {
        SMatrix::identity()
    }
    fn re(&self) -> So2<f64> {
        So2::new(self.angle.re())
    }
    fn from_re(g: &So2<f64>) -> Self {
        So2::new(T::from(g.angle))
    }
    fn coordinates(&self) -> Vec<T> {
        vec![self.angle]
    }
    fn from_coordinates(c: &[T]) -> Option<Self> {
        (c.len() == 1).then(|| So2::new(c[0]))
    }
}

impl<T: Real> GroupAction<1, 2> for So2<T> {
    fn act(&self, p: &Vector2<T>) -> Vector2<T> {
        self.matrix() * p
    }
    fn act_jacobians(&self, p: &Vector2<T>) -> (SMatrix<T, 2, 1>, SMatrix<T, 2, 2>) {
        // R exp(δ) p ≈ R p + R J p δ with J = [[0, −1], [1, 0]].
        let r = self.matrix();
        let jp = Vector2::new(-p[1], p[0]);
        (r * jp, r)
    }
}

/// `SVector<T, 1>` helper for symmetry with the other groups.
pub fn tangent<T: Real>(omega: T) -> SVector<T, 1> {
    Vector1::new(omega)
}
