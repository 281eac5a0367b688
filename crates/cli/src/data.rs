//! Where the cli's commands get their data: the dataset named on the command line or the
//! embedded default, and features from a [`FeatureSource`] — GOOD (`lgdm_pointcloud`, always
//! built) or the torch autoencoder with a checkpoint (`--encoder ae`, `lgdm_pybridge::ae`,
//! cargo feature `ae`) — through the feature cache (`lgdm_pointcloud::cache`). This module
//! chooses and renders progress; the work is the libraries'.

pub mod ae;

use anyhow::{Context, Result, bail};
use lgdm_pointcloud::cache::{self, FeatureCache, GOOD_BINS};
use lgdm_pointcloud::dataset::{self, Dataset, Progress};
use lgdm_pointcloud::features::FeatureTable;
use std::path::{Path, PathBuf};

use crate::progress::Reporter;

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
                checkpoint: ae::resolve_checkpoint(ae_checkpoint, "--encoder ae")?,
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

    /// The feature dimension this source gives (known before any feature is computed).
    pub fn dim(&self) -> usize {
        match self {
            FeatureSource::Good => 3 * GOOD_BINS * GOOD_BINS,
            FeatureSource::Ae { .. } => ae::FEATURE_DIM,
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

/// The cache directory (`lgdm_pointcloud::cache::cache_dir`).
pub fn cache_dir() -> Result<PathBuf> {
    Ok(cache::cache_dir()?)
}

/// The embedded default dataset (`lgdm_pointcloud::cache::default_dataset`), with a bar.
pub fn default_dataset(reporter: &Reporter) -> Result<PathBuf> {
    let cache = cache_dir()?;
    let dir = cache::default_dataset_dir(&cache);
    if !dir.join(dataset::MANIFEST_FILE).is_file() {
        reporter.message(&format!(
            "generating the embedded default dataset (small preset) into {} (first use only)",
            dir.display()
        ));
    }
    let bar = reporter.bar("dataset", 0);
    let dir = cache::default_dataset(&cache, &mut |p: Progress| {
        bar.update(p.stage, p.done, p.total)
    })
    .context("generating the embedded default dataset")?;
    bar.finish();
    Ok(dir)
}

/// Computes a dataset's features, or reads them from the cache
/// (`lgdm_pointcloud::cache::FeatureCache`, keyed by the dataset's files and the source).
pub fn features(ds: &Dataset, source: &FeatureSource, reporter: &Reporter) -> Result<FeatureTable> {
    let checkpoint_hash = source
        .ae_checkpoint()
        .map(|c| cache::file_hash(c).map(u64::to_le_bytes))
        .transpose()?;
    let extra: Vec<&[u8]> = match &checkpoint_hash {
        Some(hash) => vec![ae::PIPELINE.as_bytes(), hash],
        None => vec![],
    };
    FeatureCache::new(&cache_dir()?).get_or_compute_with_dim(
        ds,
        source.encoder().name(),
        &extra,
        source.dim(),
        || compute_features(ds, source, reporter),
        &mut |path, e| {
            reporter.message(&format!(
                "ignoring a broken feature cache {}: {e}",
                path.display()
            ))
        },
    )
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
    instance_names: &'a [String],
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
        instance_names,
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
