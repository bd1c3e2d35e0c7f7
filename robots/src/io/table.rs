//! The CSV reader of every tool (header, numeric rows, the line of each row for messages).

/// A parsed CSV: header names and numeric rows (NaN for empty fields when allowed, and in
/// the columns not read), with the file line number of each row for messages.
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

/// Why a CSV text was refused; the message names the file (`what`), the line and the
/// column.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsvError {
    /// The csv crate could not read a record.
    #[error("{what}: line {line}: {message}")]
    Syntax {
        what: String,
        line: u64,
        message: String,
    },
    /// The header names a column twice.
    #[error("{what}: line {line}: column '{name}' appears twice (columns {first} and {second})")]
    DuplicateColumn {
        what: String,
        line: usize,
        name: String,
        first: usize,
        second: usize,
    },
    /// A row has a different number of fields than the header.
    #[error("{what}: line {line} has {found} fields, the header has {expected}")]
    FieldCount {
        what: String,
        line: usize,
        found: usize,
        expected: usize,
    },
    /// An empty field or `NaN` where a number is required.
    #[error("{what}: line {line}, column {column} ('{name}'): missing value")]
    Missing {
        what: String,
        line: usize,
        column: usize,
        name: String,
    },
    /// Text, or a non-finite number, where a number belongs.
    #[error("{what}: line {line}, column {column} ('{name}'): '{text}' is not a finite number")]
    NotANumber {
        what: String,
        line: usize,
        column: usize,
        name: String,
        text: String,
    },
    /// No header row.
    #[error("{what}: empty file (no header row)")]
    Empty { what: String },
    /// More data rows than the reader accepts.
    #[error("{what}: more than {limit} data rows{hint}")]
    TooManyRows {
        what: String,
        limit: usize,
        hint: String,
    },
}

/// What [`parse_csv_with`] reads.
#[derive(Clone, Copy, Debug)]
pub struct CsvOptions<'a> {
    /// An empty field or `NaN` is NaN (else an error).
    pub allow_missing: bool,
    /// The most data rows accepted, and how to raise the limit (for the message).
    pub max_rows: usize,
    pub rows_hint: &'a str,
    /// The columns parsed as numbers (`None`: all). The others are not read at all: they
    /// hold NaN, whatever their text.
    pub columns: Option<&'a [&'a str]>,
}

impl<'a> CsvOptions<'a> {
    /// Every column read as a number, none missing, at most `max_rows` data rows (`hint`
    /// says how to raise the limit).
    pub fn rows(max_rows: usize, hint: &'a str) -> Self {
        CsvOptions {
            max_rows,
            rows_hint: hint,
            ..CsvOptions::default()
        }
    }
}

impl Default for CsvOptions<'_> {
    fn default() -> Self {
        CsvOptions {
            allow_missing: false,
            max_rows: usize::MAX,
            rows_hint: "",
            columns: None,
        }
    }
}

/// Parse CSV text with the csv crate (a UTF-8 byte-order mark, quoted fields and CRLF line
/// ends are handled there): `#` comment lines and blank lines skipped, a header row, then
/// numbers. A header naming a column twice is an error. An empty field or `NaN` is NaN if
/// `allow_missing`, else an error; any other text is an error naming the line and column.
pub fn parse_csv(text: &str, what: &str, allow_missing: bool) -> Result<Csv, CsvError> {
    parse_csv_with(
        text,
        what,
        CsvOptions {
            allow_missing,
            ..CsvOptions::default()
        },
    )
}

/// [`parse_csv`] with a row limit and a choice of the columns read.
pub fn parse_csv_with(text: &str, what: &str, opts: CsvOptions<'_>) -> Result<Csv, CsvError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.trim_start_matches('\u{feff}').as_bytes());
    let mut header: Option<Vec<String>> = None;
    let mut read: Vec<bool> = Vec::new();
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| CsvError::Syntax {
            what: what.to_string(),
            line: e.position().map(|p| p.line()).unwrap_or(0),
            message: e.to_string(),
        })?;
        let lineno = record.position().map(|p| p.line() as usize).unwrap_or(0);
        if record.iter().all(str::is_empty) {
            continue;
        }
        let Some(h) = &header else {
            let names: Vec<String> = record.iter().map(str::to_string).collect();
            for (j, name) in names.iter().enumerate() {
                if let Some(i) = names[..j].iter().position(|n| n == name) {
                    return Err(CsvError::DuplicateColumn {
                        what: what.to_string(),
                        line: lineno,
                        name: name.clone(),
                        first: i + 1,
                        second: j + 1,
                    });
                }
            }
            read = names
                .iter()
                .map(|n| opts.columns.is_none_or(|c| c.contains(&n.as_str())))
                .collect();
            header = Some(names);
            continue;
        };
        if record.len() != h.len() {
            return Err(CsvError::FieldCount {
                what: what.to_string(),
                line: lineno,
                found: record.len(),
                expected: h.len(),
            });
        }
        if rows.len() == opts.max_rows {
            return Err(CsvError::TooManyRows {
                what: what.to_string(),
                limit: opts.max_rows,
                hint: opts.rows_hint.to_string(),
            });
        }
        let mut row = Vec::with_capacity(record.len());
        for (j, (f, name)) in record.iter().zip(h).enumerate() {
            let v = if !read[j] {
                f64::NAN
            } else if f.is_empty() || f.eq_ignore_ascii_case("nan") {
                if !opts.allow_missing {
                    return Err(CsvError::Missing {
                        what: what.to_string(),
                        line: lineno,
                        column: j + 1,
                        name: name.clone(),
                    });
                }
                f64::NAN
            } else {
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => v,
                    _ => {
                        return Err(CsvError::NotANumber {
                            what: what.to_string(),
                            line: lineno,
                            column: j + 1,
                            name: name.clone(),
                            text: f.to_string(),
                        })
                    }
                }
            };
            row.push(v);
        }
        rows.push(row);
        lines.push(lineno);
    }
    let header = header.ok_or_else(|| CsvError::Empty {
        what: what.to_string(),
    })?;
    Ok(Csv {
        header,
        rows,
        lines,
    })
}

/// A trajectory with a non-finite value, which no result file holds.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the trajectory holds a non-finite value ({value}) at t = {t} in column '{column}': nothing written")]
pub struct NonFiniteValue {
    /// The value.
    pub value: f64,
    /// Its time.
    pub t: f64,
    /// Its column.
    pub column: &'static str,
}

/// A result table as CSV text: `header` (comma-separated column names), then one line per
/// row, every value as `{:.17e}` (read back to the same `f64`); the first column is the
/// time. An error naming the time and the column of the first non-finite value.
pub fn result_csv(
    header: &'static str,
    rows: impl IntoIterator<Item = Vec<f64>>,
) -> Result<String, NonFiniteValue> {
    let names: Vec<&'static str> = header.split(',').collect();
    let mut s = String::from(header);
    s.push('\n');
    for row in rows {
        if let Some(j) = row.iter().position(|v| !v.is_finite()) {
            return Err(NonFiniteValue {
                value: row[j],
                t: row[0],
                column: names[j],
            });
        }
        let fields: Vec<String> = row.iter().map(|v| format!("{v:.17e}")).collect();
        s.push_str(&fields.join(","));
        s.push('\n');
    }
    Ok(s)
}
