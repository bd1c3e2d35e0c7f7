//! Newton's method for the momentum-matching equation of a variational step: exact
//! Jacobians by autodiff, chord polishing, and (optionally) a Jacobian carried across steps
//! with Broyden updates. Shared by every discretisation in [`crate::variational`] and
//! [`crate::midpoint`].

use dmech_lie::linalg::Lu;
use nalgebra::{SMatrix, SVector};
use std::fmt;

/// Why a step failed. A failed step never returns a NaN state.
#[derive(Clone, Debug, PartialEq)]
pub enum StepError {
    /// Newton's method did not reach the tolerance in the allowed iterations.
    NoConvergence {
        /// The iterations taken.
        iterations: usize,
        /// The last Newton step's size, `‖Δv‖∞`.
        step_norm: f64,
    },
    /// A residual, Jacobian or iterate was not finite.
    NonFinite,
    /// The Jacobian (or the mass matrix) was singular.
    Singular,
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StepError::NoConvergence {
                iterations,
                step_norm,
            } => write!(
                f,
                "Newton iteration did not converge in {iterations} iterations (last step {step_norm:.3e})"
            ),
            StepError::NonFinite => write!(f, "non-finite value in the integrator step"),
            StepError::Singular => write!(f, "singular Jacobian in the integrator step"),
        }
    }
}
impl std::error::Error for StepError {}

/// Newton switches to chord steps (the last exact Jacobian reused) once an update is below
/// this fraction of `1 + ‖v‖∞` (≈ √tol: from there one chord step reaches the tolerance);
/// a chord step that does not contract 10× goes back to full Newton.
const CHORD_SWITCH: f64 = 3e-7;

/// When Newton's method evaluates the exact Jacobian.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum JacobianPolicy {
    /// At every iterate until the update is below ≈ √tol, then chord polishing (default).
    #[default]
    Exact,
    /// Carry the Jacobian across steps: evaluated exactly (by autodiff) at the first step
    /// and again, at the current iterate, whenever a step contracts less than 10×; between
    /// refreshes it is kept current by Broyden's secant updates. Modified Newton, as stiff
    /// ODE codes do; the converged state satisfies the same tolerance.
    ReuseAcrossSteps,
}

/// Carries Newton's last exact Jacobian from one step to the next.
#[derive(Clone, Copy, Debug)]
pub struct NewtonCache<const NS: usize> {
    /// The Jacobian and its factorisation.
    pub jacobian: Option<(SMatrix<f64, NS, NS>, Lu<f64, NS>)>,
}

impl<const NS: usize> Default for NewtonCache<NS> {
    fn default() -> Self {
        NewtonCache { jacobian: None }
    }
}

/// The stopping rule and Jacobian policy of one solve.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NewtonSettings {
    pub policy: JacobianPolicy,
    /// Stop when `‖Δv‖∞ ≤ tol · (1 + ‖v‖∞)`, or when the updates stall within 100× of that.
    pub tol: f64,
    pub max_iterations: usize,
}

/// Solves `r(v) = 0` from `guess`: `full(v)` gives the residual and its exact Jacobian,
/// `residual(v)` the residual alone (for chord and Broyden steps). Returns the solution
/// and the number of iterations.
///
/// Once an update is below ≈ `√tol`, the remaining corrections reuse the last exact
/// Jacobian: from an error ε the chord step leaves ~ε·|ΔJ| ≈ ε², the same as a full step,
/// for a fraction of the cost. A chord step that does not contract by 10× falls back to full
/// Newton.
pub(crate) fn solve_momentum_matching<const NS: usize>(
    settings: NewtonSettings,
    guess: &SVector<f64, NS>,
    cache: &mut NewtonCache<NS>,
    full: impl Fn(&SVector<f64, NS>) -> (SVector<f64, NS>, SMatrix<f64, NS, NS>),
    residual: impl Fn(&SVector<f64, NS>) -> SVector<f64, NS>,
) -> Result<(SVector<f64, NS>, usize), StepError> {
    let reuse = settings.policy == JacobianPolicy::ReuseAcrossSteps;
    let mut v = *guess;
    let mut jac: Option<(SMatrix<f64, NS, NS>, Lu<f64, NS>)> =
        if reuse { cache.jacobian } else { None };
    let mut last: Option<(SVector<f64, NS>, SVector<f64, NS>)> = None;
    let mut last_step = f64::INFINITY;
    for it in 1..=settings.max_iterations {
        let scale = 1.0 + v.amax();
        let (r, jm, lu, exact_here) = match jac {
            Some((mut jm, mut lu)) => {
                let r = residual(&v);
                // Broyden's secant update of the carried Jacobian with the last step,
                // while that step is well above the residual's round-off.
                if let Some((r_prev, dv_prev)) = last {
                    if dv_prev.amax() > 1e4 * settings.tol * scale {
                        let y = r - r_prev;
                        let corr = (y - jm * dv_prev) / dv_prev.dot(&dv_prev);
                        jm += corr * dv_prev.transpose();
                        lu = Lu::new(&jm).ok_or(StepError::Singular)?;
                    }
                }
                (r, jm, lu, false)
            }
            None => {
                let (r, j) = full(&v);
                if !j.iter().all(|z| z.is_finite()) {
                    return Err(StepError::NonFinite);
                }
                (r, j, Lu::new(&j).ok_or(StepError::Singular)?, true)
            }
        };
        if !r.iter().all(|z| z.is_finite()) {
            return Err(StepError::NonFinite);
        }
        let dv = lu.solve(&(-r));
        v += dv;
        if !v.iter().all(|z| z.is_finite()) {
            return Err(StepError::NonFinite);
        }
        let step = dv.amax();
        let scale = 1.0 + v.amax();
        // Converged: below the tolerance, or stalled within 100× of it (the round-off
        // floor of the residual, ≈ ε‖P‖/h, can sit just above a tight tolerance).
        let stalled = step <= 100.0 * settings.tol * scale && step > 0.5 * last_step;
        if step <= settings.tol * scale || stalled {
            if reuse {
                cache.jacobian = Some((jm, lu));
            }
            return Ok((v, it));
        }
        // Keep the Jacobian for chord steps while they contract 10× per step; a fresh
        // exact one otherwise. Without reuse, chord steps start only below ≈ √tol.
        let contracting = exact_here || step < 0.1 * last_step;
        let close = reuse || step <= CHORD_SWITCH * scale;
        jac = (contracting && close).then_some((jm, lu));
        last = Some((r, dv));
        last_step = step;
        if it == settings.max_iterations {
            return Err(StepError::NoConvergence {
                iterations: it,
                step_norm: step,
            });
        }
    }
    unreachable!("the loop returns on its last iteration")
}
