//! Files and directories written whole or not at all, and directories owned by one writer.
//!
//! - [`AtomicFile`] / [`write_atomic`] / [`write_bytes`] / [`write_json`]: a file goes to a
//!   temporary `.<name>.<random>.tmp` beside its target, is synced and only then renamed over
//!   it, so a failed or interrupted writer never leaves a half-written file under the final name
//!   (dropped uncommitted, the temporary file is removed). The target gets the permissions
//!   `File::create` would give it (`0o666` minus the umask), not a private temporary file's.
//! - [`DirLock`]: an exclusive `flock` on a directory's [`LOCK_FILE`], released however the
//!   process ends, so two writers never share a run or dataset directory.
//! - [`claim`]: the run-directory policy every front end shares — a directory is used when it
//!   is new or empty; one that holds a previous run of the same kind is replaced only with
//!   `force`; one that holds anything else is never touched (and is left as it was found).
//!
//! ```
//! use lgdm_base::fs::{Entry, Ownership, claim, write_bytes};
//! let dir = tempfile::tempdir().unwrap();
//! let run = dir.path().join("run");
//! let policy = Ownership {
//!     kind: "an example run",
//!     occupied: "holds another run; pass --force to replace it",
//!     classify: &|name: &str, _is_dir: bool| {
//!         if name == "results.json" { Entry::Ours } else { Entry::Foreign }
//!     },
//! };
//! let lock = claim(&run, false, &policy).unwrap();
//! write_bytes(&run.join("results.json"), b"{}").unwrap();
//! drop(lock);
//! assert!(claim(&run, false, &policy).is_err()); // a previous run: only with force
//! let _lock = claim(&run, true, &policy).unwrap();
//! assert!(!run.join("results.json").exists());
//! ```

use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

/// A file being written under a temporary name next to `path`; [`AtomicFile::commit`] renames
/// it into place, dropping it removes it. Writes are buffered.
#[derive(Debug)]
pub struct AtomicFile {
    writer: BufWriter<NamedTempFile>,
    path: PathBuf,
}

impl AtomicFile {
    /// Creates the temporary file `.<name>.<random>.tmp` in `path`'s directory, with an 8 KiB
    /// write buffer.
    pub fn create(path: &Path) -> io::Result<Self> {
        Self::with_capacity(path, 8 << 10)
    }

    /// Like [`AtomicFile::create`] with a write buffer of `capacity` bytes.
    pub fn with_capacity(path: &Path, capacity: usize) -> io::Result<Self> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path
            .file_name()
            .map_or_else(|| "file".into(), |n| n.to_string_lossy());
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let file = builder.tempfile_in(dir)?;
        Ok(Self {
            writer: BufWriter::with_capacity(capacity, file),
            path: path.to_path_buf(),
        })
    }

    /// Flushes, syncs to disk and renames the file into place; returns its size in bytes.
    pub fn commit(self) -> io::Result<u64> {
        let file = self.writer.into_inner().map_err(|e| e.into_error())?;
        file.as_file().sync_all()?;
        let bytes = file.as_file().metadata()?.len();
        file.persist(&self.path).map_err(|e| e.error)?;
        Ok(bytes)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.writer.write_all(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.writer.seek(pos)
    }
}

/// Writes `path` atomically: `write` fills a buffered temporary file (seekable, for formats
/// such as TIFF that patch offsets), which is then synced and renamed over `path`. On error the
/// temporary file is removed and `path` is untouched.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut AtomicFile) -> io::Result<()>,
) -> io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(&mut file)?;
    file.commit().map(|_| ())
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Writes `value` as pretty JSON with a final newline, atomically.
pub fn write_json<T: serde::Serialize + ?Sized>(path: &Path, value: &T) -> io::Result<()> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(io::Error::other)?;
        w.write_all(b"\n")
    })
}

/// Name of the lock file that keeps two writers out of one directory (run or dataset).
pub const LOCK_FILE: &str = ".lgdm.lock";

/// An exclusive lock on a directory, held until it is dropped or the process ends (however it
/// ends: the operating system releases it, so a killed writer never leaves a stale lock).
#[derive(Debug)]
pub struct DirLock {
    file: std::fs::File,
    path: PathBuf,
}

impl DirLock {
    /// Creates `dir` if needed and locks it through its [`LOCK_FILE`]; `Ok(None)` when another
    /// process holds the lock.
    pub fn try_acquire(dir: &Path) -> io::Result<Option<DirLock>> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(LOCK_FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)?;
        match file.try_lock() {
            Ok(()) => Ok(Some(DirLock { file, path })),
            Err(std::fs::TryLockError::WouldBlock) => Ok(None),
            Err(std::fs::TryLockError::Error(e)) => Err(e),
        }
    }

    /// Whether another process holds `dir`'s lock right now (a lock file left by a process that
    /// ended is not held).
    pub fn is_held(dir: &Path) -> bool {
        let Ok(file) = std::fs::OpenOptions::new()
            .write(true)
            .open(dir.join(LOCK_FILE))
        else {
            return false;
        };
        matches!(file.try_lock(), Err(std::fs::TryLockError::WouldBlock))
    }

    /// Removes the lock file and releases the lock (the directory is complete).
    pub fn remove(self) -> io::Result<()> {
        std::fs::remove_file(&self.path)?;
        drop(self.file);
        Ok(())
    }
}

/// What a kind of run directory makes of one entry in it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entry {
    /// A file or folder a previous run of this kind wrote (removed, folders with their
    /// contents, when the directory is replaced).
    Ours,
    /// A folder of this kind whose every entry must itself be ours (checked one by one with
    /// its path relative to the run directory, e.g. `rounds/round-0001.mcap`).
    Folder,
    /// Anything else: the directory is not used.
    Foreign,
}

/// A kind of run directory: what it is called and which entries are its own.
pub struct Ownership<'a> {
    /// What a run of this kind is called in errors (`an lgdm run`, `an lgdm sim run`).
    pub kind: &'a str,
    /// The error when the directory holds a previous run and `force` is not set (what to do).
    pub occupied: &'a str,
    /// Classifies an entry by its path relative to the run directory (`/`-separated) and
    /// whether it is a folder. The lock file is never passed.
    pub classify: &'a dyn Fn(&str, bool) -> Entry,
}

impl std::fmt::Debug for Ownership<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ownership")
            .field("kind", &self.kind)
            .finish_non_exhaustive()
    }
}

/// The file a temporary file of [`AtomicFile`] is being written for: `Some("results.json")`
/// for `.results.json.a1B2c3.tmp`, `None` for any other name. Ownership policies count a
/// temporary file as theirs only when its target is one of their own files, so that a user's
/// `.notes.tmp` is never taken for a run's.
///
/// ```
/// use lgdm_base::fs::temporary_target;
/// assert_eq!(temporary_target(".results.json.a1B2c3.tmp"), Some("results.json"));
/// assert_eq!(temporary_target(".notes.tmp"), None);
/// assert_eq!(temporary_target("results.json"), None);
/// ```
pub fn temporary_target(name: &str) -> Option<&str> {
    let inner = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (target, random) = inner.rsplit_once('.')?;
    let random_ok = !random.is_empty() && random.bytes().all(|b| b.is_ascii_alphanumeric());
    (random_ok && !target.is_empty()).then_some(target)
}

/// Why a directory cannot be claimed.
#[derive(Debug, thiserror::Error)]
#[error("{}: {reason}", path.display())]
pub struct ClaimError {
    /// The directory (or the entry that failed).
    pub path: PathBuf,
    /// What is wrong.
    pub reason: String,
}

fn claim_error(path: &Path, reason: impl std::fmt::Display) -> ClaimError {
    ClaimError {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Creates and locks `dir` for a run of `policy`'s kind. A directory that already holds
/// entries is refused, unless `force` is set and every entry is the policy's own (those are
/// removed first). A directory holding anything else is never cleared, and a refused
/// directory is left as it was found: no lock file, and no directory when there was none.
pub fn claim(dir: &Path, force: bool, policy: &Ownership<'_>) -> Result<DirLock, ClaimError> {
    let existed = dir.exists();
    let had_lock = dir.join(LOCK_FILE).exists();
    let lock = DirLock::try_acquire(dir)
        .map_err(|e| claim_error(dir, e))?
        .ok_or_else(|| claim_error(dir, "another lgdm process is writing this run directory"))?;
    match previous_run(dir, policy) {
        Ok(old) if old.is_empty() => Ok(lock),
        Ok(_) if !force => {
            leave_as_found(dir, lock, existed, had_lock);
            Err(claim_error(dir, policy.occupied))
        }
        Ok(old) => {
            for (path, is_dir) in old {
                let removed = if is_dir {
                    std::fs::remove_dir_all(&path)
                } else {
                    std::fs::remove_file(&path)
                };
                removed.map_err(|e| claim_error(&path, e))?;
            }
            Ok(lock)
        }
        Err(e) => {
            leave_as_found(dir, lock, existed, had_lock);
            Err(e)
        }
    }
}

/// Undoes what [`claim`] did to a directory it then refused.
fn leave_as_found(dir: &Path, lock: DirLock, existed: bool, had_lock: bool) {
    if !had_lock {
        let _ = lock.remove();
    }
    if !existed {
        let _ = std::fs::remove_dir(dir);
    }
}

/// The entries of a previous run in `dir` (path, is a folder), sorted; a foreign entry is an
/// error naming it.
fn previous_run(dir: &Path, policy: &Ownership<'_>) -> Result<Vec<(PathBuf, bool)>, ClaimError> {
    let mut old = Vec::new();
    let mut folders = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, prefix)) = folders.pop() {
        for entry in std::fs::read_dir(&folder).map_err(|e| claim_error(&folder, e))? {
            let entry = entry.map_err(|e| claim_error(&folder, e))?;
            let name = format!("{prefix}{}", entry.file_name().to_string_lossy());
            if name == LOCK_FILE {
                continue;
            }
            let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
            match (policy.classify)(&name, is_dir) {
                Entry::Ours => old.push((entry.path(), is_dir)),
                Entry::Folder if is_dir => {
                    old.push((entry.path(), true));
                    folders.push((entry.path(), format!("{name}/")));
                }
                Entry::Folder | Entry::Foreign => {
                    return Err(claim_error(
                        dir,
                        format!(
                            "holds {name}, which is not part of {}; choose another directory",
                            policy.kind
                        ),
                    ));
                }
            }
        }
    }
    old.sort();
    // Contents of folders are removed with their folder.
    let folders: Vec<PathBuf> = old
        .iter()
        .filter(|(_, d)| *d)
        .map(|(p, _)| p.clone())
        .collect();
    old.retain(|(p, _)| !folders.iter().any(|f| p != f && p.starts_with(f)));
    Ok(old)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_replaces_without_leftovers() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_bytes(&path, b"one").unwrap();
        write_atomic(&path, |w| w.write_all(b"two")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(entries(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_bytes(&path, b"old").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("boom"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "boom");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.txt"]);
        let mut f = AtomicFile::create(&dir.path().join("b.bin")).unwrap();
        f.write_all(b"x").unwrap();
        drop(f);
        assert_eq!(entries(dir.path()), ["a.txt"]);
    }

    #[test]
    fn commit_returns_the_size_and_honours_seeks() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.bin");
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"abcdef").unwrap();
        f.seek(SeekFrom::Start(1)).unwrap();
        f.write_all(b"XY").unwrap();
        assert_eq!(f.commit().unwrap(), 6);
        assert_eq!(std::fs::read(&path).unwrap(), b"aXYdef");
    }

    #[cfg(unix)]
    #[test]
    fn files_get_create_permissions_not_private_ones() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let atomic = dir.path().join("atomic");
        let plain = dir.path().join("plain");
        write_bytes(&atomic, b"x").unwrap();
        std::fs::write(&plain, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&atomic), mode(&plain));
    }

    #[test]
    fn a_missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write_bytes(&dir.path().join("no/such/dir/a.txt"), b"x").is_err());
    }

    fn classify(name: &str, is_dir: bool) -> Entry {
        match (name, is_dir) {
            ("results.json", false) => Entry::Ours,
            ("rounds", true) => Entry::Folder,
            (n, false) if n.starts_with("rounds/round-") => Entry::Ours,
            ("trials", true) => Entry::Ours,
            _ => Entry::Foreign,
        }
    }

    const POLICY: Ownership<'static> = Ownership {
        kind: "a test run",
        occupied: "holds another run",
        classify: &classify,
    };

    #[test]
    fn a_previous_run_is_replaced_only_with_force() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        drop(claim(&run, false, &POLICY).unwrap());
        std::fs::create_dir_all(run.join("rounds")).unwrap();
        std::fs::create_dir_all(run.join("trials/x")).unwrap();
        write_bytes(&run.join("results.json"), b"{}").unwrap();
        write_bytes(&run.join("rounds/round-0000.mcap"), b"m").unwrap();
        write_bytes(&run.join("trials/x/anything"), b"t").unwrap();
        let e = claim(&run, false, &POLICY).unwrap_err();
        assert_eq!(e.reason, "holds another run");
        assert!(run.join("results.json").exists());
        let lock = claim(&run, true, &POLICY).unwrap();
        assert_eq!(entries(&run), [LOCK_FILE]);
        assert!(DirLock::is_held(&run));
        drop(lock);
    }

    #[test]
    fn a_foreign_directory_is_left_as_it_was_found() {
        let dir = tempfile::tempdir().unwrap();
        let mine = dir.path().join("mine");
        std::fs::create_dir_all(mine.join("rounds")).unwrap();
        write_bytes(&mine.join("notes.txt"), b"keep").unwrap();
        write_bytes(&mine.join("rounds/holiday.jpg"), b"keep").unwrap();
        for force in [false, true] {
            let e = claim(&mine, force, &POLICY).unwrap_err();
            assert!(e.reason.contains("not part of a test run"), "{e}");
            assert_eq!(entries(&mine), ["notes.txt", "rounds"]);
            assert_eq!(entries(&mine.join("rounds")), ["holiday.jpg"]);
        }
        // A refused new directory is not created either.
        let foreign = |_: &str, _: bool| Entry::Foreign;
        let refusing = Ownership {
            classify: &foreign,
            ..POLICY
        };
        let fresh = dir.path().join("fresh");
        drop(claim(&fresh, false, &refusing).unwrap());
        write_bytes(&fresh.join("x"), b"x").unwrap();
        std::fs::remove_file(fresh.join(LOCK_FILE)).unwrap();
        assert!(claim(&fresh, true, &refusing).is_err());
        assert_eq!(entries(&fresh), ["x"]);
    }

    #[test]
    fn a_held_lock_refuses_a_second_writer() {
        let dir = tempfile::tempdir().unwrap();
        let _held = claim(dir.path(), false, &POLICY).unwrap();
        let e = claim(dir.path(), true, &POLICY).unwrap_err();
        assert!(e.reason.contains("another lgdm process"), "{e}");
    }
}
