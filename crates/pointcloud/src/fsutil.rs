//! Atomic file writes. Every file this crate writes (collections, manifest, grasp images and
//! rectangles, previews, feature tables) goes to a temporary file in the target's directory,
//! is flushed to disk and only then renamed over the target, so a failed or interrupted run
//! never leaves a half-written file under the final name.
//!
//! [`write_atomic`] writes a whole file from a closure; [`AtomicFile`] is the same for a writer
//! that stays open for a while (an MCAP collection) and is committed at the end. Both are
//! built on [`tempfile::NamedTempFile`], which removes the temporary file when it is dropped
//! without being committed. The target gets the permissions `File::create` would give it
//! (`0o666` minus the umask), not the `0o600` of a private temporary file.
//!
//! Errors are plain [`std::io::Error`]s; callers wrap them in their own error naming the path.

use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

/// A file being written under a temporary name next to `path`; [`AtomicFile::commit`] renames
/// it into place, dropping it removes it. Writes are buffered.
#[derive(Debug)]
pub(crate) struct AtomicFile {
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

/// Writes `path` atomically: `write` fills a buffered temporary file (seekable, for formats
/// such as TIFF that patch offsets), which is then synced and renamed over `path`. On error the
/// temporary file is removed and `path` is untouched.
pub(crate) fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut AtomicFile) -> io::Result<()>,
) -> io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(&mut file)?;
    file.commit().map(|_| ())
}

/// Writes `value` as pretty JSON with a final newline, atomically.
pub(crate) fn write_json_atomic<T: serde::Serialize + ?Sized>(
    path: &Path,
    value: &T,
) -> io::Result<()> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(io::Error::other)?;
        w.write_all(b"\n")
    })
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
        write_atomic(&path, |w| w.write_all(b"one")).unwrap();
        write_atomic(&path, |w| w.write_all(b"two")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(entries(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, |w| w.write_all(b"old")).unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("boom"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "boom");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.txt"]);
        // An abandoned AtomicFile disappears too.
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
        write_atomic(&atomic, |w| w.write_all(b"x")).unwrap();
        std::fs::write(&plain, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&atomic), mode(&plain));
    }

    #[test]
    fn a_missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/a.txt");
        assert!(write_atomic(&path, |w| w.write_all(b"x")).is_err());
    }
}
