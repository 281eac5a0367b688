//! `lgdm features`: compute one feature vector per view of a dataset and write them with their
//! labels as `.npz` (arrays `features`, `collection`, `category`, `instance`, `sequence`,
//! `frame`), which `numpy.load` reads directly.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use lgdm_pointcloud::dataset::{Dataset, Progress};
use lgdm_pointcloud::features::good_features;

use crate::progress::{ProgressMode, Reporter};

/// Feature backends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FeatureEncoder {
    /// The GOOD shape descriptor computed in Rust (3 × bins² values; 675 for 15 bins).
    Good,
    /// The torch grasp autoencoder's feature (not built yet).
    Ae,
}

/// Arguments of `lgdm features`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Feature backend.
    #[arg(long, value_enum, default_value = "good")]
    pub encoder: FeatureEncoder,
    /// Dataset directory (written by `lgdm gen-dataset`).
    #[arg(long)]
    pub dataset: PathBuf,
    /// Output `.npz` file.
    #[arg(long)]
    pub out: PathBuf,
    /// GOOD bins per projection side.
    #[arg(long, default_value_t = 15)]
    pub bins: usize,
    /// How to show progress.
    #[arg(long, value_enum, default_value = "bar")]
    pub progress: ProgressMode,
}

/// Runs `lgdm features`.
pub fn run(args: Args) -> Result<()> {
    if args.encoder == FeatureEncoder::Ae {
        bail!(
            "the autoencoder backend (--encoder ae) is not built yet: it needs the python/train_ae \
             package with torch behind the pyo3 bridge; use --encoder good"
        );
    }
    let reporter = Reporter::new(args.progress);
    let ds = Dataset::open(&args.dataset)
        .with_context(|| format!("opening the dataset in {}", args.dataset.display()))?;
    let started = Instant::now();
    let mut task = reporter.bar("features", 0);
    let table = good_features(&ds, args.bins, &mut |p: Progress| {
        task.update_coarse(p.stage, p.done, p.total)
    });
    task.finish();
    let table = table.context("computing GOOD features")?;
    table
        .write_npz(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let elapsed = started.elapsed().as_secs_f64();
    reporter.event(&serde_json::json!({
        "event": "done", "out": args.out.display().to_string(), "rows": table.len(),
        "dim": table.dim, "seconds": elapsed,
    }));
    if args.progress != ProgressMode::Jsonl {
        println!(
            "wrote {}: {} views × {} GOOD values in {:.1} s",
            args.out.display(),
            table.len(),
            table.dim,
            elapsed
        );
    }
    Ok(())
}
