//! SE(3), rigid motions of space: `g = (R, p)`, tangent `ξ = (ρ, ω)`.

use crate::scalar::{cosc, se3_alpha3, se3_q_coeff, sinc, sinc3};
use crate::{hat3, GroupAction, LieGroup, Real, So3};
use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

/// A rigid motion `x ↦ R x + p`, rotation stored as a unit quaternion ([`So3`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Se3<T: Real> {
    /// `R`.
    pub rotation: So3<T>,
    /// `p`.
    pub translation: Vector3<T>,
}

fn split<T: Real>(xi: &Vector6<T>) -> (Vector3<T>, Vector3<T>) {
    (
        Vector3::new(xi[0], xi[1], xi[2]),
        Vector3::new(xi[3], xi[4], xi[5]),
    )
}

fn blocks<T: Real>(a: Matrix3<T>, b: Matrix3<T>, c: Matrix3<T>, d: Matrix3<T>) -> Matrix6<T> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&c);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&d);
    m
}

impl<T: Real> Se3<T> {
    /// `x ↦ R x + p`.
    pub fn new(rotation: So3<T>, translation: Vector3<T>) -> Self {
        Se3 {
            rotation,
            translation,
        }
    }
}

impl<T: Real> LieGroup<6> for Se3<T> {
    type Scalar = T;
    type With<U: Real> = Se3<U>;

    fn identity() -> Self {
        Se3::new(So3::identity(), Vector3::zeros())
    }
    fn compose(&self, o: &Self) -> Self {
        Se3::new(
            self.rotation.compose(&o.rotation),
            self.rotation.act(&o.translation) + self.translation,
        )
    }
    fn inverse(&self) -> Self {
        let ri = self.rotation.inverse();
        Se3::new(ri, -ri.act(&self.translation))
    }
    fn exp(xi: &Vector6<T>) -> Self {
        let (rho, omega) = split(xi);
        Se3::new(So3::exp(&omega), So3::jl(&omega) * rho)
    }
    fn log(&self) -> Vector6<T> {
        let omega = self.rotation.log();
        let rho = So3::jl_inv(&omega) * self.translation;
        Vector6::new(rho[0], rho[1], rho[2], omega[0], omega[1], omega[2])
    }
    fn adjoint(&self) -> Matrix6<T> {
        let r = self.rotation.matrix();
        blocks(r, hat3(&self.translation) * r, Matrix3::zeros(), r)
    }
    fn ad(xi: &Vector6<T>) -> Matrix6<T> {
        let (rho, omega) = split(xi);
        let w = hat3(&omega);
        blocks(w, hat3(&rho), Matrix3::zeros(), w)
    }
    fn dexp(xi: &Vector6<T>) -> Matrix6<T> {
        // dexp = I + α₁ ad + α₂ ad² + α₃ ad³ + α₄ ad⁴ (ad⁵ = −2θ² ad³ − θ⁴ ad on se(3)),
        // α₁ = 2 cosc − ½ sinc, α₂ = (5/2) sinc3 − ½ cosc, α₃, α₄ in `scalar`.
        let (_, omega) = split(xi);
        let t = omega.dot(&omega);
        let (cc, sc) = (cosc(t), sinc(t));
        let a1 = cc * 2.0 - sc * 0.5;
        let a2 = sinc3(t) * 2.5 - cc * 0.5;
        let a3 = se3_alpha3(t);
        let a4 = se3_q_coeff(t);
        let ad = Self::ad(xi);
        let ad2 = ad * ad;
        let ad3 = ad2 * ad;
        let ad4 = ad2 * ad2;
        Matrix6::identity() + ad * a1 + ad2 * a2 + ad3 * a3 + ad4 * a4
    }
    fn dexp_inv(xi: &Vector6<T>) -> Matrix6<T> {
        // [[J, Q], [0, J]]⁻¹ = [[J⁻¹, −J⁻¹ Q J⁻¹], [0, J⁻¹]].
        let (_, omega) = split(xi);
        let q: Matrix3<T> = Self::dexp(xi).fixed_view::<3, 3>(0, 3).into_owned();
        let ji = So3::jl_inv(&omega);
        blocks(ji, -(ji * q * ji), Matrix3::zeros(), ji)
    }
    fn re(&self) -> Se3<f64> {
        Se3::new(self.rotation.re(), self.translation.map(|x| x.re()))
    }
    fn from_re(g: &Se3<f64>) -> Self {
        Se3::new(So3::from_re(&g.rotation), g.translation.map(T::from))
    }
    /// `(x, y, z, w, qx, qy, qz)`.
    fn coordinates(&self) -> Vec<T> {
        let mut c: Vec<T> = self.translation.iter().copied().collect();
        c.extend(self.rotation.coordinates());
        c
    }
    fn from_coordinates(c: &[T]) -> Option<Self> {
        if c.len() != 7 {
            return None;
        }
        Some(Se3::new(
            So3::from_coordinates(&c[3..])?,
            Vector3::new(c[0], c[1], c[2]),
        ))
    }
}

impl<T: Real> GroupAction<6, 3> for Se3<T> {
    fn act(&self, p: &Vector3<T>) -> Vector3<T> {
        self.rotation.act(p) + self.translation
    }
    fn act_jacobians(&self, p: &Vector3<T>) -> (SMatrix<T, 3, 6>, Matrix3<T>) {
        // g exp(δ) p ≈ g p + R δ_ρ − R p^ δ_ω.
        let r = self.rotation.matrix();
        let mut jg = SMatrix::<T, 3, 6>::zeros();
        jg.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        jg.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-(r * hat3(p))));
        (jg, r)
    }
}
