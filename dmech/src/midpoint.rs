//! The symmetric (midpoint) discretisation of the reduced Lagrange–d'Alembert–Pontryagin
//! principle: second order and time-reversible (derivation: `docs/integrator.md`,
//! "The midpoint discretisation").
//!
//! Discrete path `(g_k, s_k, v_k)`, `v_k` the shape velocity on `[t_k, t_{k+1})`,
//! `s_{k+½} = s_k + ½h v_k`:
//! ```text
//! g_{k+1} = g_k exp(h ξ_k),   ξ_k = −A(s_{k+½}) v_k
//! s_{k+1} = s_k + h v_k
//! momentum matching at node k (unknown v_k, given s_{k−1}, v_{k−1}, s_k):
//!   ∂ℓ_k/∂v − ½h ∂ℓ_k/∂s − A(s_k)ᵀ dexp⁻¹(hξ_k)ᵀ μ_k
//!     = ∂ℓ_{k−1}/∂v + ½h ∂ℓ_{k−1}/∂s − A(s_k)ᵀ dexp⁻¹(−hξ_{k−1})ᵀ μ_{k−1}
//!       + ½h (F_{k−½} + F_{k+½})
//! ```
//! with `ℓ_k = ℓ(s_{k+½}, v_k, ξ_k)`, `μ = ∂ℓ/∂ξ` and `F_{k+½} = F(s_{k+½}, v_k, u_k)`.
//! Everything is evaluated at interval midpoints except the variations `η_k = −A(s_k)δs_k`,
//! which live at the nodes; swapping the two intervals and flipping the velocities maps
//! the equation onto itself (the source of reversibility).

use crate::newton::{solve_momentum_matching, NewtonCache};
use crate::partials::pulled_back_gradient;
use crate::system::{Lift, PrincipalKinematicSystem};
use crate::variational::{
    interval_momentum, Discretisation, Node, StepError, VariationalIntegrator, ViState,
};
use dmech_lie::dual::value_and_jacobian;
use dmech_lie::LieGroup;
use nalgebra::SVector;
use num_dual::DualSVec64;

/// `ξ_k = −A(s_{k+½}) v_k`: the body velocity of interval `k` (the discrete constraint).
pub fn interval_body_velocity<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
) -> SVector<T, DOF>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    -(sys.connection(&Discretisation::Midpoint.evaluation_point(h, s, v)) * v)
}

/// `F_{k+½} = F(s_{k+½}, v_k, u_k)`: the force of interval `k`.
pub fn interval_force<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    u: &SVector<T, NU>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    sys.forcing(&Discretisation::Midpoint.evaluation_point(h, s, v), v, u)
}

impl VariationalIntegrator {
    /// One step of the midpoint discretisation (see [`VariationalIntegrator::step_cached`]
    /// for the arguments): `g_{k+1}`, `s_{k+1}` explicitly from `v_k`, then `v_{k+1}` from
    /// the momentum matching at node `k+1`.
    pub(crate) fn midpoint_step<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        x: &ViState<S::Group<f64>, NS>,
        u_k: &SVector<f64, NU>,
        u_next: &SVector<f64, NU>,
        guess: &SVector<f64, NS>,
        cache: &mut NewtonCache<NS>,
    ) -> Result<(ViState<S::Group<f64>, NS>, usize), StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let h = self.h;
        let xi = interval_body_velocity::<S, f64, DOF, NS, NU>(sys, h, &x.s, &x.v);
        let g_next =
            x.g.compose(&<S::Group<f64> as LieGroup<DOF>>::exp(&(xi * h)));
        let s_next = x.s + x.v * h;
        // What does not depend on the unknown v_{k+1}: once, in f64.
        let a_next = sys.connection(&s_next);
        let incoming = interval_momentum(
            sys,
            h,
            Discretisation::Midpoint,
            &x.s,
            &x.v,
            &a_next,
            Node::End,
        );
        let f_prev = interval_force::<S, f64, DOF, NS, NU>(sys, h, &x.s, &x.v, u_k);
        let known = incoming / h + f_prev * 0.5;
        let (v, it) = self.solve_outgoing(sys, &s_next, u_next, &known, guess, cache)?;
        Ok((
            ViState {
                g: g_next,
                s: s_next,
                v,
            },
            it,
        ))
    }

    /// The midpoint scheme's first interval velocity `v_0` for a start at rest or in
    /// motion with the *continuous* shape velocity `v(0)`: the discrete Legendre transform
    /// at node 0, `outgoing_0(v_0) − ½h F_{½} = P − A(s_0)ᵀ μ` at `(s_0, v(0))`. `v_0` is
    /// the velocity on `[0, h)`, ≈ `v(h/2)`; starting from `v_0 = v(0)` instead would cost
    /// an O(h) error for the whole run (the scheme would be first order).
    pub(crate) fn midpoint_start<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        s0: &SVector<f64, NS>,
        v0: &SVector<f64, NS>,
        u0: &SVector<f64, NU>,
    ) -> Result<SVector<f64, NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let a0 = sys.connection(s0);
        let xi0 = -(a0 * v0);
        let p0 = pulled_back_gradient::<S, f64, DOF, NS, NU>(sys, s0, 0.0, v0, &xi0, &-a0);
        let known = p0 / self.h;
        let mut cache = NewtonCache::default();
        Ok(self.solve_outgoing(sys, s0, u0, &known, v0, &mut cache)?.0)
    }

    /// The continuous velocity at node `k` from the interval before it
    /// ([`VariationalIntegrator::node_velocity`]): `P(s_k, v) = incoming_k + ½h F_{k−½}`
    /// for `v` by Newton's method from `v_{k−1}`, `P` the continuous momentum.
    pub(crate) fn midpoint_node_velocity<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        s_prev: &SVector<f64, NS>,
        v_prev: &SVector<f64, NS>,
        u_prev: &SVector<f64, NU>,
        s_k: &SVector<f64, NS>,
    ) -> Result<SVector<f64, NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        type D<const N: usize> = DualSVec64<N>;
        let h = self.h;
        let a_k = sys.connection(s_k);
        let incoming = interval_momentum(
            sys,
            h,
            Discretisation::Midpoint,
            s_prev,
            v_prev,
            &a_k,
            Node::End,
        );
        let f_prev = interval_force::<S, f64, DOF, NS, NU>(sys, h, s_prev, v_prev, u_prev);
        let known = incoming + f_prev * (0.5 * h);
        let momentum = |v: &SVector<D<NS>, NS>| {
            let (sk, ak) = (s_k.map(D::<NS>::from), a_k.map(D::<NS>::from));
            let xi = -(ak * v);
            pulled_back_gradient::<S, D<NS>, DOF, NS, NU>(sys, &sk, 0.0, v, &xi, &-ak)
        };
        let full = |v: &SVector<f64, NS>| {
            let (p, j) = value_and_jacobian(momentum, v);
            (p - known, j)
        };
        let residual = |v: &SVector<f64, NS>| {
            let xi = -(a_k * v);
            pulled_back_gradient::<S, f64, DOF, NS, NU>(sys, s_k, 0.0, v, &xi, &-a_k) - known
        };
        let mut cache = NewtonCache::default();
        solve_momentum_matching(self.newton_settings(), v_prev, &mut cache, full, residual)
            .map(|(v, _)| v)
    }

    /// Solves `outgoing_k(v)/h − ½ F(s_{k+½}, v, u_k) = known` for `v` by Newton's method.
    /// The Jacobian is taken by vector duals through the whole outgoing side (ℓ's gradient
    /// in nested duals): unlike the first-order scheme, `v` also moves the point `s_{k+½}`
    /// where ℓ, `A` and `F` are evaluated.
    fn solve_outgoing<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        s_k: &SVector<f64, NS>,
        u_k: &SVector<f64, NU>,
        known: &SVector<f64, NS>,
        guess: &SVector<f64, NS>,
        cache: &mut NewtonCache<NS>,
    ) -> Result<(SVector<f64, NS>, usize), StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        type D<const N: usize> = DualSVec64<N>;
        let h = self.h;
        let a_k = sys.connection(s_k);
        let outgoing_side = |v: &SVector<D<NS>, NS>| {
            let (sk, ak) = (s_k.map(D::<NS>::from), a_k.map(D::<NS>::from));
            let uk = u_k.map(D::<NS>::from);
            let out = interval_momentum(sys, h, Discretisation::Midpoint, &sk, v, &ak, Node::Start);
            let f = interval_force::<S, D<NS>, DOF, NS, NU>(sys, h, &sk, v, &uk);
            out / D::<NS>::from(h) - f * D::<NS>::from(0.5)
        };
        let full = |v: &SVector<f64, NS>| {
            let (r, j) = value_and_jacobian(outgoing_side, v);
            (r - known, j)
        };
        let residual = |v: &SVector<f64, NS>| {
            let out =
                interval_momentum(sys, h, Discretisation::Midpoint, s_k, v, &a_k, Node::Start);
            let f = interval_force::<S, f64, DOF, NS, NU>(sys, h, s_k, v, u_k);
            out / h - f * 0.5 - known
        };
        solve_momentum_matching(self.newton_settings(), guess, cache, full, residual)
    }
}
