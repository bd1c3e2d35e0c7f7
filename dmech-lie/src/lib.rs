//! Lie groups for discrete mechanics, generic over the scalar so that `num-dual` numbers
//! flow through every map.
//!
//! Conventions (the full table is in `docs/lie.md`):
//! - Tangent vectors are in the Lie algebra, identified with `Rⁿ`; for SE(2) the order is
//!   `(v_x, v_y, ω)`, for SE(3) `(ρ, ω)` (translation first, as manif and Sophus do).
//! - Perturbations and Jacobians are **right** (local, body-frame): `X ⊕ τ = X ∘ exp(τ)`,
//!   and `J` of `f` satisfies `f(X ⊕ τ) ≈ f(X) ⊕ J τ`, the convention of manif's default.
//! - [`LieGroup::dexp`] is the **right-trivialised** tangent of `exp` (Iserles et al.,
//!   Bou-Rabee & Marsden): `(d/dt exp(ξ(t))) exp(ξ(t))⁻¹ = dexp_ξ(ξ̇)`,
//!   `dexp_ξ = Σ_k ad_ξ^k/(k+1)!`. It equals manif's left Jacobian `J_l(ξ)`. The
//!   left-trivialised one is one line away: `J_r(ξ) = dexp_{−ξ}` ([`LieGroup::rjac`]).
//!
//! Every closed form with a removable singularity (`θ → 0`) branches on the real part and
//! evaluates a series in the dual variable, so derivatives at exactly zero are exact.

#![warn(missing_docs)]

pub mod dual;
pub mod lcg;
pub mod linalg;
pub mod rn;
pub mod rng;
pub mod scalar;
pub mod se2;
pub mod se3;
pub mod so2;
pub mod so3;

pub use rn::Rn;
pub use scalar::Real;
pub use se2::Se2;
pub use se3::Se3;
pub use so2::So2;
pub use so3::So3;

use nalgebra::{SMatrix, SVector};
use std::fmt::Debug;

/// A matrix Lie group with a `DOF`-dimensional algebra.
///
/// Implementations are generic structs `G<T>` over a [`Real`] scalar; [`LieGroup::With`]
/// names the same group over another scalar, which is how values are lifted into dual
/// numbers ([`LieGroup::from_re`]) and derivatives dropped ([`LieGroup::re`]). The space a
/// group acts on is a trait of its own, [`GroupAction`].
pub trait LieGroup<const DOF: usize>: Copy + Debug + Sized {
    /// The scalar of the group's coordinates (`f64` or a dual number).
    type Scalar: Real;
    /// The same group over scalar `U`.
    type With<U: Real>: LieGroup<DOF, Scalar = U, With<f64> = Self::With<f64>>;

    /// The identity `e`.
    fn identity() -> Self;
    /// `self ∘ other`.
    fn compose(&self, other: &Self) -> Self;
    /// `self⁻¹`.
    fn inverse(&self) -> Self;
    /// The exponential map of the algebra.
    fn exp(xi: &SVector<Self::Scalar, DOF>) -> Self;
    /// The principal logarithm (rotation angle in (−π, π]).
    fn log(&self) -> SVector<Self::Scalar, DOF>;
    /// `Ad_g`, with `g exp(ξ) g⁻¹ = exp(Ad_g ξ)`.
    fn adjoint(&self) -> SMatrix<Self::Scalar, DOF, DOF>;
    /// `ad_ξ η = [ξ, η]`, so that `Ad_{exp ξ} = exp(ad_ξ)`.
    fn ad(xi: &SVector<Self::Scalar, DOF>) -> SMatrix<Self::Scalar, DOF, DOF>;
    /// Right-trivialised tangent of `exp` (= manif's left Jacobian `J_l(ξ)`).
    fn dexp(xi: &SVector<Self::Scalar, DOF>) -> SMatrix<Self::Scalar, DOF, DOF>;
    /// Inverse of [`LieGroup::dexp`].
    fn dexp_inv(xi: &SVector<Self::Scalar, DOF>) -> SMatrix<Self::Scalar, DOF, DOF>;
    /// Drop all derivative parts.
    fn re(&self) -> Self::With<f64>;
    /// Lift an `f64` element into this scalar (zero derivative parts).
    fn from_re(g: &Self::With<f64>) -> Self;
    /// The stored coordinates (e.g. `(x, y, θ)` for SE(2), `(x, y, z, w, qx, qy, qz)` for SE(3)).
    fn coordinates(&self) -> Vec<Self::Scalar>;
    /// Inverse of [`LieGroup::coordinates`]; `None` on a wrong length.
    fn from_coordinates(c: &[Self::Scalar]) -> Option<Self>;

    // ---- derived operations, one definition for every group ----

    /// `X ⊕ τ = X ∘ exp(τ)` (right plus).
    fn rplus(&self, tau: &SVector<Self::Scalar, DOF>) -> Self {
        self.compose(&Self::exp(tau))
    }
    /// `τ ⊕ X = exp(τ) ∘ X` (left plus).
    fn lplus(&self, tau: &SVector<Self::Scalar, DOF>) -> Self {
        Self::exp(tau).compose(self)
    }
    /// `Y ⊖ X = log(X⁻¹ ∘ Y)` (right minus), so `X ⊕ (Y ⊖ X) = Y`.
    fn rminus(&self, x: &Self) -> SVector<Self::Scalar, DOF> {
        x.inverse().compose(self).log()
    }
    /// `X⁻¹ ∘ Y`.
    fn between(&self, y: &Self) -> Self {
        self.inverse().compose(y)
    }
    /// Left-trivialised tangent of `exp`: `exp(−ξ) d/dt exp(ξ) = J_r(ξ) ξ̇`, `J_r(ξ) = dexp_{−ξ}`.
    fn rjac(xi: &SVector<Self::Scalar, DOF>) -> SMatrix<Self::Scalar, DOF, DOF> {
        Self::dexp(&(-xi))
    }
    /// `J_r(ξ)⁻¹ = dexp⁻¹_{−ξ}`.
    fn rjac_inv(xi: &SVector<Self::Scalar, DOF>) -> SMatrix<Self::Scalar, DOF, DOF> {
        Self::dexp_inv(&(-xi))
    }
    /// Right Jacobians of `Z = X ∘ Y`: `(∂Z/∂X, ∂Z/∂Y) = (Ad_{Y⁻¹}, I)`.
    #[allow(clippy::type_complexity)]
    fn compose_jacobians(
        &self,
        other: &Self,
    ) -> (
        SMatrix<Self::Scalar, DOF, DOF>,
        SMatrix<Self::Scalar, DOF, DOF>,
    ) {
        (other.inverse().adjoint(), SMatrix::identity())
    }
    /// Right Jacobian of `X⁻¹`: `−Ad_X`.
    fn inverse_jacobian(&self) -> SMatrix<Self::Scalar, DOF, DOF> {
        -self.adjoint()
    }
}

/// The action of a [`LieGroup`] on `R^DIM` (SE(2) and SO(2) on the plane, SE(3) and SO(3)
/// on space, `Rⁿ` on itself by translation).
pub trait GroupAction<const DOF: usize, const DIM: usize>: LieGroup<DOF> {
    /// The group action on a point, `g · p`.
    fn act(&self, p: &SVector<Self::Scalar, DIM>) -> SVector<Self::Scalar, DIM>;
    /// Right Jacobians of the action: `(∂(g·p)/∂g, ∂(g·p)/∂p)`.
    #[allow(clippy::type_complexity)]
    fn act_jacobians(
        &self,
        p: &SVector<Self::Scalar, DIM>,
    ) -> (
        SMatrix<Self::Scalar, DIM, DOF>,
        SMatrix<Self::Scalar, DIM, DIM>,
    );
}

/// The `3×3` skew matrix `v^` with `v^ w = v × w`.
pub fn hat3<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
    let z = T::zero();
    SMatrix::<T, 3, 3>::new(z, -v[2], v[1], v[2], z, -v[0], -v[1], v[0], z)
}
