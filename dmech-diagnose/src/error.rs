//! Why a log cannot be diagnosed: errors a caller can match on.

/// Why a log cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A command that cannot be used (names the row and column).
    #[error(transparent)]
    Log(#[from] crate::log::CommandOutOfRange),
    /// [`DiagnoseOptions::window_s`](crate::DiagnoseOptions::window_s) spans fewer samples
    /// than a window needs to separate an effect's response from the noise.
    #[error("a window of {window_s} s is {samples} samples of {h} s; it needs at least {min} samples (--window ≥ {} s)", *min as f64 * h)]
    WindowTooShort {
        /// The requested window length (s).
        window_s: f64,
        /// The samples it spans, `window_s/h` rounded (NaN if `window_s` is NaN).
        samples: f64,
        /// The log's sample step (s).
        h: f64,
        /// The fewest samples a window may have.
        min: usize,
    },
    /// The log holds fewer rows than the plant's history plus one window.
    #[error("the log is too short: {rows} rows, need at least {need} ({window_s} s windows)")]
    LogTooShort {
        /// Rows in the log.
        rows: usize,
        /// Rows needed: the rows before the first window and one window.
        need: usize,
        /// The requested window length (s).
        window_s: f64,
    },
    /// Every reading of every channel is constant.
    #[error("the log carries no information: every reading is constant (nothing to compare the model with)")]
    NoInformation,
    /// The model cannot be linearised at its base fit (prediction failed or non-finite):
    /// in no window for the screening of the effects, or in some window for the
    /// calibration's identifiability.
    #[error("the nominal model cannot be simulated over the log (the linearisation failed)")]
    NotSimulable,
    /// A name in [`DiagnoseOptions::exclude`](crate::DiagnoseOptions::exclude) or
    /// [`DiagnoseOptions::calibrate`](crate::DiagnoseOptions::calibrate) that the plant's
    /// catalogue does not hold.
    #[error("unknown {what} '{name}' (known: {known})")]
    Unknown {
        /// What was looked up (`"effect"`, `"parameter to calibrate"`).
        what: &'static str,
        /// The name given.
        name: String,
        /// The names the catalogue holds, comma-separated.
        known: String,
    },
    /// A reported error, the gain, the chosen score, or a chosen parameter or its standard
    /// deviation is not finite; the offending values, in words.
    #[error("the fit gave non-finite results ({0}): the log does not determine the model")]
    NonFinite(String),
}
