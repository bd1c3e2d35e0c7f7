//! Transcription of optimal control problems of `dmech` systems into stage-structured
//! nonlinear programs.
//!
//! Every stage `k` has a state `x_k` and a stage decision `w_k`; the dynamics are explicit,
//! `x_{k+1} = f(x_k, w_k)`, and any implicit relation is a stage-local equality
//! `e(x_k, w_k) = 0`. That form is what a Riccati-based interior point needs (every
//! constraint couples at most one stage to the next), and both transcriptions fit it:
//!
//! - [`varint`]: `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`, `w_k = (v_k, u_k)`. The
//!   group and shape updates are the dynamics; the momentum-matching equation of node `k`
//!   (which involves `s_{k−1} = s_k − h v_{k−1}`, `v_{k−1}`, `u_{k−1}` and `(s_k, v_k, u_k)`) is
//!   the stage equality. Carrying `u_{k−1}` also makes the rate limit `|u_k − u_{k−1}|`
//!   stage-local.
//! - [`runge_kutta`]: `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`; the dynamics
//!   are one RK1/RK2/RK4 step of the continuous model; no stage equality.
//!
//! - [`transcription`]: a robot's problem in typed terms ([`transcription::Stage`],
//!   [`transcription::Condition`]) transcribed once for every discretisation: what a robot
//!   implements to plan.
//! - [`kinematic_start`]: a start from a geometric pose path, with the shape motion that
//!   realises it through the connection (a nonholonomic robot cannot follow any path).
//! - [`refine`]: a VI iterate carried to a finer mesh, the start of mesh sequencing.
//! - [`sequencing`]: continuation over a list of problems, and mesh sequencing for any
//!   robot's variational plan.
//!
//! All stage functions are generic over the scalar, so their exact Jacobians and Hessians
//! come from dual numbers, stage by stage. The design is written up in `docs/ocp.md`.

pub mod nlp;
pub mod solver;
#[cfg(test)]
mod test_rng;
pub mod toolkit;
pub mod transcription;
