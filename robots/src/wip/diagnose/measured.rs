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
}

/// A log: uniform time grid, commanded voltages, and the readings (NaN = not measured).
/// How many interquartile ranges beyond the quartiles a reading must lie to be set aside.
pub const OUTLIER_FENCE: f64 = 100.0;

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
        log.set_aside_gross_outliers(&csv.lines);
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

    /// Readings far outside their channel's range (a glitch such as 1e300, a unit slip)
    /// are set aside as missing, with a warning naming their lines, instead of being
    /// fitted: one such reading would dominate every least-squares sum. "Far" is beyond
    /// the quartiles by [`OUTLIER_FENCE`] interquartile ranges (Tukey's fences use 1.5
    /// and 3 for outliers of a distribution; this one only catches gross errors, never
    /// the dynamics: a channel's motion spans a few IQRs).
    fn set_aside_gross_outliers(&mut self, lines: &[usize]) {
        for c in Channel::ALL {
            let i = c.index();
            let mut v: Vec<f64> = self
                .data
                .iter()
                .map(|r| r[i])
                .filter(|x| !x.is_nan())
                .collect();
            if v.len() < 4 {
                continue;
            }
            v.sort_by(f64::total_cmp);
            let (q1, q3) = (v[v.len() / 4], v[(3 * v.len()) / 4]);
            // A constant channel has IQR 0: measure the fence from the level instead.
            let iqr = (q3 - q1).max(1e-6 * q1.abs().max(q3.abs()).max(1.0));
            let (lo, hi) = (q1 - OUTLIER_FENCE * iqr, q3 + OUTLIER_FENCE * iqr);
            let flagged: Vec<usize> = (0..self.len())
                .filter(|&k| {
                    let x = self.data[k][i];
                    !x.is_nan() && (x < lo || x > hi)
                })
                .collect();
            if flagged.is_empty() {
                continue;
            }
            let shown: Vec<String> = flagged
                .iter()
                .take(5)
                .map(|&k| format!("line {} ({:e})", lines[k], self.data[k][i]))
                .collect();
            self.warnings.push(format!(
                "column '{}': {} reading(s) far outside the channel's range [{lo:.4e}, {hi:.4e}] set aside as missing: {}{}",
                c.name(),
                flagged.len(),
                shown.join(", "),
                if flagged.len() > 5 { ", …" } else { "" }
            ));
            for k in flagged {
                self.data[k][i] = f64::NAN;
            }
        }
    }

    pub fn read(path: &std::path::Path) -> Result<Self, crate::io::ReadError> {
        let what = format!("{}", path.display());
        let text = crate::io::read_text(path, &what)?;
        Self::parse(&text, &what).map_err(crate::io::ReadError::Content)
    }
}
