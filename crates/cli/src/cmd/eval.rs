//! `lgdm eval`: score a saved model on a dataset's collections: instance and category accuracy,
//! a category confusion matrix (CSV + PNG), model size and inference time per sample.

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;
use lgdm_gdm::experiment::evaluate;
use lgdm_gdm::{Gdm, PredictOptions};
use lgdm_pointcloud::dataset::Split;
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::data::{self, Encoder};
use crate::progress::{ProgressMode, Reporter};
use lgdm_gdm::experiment::run_dir::write_atomic;

/// Which collections to score.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EvalSplit {
    /// The test collections of the manifest.
    Test,
    /// The training collections.
    Train,
    /// Every collection.
    All,
}

/// Arguments of `lgdm eval`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// A model checkpoint written by `lgdm train` (`model-trial0.lgdm`).
    #[arg(long)]
    pub model: PathBuf,
    /// Dataset directory (default: the embedded small dataset).
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// Feature encoder the model was trained with.
    #[arg(long, value_enum, default_value_t = Encoder::Good)]
    pub encoder: Encoder,
    /// Autoencoder checkpoint for `--encoder ae`: the one the model was trained with (see the
    /// run's config.toml; default: the one shipped with train_ae).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
    /// Collections to score.
    #[arg(long, value_enum, default_value_t = EvalSplit::Test)]
    pub split: EvalSplit,
    /// Predict without temporal context (K = 0 at test time).
    #[arg(long)]
    pub no_context: bool,
    /// Where to write confusion.csv, confusion.png and eval.json (default: beside the model).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
}

/// Runs `lgdm eval`.
pub fn run(args: Args) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let source = data::FeatureSource::resolve(args.encoder, args.ae_checkpoint.as_deref())?;
    let gdm = Gdm::load(&args.model)
        .with_context(|| format!("loading the model {}", args.model.display()))?;
    let ds = data::open_dataset(args.dataset.as_deref(), &reporter)?;
    let table = data::features(&ds, &source, &reporter)?;
    if table.dim != gdm.dim() {
        bail!(
            "the model expects {}-d features but the {} encoder gives {}-d: was it trained with another encoder?",
            gdm.dim(),
            args.encoder.name(),
            table.dim
        );
    }
    let manifest = ds.manifest();
    let wanted: Vec<u32> = match args.split {
        EvalSplit::All => manifest.collections.iter().map(|c| c.index).collect(),
        EvalSplit::Test => manifest.collections_in(Split::Test),
        EvalSplit::Train => manifest.collections_in(Split::Train),
    };
    let view = data::table(&table, &[], &[], &manifest.categories);
    let e = evaluate(
        &gdm,
        &view,
        &wanted,
        PredictOptions {
            no_context: args.no_context,
        },
    )?;
    let size_mb = gdm.size_bytes() as f64 / 1e6;
    let result = serde_json::json!({
        "model": args.model.display().to_string(),
        "dataset": ds.dir().display().to_string(),
        "split": format!("{:?}", args.split).to_lowercase(),
        "context": !args.no_context,
        "n": e.n,
        "instance_accuracy": e.instance_accuracy,
        "category_accuracy_em": e.category_accuracy_em,
        "category_accuracy_sm": e.category_accuracy_sm,
        "episodic_nodes": gdm.episodic().len(),
        "semantic_nodes": gdm.semantic().len(),
        "model_size_mb": size_mb,
        "inference_ms_per_sample": e.ms_per_sample,
    });

    let out = match &args.out {
        Some(d) => d.clone(),
        None => args
            .model
            .parent()
            .map(|p| p.to_path_buf())
            .unwrap_or_default()
            .join("eval"),
    };
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let mut csv = String::from("true\\predicted");
    for name in &manifest.categories {
        let _ = write!(csv, ",{name}");
    }
    csv.push_str(",none\n");
    for (c, row) in e.confusion.iter().enumerate() {
        csv.push_str(&manifest.categories[c]);
        for v in row {
            let _ = write!(csv, ",{v}");
        }
        csv.push('\n');
    }
    write_atomic(&out.join("confusion.csv"), csv.as_bytes())?;
    let n_cat = manifest.categories.len();
    let square: Vec<Vec<u64>> = e.confusion.iter().map(|r| r[..n_cat].to_vec()).collect();
    crate::plot::write_confusion_png(&out.join("confusion.png"), &manifest.categories, &square)?;
    write_atomic(
        &out.join("eval.json"),
        serde_json::to_string_pretty(&result)?.as_bytes(),
    )?;

    println!(
        "model {} on {} ({} samples, {:?} collections, context {})",
        args.model.display(),
        ds.dir().display(),
        e.n,
        args.split,
        if args.no_context { "off" } else { "on" }
    );
    println!(
        "instance accuracy (G-EM)   {:6.2} %",
        100.0 * e.instance_accuracy
    );
    println!(
        "category accuracy (G-EM)   {:6.2} %",
        100.0 * e.category_accuracy_em
    );
    println!(
        "category accuracy (G-SM)   {:6.2} %",
        100.0 * e.category_accuracy_sm
    );
    println!(
        "nodes G-EM / G-SM          {} / {}",
        gdm.episodic().len(),
        gdm.semantic().len()
    );
    println!("model size                 {size_mb:.3} MB");
    println!(
        "inference time             {:.4} ms/sample",
        e.ms_per_sample
    );
    println!(
        "confusion matrix           {}",
        out.join("confusion.csv").display()
    );
    Ok(())
}
