//! File input and output shared by the `wip` subcommands: whole-file writes via a
//! temporary file and rename, the trajectory CSV, and small CSV readers.

use crate::wip::simulate::{InputSchedule, Trajectory};
use std::fmt::Write as _;
use std::path::Path;

/// Write `contents` to `dir/name` whole: a temporary file in the same directory, then
/// rename, so a reader never sees a half-written file.
pub fn write_atomic(dir: &Path, name: &str, contents: &[u8]) -> Result<(), String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("cannot create output directory {}: {e}", dir.display()))?;
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let dst = dir.join(name);
    std::fs::write(&tmp, contents).map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, &dst).map_err(|e| format!("cannot write {}: {e}", dst.display()))
}

/// `trajectory.csv`: `t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL`.
pub fn trajectory_csv(traj: &Trajectory) -> String {
    let mut s = String::from("t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL\n");
    for k in 0..traj.t.len() {
        let _ = write!(s, "{}", traj.t[k]);
        for v in traj.x[k].iter() {
            let _ = write!(s, ",{v:.17e}");
        }
        let u = traj.u[k];
        let _ = writeln!(s, ",{:.17e},{:.17e}", u[0], u[1]);
    }
    s
}

/// A parsed CSV: header names and numeric rows (NaN for empty fields when allowed),
/// with the file line number of each row for messages.
pub struct Csv {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
    pub lines: Vec<usize>,
}

impl Csv {
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }
}

/// Parse CSV text: `#` comment lines and blank lines skipped, a header row, then numbers.
/// An empty field or `NaN` is NaN if `allow_missing`, else an error; any other text is an
/// error naming the line and column.
pub fn parse_csv(text: &str, what: &str, allow_missing: bool) -> Result<Csv, String> {
    let mut header: Option<Vec<String>> = None;
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let lineno = i + 1;
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        match &header {
            None => header = Some(fields.iter().map(|f| f.to_string()).collect()),
            Some(h) => {
                if fields.len() != h.len() {
                    return Err(format!(
                        "{what}: line {lineno} has {} fields, the header has {}",
                        fields.len(),
                        h.len()
                    ));
                }
                let mut row = Vec::with_capacity(fields.len());
                for (f, name) in fields.iter().zip(h) {
                    let v = if f.is_empty() || f.eq_ignore_ascii_case("nan") {
                        if allow_missing {
                            f64::NAN
                        } else {
                            return Err(format!(
                                "{what}: line {lineno}, column '{name}': missing value"
                            ));
                        }
                    } else {
                        match f.parse::<f64>() {
                            Ok(v) if v.is_finite() => v,
                            _ => {
                                return Err(format!(
                                    "{what}: line {lineno}, column '{name}': '{f}' is not a finite number"
                                ))
                            }
                        }
                    };
                    row.push(v);
                }
                rows.push(row);
                lines.push(lineno);
            }
        }
    }
    let header = header.ok_or_else(|| format!("{what}: empty file (no header row)"))?;
    Ok(Csv {
        header,
        rows,
        lines,
    })
}

/// Read an inputs file (`t,uR,uL`, zero-order hold, starting at t = 0).
pub fn read_inputs(path: &Path) -> Result<InputSchedule, String> {
    let what = format!("inputs file {}", path.display());
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {what}: {e}"))?;
    let csv = parse_csv(&text, &what, false)?;
    let col = |n: &str| {
        csv.column(n)
            .ok_or_else(|| format!("{what}: missing column '{n}' (expected t,uR,uL)"))
    };
    let (ct, cr, cl) = (col("t")?, col("uR")?, col("uL")?);
    if csv.rows.is_empty() {
        return Err(format!("{what}: no data rows"));
    }
    let mut sched = InputSchedule {
        t: Vec::new(),
        u: Vec::new(),
    };
    for (row, &line) in csv.rows.iter().zip(&csv.lines) {
        let t = row[ct];
        if let Some(&prev) = sched.t.last() {
            if t <= prev {
                return Err(format!(
                    "{what}: line {line}, column 't': time {t} is not after the previous {prev}"
                ));
            }
        }
        sched.t.push(t);
        sched.u.push([row[cr], row[cl]]);
    }
    if sched.t[0].abs() > 1e-12 {
        return Err(format!(
            "{what}: the first row must be at t = 0 (found t = {})",
            sched.t[0]
        ));
    }
    Ok(sched)
}
