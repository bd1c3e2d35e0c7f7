//! The variational integrator of the discrete reduced Lagrange–d'Alembert–Pontryagin
//! principle (derivation: `docs/integrator.md`).
//!
//! Discrete path `(g_k, s_k, v_k)`, `v_k` the shape velocity on `[t_k, t_{k+1})`:
//! ```text
//! g_{k+1} = g_k exp(h ξ_k),   ξ_k = −A(s_k) v_k
//! s_{k+1} = s_k + h v_k
//! momentum matching at node k (unknown v_k, given s_{k−1}, v_{k−1}, s_k):
//!   ∂ℓ_k/∂v − h ∂ℓ_k/∂s − A(s_k)ᵀ dexp⁻¹(hξ_k)ᵀ μ_k
//!     = ∂ℓ_{k−1}/∂v − A(s_k)ᵀ dexp⁻¹(−hξ_{k−1})ᵀ μ_{k−1} + h F̄_k
//! ```
//! with `ℓ_k = ℓ(s_k, v_k, ξ_k)`, `μ = ∂ℓ/∂ξ`, `dexp⁻¹` the right-trivialised one of
//! `dmech-lie`, and `F̄_k` the discrete force of the chosen [`ForcingQuadrature`].

use crate::newton::{solve_momentum_matching, NewtonSettings};
pub use crate::newton::{JacobianPolicy, NewtonCache, StepError};
use crate::partials::{
    momenta_and_jacobians, pulled_back_gradient, pulled_back_gradient_dual,
    pulled_back_partials_factored,
};
use crate::system::{Lift, PrincipalKinematicSystem};
use dmech_lie::dual::value_and_jacobian;
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::{DualSVec64, DualVec};

type Dv<T, const N: usize> = DualVec<T, nalgebra::Const<N>>;

/// Where the discrete force at node `k` is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ForcingQuadrature {
    /// `F(s_{k−1}, v_{k−1}, u_{k−1})`: fully explicit (the paper's choice). Unstable for
    /// stiff dissipation: for the motor current the factor per step is `1 − hR/L`.
    Left,
    /// `F(s_k, v_k, u_k)`: implicit in the unknown `v_k` (backward-Euler-like for the
    /// dissipation, L-stable). Default.
    #[default]
    Right,
    /// `F` at the average of the two: trapezoidal-like, A-stable but not L-stable (a
    /// stiff current rings with factor `(1 − hR/2L)/(1 + hR/2L)`).
    Midpoint,
}

impl ForcingQuadrature {
    /// Which ends of the step the force reads: `(left, right)`, the node before (`k − 1`)
    /// and the node itself (`k`).
    pub fn ends(self) -> (bool, bool) {
        match self {
            ForcingQuadrature::Left => (true, false),
            ForcingQuadrature::Right => (false, true),
            ForcingQuadrature::Midpoint => (true, true),
        }
    }
}

/// A name that is not a [`ForcingQuadrature`]'s.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown forcing quadrature '{0}' (left, right, midpoint)")]
pub struct UnknownQuadrature(pub String);

impl std::str::FromStr for ForcingQuadrature {
    type Err = UnknownQuadrature;
    fn from_str(s: &str) -> Result<Self, UnknownQuadrature> {
        match s {
            "left" => Ok(Self::Left),
            "right" => Ok(Self::Right),
            "midpoint" => Ok(Self::Midpoint),
            _ => Err(UnknownQuadrature(s.to_string())),
        }
    }
}

/// Which node of an interval a discrete momentum is taken at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Node {
    /// The node the interval leaves: its momentum *outgoing* there (`side = +1`).
    Start,
    /// The node the interval arrives at: its momentum *incoming* there (`side = −1`).
    End,
}

impl Discretisation {
    /// `θ` of the interval's evaluation point `s_k + θ h v_k`, where its Lagrangian and
    /// connection are read: 0 for the first-order scheme, ½ for the midpoint one.
    pub fn theta(self) -> f64 {
        match self {
            Discretisation::FirstOrder => 0.0,
            Discretisation::Midpoint => 0.5,
        }
    }

    /// The interval's evaluation point `s + θ h v` (exactly `s` for the first-order scheme).
    pub fn evaluation_point<T: Real, const NS: usize>(
        self,
        h: f64,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
    ) -> SVector<T, NS> {
        match self {
            Discretisation::FirstOrder => *s,
            Discretisation::Midpoint => s + v * T::from(self.theta() * h),
        }
    }
}

/// The discrete momentum the interval from `s_start` with velocity `v` contributes at one
/// of its nodes, forces excluded, for either discretisation: with the evaluation point
/// `s̄ = s_start + θhv`, `ξ = −A(s̄) v`, `ℓ̄ = ℓ(s̄, v, ξ)` and `side = ±1` (start, end),
///
/// ```text
/// ∂ℓ̄/∂v + c ∂ℓ̄/∂s − A(s_node)ᵀ dexp⁻¹(side·hξ)ᵀ ∂ℓ̄/∂ξ,   c = −(1 − θ)h (start), θh (end)
/// ```
///
/// one evaluation of `ℓ` along `(δs, δv, δξ) = (cν, ν, −dexp⁻¹(side·hξ) A(s_node) ν)`.
/// `a_node = A(s_node)`. First order (`θ = 0`): the outgoing momentum `∂ℓ_k/∂v −
/// h ∂ℓ_k/∂s − A(s_k)ᵀ dexp⁻¹(hξ_k)ᵀ μ_k` and the incoming `∂ℓ_{k−1}/∂v − A(s_k)ᵀ
/// dexp⁻¹(−hξ_{k−1})ᵀ μ_{k−1}`; midpoint (`θ = ½`): the two differ only in `side` (the
/// source of the scheme's symmetry, [`crate::midpoint`]).
pub fn interval_momentum<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    discretisation: Discretisation,
    s_start: &SVector<T, NS>,
    v: &SVector<T, NS>,
    a_node: &SMatrix<T, DOF, NS>,
    node: Node,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
{
    let theta = discretisation.theta();
    let s_eval = discretisation.evaluation_point(h, s_start, v);
    let (side, c) = match node {
        Node::Start => (1.0, -(1.0 - theta) * h),
        Node::End => (-1.0, theta * h),
    };
    // The first-order interval leaving a node reads the connection there: `a_node` is it.
    let xi = if discretisation == Discretisation::FirstOrder && node == Node::Start {
        -(a_node * v)
    } else {
        -(sys.connection(&s_eval) * v)
    };
    let dinv = <S::Group<T> as LieGroup<DOF>>::dexp_inv(&(xi * T::from(side * h)));
    let d = -(dinv * a_node);
    pulled_back_gradient::<S, T, DOF, NS, NU>(sys, &s_eval, c, v, &xi, &d)
}

/// `(ξ_{k−1}, dexp⁻¹(−hξ_{k−1}))` of the incoming momentum, `ξ_{k−1} = −A(s_{k−1}) v_{k−1}`:
/// [`incoming_variation`]'s factors.
fn incoming_factors<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    s_prev: &SVector<T, NS>,
    v_prev: &SVector<T, NS>,
) -> (SVector<T, DOF>, SMatrix<T, DOF, DOF>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    let xi_prev = -(sys.connection(s_prev) * v_prev);
    let dinv = <S::Group<T> as LieGroup<DOF>>::dexp_inv(&(xi_prev * T::from(-h)));
    (xi_prev, dinv)
}

/// `(ξ_k, dexp⁻¹(hξ_k))` of the outgoing momentum, `ξ_k = −A(s_k) v_k`:
/// [`outgoing_variation`]'s factors.
fn outgoing_factors<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    h: f64,
    v_k: &SVector<T, NS>,
    a_k: &SMatrix<T, DOF, NS>,
) -> (SVector<T, DOF>, SMatrix<T, DOF, DOF>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    let xi_k = -(a_k * v_k);
    let dinv = <S::Group<T> as LieGroup<DOF>>::dexp_inv(&(xi_k * T::from(h)));
    (xi_k, dinv)
}

/// `(ξ_{k−1}, D)` of the incoming momentum: `ξ_{k−1} = −A(s_{k−1}) v_{k−1}` and the
/// variation `δξ = D ν`, `D = −dexp⁻¹(−hξ_{k−1}) A(s_k)`.
pub fn incoming_variation<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    s_prev: &SVector<T, NS>,
    v_prev: &SVector<T, NS>,
    a_k: &SMatrix<T, DOF, NS>,
) -> (SVector<T, DOF>, SMatrix<T, DOF, NS>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    let (xi_prev, dinv) = incoming_factors::<S, T, DOF, NS, NU>(sys, h, s_prev, v_prev);
    (xi_prev, -(dinv * a_k))
}

/// `(ξ_k, D)` of the outgoing momentum: `ξ_k = −A(s_k) v_k`, `D = −dexp⁻¹(hξ_k) A(s_k)`.
pub fn outgoing_variation<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    h: f64,
    v_k: &SVector<T, NS>,
    a_k: &SMatrix<T, DOF, NS>,
) -> (SVector<T, DOF>, SMatrix<T, DOF, NS>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    let (xi_k, dinv) = outgoing_factors::<S, T, DOF, NS, NU>(h, v_k, a_k);
    (xi_k, -(dinv * a_k))
}

/// The first-order incoming [`interval_momentum`] for first-order vector-dual inputs (value and Jacobian in `N`
/// seeds), by [`pulled_back_gradient_dual`]: the same numbers as the generic path with
/// `T = DualVec<f64, N>`, without nesting duals inside `ℓ`.
pub fn incoming_momentum_dual<
    S,
    const DOF: usize,
    const NS: usize,
    const NU: usize,
    const N: usize,
>(
    sys: &S,
    h: f64,
    s_prev: &SVector<Dv<f64, N>, NS>,
    v_prev: &SVector<Dv<f64, N>, NS>,
    a_k: &SMatrix<Dv<f64, N>, DOF, NS>,
) -> SVector<Dv<f64, N>, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    // `D = −dexp⁻¹ A` is formed only without closed-form partials (with them,
    // `pulled_back_partials_factored` never needs it).
    let (xi_prev, dinv) = incoming_factors::<S, _, DOF, NS, NU>(sys, h, s_prev, v_prev);
    if let Some(partials) = sys.closed_form_lagrangian_gradient(s_prev, v_prev, &xi_prev) {
        return pulled_back_partials_factored(partials, 0.0, &dinv, a_k);
    }
    let d = -(dinv * a_k);
    pulled_back_gradient_dual::<S, DOF, NS, NU, N>(sys, s_prev, 0.0, v_prev, &xi_prev, &d)
}

/// The first-order outgoing [`interval_momentum`] for first-order vector-dual inputs (see
/// [`incoming_momentum_dual`]).
pub fn outgoing_momentum_dual<
    S,
    const DOF: usize,
    const NS: usize,
    const NU: usize,
    const N: usize,
>(
    sys: &S,
    h: f64,
    s_k: &SVector<Dv<f64, N>, NS>,
    v_k: &SVector<Dv<f64, N>, NS>,
    a_k: &SMatrix<Dv<f64, N>, DOF, NS>,
) -> SVector<Dv<f64, N>, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    // `D` formed only without closed-form partials.
    let (xi_k, dinv) = outgoing_factors::<S, _, DOF, NS, NU>(h, v_k, a_k);
    if let Some(partials) = sys.closed_form_lagrangian_gradient(s_k, v_k, &xi_k) {
        return pulled_back_partials_factored(partials, -h, &dinv, a_k);
    }
    let d = -(dinv * a_k);
    pulled_back_gradient_dual::<S, DOF, NS, NU, N>(sys, s_k, -h, v_k, &xi_k, &d)
}

/// The discrete force at node `k` for the chosen quadrature.
#[allow(clippy::too_many_arguments)]
pub fn discrete_force<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    quadrature: ForcingQuadrature,
    s_prev: &SVector<T, NS>,
    v_prev: &SVector<T, NS>,
    u_prev: &SVector<T, NU>,
    s_k: &SVector<T, NS>,
    v_k: &SVector<T, NS>,
    u_k: &SVector<T, NU>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
{
    match quadrature {
        ForcingQuadrature::Left => sys.forcing(s_prev, v_prev, u_prev),
        ForcingQuadrature::Right => sys.forcing(s_k, v_k, u_k),
        ForcingQuadrature::Midpoint => {
            let half = T::from(0.5);
            sys.forcing(
                &((s_prev + s_k) * half),
                &((v_prev + v_k) * half),
                &((u_prev + u_k) * half),
            )
        }
    }
}

/// The momentum-matching residual at node `k` of either discretisation, divided by `h`
/// (force units: the scaling that keeps these rows comparable to the others in an
/// optimisation): `(outgoing_k − incoming_k)/h − F̄_k` ([`interval_momentum`]), with the
/// first-order scheme's force `F̄_k` read by `quadrature` ([`discrete_force`]) and the
/// midpoint scheme's the mean `½(F_{k−½} + F_{k+½})` of its intervals' (`quadrature` unused).
///
/// `prev = (s_{k−1}, v_{k−1}, u_{k−1})`, `cur = (s_k, v_k, u_k)`; `s_k` is passed separately
/// (not recomputed as `s_{k−1} + h v_{k−1}`) so that a transcription can keep it as its
/// own variable. Generic over the scalar: differentiate it with dual numbers.
#[allow(clippy::too_many_arguments)]
pub fn momentum_matching_residual<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    discretisation: Discretisation,
    quadrature: ForcingQuadrature,
    s_prev: &SVector<T, NS>,
    v_prev: &SVector<T, NS>,
    u_prev: &SVector<T, NU>,
    s_k: &SVector<T, NS>,
    v_k: &SVector<T, NS>,
    u_k: &SVector<T, NU>,
) -> SVector<T, NS>
where
    S: PrincipalKinematicSystem<DOF, NS, NU>,
    T: Lift<S::Param>,
    Dv<T, NS>: Lift<S::Param>,
{
    let a_k = sys.connection(s_k);
    let inc = interval_momentum(sys, h, discretisation, s_prev, v_prev, &a_k, Node::End);
    let out = interval_momentum(sys, h, discretisation, s_k, v_k, &a_k, Node::Start);
    let f = match discretisation {
        Discretisation::FirstOrder => {
            discrete_force(sys, quadrature, s_prev, v_prev, u_prev, s_k, v_k, u_k)
        }
        Discretisation::Midpoint => {
            let f_prev = crate::midpoint::interval_force(sys, h, s_prev, v_prev, u_prev);
            let f_k = crate::midpoint::interval_force(sys, h, s_k, v_k, u_k);
            (f_prev + f_k) * T::from(0.5)
        }
    };
    (out - inc) / T::from(h) - f
}

/// A state `(g, s, v)`. For the variational integrator, node `k`'s `g_k`, `s_k` and the
/// velocity `v_k` on the interval `[t_k, t_{k+1})`; for the continuous model
/// ([`crate::continuous::ContinuousState`], the same type) the instantaneous velocity.
#[derive(Clone, Copy, Debug)]
pub struct ViState<G, const NS: usize> {
    /// The group element `g_k`.
    pub g: G,
    /// The shape `s_k`.
    pub s: SVector<f64, NS>,
    /// The shape velocity (on the interval after the node, for the integrators).
    pub v: SVector<f64, NS>,
}

/// Which discretisation of the reduced LDAP principle a [`VariationalIntegrator`] steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Discretisation {
    /// The paper's: rectangle-rule Lagrangian `h ℓ(s_k, v_k, ξ_k)`, connection at `s_k`,
    /// one-sided forcing ([`ForcingQuadrature`]). First order. The paper's benchmarks and
    /// robots with a stiff dissipative mode far faster than the step (the WIP's motor
    /// currents) use it (docs/integrator.md, "Which scheme").
    FirstOrder,
    /// Lagrangian, connection and forcing at the interval midpoints `s_k + ½h v_k`
    /// ([`crate::midpoint`]): second order and time-reversible. The forcing quadrature
    /// setting is not used (the midpoint rule is part of the scheme). The default: it keeps
    /// a rolling robot's energy where the first-order scheme drains it (docs/integrator.md,
    /// "Which scheme").
    #[default]
    Midpoint,
}

/// The variational integrator: step size, discretisation, forcing quadrature, Newton
/// settings.
#[derive(Clone, Copy, Debug)]
pub struct VariationalIntegrator {
    /// The step, s.
    pub h: f64,
    /// The discretisation of the principle.
    pub discretisation: Discretisation,
    /// Where the first-order scheme reads the force.
    pub quadrature: ForcingQuadrature,
    /// How Newton's method forms its Jacobian.
    pub jacobian: JacobianPolicy,
    /// Newton stops when `‖Δv‖∞ ≤ tol · (1 + ‖v‖∞)`, or when the updates stall within 100×
    /// of that (round-off).
    pub newton_tol: f64,
    /// Newton iterations per step, at most.
    pub max_newton_iterations: usize,
}

impl VariationalIntegrator {
    /// The first-order scheme at step `h` with the default forcing quadrature and Newton
    /// Jacobian ([`ForcingQuadrature::default`], [`JacobianPolicy::default`]), Newton
    /// tolerance `1e-13` and at most 30 iterations.
    pub fn new(h: f64) -> Self {
        VariationalIntegrator {
            h,
            discretisation: Discretisation::default(),
            quadrature: ForcingQuadrature::default(),
            jacobian: JacobianPolicy::default(),
            newton_tol: 1e-13,
            max_newton_iterations: 30,
        }
    }
    /// Newton's settings of this integrator's momentum matching.
    pub(crate) fn newton_settings(&self) -> NewtonSettings {
        NewtonSettings {
            policy: self.jacobian,
            tol: self.newton_tol,
            max_iterations: self.max_newton_iterations,
        }
    }
    /// The same integrator with another discretisation.
    pub fn with_discretisation(mut self, d: Discretisation) -> Self {
        self.discretisation = d;
        self
    }
    /// The same integrator with another forcing quadrature (first-order scheme).
    pub fn with_quadrature(mut self, q: ForcingQuadrature) -> Self {
        self.quadrature = q;
        self
    }
    /// The same integrator with another Newton Jacobian policy.
    pub fn with_jacobian(mut self, j: JacobianPolicy) -> Self {
        self.jacobian = j;
        self
    }

    /// The first interval velocity `v_0` of a run that starts with the continuous shape
    /// velocity `v(0)` and input `u_0`. For [`Discretisation::Midpoint`] the discrete
    /// Legendre transform at node 0 (needed for second order: `v_0 ≈ v(h/2)`); for the
    /// first-order scheme `v(0)` itself (its O(h) error is not improved by more).
    pub fn start<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        s0: &SVector<f64, NS>,
        v0: &SVector<f64, NS>,
        u0: &SVector<f64, NU>,
    ) -> Result<SVector<f64, NS>, StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        match self.discretisation {
            Discretisation::FirstOrder => Ok(*v0),
            Discretisation::Midpoint => self.midpoint_start(sys, s0, v0, u0),
        }
    }

    /// The continuous shape velocity `v(t_k)` at node `k` of a discrete path, from the
    /// interval before it (`s_{k−1}`, `v_{k−1}`, `u_{k−1}`) and the node's shape `s_k`: the
    /// inverse of [`VariationalIntegrator::start`]. For [`Discretisation::Midpoint`] the
    /// discrete Legendre transform at the node, the `v` whose continuous momentum
    /// `∂ℓ/∂v − A(s_k)ᵀ ∂ℓ/∂ξ` (at `ξ = −A(s_k) v`) is the momentum the interval brings,
    /// its incoming momentum plus `½h F_{k−½}` (second order, where `v_{k−1} ≈ v(t_{k−½})`);
    /// for the first-order scheme `v_{k−1}` itself.
    pub fn node_velocity<S, const DOF: usize, const NS: usize, const NU: usize>(
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
        match self.discretisation {
            Discretisation::FirstOrder => Ok(*v_prev),
            Discretisation::Midpoint => {
                self.midpoint_node_velocity(sys, s_prev, v_prev, u_prev, s_k)
            }
        }
    }

    /// One step `(g_k, s_k, v_k) → (g_{k+1}, s_{k+1}, v_{k+1})` with `u_k` on `[t_k, t_{k+1})`
    /// and `u_{k+1}` on the next interval, Newton started from `v_k`. Returns the new state
    /// and the number of Newton iterations.
    pub fn step<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        x: &ViState<S::Group<f64>, NS>,
        u_k: &SVector<f64, NU>,
        u_next: &SVector<f64, NU>,
    ) -> Result<(ViState<S::Group<f64>, NS>, usize), StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        self.step_from(sys, x, u_k, u_next, &x.v)
    }

    /// [`VariationalIntegrator::step`] with Newton started from `guess` (e.g. the linear
    /// extrapolation `2 v_k − v_{k−1}`, which saves about one iteration on smooth motion).
    ///
    /// Each Newton iteration evaluates the residual and its exact Jacobian (hyper-dual
    /// numbers, [`momenta_and_jacobians`]). Once the update is below ≈ `√tol`, the remaining
    /// corrections reuse that Jacobian (residual only, in `f64`): from an error ε the chord
    /// step leaves ~ε·|ΔJ| ≈ ε², the same as a full step, for a fraction of the cost. A chord
    /// step that does not contract by 10× falls back to full Newton.
    pub fn step_from<S, const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        sys: &S,
        x: &ViState<S::Group<f64>, NS>,
        u_k: &SVector<f64, NU>,
        u_next: &SVector<f64, NU>,
        guess: &SVector<f64, NS>,
    ) -> Result<(ViState<S::Group<f64>, NS>, usize), StepError>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        self.step_cached(sys, x, u_k, u_next, guess, &mut NewtonCache::default())
    }

    /// [`VariationalIntegrator::step_from`] with a cache that carries the last exact
    /// Jacobian from step to step (used with [`JacobianPolicy::ReuseAcrossSteps`]).
    pub fn step_cached<S, const DOF: usize, const NS: usize, const NU: usize>(
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
        if self.discretisation == Discretisation::Midpoint {
            return self.midpoint_step(sys, x, u_k, u_next, guess, cache);
        }
        let h = self.h;
        let xi = -(sys.connection(&x.s) * x.v);
        let g_next =
            x.g.compose(&<S::Group<f64> as LieGroup<DOF>>::exp(&(xi * h)));
        let s_next = x.s + x.v * h;

        // Everything that does not depend on the unknown v_{k+1} is evaluated once, in f64.
        let a_next = sys.connection(&s_next);
        let incoming = interval_momentum(
            sys,
            h,
            Discretisation::FirstOrder,
            &x.s,
            &x.v,
            &a_next,
            Node::End,
        );
        let f_prev = match self.quadrature {
            ForcingQuadrature::Left => sys.forcing(&x.s, &x.v, u_k),
            _ => SVector::zeros(),
        };

        type D<const N: usize> = DualSVec64<N>;
        let at = a_next.transpose();

        // Residual and exact Jacobian at v.
        // (The dual lifts live here: chord steps, the common case, never need them.)
        let full = |v: &SVector<f64, NS>| {
            let ad = a_next.map(D::<NS>::from);
            let m = momenta_and_jacobians::<S, DOF, NS, NU>(sys, &s_next, v, &a_next);
            let mu_d = m.mu.map(D::<NS>::from);
            let (dinv_mu, d_dinv_mu) = value_and_jacobian(
                |vd: &SVector<D<NS>, NS>| {
                    let xi = -(ad * vd) * D::<NS>::from(h);
                    <S::Group<D<NS>> as LieGroup<DOF>>::dexp_inv(&xi).transpose() * mu_d
                },
                v,
            );
            let dinv = <S::Group<f64> as LieGroup<DOF>>::dexp_inv(&(-(a_next * v) * h));
            let out = m.p - m.ls * h - at * dinv_mu;
            let d_out = m.dp - m.dls * h - at * (dinv.transpose() * m.dmu + d_dinv_mu);
            let (f, df) = match self.quadrature {
                ForcingQuadrature::Left => (f_prev, SMatrix::zeros()),
                q => {
                    let (sk, uk) = (s_next.map(D::<NS>::from), u_next.map(D::<NS>::from));
                    let (sp, vp) = (x.s.map(D::<NS>::from), x.v.map(D::<NS>::from));
                    let up = u_k.map(D::<NS>::from);
                    value_and_jacobian(
                        |vd: &SVector<D<NS>, NS>| {
                            discrete_force::<S, D<NS>, DOF, NS, NU>(
                                sys, q, &sp, &vp, &up, &sk, vd, &uk,
                            )
                        },
                        v,
                    )
                }
            };
            ((out - incoming) / h - f, d_out / h - df)
        };
        // Residual only, in f64.
        let residual = |v: &SVector<f64, NS>| {
            let first = Discretisation::FirstOrder;
            let out = interval_momentum(sys, h, first, &s_next, v, &a_next, Node::Start);
            let f = match self.quadrature {
                ForcingQuadrature::Left => f_prev,
                q => discrete_force::<S, f64, DOF, NS, NU>(
                    sys, q, &x.s, &x.v, u_k, &s_next, v, u_next,
                ),
            };
            (out - incoming) / h - f
        };

        solve_momentum_matching(self.newton_settings(), guess, cache, full, residual).map(
            |(v, it)| {
                (
                    ViState {
                        g: g_next,
                        s: s_next,
                        v,
                    },
                    it,
                )
            },
        )
    }
}
