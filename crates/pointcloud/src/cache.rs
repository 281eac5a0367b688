//! The user cache: the embedded default dataset (the `small` preset, generated on first use, so
//! `lgdm train --scenario ni` needs no download) and feature tables keyed by the dataset's files
//! and the encoder, so a second run on the same data skips feature extraction.
//!
//! The cache directory is `$LGDM_CACHE_DIR`, else `$XDG_CACHE_HOME/lgdm`, else `~/.cache/lgdm`
//! ([`cache_dir`]). Feature tables live in `<cache>/features/<key>-<encoder>.npz`; the key
//! ([`feature_key`]) changes when the encoder, its parameters, this crate's version, the
//! manifest or any collection file (size, modification time) changes.
//!
//! A cached table is used only if it still describes the dataset
//! ([`FeatureTable::check_dataset`]: exact dtypes, one row per view, labels consistent with the
//! manifest, the encoder's dimension, finite values). Anything else — an unreadable file, 10
//! columns instead of 675, a missing row, category 99, a NaN — is reported (path and reason)
//! and the table is computed again and rewritten (temp file + rename).
//!
//! ```no_run
//! use lgdm_pointcloud::cache::{self, FeatureCache};
//! use lgdm_pointcloud::dataset::Dataset;
//! let dir = cache::default_dataset(&cache::cache_dir()?, &mut |_| {})?;
//! let ds = Dataset::open(&dir)?;
//! let table = FeatureCache::new(&cache::cache_dir()?).good_features(&ds, &mut |_| {})?;
//! # Ok::<(), lgdm_pointcloud::dataset::DatasetError>(())
//! ```

use std::path::{Path, PathBuf};

use crate::Progress;
use crate::dataset::{self, Dataset, DatasetError, DatasetSpec};
use crate::features::{FeatureTable, good_features};

/// Seed of the embedded default dataset.
pub const DEFAULT_DATASET_SEED: u64 = 0;
/// Bins per side of the GOOD descriptor's projections that `lgdm` uses (15 → 675 values).
pub const GOOD_BINS: usize = 15;
/// Feature length of the GOOD descriptor with [`GOOD_BINS`]: `3 × 15² = 675`.
pub const GOOD_DIM: usize = 3 * GOOD_BINS * GOOD_BINS;

fn io_error(path: &Path, source: std::io::Error) -> DatasetError {
    DatasetError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The cache directory: `$LGDM_CACHE_DIR`, else `$XDG_CACHE_HOME/lgdm`, else `~/.cache/lgdm`.
pub fn cache_dir() -> Result<PathBuf, DatasetError> {
    if let Some(dir) = std::env::var_os("LGDM_CACHE_DIR") {
        return Ok(PathBuf::from(dir));
    }
    if let Some(dir) = std::env::var_os("XDG_CACHE_HOME") {
        return Ok(PathBuf::from(dir).join("lgdm"));
    }
    match std::env::var_os("HOME") {
        Some(home) => Ok(PathBuf::from(home).join(".cache").join("lgdm")),
        None => Err(io_error(
            Path::new("~/.cache/lgdm"),
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no cache directory: set LGDM_CACHE_DIR (or HOME)",
            ),
        )),
    }
}

/// Where the embedded default dataset lives under `cache` (generated there on first use).
pub fn default_dataset_dir(cache: &Path) -> PathBuf {
    cache.join("datasets").join(format!(
        "small-seed{}-v{}",
        DEFAULT_DATASET_SEED,
        env!("CARGO_PKG_VERSION")
    ))
}

/// The embedded default dataset's directory under `cache`, generated (the `small` preset, seed
/// [`DEFAULT_DATASET_SEED`]) into a temporary directory and renamed into place on first use.
pub fn default_dataset(
    cache: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<PathBuf, DatasetError> {
    let dir = default_dataset_dir(cache);
    if dir.join(dataset::MANIFEST_FILE).is_file() {
        return Ok(dir);
    }
    let spec = DatasetSpec::small(DEFAULT_DATASET_SEED);
    let parent = dir.parent().expect("joined path has a parent");
    std::fs::create_dir_all(parent).map_err(|e| io_error(parent, e))?;
    remove_stale_temp_dirs(parent);
    let tmp = parent.join(format!(
        ".tmp-{}-{}",
        std::process::id(),
        dir.file_name()
            .expect("joined path has a name")
            .to_string_lossy()
    ));
    if let Err(err) = dataset::generate(&spec, &tmp, progress) {
        std::fs::remove_dir_all(&tmp).ok();
        return Err(err);
    }
    match std::fs::rename(&tmp, &dir) {
        Ok(()) => Ok(dir),
        // Another process won the race: use its copy.
        Err(_) if dir.join(dataset::MANIFEST_FILE).is_file() => {
            std::fs::remove_dir_all(&tmp).ok();
            Ok(dir)
        }
        Err(e) => Err(io_error(&dir, e)),
    }
}

/// Removes the temporary dataset directories (`.tmp-*`) under `datasets` whose generating
/// process is gone (killed part way): a directory is stale when its lock can be taken. A
/// directory another live process is still generating keeps its lock and is left alone.
fn remove_stale_temp_dirs(datasets: &Path) {
    let Ok(entries) = std::fs::read_dir(datasets) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let stale = entry.file_name().to_string_lossy().starts_with(".tmp-")
            && path.is_dir()
            && matches!(crate::DirLock::try_acquire(&path), Ok(Some(_)));
        if stale {
            std::fs::remove_dir_all(&path).ok();
        }
    }
}

/// FNV-1a offset basis.
pub const FNV1A_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a, 64 bit: a stable hash for cache keys and file identities.
pub fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// FNV-1a hash of a file's bytes (e.g. an autoencoder checkpoint's identity).
pub fn file_hash(path: &Path) -> Result<u64, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| io_error(path, e))?;
    Ok(fnv1a(FNV1A_START, &bytes))
}

/// A key that changes when the dataset's files, the encoder (`encoder`, the GOOD bins this
/// crate's version) or the encoder's own identity (`extra`, e.g. an autoencoder's pipeline
/// version and checkpoint hash) change.
pub fn feature_key(ds: &Dataset, encoder: &str, extra: &[&[u8]]) -> Result<u64, DatasetError> {
    let mut h = FNV1A_START;
    h = fnv1a(h, encoder.as_bytes());
    h = fnv1a(h, &(GOOD_BINS as u64).to_le_bytes());
    h = fnv1a(h, env!("CARGO_PKG_VERSION").as_bytes());
    for part in extra {
        h = fnv1a(h, part);
    }
    let manifest = ds.dir().join(dataset::MANIFEST_FILE);
    h = fnv1a(
        h,
        &std::fs::read(&manifest).map_err(|e| io_error(&manifest, e))?,
    );
    for c in &ds.manifest().collections {
        let path = ds.dir().join(&c.file);
        let meta = std::fs::metadata(&path).map_err(|e| io_error(&path, e))?;
        h = fnv1a(h, c.file.as_bytes());
        h = fnv1a(h, &meta.len().to_le_bytes());
        if let Ok(t) = meta.modified()
            && let Ok(d) = t.duration_since(std::time::UNIX_EPOCH)
        {
            h = fnv1a(h, &d.as_nanos().to_le_bytes());
        }
    }
    Ok(h)
}

/// Feature tables cached under `<cache>/features`.
#[derive(Debug, Clone)]
pub struct FeatureCache {
    dir: PathBuf,
}

impl FeatureCache {
    /// The feature cache of cache directory `cache`.
    pub fn new(cache: &Path) -> FeatureCache {
        FeatureCache {
            dir: cache.join("features"),
        }
    }

    /// The cached table of `ds` for `encoder` (with its `extra` identity, see [`feature_key`]),
    /// or `compute()`'s, which is then stored. A cache file that cannot be read or does not
    /// describe `ds` ([`FeatureTable::check_dataset`], any number of columns) is reported to
    /// `on_broken` (path, reason) and replaced. Prefer
    /// [`FeatureCache::get_or_compute_with_dim`], which also checks the feature length.
    pub fn get_or_compute<E: From<DatasetError>>(
        &self,
        ds: &Dataset,
        encoder: &str,
        extra: &[&[u8]],
        compute: impl FnOnce() -> Result<FeatureTable, E>,
        on_broken: &mut dyn FnMut(&Path, String),
    ) -> Result<FeatureTable, E> {
        self.get_or_compute_checked(ds, encoder, extra, None, compute, on_broken)
    }

    /// [`FeatureCache::get_or_compute`] for an encoder that gives `dim` values per view: a
    /// cached table with another number of columns is reported and replaced too, and a
    /// computed table that does not describe `ds` with `dim` columns is an error
    /// ([`DatasetError::FeatureTable`]) and is not stored.
    pub fn get_or_compute_with_dim<E: From<DatasetError>>(
        &self,
        ds: &Dataset,
        encoder: &str,
        extra: &[&[u8]],
        dim: usize,
        compute: impl FnOnce() -> Result<FeatureTable, E>,
        on_broken: &mut dyn FnMut(&Path, String),
    ) -> Result<FeatureTable, E> {
        self.get_or_compute_checked(ds, encoder, extra, Some(dim), compute, on_broken)
    }

    fn get_or_compute_checked<E: From<DatasetError>>(
        &self,
        ds: &Dataset,
        encoder: &str,
        extra: &[&[u8]],
        dim: Option<usize>,
        compute: impl FnOnce() -> Result<FeatureTable, E>,
        on_broken: &mut dyn FnMut(&Path, String),
    ) -> Result<FeatureTable, E> {
        let key = feature_key(ds, encoder, extra)?;
        let path = self.dir.join(format!("{key:016x}-{encoder}.npz"));
        if path.is_file() {
            match FeatureTable::read_npz_exact(&path) {
                Ok(t) => match t.check_dataset(ds.manifest(), dim) {
                    Ok(()) => return Ok(t),
                    Err(reason) => on_broken(
                        &path,
                        format!(
                            "does not match the dataset {}: {reason}",
                            ds.dir().display()
                        ),
                    ),
                },
                Err(e) => on_broken(&path, e.to_string()),
            }
        }
        let table = compute()?;
        table
            .check_dataset(ds.manifest(), dim)
            .map_err(|reason| DatasetError::FeatureTable {
                dataset: ds.dir().to_path_buf(),
                reason: format!("the `{encoder}` encoder's table: {reason}"),
            })?;
        std::fs::create_dir_all(&self.dir).map_err(|e| io_error(&self.dir, e))?;
        table
            .write_npz(&path)
            .map_err(|e| io_error(&path, std::io::Error::other(e.to_string())))?;
        Ok(table)
    }

    /// GOOD features ([`GOOD_BINS`] bins per side) of `ds`, cached.
    pub fn good_features(
        &self,
        ds: &Dataset,
        progress: &mut dyn FnMut(Progress),
    ) -> Result<FeatureTable, DatasetError> {
        self.get_or_compute_with_dim(
            ds,
            "good",
            &[],
            GOOD_DIM,
            || good_features(ds, GOOD_BINS, progress),
            &mut |_, _| {},
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_reference_values() {
        // Reference vectors of FNV-1a 64 (Fowler, Noll, Vo).
        assert_eq!(fnv1a(FNV1A_START, b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(FNV1A_START, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(FNV1A_START, b"foobar"), 0x8594_4171_f739_67e8);
    }
}
