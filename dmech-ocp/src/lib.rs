//! Optimal control of `dmech` systems: a robot's planning problem transcribed into a
//! stage-structured nonlinear program and solved by a structure-exploiting interior point.
//!
//! Three layers, each a module:
//!
//! - [`transcription`]: what a robot implements to plan ([`transcription::PlanningProblem`]:
//!   cost, path constraints and conditions over a typed [`transcription::Stage`]) and its
//!   transcription for every discretisation: the first-order and midpoint variational
//!   integrators ([`transcription::VarIntTranscription`]: `x_k = (coords(g_k), s_k,
//!   v_{k−1}, u_{k−1})`, `w_k = (v_k, u_k)`, the momentum matching of node `k` as the stage
//!   equality), RK1/2/4 on the continuous model ([`transcription::RkTranscription`]:
//!   `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`), and free waypoint timing
//!   ([`transcription::free_timing`]). Carrying `u_{k−1}` makes rate limits stage-local.
//! - [`nlp`] and [`solver`]: the stage-structured program ([`nlp::StageProblem`]: explicit
//!   dynamics `x_{k+1} = f(x_k, w_k)`, stage equalities, inequalities, state equalities,
//!   optional global variables) and the primal–dual interior point that solves it
//!   ([`solver::Solver`]), its Newton systems by a Riccati recursion over the stages (or a
//!   sparse `LDLᵀ`). The solver knows no mechanics.
//! - [`toolkit`]: starts from a geometric path, refinement to a finer mesh, mesh sequencing,
//!   a plan in one call, a replay through the integrator.
//! - [`tracking`]: a plan tracked in closed loop: its linearisation, LQ gains, the
//!   constrained MPC on [`qp`], a plant run.
//! - [`qp`]: a stage-structured convex QP and its interior point, for model predictive
//!   control (`docs/qp.md`).
//!
//! Every stage function is generic over the scalar, so exact Jacobians and Hessians come
//! from dual numbers, stage by stage. Sizes are said once, by the robot and its problem
//! ([`transcription::sizes`]). The design is written up in `docs/ocp.md` (transcriptions, toolkit) and
//! `docs/solver.md` (the interior point).

#![warn(missing_docs)]

pub mod nlp;
pub mod qp;
pub mod solver;
pub mod toolkit;
pub mod tracking;
pub mod transcription;
