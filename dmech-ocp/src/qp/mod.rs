//! A stage-structured convex QP and the primal–dual interior point that solves it: the
//! linear–quadratic problems of model predictive control, in microseconds.
//!
//! ```text
//! min  Σ_{k<N} ½ [x_k;u_k]ᵀ [Q_k S_k; S_kᵀ R_k] [x_k;u_k] + q_kᵀx_k + r_kᵀu_k  + ½ x_Nᵀ Q_N x_N + q_Nᵀ x_N
//!      + Σ soft rows' prices  l1 · v + ½ l2 · v²  of their violations v
//! s.t. x_0 given,  x_{k+1} = A_k x_k + B_k u_k + c_k,
//!      lo_k ≤ D_k x_k + E_k u_k ≤ hi_k   (k ≤ N; ±∞ allowed; rows hard or soft)
//! ```
//!
//! Sizes are const generics, said once: `NX` states, `NU` inputs, `NC` rows per stage
//! (the terminal stage has as many, on `x_N` alone). [`StageQp::new`] validates the data
//! ([`QpError`]); [`QpSolver`] solves it by Mehrotra's predictor–corrector, each Newton
//! system by a Riccati recursion over the stages with every row's slack, multiplier and
//! soft violation eliminated inside its stage (`newton.rs`); [`QpSolution`] carries the
//! [`QpStatus`] (solved, or infeasible or unbounded with a certificate checked), the
//! [`QpInfo`], and makes a [`WarmStart`] for the same horizon or, shifted by a stage,
//! for the next sample of a receding horizon. [`StageQp::to_text`] and
//! [`StageQp::all_from_text`] write and read a plain-text form for other programs
//! (`text.rs`). Algorithm and derivation: `docs/qp.md`.

// Side, row and stage loops index several per-stage arrays (iterate, residual, factor,
// sides) in step.
#![allow(clippy::needless_range_loop)]

mod certificates;
mod dense;
mod ipm;
mod iterate;
mod newton;
mod problem;
mod settings;
mod solution;
mod text;

pub use ipm::QpSolver;
pub use problem::{QpError, Rows, SoftPrice, Stage, StageQp, Terminal};
pub use settings::{QpSettings, QpSettingsBuilder, SettingsError};
pub use solution::{QpInfo, QpSolution, QpStatus, WarmStart};
pub use text::QpTextError;
