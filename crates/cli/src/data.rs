//! Where runs get their data: the embedded default dataset (generated into a cache directory on
//! first use) and per-dataset, per-encoder feature caches.
//!
//! Features come from a [`FeatureSource`]: GOOD (Rust, always built) or the torch autoencoder
//! with a checkpoint (`--encoder ae`, module [`ae`]; cargo feature `ae`).

mod ae;

use anyhow::{Context, Result, bail};
use lgdm_pointcloud::dataset::{self, Dataset, DatasetSpec, Progress};
use lgdm_pointcloud::features::FeatureTable;
use std::path::{Path, PathBuf};

use crate::progress::Reporter;

/// Seed of the embedded default dataset.
pub const DEFAULT_DATASET_SEED: u64 = 0;
/// Bins per side of the GOOD descriptor's projections (15 → 675 values).
pub const GOOD_BINS: usize = 15;

/// The feature encoders `lgdm` knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Encoder {
    /// The hand-crafted GOOD descriptor (675 values), computed in Rust.
    Good,
    /// The torch grasp autoencoder's 256-d feature (needs python/train_ae and torch).
    Ae,
}

impl Encoder {
    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Encoder::Good => "good",
            Encoder::Ae => "ae",
        }
    }
}

/// What computes a dataset's features: an encoder and, for the autoencoder, its checkpoint.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FeatureSource {
    /// The GOOD descriptor ([`GOOD_BINS`] bins per side).
    Good,
    /// The autoencoder's 256-d feature, from this checkpoint.
    Ae {
        /// The checkpoint file (absolute).
        checkpoint: PathBuf,
    },
}

impl FeatureSource {
    /// Checks that `encoder` can run in this build and resolves the autoencoder's checkpoint:
    /// `ae_checkpoint` (`--ae-checkpoint`), else the one shipped with train_ae. Fails early, before
    /// any data is read, when the binary lacks the `ae` feature or no checkpoint can be found.
    pub fn resolve(encoder: Encoder, ae_checkpoint: Option<&Path>) -> Result<FeatureSource> {
        match encoder {
            Encoder::Good => {
                if let Some(p) = ae_checkpoint {
                    bail!(
                        "--ae-checkpoint {} only applies to --encoder ae (the encoder is good)",
                        p.display()
                    );
                }
                Ok(FeatureSource::Good)
            }
            Encoder::Ae => Ok(FeatureSource::Ae {
                checkpoint: ae::resolve_checkpoint(ae_checkpoint)?,
            }),
        }
    }

    /// The encoder.
    pub fn encoder(&self) -> Encoder {
        match self {
            FeatureSource::Good => Encoder::Good,
            FeatureSource::Ae { .. } => Encoder::Ae,
        }
    }

    /// The autoencoder checkpoint, if this source has one.
    pub fn ae_checkpoint(&self) -> Option<&Path> {
        match self {
            FeatureSource::Good => None,
            FeatureSource::Ae { checkpoint } => Some(checkpoint),
        }
    }
}

/// The cache directory: `$LGDM_CACHE_DIR`, else `$XDG_CACHE_HOME/lgdm`, else `~/.cache/lgdm`.
pub fn cache_dir() -> Result<PathBuf> {
    if let Some(dir) = std::env::var_os("LGDM_CACHE_DIR") {
        return Ok(PathBuf::from(dir));
    }
    if let Some(dir) = std::env::var_os("XDG_CACHE_HOME") {
        return Ok(PathBuf::from(dir).join("lgdm"));
    }
    match std::env::var_os("HOME") {
        Some(home) => Ok(PathBuf::from(home).join(".cache").join("lgdm")),
        None => bail!("no cache directory: set LGDM_CACHE_DIR (or HOME)"),
    }
}

/// Where the embedded default dataset lives (generated there on first use).
pub fn default_dataset_dir() -> Result<PathBuf> {
    Ok(cache_dir()?.join("datasets").join(format!(
        "small-seed{}-v{}",
        DEFAULT_DATASET_SEED,
        env!("CARGO_PKG_VERSION")
    )))
}

/// The embedded default dataset: the `small` preset, generated on first use.
pub fn default_dataset(reporter: &Reporter) -> Result<PathBuf> {
    let spec = DatasetSpec::small(DEFAULT_DATASET_SEED);
    let dir = default_dataset_dir()?;
    if dir.join("manifest.json").is_file() {
        return Ok(dir);
    }
    reporter.message(&format!(
        "generating the embedded default dataset (small preset) into {} (first use only)",
        dir.display()
    ));
    let parent = dir.parent().expect("joined path has a parent");
    std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
    let tmp = parent.join(format!(
        ".tmp-{}-{}",
        std::process::id(),
        dir.file_name().unwrap().to_string_lossy()
    ));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).ok();
    }
    let bar = reporter.bar("dataset", 0);
    let result = dataset::generate(&spec, &tmp, &mut |p: Progress| {
        bar.update(p.stage, p.done, p.total)
    });
    bar.finish();
    if let Err(err) = result {
        std::fs::remove_dir_all(&tmp).ok();
        return Err(err).context("generating the embedded default dataset");
    }
    match std::fs::rename(&tmp, &dir) {
        Ok(()) => Ok(dir),
        // Another process won the race: use its copy.
        Err(_) if dir.join("manifest.json").is_file() => {
            std::fs::remove_dir_all(&tmp).ok();
            Ok(dir)
        }
        Err(e) => Err(e).with_context(|| format!("moving the dataset into {}", dir.display())),
    }
}

/// FNV-1a, 64 bit: a stable hash for cache keys.
pub fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// FNV-1a offset basis.
pub const FNV1A_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a hash of a file's bytes (the autoencoder checkpoint's identity).
pub fn file_hash(path: &Path) -> Result<u64> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(fnv1a(FNV1A_START, &bytes))
}

/// A key that changes when the dataset's files, the encoder or the autoencoder checkpoint's
/// bytes change.
fn feature_key(ds: &Dataset, source: &FeatureSource) -> Result<u64> {
    let mut h = FNV1A_START;
    h = fnv1a(h, source.encoder().name().as_bytes());
    h = fnv1a(h, &(GOOD_BINS as u64).to_le_bytes());
    h = fnv1a(h, env!("CARGO_PKG_VERSION").as_bytes());
    if let Some(checkpoint) = source.ae_checkpoint() {
        h = fnv1a(h, ae::PIPELINE.as_bytes());
        h = fnv1a(h, &file_hash(checkpoint)?.to_le_bytes());
    }
    let manifest = ds.dir().join("manifest.json");
    h = fnv1a(
        h,
        &std::fs::read(&manifest).with_context(|| format!("reading {}", manifest.display()))?,
    );
    for c in &ds.manifest().collections {
        let path = ds.dir().join(&c.file);
        let meta =
            std::fs::metadata(&path).with_context(|| format!("reading {}", path.display()))?;
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

/// Computes a dataset's features, or reads them from the cache.
pub fn features(ds: &Dataset, source: &FeatureSource, reporter: &Reporter) -> Result<FeatureTable> {
    let key = feature_key(ds, source)?;
    let dir = cache_dir()?.join("features");
    let path = dir.join(format!("{key:016x}-{}.npz", source.encoder().name()));
    if path.is_file() {
        match FeatureTable::read_npz(&path) {
            Ok(t) => return Ok(t),
            Err(e) => reporter.message(&format!(
                "ignoring a broken feature cache {}: {e}",
                path.display()
            )),
        }
    }
    let table = compute_features(ds, source, reporter)?;
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let tmp = dir.join(format!(".tmp-{}-{key:016x}.npz", std::process::id()));
    table
        .write_npz(&tmp)
        .with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("writing {}", path.display()))?;
    Ok(table)
}

/// Computes features without the cache.
pub fn compute_features(
    ds: &Dataset,
    source: &FeatureSource,
    reporter: &Reporter,
) -> Result<FeatureTable> {
    match source {
        FeatureSource::Good => {
            let bar = reporter.bar("GOOD features", 0);
            let t = lgdm_pointcloud::features::good_features(ds, GOOD_BINS, &mut |p: Progress| {
                bar.update(p.stage, p.done, p.total)
            })
            .context("computing GOOD features")?;
            bar.finish();
            Ok(t)
        }
        FeatureSource::Ae { checkpoint } => ae::features(ds, checkpoint, reporter),
    }
}

/// The experiment library's view of a feature table, with the manifest's split and names.
pub fn table<'a>(
    features: &'a FeatureTable,
    train_collections: &'a [u32],
    test_collections: &'a [u32],
    category_names: &'a [String],
) -> lgdm_gdm::experiment::Table<'a> {
    lgdm_gdm::experiment::Table {
        features: &features.features,
        dim: features.dim,
        collection: &features.collection,
        category: &features.category,
        instance: &features.instance,
        sequence: &features.sequence,
        frame: &features.frame,
        train_collections,
        test_collections,
        category_names,
    }
}

/// Opens the dataset named on the command line, or the embedded default.
pub fn open_dataset(dir: Option<&Path>, reporter: &Reporter) -> Result<Dataset> {
    let dir = match dir {
        Some(d) => d.to_path_buf(),
        None => default_dataset(reporter)?,
    };
    Dataset::open(&dir).with_context(|| format!("opening the dataset in {}", dir.display()))
}
