//! Discrete mechanics of principal-kinematic nonholonomic systems on `G × M`.
//!
//! A system is given by three things only ([`PrincipalKinematicSystem`]): the reduced
//! Lagrangian `ℓ(s, v_s, ξ)`, the local connection `A(s)` (constraints `ξ + A(s) v_s = 0`,
//! `ξ = g⁻¹ġ`), and the forcing on the shape. From these the crate derives, with dual-number
//! derivatives:
//! - [`variational`]: the variational integrator of the discrete reduced
//!   Lagrange–d'Alembert–Pontryagin principle (group update, shape update, and the
//!   momentum-matching equation solved by Newton's method with an exact Jacobian);
//! - [`continuous`]: the continuous-time equations of motion and RK1/RK2/RK4 on them;
//! - [`energy`]: the energy function `E = v·∂ℓ/∂v + ξ·∂ℓ/∂ξ − ℓ`.
//!
//! The derivations are in `docs/integrator.md`.

pub mod continuous;
pub mod energy;
pub mod linalg;
pub mod partials;
pub mod system;
pub mod variational;

pub use continuous::{ContinuousModel, RungeKutta};
pub use energy::energy;
pub use system::{Lift, PrincipalKinematicSystem};
pub use variational::{ForcingQuadrature, StepError, VariationalIntegrator, ViState};
