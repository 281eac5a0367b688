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
use crate::output::outln;
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
    /// GOOD bins per projection side, 1..=256 (3 × bins² values).
    #[arg(long, default_value_t = 15, value_parser = parse_bins)]
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
    // The output may not land inside the dataset it is computed from (e.g. over manifest.json).
    let out_parent = match args.out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => std::path::Path::new("."),
    };
    if let (Ok(parent), Ok(dataset)) = (
        std::fs::canonicalize(out_parent),
        std::fs::canonicalize(ds.dir()),
    ) && parent.starts_with(&dataset)
    {
        anyhow::bail!(
            "--out {} is inside the dataset {} it reads; write the features elsewhere",
            args.out.display(),
            ds.dir().display()
        );
    }
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
        outln!(
            "wrote {}: {} views × {} {what} in {:.1} s",
            args.out.display(),
            table.len(),
            table.dim,
            elapsed
        )?;
    }
    Ok(())
}

/// `--bins`: a count in `1..=`[`lgdm_pointcloud::good::MAX_BINS`], checked by the library's own
/// check before any data is read.
fn parse_bins(text: &str) -> Result<usize, String> {
    let bins: usize = text
        .parse()
        .map_err(|e| format!("`{text}` is not a count: {e}"))?;
    lgdm_pointcloud::good::check_bins(bins).map_err(|e| e.to_string())?;
    Ok(bins)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn parse(bins: &str) -> Result<Args, clap::Error> {
        let bins = format!("--bins={bins}");
        Cli::try_parse_from(["lgdm", "--dataset", "d", "--out", "o.npz", &bins]).map(|c| c.args)
    }

    #[test]
    fn bins_are_bounded_on_the_command_line() {
        assert_eq!(parse("15").unwrap().bins, 15);
        assert_eq!(parse("256").unwrap().bins, 256);
        for bad in ["257", "100000", "0", "-3", "many"] {
            let err = parse(bad).expect_err(bad).to_string();
            assert!(err.contains("--bins"), "{bad}: {err}");
        }
        let err = parse("100000").unwrap_err().to_string();
        assert!(err.contains("1..=256"), "{err}");
    }
}
