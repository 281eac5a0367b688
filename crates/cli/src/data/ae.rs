//! `--encoder ae` in the cli: resolving the checkpoint (also for `lgdm sim grasp --grasp
//! network`) and rendering the progress of `lgdm_pybridge::ae::dataset_features` (the view
//! pipeline: projection → preprocess → infer).
//! Needs the cargo feature `ae`; without it every entry point fails with how to rebuild and
//! what to install.

use std::path::{Path, PathBuf};

use anyhow::Result;
use lgdm_pointcloud::dataset::Dataset;
use lgdm_pointcloud::features::FeatureTable;

use crate::progress::Reporter;

/// Why `--encoder ae` cannot run in a build without the `ae` feature, and what to do.
#[cfg_attr(feature = "ae", allow(dead_code))]
pub const NOT_BUILT: &str = "--encoder ae needs the torch autoencoder, and this `lgdm` binary was \
built without the `ae` feature (the default build neither links libpython nor needs torch). \
Rebuild it with `cargo build --release -p lgdm-cli --features ae`, and install torch and the \
autoencoder package into a venv: `python3 -m venv ~/.cache/lgdm/venv && \
~/.cache/lgdm/venv/bin/pip install -e python/train_ae` (or activate your own venv, or set \
LGDM_VENV to it); see docs/guide/grasp-network.md. Or use --encoder good";

/// The checkpoint to use: `explicit` (`--ae-checkpoint`), else the one shipped with train_ae;
/// `user` is the option that needs it (`--encoder ae`, `--grasp network`), for messages.
#[cfg(not(feature = "ae"))]
pub fn resolve_checkpoint(_explicit: Option<&Path>, _user: &str) -> Result<PathBuf> {
    anyhow::bail!(NOT_BUILT)
}

/// Autoencoder features of every view.
#[cfg(not(feature = "ae"))]
pub fn features(_ds: &Dataset, _checkpoint: &Path, _reporter: &Reporter) -> Result<FeatureTable> {
    anyhow::bail!(NOT_BUILT)
}

#[cfg(feature = "ae")]
pub use with_ae::{PIPELINE, bridge_error, features, resolve_checkpoint};

/// The pipeline's cache-key part; without the feature nothing reaches the cache.
#[cfg(not(feature = "ae"))]
pub const PIPELINE: &str = "";

/// The autoencoder's feature dimension (`lgdm_pybridge::ae::FEATURE_DIM`).
#[cfg(not(feature = "ae"))]
pub const FEATURE_DIM: usize = 256;
#[cfg(feature = "ae")]
pub use lgdm_pybridge::ae::FEATURE_DIM;

#[cfg(feature = "ae")]
mod with_ae {
    use super::*;

    use anyhow::{Context, bail};
    use lgdm_pointcloud::Progress;
    use lgdm_pybridge::ae::{self, AE_BATCH, AeError};

    pub use lgdm_pybridge::ae::PIPELINE;

    /// Maps bridge errors to messages that read well after `error: `; `user` is the option
    /// that needed the autoencoder (`--encoder ae`, `--grasp network`).
    pub fn bridge_error(e: AeError, user: &str) -> anyhow::Error {
        match e {
            AeError::NoDefaultCheckpoint(_) => anyhow::anyhow!(
                "{user}: {e}; pass a checkpoint with --ae-checkpoint PATH (one written by \
                 `python -m train_ae.train`)"
            ),
            other => anyhow::Error::new(other).context(user.to_string()),
        }
    }

    /// The checkpoint to use: `explicit` (`--ae-checkpoint`), else the one shipped with
    /// train_ae (`train_ae.bridge.default_checkpoint()`); absolute. `user` is the option that
    /// needs it (`--encoder ae`, `--grasp network`), for messages.
    pub fn resolve_checkpoint(explicit: Option<&Path>, user: &str) -> Result<PathBuf> {
        let path = match explicit {
            Some(p) => {
                if !p.is_file() {
                    bail!("--ae-checkpoint {}: no such file", p.display());
                }
                p.to_path_buf()
            }
            None => ae::default_checkpoint().map_err(|e| bridge_error(e, user))?,
        };
        std::fs::canonicalize(&path).with_context(|| format!("resolving {}", path.display()))
    }

    /// Autoencoder features of every view of `ds` (`lgdm_pybridge::ae::dataset_features`), with
    /// a progress bar and a note on blank views.
    pub fn features(ds: &Dataset, checkpoint: &Path, reporter: &Reporter) -> Result<FeatureTable> {
        reporter.message(&format!(
            "autoencoder features: {} (batches of {AE_BATCH})",
            checkpoint.display()
        ));
        let task = reporter.bar("AE features", ds.manifest().views);
        let (table, stats) = ae::dataset_features(ds, checkpoint, &mut |p: Progress| {
            task.update(p.stage, p.done, p.total)
        })
        .map_err(|e| bridge_error(e, "--encoder ae"))?;
        task.finish();
        if stats.empty_views > 0 {
            reporter.message(&format!(
                "{} view(s) had no point in front of the camera: blank images",
                stats.empty_views
            ));
        }
        Ok(table)
    }
}
