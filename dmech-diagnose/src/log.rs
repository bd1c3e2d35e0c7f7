//! The measured log: a uniform time grid, the commanded inputs (zero-order hold) and the
//! readings of a system's channels (missing where not measured). The file format is
//! docs/formats.md, "Measured log"; the channels are the plant's. Reading the CSV file is
//! the tools' business (`robots::diagnose::read_log`): this crate takes the log built.

use std::fmt::Write as _;

/// A measured channel: its CSV column, unit, and the largest magnitude a reading can
/// physically have (a reading beyond it is a logging fault, not a measurement).
#[derive(Clone, Debug)]
pub struct ChannelSpec {
    /// The CSV column, and the channel's part of a reading hypothesis's name.
    pub name: String,
    /// The unit of the readings, for reports (e.g. `rad/s`).
    pub unit: String,
    /// The largest physical magnitude of a reading, in the channel's unit.
    pub range: f64,
    /// An angle that wraps: residuals are taken modulo 2π.
    pub wraps: bool,
    /// The largest zero-point offset a working sensor of this channel can have, in its
    /// unit: the plausible range of the generic `reading_offset` hypothesis
    /// (`super::readings`); 0 declares none.
    pub offset_limit: f64,
}

impl ChannelSpec {
    /// A channel that does not wrap and declares no offset limit (no `reading_offset`
    /// hypothesis).
    pub fn new(name: &str, unit: &str, range: f64) -> Self {
        ChannelSpec {
            name: name.into(),
            unit: unit.into(),
            range,
            wraps: false,
            offset_limit: 0.0,
        }
    }
    /// Reading minus prediction residual (prediction − reading), wrapped for an angle.
    pub fn residual(&self, predicted: f64, measured: f64) -> f64 {
        let d = predicted - measured;
        if self.wraps {
            d - (d / std::f64::consts::TAU).round() * std::f64::consts::TAU
        } else {
            d
        }
    }
}

/// The largest magnitude of a commanded input that can be a command (10³ in the input's
/// unit; the robots here run on a few volts).
pub const COMMAND_RANGE: f64 = 1e3;

/// A log row whose command is beyond [`COMMAND_RANGE`] (or not a number): the model needs
/// every input, so the row cannot be dropped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "row {row} (t = {t}), column '{column}': command {value} is outside ±{}",
    COMMAND_RANGE
)]
pub struct CommandOutOfRange {
    /// The row.
    pub row: usize,
    /// Its time.
    pub t: f64,
    /// The input column.
    pub column: String,
    /// The command.
    pub value: f64,
}

/// A log: uniform time grid, commanded inputs, and the readings (NaN = not measured).
#[derive(Clone, Debug)]
pub struct MeasuredLog {
    /// The sample step (s).
    pub h: f64,
    /// The time of each row (s).
    pub t: Vec<f64>,
    /// Inputs per row, `n_inputs` each.
    inputs: Vec<f64>,
    /// Commanded inputs per row (the plant's inputs).
    pub n_inputs: usize,
    /// Readings per row, `n_channels` each.
    data: Vec<f64>,
    /// Readings per row (the plant's channels, measured or not).
    pub n_channels: usize,
    /// Which channels the log has (a column with at least one value).
    pub present: Vec<bool>,
    /// Non-fatal remarks (unknown or duplicated columns), for stderr and the report.
    pub warnings: Vec<String>,
}

impl MeasuredLog {
    /// A log with no rows and no channel present.
    pub fn empty(h: f64, n_inputs: usize, n_channels: usize) -> Self {
        MeasuredLog {
            h,
            t: Vec::new(),
            inputs: Vec::new(),
            n_inputs,
            data: Vec::new(),
            n_channels,
            present: vec![false; n_channels],
            warnings: Vec::new(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Append a row: its time, `n_inputs` commands and `n_channels` readings (NaN where not
    /// measured); panics on other lengths. [`MeasuredLog::present`] is not updated
    /// ([`MeasuredLog::channels_present_from_data`]).
    pub fn push_row(&mut self, t: f64, input: &[f64], row: &[f64]) {
        assert_eq!(input.len(), self.n_inputs);
        assert_eq!(row.len(), self.n_channels);
        self.t.push(t);
        self.inputs.extend_from_slice(input);
        self.data.extend_from_slice(row);
    }

    /// The inputs commanded at row `k` (held until row `k + 1`).
    pub fn input(&self, k: usize) -> &[f64] {
        &self.inputs[k * self.n_inputs..(k + 1) * self.n_inputs]
    }

    /// The readings of row `k` (NaN where not measured).
    pub fn row(&self, k: usize) -> &[f64] {
        &self.data[k * self.n_channels..(k + 1) * self.n_channels]
    }

    /// The readings of row `k`, mutable.
    pub fn row_mut(&mut self, k: usize) -> &mut [f64] {
        &mut self.data[k * self.n_channels..(k + 1) * self.n_channels]
    }

    /// The reading of channel `c` at row `k`; `None` where not measured.
    pub fn value(&self, k: usize, c: usize) -> Option<f64> {
        let v = self.data[k * self.n_channels + c];
        (!v.is_nan()).then_some(v)
    }

    /// Mark as present every channel with at least one value.
    pub fn channels_present_from_data(&mut self) {
        for c in 0..self.n_channels {
            self.present[c] = (0..self.len()).any(|k| self.value(k, c).is_some());
        }
    }

    /// Set a channel aside entirely (not fitted, not tested).
    pub fn drop_channel(&mut self, c: usize) {
        for k in 0..self.len() {
            self.data[k * self.n_channels + c] = f64::NAN;
        }
        self.present[c] = false;
    }

    /// Drop (set to missing) every reading beyond its channel's range, and say which; an
    /// input beyond [`COMMAND_RANGE`] cannot be dropped (the model needs every input) and
    /// is an error.
    pub fn drop_out_of_range(
        &mut self,
        channels: &[ChannelSpec],
        inputs: &[String],
    ) -> Result<Vec<String>, CommandOutOfRange> {
        let mut flagged = Vec::new();
        for k in 0..self.len() {
            for (j, name) in inputs.iter().enumerate() {
                let u = self.input(k)[j];
                if u.is_nan() || u.abs() > COMMAND_RANGE {
                    return Err(CommandOutOfRange {
                        row: k,
                        t: self.t[k],
                        column: name.clone(),
                        value: u,
                    });
                }
            }
            for (c, spec) in channels.iter().enumerate() {
                let v = self.row(k)[c];
                if v.abs() > spec.range {
                    flagged.push(format!(
                        "row {k} (t = {}), column '{}': reading {v:e} {} is outside ±{} and is not fitted",
                        self.t[k], spec.name, spec.unit, spec.range
                    ));
                    self.row_mut(k)[c] = f64::NAN;
                }
            }
        }
        if !flagged.is_empty() {
            self.channels_present_from_data();
        }
        Ok(flagged)
    }

    /// Channels whose readings equal an earlier channel's in every row: a copy is not a
    /// second measurement, and counting it would weigh one sensor twice in the fit and in
    /// the error measure. Returns `(copy, original)` pairs.
    pub fn duplicated_channels(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for c in 0..self.n_channels {
            if !self.present[c] {
                continue;
            }
            let original = (0..c).find(|&o| {
                self.present[o]
                    && (0..self.len()).all(|k| {
                        let (a, b) = (self.row(k)[c], self.row(k)[o]);
                        a == b || (a.is_nan() && b.is_nan())
                    })
            });
            if let Some(o) = original {
                out.push((c, o));
            }
        }
        out
    }

    /// The decimal resolution channel `c` was written with: the largest `10⁻ᵏ`
    /// (`k = 0..=12`) of which every reading is an integer multiple, to the parse's
    /// rounding. `None` for a channel without readings or one written to more than twelve
    /// decimals (a simulator's full-precision output). A relation between channels that
    /// holds to their resolutions holds exactly in what the log's writer had.
    pub fn decimal_resolution(&self, c: usize) -> Option<f64> {
        let values: Vec<f64> = (0..self.len()).filter_map(|k| self.value(k, c)).collect();
        if values.is_empty() {
            return None;
        }
        (0..=12).map(|k| 10f64.powi(-k)).find(|&q| {
            values.iter().all(|&v| {
                let n = v / q;
                // Past 2⁵² every f64 is an integer: no resolution can be read there.
                n.abs() < 4.5e15 && (n - n.round()).abs() <= 1e-6
            })
        })
    }

    /// The log as CSV text (docs/formats.md), empty fields for missing samples.
    pub fn to_csv(&self, channels: &[ChannelSpec], inputs: &[String]) -> String {
        let mut s = String::from("t");
        for n in inputs {
            let _ = write!(s, ",{n}");
        }
        let cols: Vec<usize> = (0..self.n_channels).filter(|&c| self.present[c]).collect();
        for &c in &cols {
            let _ = write!(s, ",{}", channels[c].name);
        }
        s.push('\n');
        for k in 0..self.len() {
            let _ = write!(s, "{:.6}", self.t[k]);
            for u in self.input(k) {
                let _ = write!(s, ",{u:.6}");
            }
            for &c in &cols {
                match self.value(k, c) {
                    Some(v) => {
                        let _ = write!(s, ",{v:.7e}");
                    }
                    None => s.push(','),
                }
            }
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log_of(column: &[f64]) -> MeasuredLog {
        let mut log = MeasuredLog::empty(0.01, 0, 1);
        for (k, &v) in column.iter().enumerate() {
            log.push_row(0.01 * k as f64, &[], &[v]);
        }
        log.channels_present_from_data();
        log
    }

    #[test]
    fn decimal_resolution_is_the_coarsest_grid_of_the_written_values() {
        // Values as a CSV parse gives them: "0.1234", "-2.5", "17".
        let parsed = |s: &str| s.parse::<f64>().unwrap();
        let four = log_of(&[parsed("0.1234"), parsed("-2.5"), parsed("17")]);
        assert_eq!(four.decimal_resolution(0), Some(1e-4));
        let whole = log_of(&[3.0, -12.0, 0.0]);
        assert_eq!(whole.decimal_resolution(0), Some(1.0));
        // A value off a coarser grid decides: 0.5 alone would be 1e-1.
        let mixed = log_of(&[0.5, parsed("0.007")]);
        assert_eq!(mixed.decimal_resolution(0), Some(1e-3));
        // A simulator's full precision has no decimal resolution.
        let full = log_of(&[std::f64::consts::PI, 1.0 / 3.0]);
        assert_eq!(full.decimal_resolution(0), None);
        // Missing readings are ignored; none at all gives no resolution.
        let gappy = log_of(&[f64::NAN, parsed("0.25"), f64::NAN]);
        assert_eq!(gappy.decimal_resolution(0), Some(1e-2));
        assert_eq!(log_of(&[f64::NAN]).decimal_resolution(0), None);
    }
}
