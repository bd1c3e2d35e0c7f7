//! What `diagnose` takes ([`DiagnoseOptions`]) and gives ([`Diagnosis`]).

use super::adequacy::ChannelTest;
use super::conditions::Condition;
use super::noise::Residuals;
use super::session::{Calibration, Scored};

/// Options of `diagnose`.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Window length (s) of the prediction-error fit.
    pub window_s: f64,
    /// Threads the windows of a fit are spread over.
    pub threads: usize,
    /// Levenberg–Marquardt iterations per fit before it stops unconverged (a leading fit
    /// still descending gets further rounds of as many).
    pub max_iterations: usize,
    /// A model "explains" the log when its error is at most this (1 = the noise floor).
    pub explained: f64,
    /// The most effects named together: while the chosen ones leave the error above
    /// `explained`, another is added if it pays for its parameters (1: single effects only).
    pub max_effects: usize,
    /// At most this many single effects are fitted to convergence after screening.
    pub max_full_fits: usize,
    /// Effects of the catalogue left out, by name (to test what the tool says about an
    /// effect it does not know).
    pub exclude: Vec<String>,
    /// The system's own parameters to calibrate before effects are judged, by name (empty:
    /// no calibration).
    pub calibrate: Vec<String>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            window_s: 0.5,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
            max_iterations: 15,
            explained: 1.2,
            max_effects: 2,
            max_full_fits: usize::MAX,
            exclude: Vec::new(),
            calibrate: Vec::new(),
        }
    }
}

/// The outcome of `diagnose`.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// `"none"`, `"calibration"` (the system's own parameters, calibrated, explain the
    /// log), `"unexplained"`, or an effect name (the stronger one if two effects are
    /// found; `effects` lists both).
    pub cause: String,
    /// Indices of the named effects in the plant's catalogue.
    pub effects: Vec<usize>,
    /// Effects the log cannot tell from the cause: alone, each explains it as well (BIC
    /// within [`crate::verdict::INDISTINGUISHABLE_BIC`] of the cause's own), nameable and
    /// fitted. Empty when the verdict is not an effect.
    pub alternatives: Vec<String>,
    /// The chosen model, with its standard deviations recomputed at its own point (the
    /// base model, nominal or calibrated, when no effect is named).
    pub chosen: Scored,
    /// The nominal model: window states fitted, no parameter free.
    pub nominal: Scored,
    /// Every candidate tried, best (lowest score) first.
    pub candidates: Vec<Scored>,
    /// The identifiability of the system's own parameters and the calibrated fit; `None`
    /// when [`DiagnoseOptions::calibrate`] is empty.
    pub calibration: Option<Calibration>,
    /// Noise level per channel used as first fit weights (from the nominal residuals).
    pub sigma: Vec<f64>,
    /// Noise level per channel from the chosen model's residuals: the error's yardstick
    /// (NaN where the channel is absent).
    pub sigma_final: Vec<f64>,
    /// The nominal model's error `E` against `sigma_final` (1 = the noise floor).
    pub error_before: f64,
    /// The chosen model's error `E` against `sigma_final`.
    pub error_after: f64,
    /// `1 − error_after/error_before` (0 when `error_before` is 0).
    pub gain: f64,
    /// Per channel `RMS(r_c)/σ_c` before and after (NaN where absent).
    pub channel_before: Vec<f64>,
    /// Per channel `RMS(r_c)/σ_c` of the chosen model (see `channel_before`).
    pub channel_after: Vec<f64>,
    /// The nominal model's residuals (prediction − reading) over the windows.
    pub residuals_before: Residuals,
    /// The chosen model's residuals over the windows.
    pub residuals_after: Residuals,
    /// The prediction windows `(first row, rows)`.
    pub windows: Vec<(usize, usize)>,
    /// "Is anything left" per channel, for the nominal model and the chosen one.
    pub tests_before: Vec<ChannelTest>,
    /// The chosen model's residual tests (see `tests_before`).
    pub tests_after: Vec<ChannelTest>,
    /// The operating conditions that the chosen model's residual follows, in the channels
    /// that fail their tests.
    pub conditions: Vec<Condition>,
    /// The operating conditions that the nominal model's residual follows, in the channels
    /// that fail their tests before: the signature of what the model lacks, whichever
    /// candidate was chosen (a wrong candidate can smear it in its own residual).
    pub conditions_before: Vec<Condition>,
    /// Readings dropped as far outside their channel's range, and copied channels set
    /// aside, in words.
    pub flagged: Vec<String>,
    /// A one-paragraph verdict for the report.
    pub verdict: String,
    /// Wall time of the diagnosis (s).
    pub elapsed_s: f64,
}
