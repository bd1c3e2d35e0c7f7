//! The energy function of the constrained system.

use crate::partials::{dl_dv, dl_dxi};
use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::SVector;
use num_dual::DualVec;

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// `E(s, v) = v·∂ℓ/∂v + ξ·∂ℓ/∂ξ − ℓ` at `ξ = −A(s) v`: the energy (Legendre transform of `ℓ`,
/// restricted to the constraint). Velocity-linear (gyroscopic) terms of `ℓ` drop out.
pub fn energy<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
) -> T
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Real + Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
    Dv<T, DOF>: Lift<S::Param>,
{
    let xi = -(sys.connection(s) * v);
    let p = dl_dv::<S, T, DOF, NS, NU>(sys, s, v, &xi);
    let mu = dl_dxi::<S, T, DOF, NS, NU>(sys, s, v, &xi);
    v.dot(&p) + xi.dot(&mu) - sys.reduced_lagrangian(s, v, &xi)
}
