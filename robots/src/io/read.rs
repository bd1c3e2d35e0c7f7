//! Reading input files: the errors a caller tells apart, and the size limits.

use super::*;

/// Why a file could not be read: a caller can tell a missing or unreadable file from one
/// too large to read or whose contents are wrong.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read.
    #[error("cannot read {what}: {source}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
    /// The file is larger than its reader accepts; nothing of it was parsed.
    #[error("{what}: {size} bytes is more than the {limit} bytes accepted{hint}")]
    TooLarge {
        what: String,
        size: u64,
        limit: u64,
        /// How to raise the limit (e.g. ` (raise it with --max-rows)`), or empty.
        hint: String,
    },
    /// A CSV file's contents are malformed.
    #[error(transparent)]
    Csv(#[from] CsvError),
    /// An inputs file's contents are malformed or cannot be applied.
    #[error(transparent)]
    Inputs(#[from] InputError),
    /// A plan's contents are malformed or have a hole.
    #[error(transparent)]
    Plan(#[from] crate::wip::track::report::PlanError),
    /// A measured log's contents are malformed.
    #[error(transparent)]
    Log(#[from] crate::diagnose::read_log::LogError),
    /// A JSON file's contents are malformed; the message names the file and the key.
    #[error("{what}: {source}")]
    Json {
        what: String,
        #[source]
        source: JsonError,
    },
    /// The contents are malformed or out of range; the message names the file, and the
    /// line and column where there is one.
    #[error("{0}")]
    Content(String),
}

/// The largest JSON input file read (parameter, waypoint and pose files): 16 MiB.
pub const MAX_JSON_BYTES: u64 = 16 << 20;

/// The whole text of a file; `what` names it in the error.
pub fn read_text(path: &Path, what: &str) -> Result<String, ReadError> {
    read_text_limited(path, what, u64::MAX, "")
}

/// The whole text of a file of at most `limit` bytes: a larger one is refused from its size
/// before it is read (and a file that grows while it is read, or a pipe, after `limit`
/// bytes). `hint` says how to raise the limit.
pub fn read_text_limited(
    path: &Path,
    what: &str,
    limit: u64,
    hint: &str,
) -> Result<String, ReadError> {
    let io = |source| ReadError::Io {
        what: what.to_string(),
        source,
    };
    let too_large = |size| ReadError::TooLarge {
        what: what.to_string(),
        size,
        limit,
        hint: hint.to_string(),
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(size.min(limit) as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        ))
    })
}

/// The byte limit of a CSV file of at most `rows` rows of about `bytes_per_row` bytes:
/// room for comments and wide formatting, and a quick refusal of a file orders of
/// magnitude too long.
pub fn csv_byte_limit(rows: usize, bytes_per_row: u64) -> u64 {
    (rows as u64)
        .saturating_add(16)
        .saturating_mul(bytes_per_row)
}
