//! Input schedules: two inputs held from each row's time until the next (zero-order hold),
//! read from `t,u1,u2` files on the step grid they are simulated on.

use super::*;

/// Two inputs held from `t_j` until the next sample (zero-order hold): the WIP's voltages
/// `(uR, uL)`, the car's `(τ_s, u_d)`.
#[derive(Clone, Debug)]
pub struct InputSchedule {
    pub t: Vec<f64>,
    pub u: Vec<[f64; 2]>,
}

/// Why an inputs file cannot be simulated as written; the message names the file, and the
/// line or the data row.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    #[error(transparent)]
    Csv(#[from] CsvError),
    #[error("{what}: missing column '{name}' (expected {expected})")]
    MissingColumn {
        what: String,
        name: String,
        expected: String,
    },
    #[error("{what}: no data rows")]
    NoRows { what: String },
    #[error(transparent)]
    NotIncreasing(#[from] TimeNotAfter),
    #[error("{what}: the first row must be at t = 0 (found t = {t})")]
    FirstNotAtZero { what: String, t: f64 },
    /// A row between two steps of the grid: its input would be applied late, or never.
    #[error(
        "{what}: data row {row}: t = {t} s is not a whole number of steps of {h} s \
         ({steps:.4}): the zero-order hold would {fate}; put every row on the step grid{fix}"
    )]
    OffGrid {
        what: String,
        row: usize,
        t: f64,
        steps: f64,
        h: f64,
        /// What the hold would do with it ("apply it from t = … s", "drop it").
        fate: String,
        /// A step that puts every row on the grid, as an option (or empty).
        fix: String,
    },
    /// The horizon is shorter than one step.
    #[error("{what}: the horizon ends at t = {end} s, less than one step of {h} s")]
    NoSteps { what: String, end: f64, h: f64 },
    /// An input beyond the limit the command accepts.
    #[error(
        "{what}: data row {row} (t = {t}): {name} = {} {unit} is beyond ±{limit} {unit} \
         ({option})",
        number(*.value)
    )]
    BeyondLimit {
        what: String,
        row: usize,
        t: f64,
        name: &'static str,
        value: f64,
        limit: f64,
        unit: &'static str,
        option: &'static str,
    },
}

/// A row of a CSV file whose time `t` is not after the previous row's (inputs, logs).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what}: line {line}, column 't': time {t} is not after the previous {previous}")]
pub struct TimeNotAfter {
    pub what: String,
    pub line: usize,
    pub t: f64,
    pub previous: f64,
}

impl InputSchedule {
    /// The input in force at time `t` (the last sample at or before `t`, with a tolerance
    /// of 1e-9 s so that grid times computed as `k h` do not fall just short of a sample).
    pub fn at(&self, t: f64) -> [f64; 2] {
        let idx = self.t.partition_point(|&tj| tj <= t + 1e-9);
        self.u[idx.saturating_sub(1)]
    }
    /// The last sample time: the end of the horizon.
    pub fn end(&self) -> f64 {
        *self.t.last().unwrap_or(&0.0)
    }

    /// The number of steps of `h` the schedule spans, if every row lies on the step grid
    /// (within 1e-6 of a step): the zero-order hold applies each row's input from its own
    /// time, so that what runs is what the file says. A row between two steps is an error
    /// that says what would have happened to it (applied late, or dropped when the next
    /// row comes first) and, where one exists, a step (`option`, e.g. `--step`) that puts
    /// every row on the grid.
    pub fn steps_on_grid(&self, h: f64, what: &str, option: &str) -> Result<usize, InputError> {
        let off = |t: f64, h: f64| {
            let m = t / h;
            (m - m.round()).abs() > 1e-6 * m.abs().max(1.0)
        };
        if let Some(j) = self.t.iter().position(|&t| off(t, h)) {
            let t = self.t[j];
            let applied = (t / h).ceil() * h;
            let next = self.t.get(j + 1).copied();
            let fate = match next {
                Some(n) if n <= applied + 1e-9 * h => {
                    "drop it (the next row comes before the next step)".to_string()
                }
                Some(_) => format!("apply it from t = {applied} s, late"),
                None => "end the run between two steps".to_string(),
            };
            let fix = (2..=1000)
                .map(|k| h / k as f64)
                .find(|&hk| !self.t.iter().any(|&t| off(t, hk)))
                .map_or(String::new(), |hk| {
                    format!(", or use {option} {}", short(hk))
                });
            return Err(InputError::OffGrid {
                what: what.to_string(),
                row: j + 1,
                t,
                steps: t / h,
                h,
                fate,
                fix,
            });
        }
        let n = (self.end() / h).round() as usize;
        if n == 0 {
            return Err(InputError::NoSteps {
                what: what.to_string(),
                end: self.end(),
                h,
            });
        }
        Ok(n)
    }

    /// Refuse an input beyond its limit in magnitude: `limits[i]` is input `i`'s
    /// `(name, limit, unit, option that sets the limit)`.
    pub fn check_limits(
        &self,
        what: &str,
        limits: [(&'static str, f64, &'static str, &'static str); 2],
    ) -> Result<(), InputError> {
        for (j, u) in self.u.iter().enumerate() {
            for (i, (name, limit, unit, option)) in limits.iter().enumerate() {
                if u[i].abs() > *limit {
                    return Err(InputError::BeyondLimit {
                        what: what.to_string(),
                        row: j + 1,
                        t: self.t[j],
                        name,
                        value: u[i],
                        limit: *limit,
                        unit,
                        option,
                    });
                }
            }
        }
        Ok(())
    }
}

/// The byte size of an inputs row the readers allow for (`t,u1,u2` with room to spare).
pub const INPUT_ROW_BYTES: u64 = 256;

/// Read an inputs file (`t,uR,uL`, zero-order hold, starting at t = 0) of at most
/// `max_rows` data rows (`hint` says how to raise the limit).
pub fn read_inputs(path: &Path, max_rows: usize, hint: &str) -> Result<InputSchedule, ReadError> {
    read_input_columns(path, ["uR", "uL"], max_rows, hint)
}

/// Read an inputs file with columns `t` and the two named inputs, of at most `max_rows`
/// data rows.
pub fn read_input_columns(
    path: &Path,
    names: [&str; 2],
    max_rows: usize,
    hint: &str,
) -> Result<InputSchedule, ReadError> {
    let what = format!("inputs file {}", path.display());
    let text = read_text_limited(path, &what, csv_byte_limit(max_rows, INPUT_ROW_BYTES), hint)?;
    Ok(input_columns(&text, &what, names, max_rows, hint)?)
}

/// [`read_inputs`] on the file's text; `what` names the file in messages.
pub fn parse_inputs(text: &str, what: &str) -> Result<InputSchedule, InputError> {
    parse_input_columns(text, what, ["uR", "uL"])
}

/// An inputs file with columns `t` and the two named inputs (zero-order hold, from t = 0).
pub fn parse_input_columns(
    text: &str,
    what: &str,
    names: [&str; 2],
) -> Result<InputSchedule, InputError> {
    input_columns(text, what, names, usize::MAX, "")
}

fn input_columns(
    text: &str,
    what: &str,
    names: [&str; 2],
    max_rows: usize,
    hint: &str,
) -> Result<InputSchedule, InputError> {
    let csv = parse_csv_with(text, what, CsvOptions::rows(max_rows, hint))?;
    let col = |n: &str| {
        csv.column(n).ok_or_else(|| InputError::MissingColumn {
            what: what.to_string(),
            name: n.to_string(),
            expected: format!("t,{},{}", names[0], names[1]),
        })
    };
    let (ct, cr, cl) = (col("t")?, col(names[0])?, col(names[1])?);
    if csv.rows.is_empty() {
        return Err(InputError::NoRows {
            what: what.to_string(),
        });
    }
    let mut sched = InputSchedule {
        t: Vec::new(),
        u: Vec::new(),
    };
    for (row, &line) in csv.rows.iter().zip(&csv.lines) {
        let t = row[ct];
        if let Some(&prev) = sched.t.last() {
            if t <= prev {
                return Err(TimeNotAfter {
                    what: what.to_string(),
                    line,
                    t,
                    previous: prev,
                }
                .into());
            }
        }
        sched.t.push(t);
        sched.u.push([row[cr], row[cl]]);
    }
    if sched.t[0].abs() > 1e-12 {
        return Err(InputError::FirstNotAtZero {
            what: what.to_string(),
            t: sched.t[0],
        });
    }
    Ok(sched)
}
