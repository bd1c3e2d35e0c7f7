//! What the robots' open-loop simulators share: how a simulation fails.

use dmech::StepError;

/// Why a simulation stopped before its end.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulationError {
    /// The midpoint scheme's first velocity (the discrete Legendre transform of the start)
    /// was not found.
    #[error("the midpoint scheme's start failed: {0}")]
    Start(StepError),
    /// A step's Newton iteration failed, or a Runge–Kutta step left the finite numbers.
    #[error("step {step} (t = {t:.4} s) failed: {source}{advice}")]
    Step {
        /// The step.
        step: usize,
        /// Its time.
        t: f64,
        /// What failed.
        source: StepError,
        /// What to change, for the message (empty, or beginning with `; `).
        advice: String,
    },
}
