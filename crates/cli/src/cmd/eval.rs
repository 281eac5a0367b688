//! `lgdm eval`: score a saved model on a dataset's collections: instance and category accuracy,
//! a category confusion matrix (CSV + PNG), model size and inference time per sample.

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;
use lgdm_gdm::{Gdm, PredictOptions, Sample};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

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
    let wanted: Vec<u32> = manifest
        .collections
        .iter()
        .filter(|c| match args.split {
            EvalSplit::All => true,
            EvalSplit::Test => c.split == lgdm_pointcloud::dataset::Split::Test,
            EvalSplit::Train => c.split == lgdm_pointcloud::dataset::Split::Train,
        })
        .map(|c| c.index)
        .collect();
    // Rows grouped by sequence, frames in order, so the temporal context runs as in training.
    let mut by_seq: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for i in 0..table.len() {
        if wanted.contains(&table.collection[i]) {
            by_seq.entry(table.sequence[i]).or_default().push(i);
        }
    }
    let mut rows = Vec::new();
    for mut seq in by_seq.into_values() {
        seq.sort_by_key(|&i| table.frame[i]);
        rows.extend(seq);
    }
    if rows.is_empty() {
        bail!("no samples in the selected collections");
    }
    let samples: Vec<Sample<'_>> = rows
        .iter()
        .map(|&i| Sample {
            x: table.row(i),
            sequence: table.sequence[i],
            instance: Some(table.instance[i]),
            category: Some(table.category[i]),
        })
        .collect();
    let opts = PredictOptions {
        no_context: args.no_context,
    };
    let t0 = Instant::now();
    let predictions = gdm.predict(&samples, opts).context("predicting")?;
    let ms_per_sample = t0.elapsed().as_secs_f64() * 1e3 / samples.len() as f64;

    let n_cat = manifest.categories.len();
    let mut confusion = vec![vec![0u64; n_cat + 1]; n_cat];
    let (mut inst_hits, mut cat_em_hits, mut cat_sm_hits) = (0usize, 0usize, 0usize);
    for (s, p) in samples.iter().zip(&predictions) {
        inst_hits += usize::from(p.instance == s.instance);
        cat_em_hits += usize::from(p.category_em == s.category);
        cat_sm_hits += usize::from(p.category == s.category);
        let truth = s.category.unwrap_or(0) as usize;
        let predicted = p.category.map_or(n_cat, |c| (c as usize).min(n_cat));
        if truth < n_cat {
            confusion[truth][predicted] += 1;
        }
    }
    let n = samples.len() as f64;
    let size_mb = gdm.size_bytes() as f64 / 1e6;
    let result = serde_json::json!({
        "model": args.model.display().to_string(),
        "dataset": ds.dir().display().to_string(),
        "split": format!("{:?}", args.split).to_lowercase(),
        "context": !args.no_context,
        "n": samples.len(),
        "instance_accuracy": inst_hits as f64 / n,
        "category_accuracy_em": cat_em_hits as f64 / n,
        "category_accuracy_sm": cat_sm_hits as f64 / n,
        "episodic_nodes": gdm.episodic().len(),
        "semantic_nodes": gdm.semantic().len(),
        "model_size_mb": size_mb,
        "inference_ms_per_sample": ms_per_sample,
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
    for (c, row) in confusion.iter().enumerate() {
        csv.push_str(&manifest.categories[c]);
        for v in row {
            let _ = write!(csv, ",{v}");
        }
        csv.push('\n');
    }
    write_atomic(&out.join("confusion.csv"), csv.as_bytes())?;
    let square: Vec<Vec<u64>> = confusion.iter().map(|r| r[..n_cat].to_vec()).collect();
    crate::plot::write_confusion_png(&out.join("confusion.png"), &manifest.categories, &square)?;
    write_atomic(
        &out.join("eval.json"),
        serde_json::to_string_pretty(&result)?.as_bytes(),
    )?;

    println!(
        "model {} on {} ({} samples, {:?} collections, context {})",
        args.model.display(),
        ds.dir().display(),
        samples.len(),
        args.split,
        if args.no_context { "off" } else { "on" }
    );
    println!(
        "instance accuracy (G-EM)   {:6.2} %",
        100.0 * inst_hits as f64 / n
    );
    println!(
        "category accuracy (G-EM)   {:6.2} %",
        100.0 * cat_em_hits as f64 / n
    );
    println!(
        "category accuracy (G-SM)   {:6.2} %",
        100.0 * cat_sm_hits as f64 / n
    );
    println!(
        "nodes G-EM / G-SM          {} / {}",
        gdm.episodic().len(),
        gdm.semantic().len()
    );
    println!("model size                 {size_mb:.3} MB");
    println!("inference time             {ms_per_sample:.4} ms/sample");
    println!(
        "confusion matrix           {}",
        out.join("confusion.csv").display()
    );
    Ok(())
}
