//! Output sets: a run's files staged aside and put in place together under a journal,
//! named by a manifest, with the staging cleaned on signals and at the next run.

use super::*;

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
pub(super) struct Journal {
    staging: String,
    files: Vec<String>,
    stale: Vec<String>,
}

impl Journal {
    pub(super) fn to_text(&self) -> String {
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
pub(super) fn number(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// A step for a message: at most 12 decimals, trailing zeros dropped (`0.005 / 5` reads
/// `0.001`).
pub(super) fn short(h: f64) -> String {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("wip-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
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
