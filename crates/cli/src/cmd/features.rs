//! `lgdm features`: compute one feature vector per view of a dataset and write them with their
//! labels as `.npz` (arrays `features`, `collection`, `category`, `instance`, `sequence`,
//! `frame`), which `numpy.load` reads directly.
//!
//! `--encoder good` (default) computes GOOD descriptors in Rust; `--encoder ae` runs the torch
//! autoencoder (build with `--features ae`) and also fills the feature cache `lgdm train` reads.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use lgdm_pointcloud::dataset::{Dataset, Progress};
use lgdm_pointcloud::features::good_features;

use crate::data::{self, Encoder, FeatureSource};
use crate::progress::{ProgressMode, Reporter};

/// Arguments of `lgdm features`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Feature backend: good (GOOD descriptor, 3 × bins² values) or ae (the torch autoencoder's
    /// 256-d feature; needs a build with `--features ae` and torch + python/train_ae in a venv).
    #[arg(long, value_enum, default_value = "good")]
    pub encoder: Encoder,
    /// Dataset directory (written by `lgdm gen-dataset`).
    #[arg(long)]
    pub dataset: PathBuf,
    /// Output `.npz` file.
    #[arg(long)]
    pub out: PathBuf,
    /// GOOD bins per projection side.
    #[arg(long, default_value_t = 15)]
    pub bins: usize,
    /// Autoencoder checkpoint for `--encoder ae` (default: the one shipped with train_ae,
    /// `train_ae.bridge.default_checkpoint()`).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
    /// How to show progress.
    #[arg(long, value_enum, default_value = "bar")]
    pub progress: ProgressMode,
}

/// Runs `lgdm features`.
pub fn run(args: Args) -> Result<()> {
    let source = FeatureSource::resolve(args.encoder, args.ae_checkpoint.as_deref())?;
    if source != FeatureSource::Good && args.bins != 15 {
        bail!("--bins only applies to --encoder good");
    }
    let reporter = Reporter::new(args.progress);
    let ds = Dataset::open(&args.dataset)
        .with_context(|| format!("opening the dataset in {}", args.dataset.display()))?;
    let started = Instant::now();
    let table = match &source {
        FeatureSource::Good => {
            let mut task = reporter.bar("features", 0);
            let table = good_features(&ds, args.bins, &mut |p: Progress| {
                task.update_coarse(p.stage, p.done, p.total)
            });
            task.finish();
            table.context("computing GOOD features")?
        }
        // Through the cache, so a later `lgdm train --encoder ae` on this dataset and
        // checkpoint reuses the result.
        FeatureSource::Ae { .. } => data::features(&ds, &source, &reporter)?,
    };
    table
        .write_npz(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let elapsed = started.elapsed().as_secs_f64();
    reporter.event(&serde_json::json!({
        "event": "done", "out": args.out.display().to_string(), "rows": table.len(),
        "dim": table.dim, "seconds": elapsed, "encoder": args.encoder.name(),
        "ae_checkpoint": source.ae_checkpoint().map(|p| p.display().to_string()),
    }));
    if args.progress != ProgressMode::Jsonl {
        let what = match source {
            FeatureSource::Good => "GOOD values",
            FeatureSource::Ae { .. } => "autoencoder values",
        };
        println!(
            "wrote {}: {} views × {} {what} in {:.1} s",
            args.out.display(),
            table.len(),
            table.dim,
            elapsed
        );
    }
    Ok(())
}
