//! Nonholonomic systems with symmetry whose constraints leave group directions free: the
//! snakeboard, the Chaplygin sleigh, a disk that yaws freely. Their body velocity is
//!
//! ```text
//! ξ = −A(s) v + E(s) p,      A: DOF × NS,  E: DOF × NM,
//! ```
//!
//! the kinematic part of a principal-kinematic system plus `NM ≥ 0` free directions
//! `E(s)`, along which the velocity `p ∈ R^NM` is not set by the shape. The momentum along
//! them, `J = E(s)ᵀ ∂ℓ/∂ξ` (the nonholonomic momentum of Bloch, Krishnaprasad, Marsden and
//! Murray), changes only by the momentum equation.
//!
//! A user writes the system in these terms ([`NonholonomicSystem`]); [`WithMomentum`] is the
//! same system written as a principal-kinematic one on the shape extended by one cyclic
//! coordinate `σ_j` per free direction, `σ̇ = p`, with the connection `[A(s) | −E(s)]`, the
//! reduced Lagrangian that does not read `σ`, and no force on `σ` beyond the free
//! directions' own. The variations of the Lagrange–d'Alembert principle of the extended
//! system are those of the original (`η = −A δs + E δσ`, `δσ` arbitrary), so its equation
//! for `σ` is the momentum equation, and its discrete schemes (first order and midpoint)
//! carry the discrete momentum equation of Kobilarov, Marsden and Sukhatme 2010 beside
//! the discrete reduced equations of the shape. Every integrator, the continuous model, the
//! energy and the planning transcriptions then apply unchanged; `σ`'s positions are
//! ignorable ([`PrincipalKinematicSystem::ignorable_shape`]), so a transcription's state
//! carries `p` and not `σ`. The derivation is in `docs/integrator.md`.

use crate::partials::dl_dxi;
use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualVec;

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// A nonholonomic system with symmetry on `G × M`: `NS` shape coordinates, `NM` free group
/// directions, `NU` inputs; constraints `ξ = −A(s) v + E(s) p` (module documentation).
/// `NM = 0` is the principal-kinematic case.
pub trait NonholonomicSystem<const DOF: usize, const NS: usize, const NM: usize, const NU: usize> {
    /// Scalar of the model parameters (`f64`, or a dual number for parameter derivatives).
    type Param: Real;
    /// The symmetry group `G` over scalar `T`.
    type Group<T: Real>: LieGroup<DOF, Scalar = T>;

    /// The reduced Lagrangian `ℓ(s, v_s, ξ)`, all `DOF` components of `ξ` kept.
    fn reduced_lagrangian<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, DOF>,
    ) -> T;

    /// The kinematic part of the constraints, `A(s)` of `ξ = −A(s) v + E(s) p`.
    fn connection<T: Lift<Self::Param>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NS>;

    /// The free directions `E(s)`, `DOF × NM`, independent at every shape.
    fn free_directions<T: Lift<Self::Param>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NM>;

    /// Generalised force on the shape (dissipation and inputs), `F(s, v_s, u)`.
    fn forcing<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS>;

    /// Generalised force along the free directions, `⟨f_ext, E(s)⟩` (a thrust, a drag on the
    /// body). Default: none.
    fn free_forcing<T: Lift<Self::Param>>(
        &self,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
        _p: &SVector<T, NM>,
        _u: &SVector<T, NU>,
    ) -> SVector<T, NM> {
        SVector::zeros()
    }

    /// The shape coordinates whose positions the equations of motion do not read (as
    /// [`PrincipalKinematicSystem::ignorable_shape`]). Default: none.
    fn ignorable_shape(&self) -> &[usize] {
        &[]
    }
}

/// The shape sizes of a system with momentum: `NS` shape coordinates and `NM` free
/// directions; a key of the [`ExtendedShape`] table.
pub struct ShapeWithMomentum<const NS: usize, const NM: usize>;

/// `NA = NS + NM`, the extended shape's size: implemented by [`ShapeWithMomentum`] for
/// `NS ≤ 12`, `NM ≤ 4`, so that the compiler infers `NA` for a concrete system.
pub trait ExtendedShape<const NA: usize> {}

macro_rules! extended_shape {
    ([$($ns:literal)*] $nms:tt) => { $( extended_shape!(@nm $ns $nms); )* };
    (@nm $ns:literal [$($nm:literal)*]) => {
        $( impl ExtendedShape<{ $ns + $nm }> for ShapeWithMomentum<$ns, $nm> {} )*
    };
}
extended_shape!([0 1 2 3 4 5 6 7 8 9 10 11 12] [0 1 2 3 4]);

/// A [`NonholonomicSystem`] as the principal-kinematic system on the extended shape
/// `(s, σ)` with velocity `(v, p)` (module documentation). Its `NA = NS + NM` shape
/// coordinates are the system's followed by the `σ_j`; its ignorable ones are the
/// system's and every `σ_j`.
#[derive(Clone, Debug, PartialEq)]
pub struct WithMomentum<S, const NS: usize, const NM: usize> {
    /// The system.
    pub system: S,
    ignorable: Vec<usize>,
}

impl<S, const NS: usize, const NM: usize> WithMomentum<S, NS, NM> {
    /// `system` on its extended shape.
    pub fn new<const DOF: usize, const NU: usize>(system: S) -> Self
    where
        S: NonholonomicSystem<DOF, NS, NM, NU>,
    {
        let mut ignorable = system.ignorable_shape().to_vec();
        ignorable.extend(NS..NS + NM);
        WithMomentum { system, ignorable }
    }

    /// The shape `s` of an extended shape `(s, σ)` (or the velocity `v` of `(v, p)`).
    pub fn shape_part<T: Real, const NA: usize>(x: &SVector<T, NA>) -> SVector<T, NS> {
        SVector::from_fn(|i, _| x[i])
    }

    /// The velocities `p` along the free directions of an extended velocity `(v, p)`.
    pub fn momentum_part<T: Real, const NA: usize>(x: &SVector<T, NA>) -> SVector<T, NM> {
        SVector::from_fn(|j, _| x[NS + j])
    }

    /// The extended vector `(a, b)`.
    pub fn join<T: Real, const NA: usize>(
        a: &SVector<T, NS>,
        b: &SVector<T, NM>,
    ) -> SVector<T, NA> {
        SVector::from_fn(|i, _| if i < NS { a[i] } else { b[i - NS] })
    }
}

impl<S, const DOF: usize, const NS: usize, const NM: usize, const NU: usize, const NA: usize>
    PrincipalKinematicSystem<DOF, NA, NU> for WithMomentum<S, NS, NM>
where
    S: NonholonomicSystem<DOF, NS, NM, NU>,
    ShapeWithMomentum<NS, NM>: ExtendedShape<NA>,
{
    type Param = S::Param;
    type Group<T: Real> = S::Group<T>;

    fn reduced_lagrangian<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NA>,
        v: &SVector<T, NA>,
        xi: &SVector<T, DOF>,
    ) -> T {
        self.system
            .reduced_lagrangian(&Self::shape_part(s), &Self::shape_part(v), xi)
    }

    fn connection<T: Lift<Self::Param>>(&self, s: &SVector<T, NA>) -> SMatrix<T, DOF, NA> {
        let shape = Self::shape_part(s);
        let a = self.system.connection(&shape);
        let e = self.system.free_directions(&shape);
        SMatrix::from_fn(|r, c| if c < NS { a[(r, c)] } else { -e[(r, c - NS)] })
    }

    fn ignorable_shape(&self) -> &[usize] {
        &self.ignorable
    }

    fn forcing<T: Lift<Self::Param>>(
        &self,
        s: &SVector<T, NA>,
        v: &SVector<T, NA>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NA> {
        let (shape, vel, p) = (
            Self::shape_part(s),
            Self::shape_part(v),
            Self::momentum_part(v),
        );
        Self::join(
            &self.system.forcing(&shape, &vel, u),
            &self.system.free_forcing(&shape, &vel, &p, u),
        )
    }
}

/// The nonholonomic momentum `J = E(s)ᵀ ∂ℓ/∂ξ` at `(s, v, p)`, `ξ = −A(s) v + E(s) p`: the
/// component of the body momentum along the free directions, whose rate the momentum
/// equation gives.
pub fn nonholonomic_momentum<
    S,
    T,
    const DOF: usize,
    const NS: usize,
    const NM: usize,
    const NU: usize,
    const NA: usize,
>(
    sys: &WithMomentum<S, NS, NM>,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    p: &SVector<T, NM>,
) -> SVector<T, NM>
where
    S: NonholonomicSystem<DOF, NS, NM, NU>,
    ShapeWithMomentum<NS, NM>: ExtendedShape<NA>,
    T: Lift<S::Param>,
    Dv<T, DOF>: Lift<S::Param>,
{
    let xi = -(sys.system.connection(s) * v) + sys.system.free_directions(s) * p;
    let (se, ve) = (
        WithMomentum::<S, NS, NM>::join(s, &SVector::<T, NM>::zeros()),
        WithMomentum::<S, NS, NM>::join(v, p),
    );
    let mu = dl_dxi::<WithMomentum<S, NS, NM>, T, DOF, NA, NU>(sys, &se, &ve, &xi);
    sys.system.free_directions(s).transpose() * mu
}
