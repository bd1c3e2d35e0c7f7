//! SE(2), rigid motions of the plane: `g = (x, y, θ)`, tangent `ξ = (v_x, v_y, ω)`.

use crate::scalar::{cosc, dexp_inv_coeff, sinc, sinc3, wrap_angle};
use crate::{GroupAction, LieGroup, Real};
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2, Vector3};

/// A planar pose: translation `(x, y)` and heading `θ` (kept unwrapped, like [`crate::So2`]).
/// As a matrix, `[[R(θ), (x, y)ᵀ], [0, 1]]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Se2<T: Real> {
    /// The translation's first coordinate.
    pub x: T,
    /// The translation's second coordinate.
    pub y: T,
    /// The heading, rad.
    pub theta: T,
}

impl<T: Real> Se2<T> {
    /// The pose at `(x, y)` with heading `θ`.
    pub fn new(x: T, y: T, theta: T) -> Self {
        Se2 { x, y, theta }
    }
    /// `R(θ)`.
    pub fn rotation(&self) -> Matrix2<T> {
        let (s, c) = self.theta.sin_cos();
        Matrix2::new(c, -s, s, c)
    }
    /// `(x, y)`.
    pub fn translation(&self) -> Vector2<T> {
        Vector2::new(self.x, self.y)
    }
    /// `V(ω)` with `exp(v, ω) = (V(ω) v, ω)`; also the upper-left block of `dexp`.
    fn v_matrix(omega: T) -> Matrix2<T> {
        let t = omega * omega;
        let a = sinc(t);
        let b = omega * cosc(t);
        Matrix2::new(a, -b, b, a)
    }
    /// `V(ω)⁻¹ = [[A, ω/2], [−ω/2, A]]`, `A = (ω/2) cot(ω/2)`.
    fn v_inv(omega: T) -> Matrix2<T> {
        let t = omega * omega;
        let a = T::one() - t * dexp_inv_coeff(t);
        let b = omega * 0.5;
        Matrix2::new(a, b, -b, a)
    }
    /// Last column of `dexp` (its translational part).
    fn dexp_column(xi: &Vector3<T>) -> Vector2<T> {
        let (r1, r2, w) = (xi[0], xi[1], xi[2]);
        let t = w * w;
        let c = cosc(t);
        let s3 = w * sinc3(t);
        Vector2::new(r1 * s3 + r2 * c, -r1 * c + r2 * s3)
    }
}

impl<T: Real> LieGroup<3> for Se2<T> {
    type Scalar = T;
    type With<U: Real> = Se2<U>;

    fn identity() -> Self {
        Se2::new(T::zero(), T::zero(), T::zero())
    }
    fn compose(&self, other: &Self) -> Self {
        let p = self.rotation() * other.translation() + self.translation();
        Se2::new(p[0], p[1], self.theta + other.theta)
    }
    fn inverse(&self) -> Self {
        let p = -(self.rotation().transpose() * self.translation());
        Se2::new(p[0], p[1], -self.theta)
    }
    fn exp(xi: &Vector3<T>) -> Self {
        let p = Self::v_matrix(xi[2]) * Vector2::new(xi[0], xi[1]);
        Se2::new(p[0], p[1], xi[2])
    }
    fn log(&self) -> Vector3<T> {
        let w = wrap_angle(self.theta);
        let v = Self::v_inv(w) * self.translation();
        Vector3::new(v[0], v[1], w)
    }
    fn adjoint(&self) -> Matrix3<T> {
        let (s, c) = self.theta.sin_cos();
        let (z, o) = (T::zero(), T::one());
        Matrix3::new(c, -s, self.y, s, c, -self.x, z, z, o)
    }
    fn ad(xi: &Vector3<T>) -> Matrix3<T> {
        let z = T::zero();
        Matrix3::new(z, -xi[2], xi[1], xi[2], z, -xi[0], z, z, z)
    }
    fn dexp(xi: &Vector3<T>) -> Matrix3<T> {
        let v = Self::v_matrix(xi[2]);
        let col = Self::dexp_column(xi);
        let (z, o) = (T::zero(), T::one());
        Matrix3::new(
            v[(0, 0)],
            v[(0, 1)],
            col[0],
            v[(1, 0)],
            v[(1, 1)],
            col[1],
            z,
            z,
            o,
        )
    }
    fn dexp_inv(xi: &Vector3<T>) -> Matrix3<T> {
        // [[V, c], [0, 1]]⁻¹ = [[V⁻¹, −V⁻¹ c], [0, 1]].
        let vi = Self::v_inv(xi[2]);
        let col = -(vi * Self::dexp_column(xi));
        let (z, o) = (T::zero(), T::one());
        Matrix3::new(
            vi[(0, 0)],
            vi[(0, 1)],
            col[0],
            vi[(1, 0)],
            vi[(1, 1)],
            col[1],
            z,
            z,
            o,
        )
    }
    fn re(&self) -> Se2<f64> {
        Se2::new(self.x.re(), self.y.re(), self.theta.re())
    }
    fn from_re(g: &Se2<f64>) -> Self {
        Se2::new(T::from(g.x), T::from(g.y), T::from(g.theta))
    }
    fn coordinates(&self) -> Vec<T> {
        vec![self.x, self.y, self.theta]
    }
    fn from_coordinates(c: &[T]) -> Option<Self> {
        (c.len() == 3).then(|| Se2::new(c[0], c[1], c[2]))
    }
}

impl<T: Real> GroupAction<3, 2> for Se2<T> {
    fn act(&self, p: &Vector2<T>) -> Vector2<T> {
        self.rotation() * p + self.translation()
    }
    fn act_jacobians(&self, p: &Vector2<T>) -> (SMatrix<T, 2, 3>, Matrix2<T>) {
        // g exp(δ) p ≈ g p + R (δ_v + δ_ω J p), J = [[0, −1], [1, 0]].
        let r = self.rotation();
        let rjp = r * Vector2::new(-p[1], p[0]);
        let jg =
            SMatrix::<T, 2, 3>::new(r[(0, 0)], r[(0, 1)], rjp[0], r[(1, 0)], r[(1, 1)], rjp[1]);
        (jg, r)
    }
}
