//! File input and output shared by the tools: output sets written whole (staged, then
//! renamed into place), the CSV reader, input schedules, and progress and
//! result lines that never panic on a closed or full stream.

use std::path::{Path, PathBuf};

/// A line on stderr (progress, warnings). Best-effort: a closed or full stderr
/// (`2>/dev/full`, `2>&1 | head -1`) loses the line instead of panicking as `eprintln!`
/// does, so the run still finishes and writes its files.
#[macro_export]
macro_rules! progress {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

/// A line on stdout (the short result summary). Best-effort, as [`progress!`]: the results
/// are in the files and the exit status tells success.
#[macro_export]
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// Write `contents` to `dir/name` whole: a temporary file in the same directory, then
/// rename, so a reader never sees a half-written file. The temporary file is removed if
/// the write fails.
pub fn write_atomic(dir: &Path, name: &str, contents: &[u8]) -> Result<(), String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("cannot create output directory {}: {e}", dir.display()))?;
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let dst = dir.join(name);
    if let Err(e) = std::fs::write(&tmp, contents) {
        let _ = std::fs::remove_file(&tmp);
        return Err(format!("cannot write {}: {e}", dst.display()));
    }
    std::fs::rename(&tmp, &dst).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write {}: {e}", dst.display())
    })
}

/// The files of one run, which belong together. Opened before any long work (so an
/// unwritable directory is found at once), written into a staging directory inside the
/// output directory, and moved into place only by [`OutputSet::commit`]: a failed run
/// leaves the previous run's files as they were and no stray temporary files (the staging
/// directory is removed on drop).
pub struct OutputSet {
    dir: PathBuf,
    staging: PathBuf,
    names: Vec<String>,
}

impl OutputSet {
    /// Create `dir` (and a staging directory in it) or fail with a one-line reason.
    pub fn create(dir: &Path) -> Result<Self, String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create output directory {}: {e}", dir.display()))?;
        let staging = dir.join(format!(".staging-{}", std::process::id()));
        std::fs::create_dir_all(&staging)
            .map_err(|e| format!("output directory {} is not writable: {e}", dir.display()))?;
        Ok(OutputSet {
            dir: dir.to_path_buf(),
            staging,
            names: Vec::new(),
        })
    }

    /// Stage one file of the set.
    pub fn write(&mut self, name: &str, contents: &[u8]) -> Result<(), String> {
        std::fs::write(self.staging.join(name), contents)
            .map_err(|e| format!("cannot write {}: {e}", self.dir.join(name).display()))?;
        self.names.push(name.to_string());
        Ok(())
    }

    /// Move every staged file into the output directory (each by an atomic rename).
    pub fn commit(self) -> Result<(), String> {
        for name in &self.names {
            std::fs::rename(self.staging.join(name), self.dir.join(name))
                .map_err(|e| format!("cannot write {}: {e}", self.dir.join(name).display()))?;
        }
        Ok(())
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.staging);
    }
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

/// Parse CSV text with the csv crate (a UTF-8 byte-order mark, quoted fields and CRLF line
/// ends are handled there): `#` comment lines and blank lines skipped, a header row, then
/// numbers. A header naming a column twice is an error. An empty field or `NaN` is NaN if
/// `allow_missing`, else an error; any other text is an error naming the line and column.
pub fn parse_csv(text: &str, what: &str, allow_missing: bool) -> Result<Csv, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.trim_start_matches('\u{feff}').as_bytes());
    let mut header: Option<Vec<String>> = None;
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map(|p| p.line()).unwrap_or(0);
            format!("{what}: line {line}: {e}")
        })?;
        let lineno = record.position().map(|p| p.line() as usize).unwrap_or(0);
        if record.iter().all(str::is_empty) {
            continue;
        }
        let Some(h) = &header else {
            let names: Vec<String> = record.iter().map(str::to_string).collect();
            for (j, name) in names.iter().enumerate() {
                if let Some(i) = names[..j].iter().position(|n| n == name) {
                    return Err(format!(
                        "{what}: line {lineno}: column '{name}' appears twice (columns {} and {})",
                        i + 1,
                        j + 1
                    ));
                }
            }
            header = Some(names);
            continue;
        };
        if record.len() != h.len() {
            return Err(format!(
                "{what}: line {lineno} has {} fields, the header has {}",
                record.len(),
                h.len()
            ));
        }
        let mut row = Vec::with_capacity(record.len());
        for (j, (f, name)) in record.iter().zip(h).enumerate() {
            let v = if f.is_empty() || f.eq_ignore_ascii_case("nan") {
                if !allow_missing {
                    return Err(format!(
                        "{what}: line {lineno}, column {} ('{name}'): missing value",
                        j + 1
                    ));
                }
                f64::NAN
            } else {
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => v,
                    _ => {
                        return Err(format!(
                        "{what}: line {lineno}, column {} ('{name}'): '{f}' is not a finite number",
                        j + 1
                    ))
                    }
                }
            };
            row.push(v);
        }
        rows.push(row);
        lines.push(lineno);
    }
    let header = header.ok_or_else(|| format!("{what}: empty file (no header row)"))?;
    Ok(Csv {
        header,
        rows,
        lines,
    })
}

/// Why a file could not be read: a caller can tell a missing or unreadable file from one
/// whose contents are wrong.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read.
    #[error("cannot read {what}: {source}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
    /// The contents are malformed or out of range; the message names the file, and the
    /// line and column where there is one.
    #[error("{0}")]
    Content(String),
}

/// The whole text of a file; `what` names it in the error.
pub fn read_text(path: &Path, what: &str) -> Result<String, ReadError> {
    std::fs::read_to_string(path).map_err(|source| ReadError::Io {
        what: what.to_string(),
        source,
    })
}

/// Two inputs held from `t_j` until the next sample (zero-order hold): the WIP's voltages
/// `(uR, uL)`, the car's `(τ_s, u_d)`.
#[derive(Clone, Debug)]
pub struct InputSchedule {
    pub t: Vec<f64>,
    pub u: Vec<[f64; 2]>,
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
}

/// Read an inputs file (`t,uR,uL`, zero-order hold, starting at t = 0).
pub fn read_inputs(path: &Path) -> Result<InputSchedule, ReadError> {
    let what = format!("inputs file {}", path.display());
    let text = read_text(path, &what)?;
    parse_inputs(&text, &what).map_err(ReadError::Content)
}

/// [`read_inputs`] on the file's text; `what` names the file in messages.
pub fn parse_inputs(text: &str, what: &str) -> Result<InputSchedule, String> {
    parse_input_columns(text, what, ["uR", "uL"])
}

/// An inputs file with columns `t` and the two named inputs (zero-order hold, from t = 0).
pub fn parse_input_columns(
    text: &str,
    what: &str,
    names: [&str; 2],
) -> Result<InputSchedule, String> {
    let csv = parse_csv(text, what, false)?;
    let col = |n: &str| {
        csv.column(n).ok_or_else(|| {
            format!(
                "{what}: missing column '{n}' (expected t,{},{})",
                names[0], names[1]
            )
        })
    };
    let (ct, cr, cl) = (col("t")?, col(names[0])?, col(names[1])?);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_and_a_malformed_one_are_different_errors() {
        let dir = std::env::temp_dir().join(format!("wip-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = read_inputs(&dir.join("missing.csv"));
        assert!(
            matches!(&missing, Err(ReadError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound),
            "{missing:?}"
        );
        std::fs::write(dir.join("bad.csv"), "t,uR,uL\n0,1,x\n").unwrap();
        let bad = read_inputs(&dir.join("bad.csv"));
        assert!(
            matches!(&bad, Err(ReadError::Content(m)) if m.contains("line 2, column 3")),
            "{bad:?}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
