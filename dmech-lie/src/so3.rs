//! SO(3), rotations of space, stored as a unit quaternion.

use crate::scalar::{atan_over, cos_half, cosc, dexp_inv_coeff, sin_half_over, sinc3};
use crate::{hat3, GroupAction, LieGroup, Real};
use nalgebra::{Matrix3, Vector3};

/// A rotation as a unit quaternion `w + (x, y, z)`. Our own quaternion arithmetic (not
/// nalgebra's `UnitQuaternion`) so that `exp`/`log` keep exact dual derivatives at zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct So3<T: Real> {
    /// The quaternion's scalar part, `cos(θ/2)`.
    pub w: T,
    /// The quaternion's vector part, `sin(θ/2) n`.
    pub v: Vector3<T>,
}

impl<T: Real> So3<T> {
    /// From quaternion components; normalised here.
    pub fn from_quaternion(w: T, x: T, y: T, z: T) -> Self {
        let n = (w * w + x * x + y * y + z * z).sqrt();
        So3 {
            w: w / n,
            v: Vector3::new(x / n, y / n, z / n),
        }
    }
    /// The rotation matrix.
    pub fn matrix(&self) -> Matrix3<T> {
        let (w, x, y, z) = (self.w, self.v[0], self.v[1], self.v[2]);
        let o = T::one();
        let two = T::from(2.0);
        Matrix3::new(
            o - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
            two * (x * y + w * z),
            o - two * (x * x + z * z),
            two * (y * z - w * x),
            two * (x * z - w * y),
            two * (y * z + w * x),
            o - two * (x * x + y * y),
        )
    }
    /// The SO(3) left Jacobian `J_l(ω) = I + cosc W + sinc3 W²` (also SE(3)'s `V`).
    pub fn jl(omega: &Vector3<T>) -> Matrix3<T> {
        let t = omega.dot(omega);
        let w = hat3(omega);
        Matrix3::identity() + w * cosc(t) + w * w * sinc3(t)
    }
    /// `J_l(ω)⁻¹ = I − ½ W + ((1 − (θ/2)cot(θ/2))/θ²) W²`.
    pub fn jl_inv(omega: &Vector3<T>) -> Matrix3<T> {
        let t = omega.dot(omega);
        let w = hat3(omega);
        Matrix3::identity() - w * T::from(0.5) + w * w * dexp_inv_coeff(t)
    }
}

impl<T: Real> LieGroup<3> for So3<T> {
    type Scalar = T;
    type With<U: Real> = So3<U>;

    fn identity() -> Self {
        So3 {
            w: T::one(),
            v: Vector3::zeros(),
        }
    }
    fn compose(&self, o: &Self) -> Self {
        So3 {
            w: self.w * o.w - self.v.dot(&o.v),
            v: o.v * self.w + self.v * o.w + self.v.cross(&o.v),
        }
    }
    fn inverse(&self) -> Self {
        So3 {
            w: self.w,
            v: -self.v,
        }
    }
    fn exp(omega: &Vector3<T>) -> Self {
        let t = omega.dot(omega);
        So3 {
            w: cos_half(t),
            v: omega * sin_half_over(t),
        }
    }
    fn log(&self) -> Vector3<T> {
        // q and −q are the same rotation: take w ≥ 0 so the angle is in [0, π].
        let (w, v) = if self.w.re() < 0.0 {
            (-self.w, -self.v)
        } else {
            (self.w, self.v)
        };
        let n2 = v.dot(&v);
        if w.re() >= n2.re().sqrt() {
            // θ ≤ π/2: θ/|v| = 2 atan(|v|/w)/|v|, smooth in |v|² for w > 0.
            let z2 = n2 / (w * w);
            v * (atan_over(z2) * 2.0 / w)
        } else {
            // θ > π/2, so |v| > 0.7 and atan2 is smooth; well conditioned up to θ = π.
            let n = n2.sqrt();
            v * (n.atan2(w) * 2.0 / n)
        }
    }
    fn adjoint(&self) -> Matrix3<T> {
        self.matrix()
    }
    fn ad(omega: &Vector3<T>) -> Matrix3<T> {
        hat3(omega)
    }
    fn dexp(omega: &Vector3<T>) -> Matrix3<T> {
        Self::jl(omega)
    }
    fn dexp_inv(omega: &Vector3<T>) -> Matrix3<T> {
        Self::jl_inv(omega)
    }
    fn re(&self) -> So3<f64> {
        So3 {
            w: self.w.re(),
            v: self.v.map(|x| x.re()),
        }
    }
    fn from_re(g: &So3<f64>) -> Self {
        So3 {
            w: T::from(g.w),
            v: g.v.map(T::from),
        }
    }
    /// `(w, x, y, z)`.
    fn coordinates(&self) -> Vec<T> {
        vec![self.w, self.v[0], self.v[1], self.v[2]]
    }
    fn from_coordinates(c: &[T]) -> Option<Self> {
        (c.len() == 4).then(|| So3::from_quaternion(c[0], c[1], c[2], c[3]))
    }
}

impl<T: Real> GroupAction<3, 3> for So3<T> {
    fn act(&self, p: &Vector3<T>) -> Vector3<T> {
        // p + 2w (v × p) + 2 v × (v × p)
        let t = self.v.cross(p) * T::from(2.0);
        p + t * self.w + self.v.cross(&t)
    }
    fn act_jacobians(&self, p: &Vector3<T>) -> (Matrix3<T>, Matrix3<T>) {
        // R exp(δ) p ≈ R p − R p^ δ.
        let r = self.matrix();
        (-(r * hat3(p)), r)
    }
}
