//! File input and output shared by the tools: output sets written whole (staged, then put
//! in place under a journal and named by a manifest), the readers' size limits, the CSV and
//! JSON readers, input schedules, and progress and result lines that never panic on a
//! closed or full stream.

use serde::de::DeserializeOwned;
use std::io::Read as _;
use std::os::fd::AsRawFd as _;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

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

// ---------------------------------------------------------------------------------------
// Output sets
// ---------------------------------------------------------------------------------------

/// The file in an output directory that names the files of the last run written there.
pub const MANIFEST: &str = ".manifest";
/// The journal of an output set being put in place: present only while a run moves its
/// files into the directory (or after a crash during that, until the next run finishes the
/// move).
pub const JOURNAL: &str = ".commit";
/// The staging directory of process `PID` is `DIR/.staging-PID`.
const STAGING_PREFIX: &str = ".staging-";

/// Why an output set could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output directory could not be created.
    #[error("cannot create output directory {}: {source}", dir.display())]
    CreateDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The staging directory (inside the output directory) could not be created.
    #[error("output directory {} is not writable: {source}", dir.display())]
    NotWritable {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file of the set could not be written, moved into place or removed.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A set names a file twice, or a name that is not a plain file name.
    #[error("output set {}: bad or repeated file name '{name}'", dir.display())]
    BadName { dir: PathBuf, name: String },
}

/// The staging directories of this process's open output sets, for the signal handler; its
/// lock is held while a set is put in place, so that a signal waits for the set.
static STAGED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The signal received (0: none): a commit that finishes after one arrived waits for the
/// handler to end the process, so that an interrupted run always dies of its signal.
static SIGNALLED: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

fn staged() -> MutexGuard<'static, Vec<PathBuf>> {
    STAGED.lock().unwrap_or_else(|p| p.into_inner())
}

/// SIGINT, SIGTERM and SIGHUP handled on a thread of their own: the staging directories of
/// the open output sets are removed (an output set being put in place is finished first),
/// then the process dies of the signal as it would have (exit status 128 + signal in a
/// shell). Call it first in `main`, before any other thread starts: the signals are
/// blocked in the calling thread and every thread it starts afterwards.
pub fn clean_up_on_signals() {
    // SAFETY: plain libc calls on a local, initialised signal set.
    let set = unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, sig);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        set
    };
    let spawned = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || loop {
            let mut sig: libc::c_int = 0;
            // SAFETY: `set` is initialised; `sig` is a valid out-pointer.
            if unsafe { libc::sigwait(&set, &mut sig) } != 0 {
                continue;
            }
            SIGNALLED.store(sig, std::sync::atomic::Ordering::SeqCst);
            let held = staged();
            for dir in held.iter() {
                let _ = std::fs::remove_dir_all(dir);
            }
            // SAFETY: restore the default action, unblock in this thread and raise: the
            // process ends as killed by `sig`.
            unsafe {
                libc::signal(sig, libc::SIG_DFL);
                libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
                libc::raise(sig);
            }
            std::process::exit(128 + sig);
        });
    if spawned.is_err() {
        // No thread for the signals: unblock them again (their default action stays).
        // SAFETY: as above.
        unsafe {
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        }
    }
}

/// An exclusive `flock(2)` on a directory, released on drop: output sets written into one
/// directory by several processes are put in place one after the other.
struct DirLock(std::fs::File);

impl DirLock {
    fn take(dir: &Path) -> Result<Self, OutputError> {
        let f = std::fs::File::open(dir).map_err(|source| OutputError::NotWritable {
            dir: dir.to_path_buf(),
            source,
        })?;
        // SAFETY: a valid open descriptor.
        while unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(OutputError::NotWritable {
                    dir: dir.to_path_buf(),
                    source: e,
                });
            }
        }
        Ok(DirLock(f))
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // SAFETY: a valid open descriptor.
        unsafe {
            libc::flock(self.0.as_raw_fd(), libc::LOCK_UN);
        }
    }
}

/// Whether process `pid` exists (a staging directory of a dead one is stale).
fn process_alive(pid: i32) -> bool {
    // SAFETY: signal 0 checks for existence only.
    pid > 0
        && (unsafe { libc::kill(pid, 0) } == 0
            || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH))
}

/// Write `contents` to `dir/name` whole: a temporary file in the same directory, then
/// rename, so a reader never sees a half-written file. The temporary file is removed if
/// the write fails.
pub fn write_atomic(dir: &Path, name: &str, contents: &[u8]) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::CreateDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let dst = dir.join(name);
    let fail = |source| OutputError::Write {
        path: dst.clone(),
        source,
    };
    if let Err(e) = std::fs::write(&tmp, contents) {
        let _ = std::fs::remove_file(&tmp);
        return Err(fail(e));
    }
    std::fs::rename(&tmp, &dst).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        fail(e)
    })
}

/// The names the manifest of `dir` lists (none without a manifest).
pub fn manifest(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join(MANIFEST))
        .map(|t| names_of(&t).map(str::to_string).collect())
        .unwrap_or_default()
}

fn names_of(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
}

/// An output set being put in place: the staging directory it comes from, the files it
/// moves in, and the files of the previous set it removes.
struct Journal {
    staging: String,
    files: Vec<String>,
    stale: Vec<String>,
}

impl Journal {
    fn to_text(&self) -> String {
        let mut s =
            String::from("# an output set being put in place (docs/formats.md, \"Output sets\")\n");
        s += &format!("staging {}\n", self.staging);
        for f in &self.files {
            s += &format!("file {f}\n");
        }
        for f in &self.stale {
            s += &format!("stale {f}\n");
        }
        s
    }

    fn parse(text: &str) -> Option<Journal> {
        let mut j = Journal {
            staging: String::new(),
            files: Vec::new(),
            stale: Vec::new(),
        };
        for line in names_of(text) {
            let (kind, name) = line.split_once(' ')?;
            if !plain_name(name) {
                return None;
            }
            match kind {
                "staging" => j.staging = name.to_string(),
                "file" => j.files.push(name.to_string()),
                "stale" => j.stale.push(name.to_string()),
                _ => return None,
            }
        }
        j.staging.starts_with(STAGING_PREFIX).then_some(j)
    }

    /// Move the staged files in, remove the stale ones, write the manifest, drop the
    /// journal and the staging directory. A file already moved (a journal finished after a
    /// crash) is skipped; a failure leaves the journal for the next run.
    fn apply(&self, dir: &Path) -> Result<(), OutputError> {
        let staging = dir.join(&self.staging);
        let pause = commit_pause();
        for name in &self.files {
            let from = staging.join(name);
            if from.exists() {
                std::fs::rename(&from, dir.join(name)).map_err(|source| OutputError::Write {
                    path: dir.join(name),
                    source,
                })?;
            }
            if let Some(p) = pause {
                std::thread::sleep(p);
            }
        }
        for name in &self.stale {
            match std::fs::remove_file(dir.join(name)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(OutputError::Write {
                        path: dir.join(name),
                        source: e,
                    })
                }
                _ => {}
            }
        }
        let mut list = String::from(
            "# the files of the last run written into this directory, put in place together \
             (docs/formats.md, \"Output sets\")\n",
        );
        for name in &self.files {
            list += name;
            list.push('\n');
        }
        write_atomic(dir, MANIFEST, list.as_bytes())?;
        std::fs::remove_file(dir.join(JOURNAL)).map_err(|source| OutputError::Write {
            path: dir.join(JOURNAL),
            source,
        })?;
        let _ = std::fs::remove_dir_all(&staging);
        Ok(())
    }
}

/// A pause after each file moved into place, for the tests that interrupt a run while it
/// puts its set in place (`ROBOTS_TEST_COMMIT_PAUSE_MS`; unset in normal use).
fn commit_pause() -> Option<std::time::Duration> {
    std::env::var("ROBOTS_TEST_COMMIT_PAUSE_MS")
        .ok()?
        .parse::<u64>()
        .ok()
        .map(std::time::Duration::from_millis)
}

/// A number for a message: as written for everyday magnitudes, in exponent form beyond
/// (`1e300`, not three hundred digits).
fn number(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// A step for a message: at most 12 decimals, trailing zeros dropped (`0.005 / 5` reads
/// `0.001`).
fn short(h: f64) -> String {
    let s = format!("{h:.12}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A file name without a directory part.
fn plain_name(name: &str) -> bool {
    !name.is_empty() && name != "." && name != ".." && !name.contains('/') && !name.contains('\0')
}

/// Finish what an earlier run left in `dir` (the caller holds the directory's lock): a
/// journal of a set that was being put in place is carried out, and the staging
/// directories and temporary files of processes that no longer exist are removed.
fn recover(dir: &Path) -> Result<(), OutputError> {
    if let Ok(text) = std::fs::read_to_string(dir.join(JOURNAL)) {
        match Journal::parse(&text) {
            Some(j) => j.apply(dir)?,
            // Not a journal of ours: leave the directory's files alone, drop the journal.
            None => {
                let _ = std::fs::remove_file(dir.join(JOURNAL));
            }
        }
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        // Ours: `.staging-PID` directories, and `.NAME.tmpPID` files of `write_atomic`.
        let pid = name
            .strip_prefix(STAGING_PREFIX)
            .or_else(|| {
                name.starts_with('.')
                    .then(|| name.rsplit_once(".tmp").map(|(_, p)| p))
                    .flatten()
            })
            .filter(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|p| p.parse::<i32>().ok());
        if let Some(pid) = pid {
            if pid as u32 != std::process::id() && !process_alive(pid) {
                let _ = if e.path().is_dir() {
                    std::fs::remove_dir_all(e.path())
                } else {
                    std::fs::remove_file(e.path())
                };
            }
        }
    }
    Ok(())
}

/// The files of one run, which belong together.
///
/// Opened before any long work (so that an unwritable directory is found at once; what an
/// earlier, interrupted run left in the directory is finished or removed then), written
/// into a staging directory `DIR/.staging-PID`, and put in place only by
/// [`OutputSet::commit`]: under a journal (`DIR/.commit`) the files move in, the files of
/// the previous set that this one does not have are removed, and the manifest
/// (`DIR/.manifest`) names the new set. A failed run leaves the previous set as it was and
/// no stray files (the staging directory is removed on drop, and by the signal handler of
/// [`clean_up_on_signals`]). The guarantees are those of docs/formats.md, "Output sets".
pub struct OutputSet {
    dir: PathBuf,
    staging: PathBuf,
    names: Vec<String>,
}

impl OutputSet {
    /// Create `dir` (and a staging directory in it) or fail with a one-line reason.
    pub fn create(dir: &Path) -> Result<Self, OutputError> {
        std::fs::create_dir_all(dir).map_err(|source| OutputError::CreateDir {
            dir: dir.to_path_buf(),
            source,
        })?;
        {
            let _lock = DirLock::take(dir)?;
            recover(dir)?;
        }
        let staging = dir.join(format!("{STAGING_PREFIX}{}", std::process::id()));
        let mut held = staged();
        std::fs::create_dir_all(&staging).map_err(|source| OutputError::NotWritable {
            dir: dir.to_path_buf(),
            source,
        })?;
        held.push(staging.clone());
        Ok(OutputSet {
            dir: dir.to_path_buf(),
            staging,
            names: Vec::new(),
        })
    }

    /// Stage one file of the set.
    pub fn write(&mut self, name: &str, contents: &[u8]) -> Result<(), OutputError> {
        if !plain_name(name) || name.starts_with('.') || self.names.iter().any(|n| n == name) {
            return Err(OutputError::BadName {
                dir: self.dir.clone(),
                name: name.to_string(),
            });
        }
        std::fs::write(self.staging.join(name), contents).map_err(|source| OutputError::Write {
            path: self.dir.join(name),
            source,
        })?;
        self.names.push(name.to_string());
        Ok(())
    }

    /// Put the staged files in place as the directory's set: see [`OutputSet`]. SIGINT and
    /// SIGTERM wait until it is done.
    pub fn commit(self) -> Result<(), OutputError> {
        {
            let _signals_wait = staged();
            let _lock = DirLock::take(&self.dir)?;
            let old = manifest(&self.dir);
            let journal = Journal {
                staging: self
                    .staging
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                files: self.names.clone(),
                stale: old
                    .into_iter()
                    .filter(|n| plain_name(n) && !self.names.contains(n))
                    .collect(),
            };
            write_atomic(&self.dir, JOURNAL, journal.to_text().as_bytes())?;
            journal.apply(&self.dir)?;
        }
        if SIGNALLED.load(std::sync::atomic::Ordering::SeqCst) != 0 {
            // The set is in place; the handler, which waited for it, ends the process.
            loop {
                std::thread::park();
            }
        }
        Ok(())
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut held = staged();
        let _ = std::fs::remove_dir_all(&self.staging);
        held.retain(|d| d != &self.staging);
    }
}

// ---------------------------------------------------------------------------------------
// Reading files: errors and size limits
// ---------------------------------------------------------------------------------------

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
    Log(#[from] crate::diagnose::log::LogError),
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

// ---------------------------------------------------------------------------------------
// CSV
// ---------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------
// JSON
// ---------------------------------------------------------------------------------------

/// Why a JSON input was refused. Every variant but `Syntax` names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JsonError {
    /// Not JSON (serde's message, with the line and column).
    #[error("not valid JSON: {0}")]
    Syntax(String),
    /// The file is JSON, but not an object.
    #[error("expected a JSON object {{ \"key\": value, … }}, got {found}")]
    NotAnObject { found: &'static str },
    /// A key the format does not have.
    #[error("unknown key '{key}' (expected {known})")]
    UnknownKey { key: String, known: String },
    /// A required key is absent.
    #[error("missing key '{key}'")]
    MissingKey { key: String },
    /// A value the format's type does not take (serde's reason, and where in the file).
    #[error("'{key}': {reason} at {at}")]
    Invalid {
        key: String,
        reason: String,
        at: String,
    },
    /// A value of the wrong type, or `null` (never read as "the default"); `key` is the
    /// path to it (`points[1][0]`).
    #[error("'{key}' must be {expected}, got {found}")]
    WrongType {
        key: String,
        expected: String,
        found: String,
    },
}

/// The JSON type of a value, for messages.
fn json_type(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// The first `null` inside `v`, as a key path below `path`.
fn find_null(v: &serde_json::Value, path: &str) -> Option<String> {
    match v {
        serde_json::Value::Null => Some(path.to_string()),
        serde_json::Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| find_null(x, &format!("{path}[{i}]"))),
        serde_json::Value::Object(m) => m
            .iter()
            .find_map(|(k, x)| find_null(x, &format!("{path}.{k}"))),
        _ => None,
    }
}

/// The top-level key of the JSON object `text` whose value holds byte offset `pos` (for
/// an error serde locates there).
fn key_at(text: &str, pos: usize) -> Option<String> {
    let (mut depth, mut in_string, mut escaped) = (0usize, false, false);
    let (mut start, mut last_string, mut key) = (0usize, None::<(usize, usize)>, None);
    for (i, c) in text.char_indices() {
        if i >= pos {
            break;
        }
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => {
                    in_string = false;
                    last_string = Some((start, i));
                }
                _ => {}
            }
            continue;
        }
        match c {
            '"' => {
                in_string = true;
                start = i + 1;
            }
            '{' | '[' => depth += 1,
            '}' | ']' => depth = depth.saturating_sub(1),
            ':' if depth == 1 => key = last_string.map(|(a, b)| text[a..b].to_string()),
            _ => {}
        }
    }
    key
}

/// A JSON object read from a file: its keys checked against the format's, and typed
/// access to each that names the key in every error.
#[derive(Debug)]
pub struct JsonObject {
    map: serde_json::Map<String, serde_json::Value>,
    text: String,
}

impl JsonObject {
    /// Parse `text` (a byte-order mark allowed) as an object whose keys are among `known`,
    /// with no `null` anywhere in it.
    pub fn parse(text: &str, known: &[&str]) -> Result<Self, JsonError> {
        let v: serde_json::Value = serde_json::from_str(text.trim_start_matches('\u{feff}'))
            .map_err(|e| JsonError::Syntax(e.to_string()))?;
        let serde_json::Value::Object(map) = v else {
            return Err(JsonError::NotAnObject {
                found: json_type(&v),
            });
        };
        if let Some(key) = map.keys().find(|k| !known.contains(&k.as_str())) {
            return Err(JsonError::UnknownKey {
                key: key.clone(),
                known: known.join(", "),
            });
        }
        for (k, v) in &map {
            if let Some(path) = find_null(v, k) {
                return Err(JsonError::WrongType {
                    key: path,
                    expected: "a value".into(),
                    found: "null (leave the key out for its default)".into(),
                });
            }
        }
        Ok(JsonObject {
            map,
            text: text.trim_start_matches('\u{feff}').to_string(),
        })
    }

    /// The whole object as a `T` (a struct of the format's fields), read from the text so
    /// that an error says where: a value of the wrong type names its key, the line and the
    /// column; a missing field is [`JsonError::MissingKey`].
    pub fn typed<T: DeserializeOwned>(&self) -> Result<T, JsonError> {
        serde_json::from_str(&self.text).map_err(|e| {
            let message = e.to_string();
            let reason = message
                .rsplit_once(" at line ")
                .map_or(message.as_str(), |(r, _)| r);
            if let Some(k) = reason
                .strip_prefix("missing field `")
                .and_then(|r| r.strip_suffix('`'))
            {
                return JsonError::MissingKey { key: k.to_string() };
            }
            let line_start: usize = self
                .text
                .split_inclusive('\n')
                .take(e.line().saturating_sub(1))
                .map(str::len)
                .sum();
            JsonError::Invalid {
                key: key_at(&self.text, line_start + e.column()).unwrap_or_default(),
                reason: reason.to_string(),
                at: format!("line {} column {}", e.line(), e.column()),
            }
        })
    }

    /// The value of `key` as a `T` (`expected` describes `T` in the message), or `None`
    /// if the key is absent.
    pub fn get<T: DeserializeOwned>(
        &self,
        key: &str,
        expected: &str,
    ) -> Result<Option<T>, JsonError> {
        let Some(v) = self.map.get(key) else {
            return Ok(None);
        };
        serde_json::from_value(v.clone()).map(Some).map_err(|e| {
            let mut shown = v.to_string();
            if shown.chars().count() > 60 {
                shown = shown.chars().take(57).collect::<String>() + "…";
            }
            JsonError::WrongType {
                key: key.to_string(),
                expected: expected.to_string(),
                found: format!("{shown} ({e})"),
            }
        })
    }

    /// The value of a key the format requires.
    pub fn require<T: DeserializeOwned>(&self, key: &str, expected: &str) -> Result<T, JsonError> {
        self.get(key, expected)?
            .ok_or_else(|| JsonError::MissingKey {
                key: key.to_string(),
            })
    }

    /// A finite number, if the key is given.
    pub fn number(&self, key: &str) -> Result<Option<f64>, JsonError> {
        match self.get::<f64>(key, "a number")? {
            Some(v) if !v.is_finite() => Err(JsonError::WrongType {
                key: key.to_string(),
                expected: "a finite number".into(),
                found: v.to_string(),
            }),
            v => Ok(v),
        }
    }
}

// ---------------------------------------------------------------------------------------
// Input schedules
// ---------------------------------------------------------------------------------------

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

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("wip-io-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_missing_file_and_a_malformed_one_are_different_errors() {
        let dir = scratch("read");
        let missing = read_inputs(&dir.join("missing.csv"), 100, "");
        assert!(
            matches!(&missing, Err(ReadError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound),
            "{missing:?}"
        );
        std::fs::write(dir.join("bad.csv"), "t,uR,uL\n0,1,x\n").unwrap();
        let bad = read_inputs(&dir.join("bad.csv"), 100, "");
        assert!(
            matches!(
                &bad,
                Err(ReadError::Inputs(InputError::Csv(CsvError::NotANumber {
                    line: 2,
                    column: 3,
                    ..
                })))
            ),
            "{bad:?}"
        );
        // Too many rows: refused by size before parsing, or by the row count.
        let long: String = std::iter::once("t,uR,uL\n".to_string())
            .chain((0..2000).map(|k| format!("{k},0,0\n")))
            .collect();
        std::fs::write(dir.join("long.csv"), &long).unwrap();
        let e = read_inputs(&dir.join("long.csv"), 100, " (--max-steps)").unwrap_err();
        assert!(
            matches!(
                &e,
                ReadError::Inputs(InputError::Csv(CsvError::TooManyRows { limit: 100, .. }))
            ),
            "{e:?}"
        );
        let e = read_inputs(&dir.join("long.csv"), 1, " (--max-steps)").unwrap_err();
        assert!(matches!(&e, ReadError::TooLarge { .. }), "{e:?}");
        assert!(e.to_string().contains("--max-steps"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn rows_between_steps_are_refused_with_a_step_that_fits() {
        let s = parse_inputs("t,uR,uL\n0,0,0\n0.001,5,5\n0.004,0,0\n1,0,0\n", "f").unwrap();
        let e = s.steps_on_grid(0.005, "f", "--step").unwrap_err();
        assert!(
            matches!(&e, InputError::OffGrid { row: 2, fate, fix, .. } if fate.contains("drop") && fix.contains("--step 0.001")),
            "{e}"
        );
        assert_eq!(s.steps_on_grid(0.001, "f", "--step").unwrap(), 1000);
        let late = parse_inputs("t,uR,uL\n0,0,0\n0.007,5,5\n1,0,0\n", "f").unwrap();
        let e = late.steps_on_grid(0.005, "f", "--step").unwrap_err();
        assert!(
            e.to_string().contains("apply it from t = 0.01 s, late"),
            "{e}"
        );
    }

    #[test]
    fn unread_columns_may_hold_text() {
        let text = "t,a,note\n0,1,ok\n1,2,fine\n";
        assert!(parse_csv(text, "f", true).is_err());
        let csv = parse_csv_with(
            text,
            "f",
            CsvOptions {
                allow_missing: true,
                columns: Some(&["t", "a"]),
                ..CsvOptions::default()
            },
        )
        .unwrap();
        assert_eq!(csv.rows[1][1], 2.0);
        assert!(csv.rows[1][2].is_nan());
    }

    #[test]
    fn json_objects_refuse_arrays_nulls_and_wrong_types_by_key() {
        let known = ["a", "b"];
        let e = JsonObject::parse("[1.0, 2.0]", &known).unwrap_err();
        assert_eq!(e, JsonError::NotAnObject { found: "an array" });
        let e = JsonObject::parse(r#"{"a": null}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::WrongType { key, .. } if key == "a"),
            "{e}"
        );
        let e = JsonObject::parse(r#"{"b": [1, null]}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::WrongType { key, .. } if key == "b[1]"),
            "{e}"
        );
        let e = JsonObject::parse(r#"{"c": 1}"#, &known).unwrap_err();
        assert!(
            matches!(&e, JsonError::UnknownKey { key, .. } if key == "c"),
            "{e}"
        );
        let o = JsonObject::parse(r#"{"a": "x"}"#, &known).unwrap();
        let e = o.number("a").unwrap_err();
        assert!(e.to_string().starts_with("'a' must be a number"), "{e}");
        assert!(matches!(
            o.require::<f64>("b", "a number"),
            Err(JsonError::MissingKey { .. })
        ));
    }

    /// A commit replaces the previous set: its files that the new set lacks go, other files
    /// of the directory stay, and the manifest names the new set. An interrupted commit
    /// (its journal and staging directory left behind) is finished by the next set's
    /// creation, and a dead process's staging directory removed.
    #[test]
    fn a_set_replaces_the_previous_one_and_a_journal_is_finished() {
        let dir = scratch("sets");
        std::fs::write(dir.join("mine.txt"), "the user's").unwrap();
        let mut a = OutputSet::create(&dir).unwrap();
        a.write("one", b"1").unwrap();
        a.write("two", b"2").unwrap();
        assert!(a.write("two", b"again").is_err());
        a.commit().unwrap();
        assert_eq!(manifest(&dir), ["one", "two"]);
        let mut b = OutputSet::create(&dir).unwrap();
        b.write("one", b"1b").unwrap();
        b.commit().unwrap();
        assert_eq!(manifest(&dir), ["one"]);
        assert!(!dir.join("two").exists());
        assert_eq!(std::fs::read_to_string(dir.join("one")).unwrap(), "1b");
        assert!(dir.join("mine.txt").exists());
        // A crash half-way through a commit: "one" moved, "three" still staged.
        let staging = dir.join(".staging-999999999");
        std::fs::create_dir_all(&staging).unwrap();
        std::fs::write(staging.join("three"), "3").unwrap();
        std::fs::write(dir.join("one"), "1c").unwrap();
        let j = Journal {
            staging: ".staging-999999999".into(),
            files: vec!["one".into(), "three".into()],
            stale: vec![],
        };
        std::fs::write(dir.join(JOURNAL), j.to_text()).unwrap();
        std::fs::create_dir_all(dir.join(".staging-999999998")).unwrap();
        let c = OutputSet::create(&dir).unwrap();
        assert_eq!(manifest(&dir), ["one", "three"]);
        assert!(!dir.join(JOURNAL).exists() && !staging.exists());
        assert!(!dir.join(".staging-999999998").exists());
        drop(c);
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".staging") || n.contains(".tmp"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
