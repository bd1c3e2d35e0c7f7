//! The continuous-time equations of motion, derived from the same `ℓ`, `A` and forcing,
//! and explicit Runge–Kutta methods on them (derivation: `docs/integrator.md`).
//!
//! With `ξ = −A(s) v`, `P = ∂ℓ/∂v`, `μ = ∂ℓ/∂ξ`, the reduced Lagrange–d'Alembert equations
//! (horizontal variations `g⁻¹δg = −A δs`, `δξ = η̇ + ad_ξ η`) are
//! ```text
//! d/dt P − Aᵀ d/dt μ + Aᵀ ad_ξᵀ μ − ∂ℓ/∂s = F,      ġ = g ξ,   ṡ = v.
//! ```
//! They are affine in the acceleration `a = v̇`: `r(a) = 𝕄 a + r₀ = 0` with
//! `𝕄 = ∂(P − Aᵀμ)/∂v` (at fixed `A`) and `r₀ = r(0)`, whose time derivatives are taken
//! by a dual number in time along `(ṡ, v̇) = (v, 0)`.

use crate::newton::StepError;
use crate::partials::{dl_ds, dl_dxi, pulled_back_gradient};
use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::dual::{jacobian_part, seeded, value_and_jacobian};
use dmech_lie::linalg::{solve, Lu};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::{Dual, DualVec};

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// The shape acceleration `v̇ = a(s, v, u)`; `None` if the mass matrix is singular.
pub fn acceleration<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    u: &SVector<T, NU>,
) -> Option<SVector<T, NS>>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    T: Real,
{
    acceleration_with_force::<S, T, DOF, NS, NU>(sys, s, v, u, &SVector::zeros())
}

/// The shape acceleration with an external generalised force `f_ext` on the shape added to
/// the system's forcing, for any parameter scalar (dual parameters give derivatives with
/// respect to parameters). A force `f_b` on the group, in the body frame, enters as
/// `f_ext = −Aᵀ f_b` (virtual work along the horizontal variations `g⁻¹δg = −A δs`).
pub fn acceleration_with_force<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    u: &SVector<T, NU>,
    f_ext: &SVector<T, NS>,
) -> Option<SVector<T, NS>>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
    Dv<T, DOF>: Lift<S::Param>,
    Dv<Dv<T, NS>, NS>: Lift<S::Param>,
    Dual<T>: Lift<S::Param>,
    Dv<Dual<T>, NS>: Lift<S::Param>,
{
    let (m, r0) = mass_and_bias::<S, T, DOF, NS, NU>(sys, s, v, u);
    solve(&m, &(-(r0 - f_ext)))
}

/// `(𝕄, r₀)` of the equations of motion `𝕄 v̇ + r₀ = 0` (no external force).
fn mass_and_bias<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    u: &SVector<T, NU>,
) -> (SMatrix<T, NS, NS>, SVector<T, NS>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
    Dv<T, DOF>: Lift<S::Param>,
    Dv<Dv<T, NS>, NS>: Lift<S::Param>,
    Dual<T>: Lift<S::Param>,
    Dv<Dual<T>, NS>: Lift<S::Param>,
{
    let a = sys.connection(s);

    // 𝕄 = ∂/∂v [P(s, v, −A v) − Aᵀ μ(s, v, −A v)] at fixed s. `P − Aᵀμ` is the momentum
    // paired with a shape variation ν along the constraint, the ν-gradient of
    // ℓ(s, v + ν, ξ − Aν): one evaluation of ℓ, not one per partial.
    let sd = s.map(Dv::<T, NS>::from_re);
    let ad_ = a.map(Dv::<T, NS>::from_re);
    let (_, m) = value_and_jacobian(
        |vd: &SVector<Dv<T, NS>, NS>| {
            let xid = -(ad_ * vd);
            pulled_back_gradient::<S, _, DOF, NS, NU>(sys, &sd, 0.0, vd, &xid, &(-ad_))
        },
        v,
    );

    // r₀ = r(a = 0): the time derivative of P − A(s₀)ᵀμ along (ṡ, v̇) = (v, 0) and the rest.
    let r0 = motion_residual::<S, T, DOF, NS, NU>(sys, s, v, &SVector::zeros(), u);
    (m, r0)
}

/// The residual of the equations of motion at a trial acceleration `a`:
/// `r(s, v, a, u) = d/dt (P − A(s₀)ᵀμ) + Aᵀ ad_ξᵀ μ − ∂ℓ/∂s − F`, the time derivative taken
/// along `(ṡ, v̇) = (v, a)` by one dual number in time (so `r = 𝕄 a + r₀`; it vanishes
/// exactly at [`acceleration`]). Generic over the scalar; [`acceleration_jacobian`] uses it
/// for the implicit-function derivative of the acceleration.
pub fn motion_residual<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    a: &SVector<T, NS>,
    u: &SVector<T, NU>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
    Dv<T, DOF>: Lift<S::Param>,
    Dual<T>: Lift<S::Param>,
    Dv<Dual<T>, NS>: Lift<S::Param>,
{
    let a0 = sys.connection(s);
    let xi = -(a0 * v);
    let st = SVector::<Dual<T>, NS>::from_fn(|i, _| Dual::new(s[i], v[i]));
    let vt = SVector::<Dual<T>, NS>::from_fn(|i, _| Dual::new(v[i], a[i]));
    let xit = -(sys.connection(&st) * vt);
    let a0t = a0.map(Dual::from_re);
    let momentum_dot =
        pulled_back_gradient::<S, _, DOF, NS, NU>(sys, &st, 0.0, &vt, &xit, &(-a0t)).map(|z| z.eps);
    let mu = dl_dxi::<S, T, DOF, NS, NU>(sys, s, v, &xi);
    let ls = dl_ds::<S, T, DOF, NS, NU>(sys, s, v, &xi);
    let ad = <S::Group<T> as LieGroup<DOF>>::ad(&xi);
    momentum_dot + a0.transpose() * (ad.transpose() * mu) - ls - sys.forcing(s, v, u)
}

/// The shape acceleration and its Jacobians, in `f64`.
#[derive(Clone, Copy, Debug)]
pub struct AccelerationJacobian<const NS: usize, const NU: usize> {
    /// `a(s, v, u)`.
    pub a: SVector<f64, NS>,
    /// `∂a/∂s`.
    pub a_s: SMatrix<f64, NS, NS>,
    /// `∂a/∂v`.
    pub a_v: SMatrix<f64, NS, NS>,
    /// `∂a/∂u`.
    pub a_u: SMatrix<f64, NS, NU>,
}

/// [`acceleration`] with its Jacobians by the implicit function theorem on
/// `r(s, v, a, u) = 0` ([`motion_residual`]), each block seeded alone:
/// `∂a/∂θ = −𝕄⁻¹ ∂r/∂θ|_a` for `θ = s` and `θ = v` (one vector-dual evaluation of `r` each,
/// `NS` lanes), and `∂a/∂u = 𝕄⁻¹ ∂F/∂u` (the input enters `r` only through the forcing:
/// one evaluation of `F`). Seeding only the blocks `r` reads (not the group coordinates, not
/// a whole stage vector) is what makes it cheap on a stage.
/// `None` if the mass matrix is singular.
pub fn acceleration_jacobian<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<f64, NS>,
    v: &SVector<f64, NS>,
    u: &SVector<f64, NU>,
) -> Option<AccelerationJacobian<NS, NU>>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    // `r` is affine in `a`, `r = 𝕄 a + r₀`: `𝕄` as the momentum's Jacobian in `v`, `r₀` in
    // plain numbers ([`mass_and_bias`]; a pass of `r` seeded in `a` costs more).
    let (sl, vl) = (s.map(Dv::from_re), v.map(Dv::from_re));
    let ul = u.map(Dv::<f64, NS>::from_re);
    let (m, r0) = mass_and_bias::<S, f64, DOF, NS, NU>(sys, s, v, u);
    let lu = Lu::new(&m)?;
    let a = lu.solve(&(-r0));
    let ad = a.map(Dv::<f64, NS>::from_re);
    let r_s = motion_residual::<S, Dv<f64, NS>, DOF, NS, NU>(sys, &seeded(s), &vl, &ad, &ul);
    let r_v = motion_residual::<S, Dv<f64, NS>, DOF, NS, NU>(sys, &sl, &seeded(v), &ad, &ul);
    let f_u = sys.forcing(
        &s.map(Dv::<f64, NU>::from_re),
        &v.map(Dv::<f64, NU>::from_re),
        &seeded(u),
    );
    Some(AccelerationJacobian {
        a,
        a_s: lu.solve_columns(&(-jacobian_part(&r_s))),
        a_v: lu.solve_columns(&(-jacobian_part(&r_v))),
        a_u: lu.solve_columns(&jacobian_part(&f_u)),
    })
}

/// The rate of the group coordinates (`LieGroup::coordinates`) for body velocity `ξ`:
/// `d/dt coords(g exp(t ξ))` at `t = 0`, by a dual number.
pub fn coordinate_rate<G, T, const DOF: usize>(g: &G, xi: &SVector<T, DOF>) -> Vec<T>
where
    G: LieGroup<DOF, Scalar = T>,
    T: Real,
{
    let c: Vec<Dual<T>> = g.coordinates().into_iter().map(Dual::from_re).collect();
    let gd =
        <G::With<Dual<T>> as LieGroup<DOF>>::from_coordinates(&c).expect("coordinates round-trip");
    let xid = xi.map(|x| Dual::new(T::zero(), x));
    gd.rplus(&xid)
        .coordinates()
        .into_iter()
        .map(|z| z.eps)
        .collect()
}

/// Explicit Runge–Kutta methods on the continuous model, in the coordinates
/// `(coords(g), s, v)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RungeKutta {
    /// Explicit Euler.
    Rk1,
    /// Explicit midpoint.
    Rk2,
    /// The classical fourth-order method.
    Rk4,
}

/// A state of the continuous model: group element, shape, shape velocity (the same
/// type as the integrator's state).
pub type ContinuousState<G, const NS: usize> = crate::variational::ViState<G, NS>;

/// An external generalised force on the shape as a function of the state.
pub type ShapeForce<'a, G, const NS: usize> =
    dyn Fn(&ContinuousState<G, NS>) -> SVector<f64, NS> + 'a;

/// The continuous model of a system, with its Runge–Kutta steps.
pub struct ContinuousModel;

type Deriv<const NS: usize> = (Vec<f64>, SVector<f64, NS>, SVector<f64, NS>);

impl ContinuousModel {
    /// `(d coords(g)/dt, ṡ, v̇)` at a state.
    pub fn derivative<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        x: &ContinuousState<S::Group<f64>, NS>,
        u: &SVector<f64, NU>,
    ) -> Result<Deriv<NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        Self::derivative_with_force::<S, DOF, NS, NU>(sys, x, u, &|_| SVector::zeros())
    }

    /// The same with an external generalised force on the shape that depends on the state
    /// (e.g. gravity along an inclined floor), added to the system's forcing as in
    /// [`acceleration_with_force`].
    pub fn derivative_with_force<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        x: &ContinuousState<S::Group<f64>, NS>,
        u: &SVector<f64, NU>,
        f_ext: &ShapeForce<'_, S::Group<f64>, NS>,
    ) -> Result<Deriv<NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let xi = -(sys.connection(&x.s) * x.v);
        let gdot = coordinate_rate::<_, f64, DOF>(&x.g, &xi);
        let a = acceleration_with_force::<S, f64, DOF, NS, NU>(sys, &x.s, &x.v, u, &f_ext(x))
            .ok_or(StepError::Singular)?;
        if !a.iter().all(|z| z.is_finite()) {
            return Err(StepError::NonFinite);
        }
        Ok((gdot, x.v, a))
    }

    fn advance<G, const DOF: usize, const NS: usize>(
        x: &ContinuousState<G, NS>,
        k: &Deriv<NS>,
        dt: f64,
    ) -> ContinuousState<G, NS>
    where
        G: LieGroup<DOF, Scalar = f64>,
    {
        let c: Vec<f64> =
            x.g.coordinates()
                .iter()
                .zip(&k.0)
                .map(|(a, b)| a + dt * b)
                .collect();
        ContinuousState {
            g: G::from_coordinates(&c).expect("same length"),
            s: x.s + k.1 * dt,
            v: x.v + k.2 * dt,
        }
    }

    /// One explicit Runge–Kutta step of size `h` with the input held constant.
    pub fn step<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        method: RungeKutta,
        h: f64,
        x: &ContinuousState<S::Group<f64>, NS>,
        u: &SVector<f64, NU>,
    ) -> Result<ContinuousState<S::Group<f64>, NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        Self::step_with_force::<S, DOF, NS, NU>(sys, method, h, x, u, &|_| SVector::zeros())
    }

    /// One explicit Runge–Kutta step with a state-dependent external shape force
    /// ([`ContinuousModel::derivative_with_force`]).
    pub fn step_with_force<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        method: RungeKutta,
        h: f64,
        x: &ContinuousState<S::Group<f64>, NS>,
        u: &SVector<f64, NU>,
        f_ext: &ShapeForce<'_, S::Group<f64>, NS>,
    ) -> Result<ContinuousState<S::Group<f64>, NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let f = |y: &ContinuousState<S::Group<f64>, NS>| {
            Self::derivative_with_force::<S, DOF, NS, NU>(sys, y, u, f_ext)
        };
        let adv = Self::advance::<S::Group<f64>, DOF, NS>;
        let out = match method {
            RungeKutta::Rk1 => adv(x, &f(x)?, h),
            RungeKutta::Rk2 => {
                let k1 = f(x)?;
                let k2 = f(&adv(x, &k1, 0.5 * h))?;
                adv(x, &k2, h)
            }
            RungeKutta::Rk4 => {
                let k1 = f(x)?;
                let k2 = f(&adv(x, &k1, 0.5 * h))?;
                let k3 = f(&adv(x, &k2, 0.5 * h))?;
                let k4 = f(&adv(x, &k3, h))?;
                let comb = |i: usize| k1.0[i] + 2.0 * k2.0[i] + 2.0 * k3.0[i] + k4.0[i];
                let k: Deriv<NS> = (
                    (0..k1.0.len()).map(|i| comb(i) / 6.0).collect(),
                    (k1.1 + k2.1 * 2.0 + k3.1 * 2.0 + k4.1) / 6.0,
                    (k1.2 + k2.2 * 2.0 + k3.2 * 2.0 + k4.2) / 6.0,
                );
                adv(x, &k, h)
            }
        };
        if !out.s.iter().chain(out.v.iter()).all(|z| z.is_finite()) {
            return Err(StepError::NonFinite);
        }
        Ok(out)
    }
}
