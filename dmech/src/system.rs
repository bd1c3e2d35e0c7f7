//! The system description: reduced Lagrangian, local connection, forcing.

use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::{DualSVec64, DualVec};

/// How a model parameter of scalar type `P` enters a computation in scalar `Self`.
///
/// With `P = f64` (the usual case) every scalar lifts it. With parameters that are dual
/// numbers themselves (derivatives with respect to parameters, for identification from
/// data), the computation runs in that dual type, or in a vector dual over it.
pub trait Lift<P>: Real {
    fn lift(p: P) -> Self;
}

impl<T: Real> Lift<f64> for T {
    #[inline(always)]
    fn lift(p: f64) -> T {
        T::from(p)
    }
}

impl<const K: usize> Lift<DualSVec64<K>> for DualSVec64<K> {
    #[inline(always)]
    fn lift(p: DualSVec64<K>) -> Self {
        p
    }
}

impl<const K: usize, const N: usize> Lift<DualSVec64<K>>
    for DualVec<DualSVec64<K>, nalgebra::Const<N>>
{
    #[inline(always)]
    fn lift(p: DualSVec64<K>) -> Self {
        DualVec::from_re(p)
    }
}

/// A principal-kinematic nonholonomic system on `G × M`: `DOF = dim G` constraints
/// `ξ + A(s) v_s = 0`, an `NS`-dimensional vector shape space `M`, `NU` inputs.
///
/// Everything is written once over the scalar `T`, so values, gradients and Hessians come
/// from the same code. Nothing here knows a particular robot.
pub trait PrincipalKinematicSystem<
    const DOF: usize,
    const DIM: usize,
    const NS: usize,
    const NU: usize,
>
{
    /// Scalar of the model parameters (`f64`, or a dual number for parameter derivatives).
    type Param: Real;
    /// The symmetry group `G` over scalar `T`.
    type Group<T: Real>: LieGroup<DOF, DIM, Scalar = T>;

    /// The reduced Lagrangian `ℓ(s, v_s, ξ) = L(e, s, ξ, v_s)` (the Lagrangian at `g = e`,
    /// with body velocity `ξ`). All `DOF` components of `ξ` must be kept.
    fn reduced_lagrangian<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, DOF>,
    ) -> T;

    /// The local form of the nonholonomic connection `A(s)`, `ξ = −A(s) v_s`.
    fn connection<T: Lift<Self::Param>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NS>;

    /// Generalised force on the shape coordinates (dissipation and inputs), `F(s, v_s, u)`.
    fn forcing<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS>;
}
