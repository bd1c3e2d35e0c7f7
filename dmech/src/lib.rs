//! Discrete mechanics of principal-kinematic nonholonomic systems on `G × M`.
//!
//! A system is given by three things only ([`PrincipalKinematicSystem`]): the reduced
//! Lagrangian `ℓ(s, v_s, ξ)`, the local connection `A(s)` (constraints `ξ + A(s) v_s = 0`,
//! `ξ = g⁻¹ġ`), and the forcing on the shape. From these the crate derives, with dual-number
//! derivatives:
//! - [`variational`]: the variational integrator of the discrete reduced
//!   Lagrange–d'Alembert–Pontryagin principle (group update, shape update, and the
//!   momentum-matching equation solved by Newton's method with an exact Jacobian), in the
//!   paper's first-order form or the symmetric, second-order [`midpoint`] form;
//! - [`continuous`]: the continuous-time equations of motion and RK1/RK2/RK4 on them;
//! - [`energy`](mod@energy): the energy function `E = v·∂ℓ/∂v + ξ·∂ℓ/∂ξ − ℓ`.
//!
//! A system that has them may also hand over closed forms (the partials of `ℓ`, the shape
//! acceleration): optional trait methods, `None` by default, that the planner's
//! transcriptions differentiate instead of nesting duals inside `ℓ`; the system's tests
//! must hold them equal to the derived ones.
//!
//! The derivations are in `docs/integrator.md`; how to add a robot: `docs/add-a-robot.md`.
//!
//! # Example: a differential-drive robot
//!
//! ```
//! use dmech::{energy, Lift, PrincipalKinematicSystem, VariationalIntegrator, ViState};
//! use dmech_lie::{Real, Se2};
//! use nalgebra::{SMatrix, SVector};
//!
//! /// Shape (φR, φL); wheel radius r, half-track d; wheel friction c; motor torques u.
//! struct Drive { m: f64, j: f64, i: f64, r: f64, d: f64, c: f64 }
//!
//! impl PrincipalKinematicSystem<3, 2, 2> for Drive {
//!     type Param = f64;
//!     type Group<T: Real> = Se2<T>;
//!     fn reduced_lagrangian<T: Lift<f64>>(&self, _s: &SVector<T, 2>, v: &SVector<T, 2>,
//!                                         xi: &SVector<T, 3>) -> T {
//!         (xi[0] * xi[0] + xi[1] * xi[1]) * (0.5 * self.m) + xi[2] * xi[2] * (0.5 * self.j)
//!             + (v[0] * v[0] + v[1] * v[1]) * (0.5 * self.i)
//!     }
//!     fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
//!         let (a, b, z) = (T::from(self.r / 2.0), T::from(self.r / (2.0 * self.d)), T::zero());
//!         SMatrix::<T, 3, 2>::new(-a, -a, z, z, -b, b)
//!     }
//!     fn forcing<T: Lift<f64>>(&self, _s: &SVector<T, 2>, v: &SVector<T, 2>,
//!                              u: &SVector<T, 2>) -> SVector<T, 2> {
//!         u - v * T::from(self.c)
//!     }
//! }
//!
//! let robot = Drive { m: 2.0, j: 0.05, i: 0.002, r: 0.05, d: 0.15, c: 0.01 };
//! let vi = VariationalIntegrator::new(0.01);
//! let mut x = ViState { g: Se2::new(0.0, 0.0, 0.0), s: SVector::zeros(), v: SVector::zeros() };
//! let u = SVector::<f64, 2>::new(0.02, 0.01); // more torque on the right wheel: turn left
//! for _ in 0..500 {
//!     x = vi.step(&robot, &x, &u, &u).expect("Newton converges").0;
//! }
//! assert!(x.g.theta > 0.0 && x.g.x > 0.0);
//! let e = energy(&robot, &x.s, &x.v);
//! assert!(e > 0.0);
//! ```

#![warn(missing_docs)]

pub mod continuous;
pub mod energy;
pub mod integrator;
pub mod midpoint;
pub mod momentum;
pub mod newton;
pub mod partials;
pub mod system;
pub mod variational;

pub use continuous::{ContinuousModel, RungeKutta};
pub use energy::energy;
pub use integrator::{Integrator, UnknownIntegrator};
pub use momentum::{nonholonomic_momentum, NonholonomicSystem, WithMomentum};
pub use system::{Lift, Param, PrincipalKinematicSystem};
pub use variational::{
    Discretisation, ForcingQuadrature, JacobianPolicy, NewtonCache, StepError,
    VariationalIntegrator, ViState,
};
