//! Why a log cannot be diagnosed: errors a caller can match on.

/// Why a log cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A command that cannot be used (names the row and column).
    #[error(transparent)]
    Log(#[from] crate::log::CommandOutOfRange),
    #[error("a window of {window_s} s is {samples} samples of {h} s; it needs at least {min} samples (--window ≥ {} s)", *min as f64 * h)]
    WindowTooShort {
        window_s: f64,
        samples: f64,
        h: f64,
        min: usize,
    },
    #[error("the log is too short: {rows} rows, need at least {need} ({window_s} s windows)")]
    LogTooShort {
        rows: usize,
        need: usize,
        window_s: f64,
    },
    #[error("the log carries no information: every reading is constant (nothing to compare the model with)")]
    NoInformation,
    #[error("the nominal model cannot be simulated over the log (the linearisation failed)")]
    NotSimulable,
    #[error("unknown {what} '{name}' (known: {known})")]
    Unknown {
        what: &'static str,
        name: String,
        known: String,
    },
    #[error("the fit gave non-finite results ({0}): the log does not determine the model")]
    NonFinite(String),
}
