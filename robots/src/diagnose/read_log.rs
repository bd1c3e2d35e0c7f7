//! Reading a measured log from CSV text (docs/formats.md, "Measured log"): the tools' side
//! of `dmech_diagnose::MeasuredLog`, with the `csv`-based parser of `crate::io`.

use crate::io::{parse_csv_with, CsvError, CsvOptions, TimeNotAfter};
use dmech_diagnose::{ChannelSpec, MeasuredLog};

/// Parse a log with the given channels and input columns. Every malformed input is an
/// error naming the line and the column; a column that is neither `t`, an input nor a
/// channel is not read (whatever it holds) and named in a warning.
pub fn parse_log(
    text: &str,
    what: &str,
    channels: &[ChannelSpec],
    inputs: &[String],
) -> Result<MeasuredLog, LogError> {
    parse_log_limited(text, what, channels, inputs, usize::MAX, "")
}

/// [`parse_log`] of at most `max_rows` data rows (`hint` says how to raise
/// the limit).
pub fn parse_log_limited(
    text: &str,
    what: &str,
    channels: &[ChannelSpec],
    inputs: &[String],
    max_rows: usize,
    hint: &str,
) -> Result<MeasuredLog, LogError> {
    let known: Vec<&str> = std::iter::once("t")
        .chain(inputs.iter().map(String::as_str))
        .chain(channels.iter().map(|c| c.name.as_str()))
        .collect();
    let csv = parse_csv_with(
        text,
        what,
        CsvOptions {
            allow_missing: true,
            max_rows,
            rows_hint: hint,
            columns: Some(&known),
        },
    )?;
    let need = || {
        std::iter::once("t".to_string())
            .chain(inputs.iter().cloned())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let col = |n: &str| {
        csv.column(n).ok_or_else(|| LogError::MissingColumn {
            what: what.to_string(),
            name: n.to_string(),
            need: need(),
        })
    };
    let ct = col("t")?;
    let cin: Vec<usize> = inputs.iter().map(|n| col(n)).collect::<Result<_, _>>()?;
    let mut warnings = Vec::new();
    for h in &csv.header {
        if !known.contains(&h.as_str()) {
            warnings.push(format!("{what}: unknown column '{h}' ignored"));
        }
    }
    if csv.rows.len() < 2 {
        return Err(LogError::TooFewRows {
            what: what.to_string(),
            rows: csv.rows.len(),
        });
    }
    let chan_cols: Vec<(usize, usize)> = channels
        .iter()
        .enumerate()
        .filter_map(|(c, spec)| csv.column(&spec.name).map(|i| (c, i)))
        .collect();
    if chan_cols.is_empty() {
        let names: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
        return Err(LogError::NoChannel {
            what: what.to_string(),
            expected: names.join(", "),
        });
    }
    let h = csv.rows[1][ct] - csv.rows[0][ct];
    let mut log = MeasuredLog::empty(h, inputs.len(), channels.len());
    log.warnings = warnings;
    let mut u = vec![0.0; inputs.len()];
    let mut data = vec![f64::NAN; channels.len()];
    for (row, &line) in csv.rows.iter().zip(&csv.lines) {
        for (c, name) in
            std::iter::once((ct, "t")).chain(cin.iter().zip(inputs).map(|(&c, n)| (c, n.as_str())))
        {
            if row[c].is_nan() {
                return Err(LogError::Missing {
                    what: what.to_string(),
                    line,
                    name: name.to_string(),
                });
            }
        }
        let t = row[ct];
        if let Some(&prev) = log.t.last() {
            if t <= prev {
                return Err(TimeNotAfter {
                    what: what.to_string(),
                    line,
                    t,
                    previous: prev,
                }
                .into());
            }
            if ((t - prev) - h).abs() > 1e-3 * h {
                return Err(LogError::NotUniform {
                    what: what.to_string(),
                    line,
                    step: t - prev,
                    first: h,
                });
            }
        }
        for (j, &c) in cin.iter().enumerate() {
            u[j] = row[c];
        }
        data.fill(f64::NAN);
        for &(c, i) in &chan_cols {
            data[c] = row[i];
        }
        log.push_row(t, &u, &data);
    }
    log.channels_present_from_data();
    for &(c, _) in &chan_cols {
        if !log.present[c] {
            return Err(LogError::EmptyColumn {
                what: what.to_string(),
                name: channels[c].name.clone(),
            });
        }
    }
    Ok(log)
}

/// Why a measured log was refused; the message names the file, and the line and column
/// where there is one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LogError {
    #[error(transparent)]
    Csv(#[from] CsvError),
    #[error("{what}: missing required column '{name}' (need {need})")]
    MissingColumn {
        what: String,
        name: String,
        need: String,
    },
    #[error("{what}: needs at least two data rows, found {rows}")]
    TooFewRows { what: String, rows: usize },
    #[error("{what}: no measured channel (expected some of {expected})")]
    NoChannel { what: String, expected: String },
    #[error("{what}: line {line}, column '{name}': missing value")]
    Missing {
        what: String,
        line: usize,
        name: String,
    },
    #[error(transparent)]
    NotIncreasing(#[from] TimeNotAfter),
    #[error(
        "{what}: line {line}, column 't': step {step} differs from the first step {first} (the \
         grid must be uniform)"
    )]
    NotUniform {
        what: String,
        line: usize,
        step: f64,
        first: f64,
    },
    #[error("{what}: column '{name}' has no values (every sample empty or NaN)")]
    EmptyColumn { what: String, name: String },
}
