//! `lgdm info`: version, cache locations and the embedded defaults.

use crate::data;

/// Prints the version, the cache directory and the embedded defaults.
pub fn run() -> anyhow::Result<()> {
    println!("lgdm {}", env!("CARGO_PKG_VERSION"));
    match (data::cache_dir(), data::default_dataset_dir()) {
        (Ok(dir), Ok(dataset)) => {
            println!("cache directory      {}", dir.display());
            println!(
                "embedded dataset     {} (small preset, seed {}, generated on first use)",
                dataset.display(),
                data::DEFAULT_DATASET_SEED
            );
        }
        (Err(e), _) | (_, Err(e)) => println!("cache directory      unavailable: {e}"),
    }
    println!(
        "default encoder      good (GOOD descriptor, {} bins per side → {} values)",
        data::GOOD_BINS,
        3 * data::GOOD_BINS * data::GOOD_BINS
    );
    println!(
        "autoencoder          {}",
        if cfg!(feature = "ae") {
            "--encoder ae built in (torch + train_ae from $VIRTUAL_ENV, $LGDM_VENV or ~/.cache/lgdm/venv)"
        } else {
            "--encoder ae not built in (rebuild with `cargo build --release -p lgdm-cli --features ae`)"
        }
    );
    println!(
        "presets              {}",
        lgdm_gdm::config::PRESETS.join(", ")
    );
    Ok(())
}
