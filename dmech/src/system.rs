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
    /// The parameter `p` as a value of this scalar.
    fn lift(p: P) -> Self;
    /// `self · p`. For `f64` parameters this is a scalar product, several times cheaper in
    /// dual arithmetic than multiplying by the lifted parameter.
    #[inline(always)]
    fn mul_param(self, p: P) -> Self {
        self * Self::lift(p)
    }
}

impl<T: Real> Lift<f64> for T {
    #[inline(always)]
    fn lift(p: f64) -> T {
        T::from(p)
    }
    #[inline(always)]
    fn mul_param(self, p: f64) -> T {
        self * p
    }
}

/// A model parameter of scalar `P`, to write models as `p.m * x` with `x` in any scalar
/// `T: Lift<P>` (products of parameters stay parameters, so `p.m * p.g * x` lifts once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Param<P>(pub P);

impl<P: Real> Param<P> {
    /// The parameter as a value of scalar `T`.
    #[inline(always)]
    pub fn lift<T: Lift<P>>(self) -> T {
        T::lift(self.0)
    }
}

impl<P: Real, T: Lift<P>> std::ops::Mul<T> for Param<P> {
    type Output = T;
    #[inline(always)]
    fn mul(self, x: T) -> T {
        x.mul_param(self.0)
    }
}

macro_rules! param_param_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<P: Real> std::ops::$tr<Param<P>> for Param<P> {
            type Output = Param<P>;
            #[inline(always)]
            fn $f(self, o: Param<P>) -> Param<P> {
                Param(self.0 $op o.0)
            }
        }
        impl<P: Real> std::ops::$tr<f64> for Param<P> {
            type Output = Param<P>;
            #[inline(always)]
            fn $f(self, o: f64) -> Param<P> {
                Param(self.0 $op o)
            }
        }
    };
}
param_param_op!(Add, add, +);
param_param_op!(Sub, sub, -);
param_param_op!(Div, div, /);

impl<P: Real> std::ops::Mul<Param<P>> for Param<P> {
    type Output = Param<P>;
    #[inline(always)]
    fn mul(self, o: Param<P>) -> Param<P> {
        Param(self.0 * o.0)
    }
}

impl<P: Real> std::ops::Mul<Param<P>> for f64 {
    type Output = Param<P>;
    #[inline(always)]
    fn mul(self, o: Param<P>) -> Param<P> {
        Param(o.0 * self)
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

impl<const K: usize> Lift<DualSVec64<K>> for num_dual::Dual<DualSVec64<K>> {
    #[inline(always)]
    fn lift(p: DualSVec64<K>) -> Self {
        num_dual::Dual::from_re(p)
    }
}

impl<const K: usize, const N: usize> Lift<DualSVec64<K>>
    for DualVec<num_dual::Dual<DualSVec64<K>>, nalgebra::Const<N>>
{
    #[inline(always)]
    fn lift(p: DualSVec64<K>) -> Self {
        DualVec::from_re(num_dual::Dual::from_re(p))
    }
}

impl<const K: usize, const N: usize, const M: usize> Lift<DualSVec64<K>>
    for DualVec<DualVec<DualSVec64<K>, nalgebra::Const<N>>, nalgebra::Const<M>>
{
    #[inline(always)]
    fn lift(p: DualSVec64<K>) -> Self {
        DualVec::from_re(DualVec::from_re(p))
    }
}

/// A principal-kinematic nonholonomic system on `G × M`: `DOF = dim G` constraints
/// `ξ + A(s) v_s = 0`, an `NS`-dimensional vector shape space `M`, `NU` inputs.
///
/// Everything is written once over the scalar `T`, so values, gradients and Hessians come
/// from the same code. Nothing here knows a particular robot.
pub trait PrincipalKinematicSystem<const DOF: usize, const NS: usize, const NU: usize> {
    /// Scalar of the model parameters (`f64`, or a dual number for parameter derivatives).
    type Param: Real;
    /// The symmetry group `G` over scalar `T`.
    type Group<T: Real>: LieGroup<DOF, Scalar = T>;

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

    /// The shape coordinates whose positions the equations of motion do not read: the
    /// connection and the forcing do not depend on them, and the reduced Lagrangian at
    /// most through a total time derivative (a term `c(s) ṡ_j`-like coupling whose change
    /// under `s_j → s_j + const` is exact), so that the momentum-matching residual does not
    /// either. A transcription may leave their positions out of its state
    /// (`dmech_ocp::transcription::layout::Layout::ignoring`). Default: none.
    fn ignorable_shape(&self) -> &[usize] {
        &[]
    }

    /// Generalised force on the shape coordinates (dissipation and inputs), `F(s, v_s, u)`.
    fn forcing<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS>;

    /// The partial derivatives `(∂ℓ/∂s, ∂ℓ/∂v_s, ∂ℓ/∂ξ)` of the reduced Lagrangian in closed
    /// form, where the system has them. `None`, the default, says it has none: they are
    /// taken from [`PrincipalKinematicSystem::reduced_lagrangian`] by dual numbers. Where a
    /// system supplies them, every discrete momentum is formed from them
    /// ([`crate::partials::pulled_back_gradient`], in whatever scalar it is evaluated), and
    /// the variational transcription's Jacobian pass differentiates them by first-order
    /// duals ([`crate::partials::pulled_back_gradient_dual`]) instead of evaluating `ℓ` in
    /// hyper-duals. A system that supplies them must check them against the generic
    /// partials in a test.
    #[allow(clippy::type_complexity)]
    fn closed_form_lagrangian_gradient<T: Lift<Self::Param>>(
        &self,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
        _xi: &SVector<T, DOF>,
    ) -> Option<(SVector<T, NS>, SVector<T, NS>, SVector<T, DOF>)> {
        None
    }

    /// The shape acceleration `v̇ = a(s, v_s, u)` in closed form, where the system has one.
    /// `None`, the default, says it has none: [`crate::continuous::acceleration`] derives it
    /// from `ℓ`, `A` and the forcing, and its Jacobian by the implicit function theorem
    /// needs third derivatives of `ℓ` (nested duals). Where a system supplies it, the
    /// Runge–Kutta transcriptions of `dmech-ocp` evaluate and differentiate it instead (one
    /// vector-dual pass), so a system that does must check it against the generic path in
    /// a test. A singular mass matrix is reported as non-finite entries. Where one of a
    /// Jacobian's passes returns `None`, the transcription takes the generic path there.
    fn closed_form_acceleration<T: Lift<Self::Param>>(
        &self,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
        _u: &SVector<T, NU>,
    ) -> Option<SVector<T, NS>> {
        None
    }
}
