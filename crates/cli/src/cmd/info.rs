//! `lgdm info`: version, cache locations and the embedded defaults.

use lgdm_pointcloud::cache::{self, DEFAULT_DATASET_SEED, GOOD_BINS};

use crate::output::outln;

/// Prints the version, the cache directory and the embedded defaults.
pub fn run() -> anyhow::Result<()> {
    outln!("lgdm {}", env!("CARGO_PKG_VERSION"))?;
    match cache::cache_dir() {
        Ok(dir) => {
            outln!("cache directory      {}", dir.display())?;
            outln!(
                "embedded dataset     {} (small preset, seed {DEFAULT_DATASET_SEED}, generated on first use)",
                cache::default_dataset_dir(&dir).display(),
            )?;
        }
        Err(e) => outln!("cache directory      unavailable: {e}")?,
    }
    outln!(
        "default encoder      good (GOOD descriptor, {} bins per side → {} values)",
        GOOD_BINS,
        3 * GOOD_BINS * GOOD_BINS
    )?;
    outln!(
        "autoencoder          {}",
        if cfg!(feature = "ae") {
            "--encoder ae built in (torch + train_ae from $VIRTUAL_ENV, $LGDM_VENV or ~/.cache/lgdm/venv)"
        } else {
            "--encoder ae not built in (rebuild with `cargo build --release -p lgdm-cli --features ae`)"
        }
    )?;
    outln!(
        "presets              {}",
        lgdm_gdm::config::PRESETS.join(", ")
    )?;
    Ok(())
}
