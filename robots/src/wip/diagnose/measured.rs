//! The measured log that `diagnose` reads (docs/formats.md, "Measured log").

use crate::io::parse_csv;
use std::fmt::Write as _;

/// A measured channel. The order is that of [`super::prediction::Predictor::readings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    X,
    Y,
    Theta,
    Alpha,
    VAlpha,
    PhiRRel,
    PhiLRel,
    IR,
    IL,
}

impl Channel {
    pub const ALL: [Channel; 9] = [
        Channel::X,
        Channel::Y,
        Channel::Theta,
        Channel::Alpha,
        Channel::VAlpha,
        Channel::PhiRRel,
        Channel::PhiLRel,
        Channel::IR,
        Channel::IL,
    ];
    /// The CSV column name.
    pub fn name(self) -> &'static str {
        [
            "x", "y", "theta", "alpha", "v_alpha", "phiR_rel", "phiL_rel", "iR", "iL",
        ][self.index()]
    }
    pub fn unit(self) -> &'static str {
        ["m", "m", "rad", "rad", "rad/s", "rad", "rad", "A", "A"][self.index()]
    }
    pub fn index(self) -> usize {
        self as usize
    }

    /// The largest magnitude a reading of this channel can physically have; a reading
    /// beyond it is a logging fault, not a measurement. Generous on purpose: a position of
    /// 10 km, a heading or wheel angle of 10⁶ rad (40 km of a 4 cm wheel), a tilt of 2π,
    /// a tilt rate of 10³ rad/s (gyros saturate near 35 rad/s), a current of 10³ A.
    pub fn range(self) -> f64 {
        [
            1e4,
            1e4,
            1e6,
            std::f64::consts::TAU,
            1e3,
            1e6,
            1e6,
            1e3,
            1e3,
        ][self.index()]
    }
}

/// The largest magnitude of a commanded voltage that can be a command (10³ V; the robots
/// here run on a few volts).
pub const COMMAND_RANGE: f64 = 1e3;

/// A log: uniform time grid, commanded voltages, and the readings (NaN = not measured).
#[derive(Clone, Debug)]
pub struct MeasuredLog {
    pub h: f64,
    pub t: Vec<f64>,
    pub cmd: Vec<[f64; 2]>,
    pub data: Vec<[f64; 9]>,
    /// Which channels the log has (a column with at least one value).
    pub present: [bool; 9],
    /// Non-fatal remarks (unknown columns), for stderr and the report.
    pub warnings: Vec<String>,
}

impl MeasuredLog {
    pub fn empty(h: f64) -> Self {
        MeasuredLog {
            h,
            t: Vec::new(),
            cmd: Vec::new(),
            data: Vec::new(),
            present: [false; 9],
            warnings: Vec::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn push_row(&mut self, t: f64, cmd: [f64; 2], row: &[f64; 9]) {
        self.t.push(t);
        self.cmd.push(cmd);
        self.data.push(*row);
    }

    /// Mark as present every channel with at least one value.
    pub fn channels_present_from_data(&mut self) {
        for c in Channel::ALL {
            self.present[c.index()] = self.data.iter().any(|r| !r[c.index()].is_nan());
        }
    }

    /// Drop (set to missing) every reading beyond its channel's [`Channel::range`], and
    /// say which; a command beyond [`COMMAND_RANGE`] cannot be dropped (the model needs
    /// every input) and is an error.
    pub fn drop_out_of_range(&mut self) -> Result<Vec<String>, String> {
        let mut flagged = Vec::new();
        for k in 0..self.len() {
            for (j, name) in ["uR", "uL"].into_iter().enumerate() {
                let u = self.cmd[k][j];
                if u.is_nan() || u.abs() > COMMAND_RANGE {
                    return Err(format!(
                        "row {k} (t = {}), column '{name}': command {u} V is outside ±{COMMAND_RANGE} V",
                        self.t[k]
                    ));
                }
            }
            for c in Channel::ALL {
                let v = self.data[k][c.index()];
                if v.abs() > c.range() {
                    flagged.push(format!(
                        "row {k} (t = {}), column '{}': reading {v:e} {} is outside ±{} and is not fitted",
                        self.t[k],
                        c.name(),
                        c.unit(),
                        c.range()
                    ));
                    self.data[k][c.index()] = f64::NAN;
                }
            }
        }
        if !flagged.is_empty() {
            self.channels_present_from_data();
        }
        Ok(flagged)
    }

    pub fn value(&self, k: usize, c: Channel) -> Option<f64> {
        let v = self.data[k][c.index()];
        (!v.is_nan()).then_some(v)
    }

    /// The log as CSV text (docs/formats.md), empty fields for missing samples.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("t,uR,uL");
        let cols: Vec<Channel> = Channel::ALL
            .into_iter()
            .filter(|c| self.present[c.index()])
            .collect();
        for c in &cols {
            let _ = write!(s, ",{}", c.name());
        }
        s.push('\n');
        for k in 0..self.len() {
            let _ = write!(
                s,
                "{:.6},{:.6},{:.6}",
                self.t[k], self.cmd[k][0], self.cmd[k][1]
            );
            for c in &cols {
                match self.value(k, *c) {
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

    /// Parse a log. Every malformed input is an error naming the line and the column.
    pub fn parse(text: &str, what: &str) -> Result<Self, String> {
        let csv = parse_csv(text, what, true)?;
        let col = |n: &str| {
            csv.column(n)
                .ok_or_else(|| format!("{what}: missing required column '{n}' (need t, uR, uL)"))
        };
        let (ct, cr, cl) = (col("t")?, col("uR")?, col("uL")?);
        let mut warnings = Vec::new();
        let known: Vec<&str> = ["t", "uR", "uL"]
            .into_iter()
            .chain(Channel::ALL.iter().map(|c| c.name()))
            .collect();
        for h in &csv.header {
            if !known.contains(&h.as_str()) {
                warnings.push(format!("{what}: unknown column '{h}' ignored"));
            }
        }
        if csv.rows.len() < 2 {
            return Err(format!(
                "{what}: needs at least two data rows, found {}",
                csv.rows.len()
            ));
        }
        let chan_cols: Vec<(Channel, usize)> = Channel::ALL
            .into_iter()
            .filter_map(|c| csv.column(c.name()).map(|i| (c, i)))
            .collect();
        if chan_cols.is_empty() {
            return Err(format!(
                "{what}: no measured channel (expected some of x, y, theta, alpha, v_alpha, phiR_rel, phiL_rel, iR, iL)"
            ));
        }
        let h = csv.rows[1][ct] - csv.rows[0][ct];
        let mut log = MeasuredLog::empty(h);
        log.warnings = warnings;
        for (row, &line) in csv.rows.iter().zip(&csv.lines) {
            for (c, name) in [(ct, "t"), (cr, "uR"), (cl, "uL")] {
                if row[c].is_nan() {
                    return Err(format!(
                        "{what}: line {line}, column '{name}': missing value"
                    ));
                }
            }
            let t = row[ct];
            if let Some(&prev) = log.t.last() {
                if t <= prev {
                    return Err(format!(
                        "{what}: line {line}, column 't': time {t} is not after the previous {prev}"
                    ));
                }
                if ((t - prev) - h).abs() > 1e-3 * h {
                    return Err(format!(
                        "{what}: line {line}, column 't': step {} differs from the first step {h} (the grid must be uniform)",
                        t - prev
                    ));
                }
            }
            let mut data = [f64::NAN; 9];
            for &(c, i) in &chan_cols {
                data[c.index()] = row[i];
            }
            log.push_row(t, [row[cr], row[cl]], &data);
        }
        log.channels_present_from_data();
        for &(c, _) in &chan_cols {
            if !log.present[c.index()] {
                return Err(format!(
                    "{what}: column '{}' has no values (every sample empty or NaN)",
                    c.name()
                ));
            }
        }
        Ok(log)
    }

    pub fn read(path: &std::path::Path) -> Result<Self, crate::io::ReadError> {
        let what = format!("{}", path.display());
        let text = crate::io::read_text(path, &what)?;
        Self::parse(&text, &what).map_err(crate::io::ReadError::Content)
    }
}
