//! `lgdm eval`: score a saved model of any learner (the GDM, or a `--learner slda|ncm` baseline)
//! on a dataset's collections: instance and category accuracy, a category confusion matrix (CSV +
//! PNG), model size and inference time per sample.

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;
use lgdm_gdm::PredictOptions;
use lgdm_gdm::experiment::evaluate;
use lgdm_gdm::learner::{Learner, Model};
use lgdm_pointcloud::dataset::Split;
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::data::{self, Encoder};
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};
use lgdm_gdm::experiment::run_dir::{self, write_atomic};

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
    /// A model file written by `lgdm train` (`model-trial0.lgdm`), of any learner.
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
    /// Where to write confusion.csv, confusion.png and eval.json (default: `eval/` beside the
    /// model). An earlier evaluation there is replaced; a directory holding anything else (a
    /// training run, other files) is refused.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Score the model even though the dataset's category or instance names differ from those
    /// of the run that trained it (its metrics.json beside the model).
    #[arg(long)]
    pub allow_other_labels: bool,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
}

/// Whether two paths name the same file (both resolved where they exist).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Compares the dataset's names with those the model's run recorded (metrics.json beside the
/// model): a model of other categories would be scored against the wrong names.
fn check_labels(
    args: &Args,
    categories: &[String],
    instances: &[lgdm_pointcloud::dataset::InstanceInfo],
    reporter: &Reporter,
) -> Result<()> {
    let Some(dir) = args.model.parent() else {
        return Ok(());
    };
    let path = dir.join(run_dir::METRICS_FILE);
    let Ok(text) = std::fs::read_to_string(&path) else {
        reporter.message(&format!(
            "note: no run record ({}) beside the model: its category names cannot be checked \
             against the dataset's",
            path.display()
        ));
        return Ok(());
    };
    let run: lgdm_gdm::experiment::RunMetrics =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let names: Vec<String> = instances.iter().map(|i| i.name.clone()).collect();
    let mismatch = if run.categories != categories {
        Some(format!(
            "the model's run learnt categories {:?}, the dataset has {:?}",
            run.categories, categories
        ))
    } else if !run.instances.is_empty() && run.instances != names {
        Some(format!(
            "the model's run learnt instances {:?}, the dataset has {:?}",
            run.instances, names
        ))
    } else {
        None
    };
    match mismatch {
        Some(m) if !args.allow_other_labels => bail!(
            "{m} ({}); scores would compare unrelated labels. Pass --allow-other-labels to score \
             it anyway",
            path.display()
        ),
        Some(m) => reporter.message(&format!("warning: {m}")),
        None => {}
    }
    Ok(())
}

/// Runs `lgdm eval`.
pub fn run(args: Args) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let source = data::FeatureSource::resolve(args.encoder, args.ae_checkpoint.as_deref())?;
    let model = Model::load(&args.model)
        .with_context(|| format!("loading the model {}", args.model.display()))?;
    if args.no_context && !model.kind().is_gdm() {
        bail!(
            "--no-context applies to a GDM model only: {} is a model of the {} learner, which has \
             no temporal context",
            args.model.display(),
            model.kind()
        );
    }
    if source.dim() != model.dim() {
        bail!(
            "the model expects {}-d features but the {} encoder gives {}-d: was it trained with another encoder?",
            model.dim(),
            args.encoder.name(),
            source.dim()
        );
    }
    let out = match &args.out {
        Some(d) => d.clone(),
        None => args
            .model
            .parent()
            .map(|p| p.to_path_buf())
            .unwrap_or_default()
            .join(run_dir::EVAL_DIR),
    };
    for name in std::iter::once("").chain(run_dir::EVAL_FILES) {
        let target = if name.is_empty() {
            out.clone()
        } else {
            out.join(name)
        };
        if same_file(&target, &args.model) {
            bail!(
                "--out {} would write {} over the model being scored ({}); choose another --out",
                out.display(),
                target.display(),
                args.model.display()
            );
        }
    }
    let ds = data::open_dataset(args.dataset.as_deref(), &reporter)?;
    let manifest = ds.manifest();
    check_labels(&args, &manifest.categories, &manifest.instances, &reporter)?;
    let table = data::features(&ds, &source, &reporter)?;
    let wanted: Vec<u32> = match args.split {
        EvalSplit::All => manifest.collections.iter().map(|c| c.index).collect(),
        EvalSplit::Test => manifest.collections_in(Split::Test),
        EvalSplit::Train => manifest.collections_in(Split::Train),
    };
    let view = data::table(&table, &[], &[], &manifest.categories, &[]);
    let e = evaluate(
        &model,
        &view,
        &wanted,
        PredictOptions {
            no_context: args.no_context,
        },
    )?;
    let size_mb = model.size_bytes() as f64 / 1e6;
    let (episodic_nodes, semantic_nodes) = model.nodes();
    let result = serde_json::json!({
        "model": args.model.display().to_string(),
        "dataset": ds.dir().display().to_string(),
        "split": format!("{:?}", args.split).to_lowercase(),
        "learner": model.kind().name(),
        "context": model.kind().is_gdm() && !args.no_context,
        "n": e.n,
        "instance_accuracy": e.instance_accuracy,
        "category_accuracy_em": e.category_accuracy_em,
        "category_accuracy_sm": e.category_accuracy_sm,
        "episodic_nodes": episodic_nodes,
        "semantic_nodes": semantic_nodes,
        "model_size_mb": size_mb,
        "inference_ms_per_sample": e.ms_per_sample,
    });

    // Held while the files are written; an earlier evaluation's files are replaced, a directory
    // holding anything else is refused untouched.
    let _lock = run_dir::claim_eval_dir(&out)?;
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
    let png = out.join("confusion.png");
    lgdm_base::plot::heat_map(
        &png,
        "Category confusion (rows: true, columns: predicted)",
        &manifest.categories,
        &square,
    )
    .with_context(|| format!("writing {}", png.display()))?;
    write_atomic(
        &out.join("eval.json"),
        serde_json::to_string_pretty(&result)?.as_bytes(),
    )?;

    outln!(
        "model {} ({}) on {} ({} samples, {:?} collections, context {})",
        args.model.display(),
        model.kind(),
        ds.dir().display(),
        e.n,
        args.split,
        if model.kind().is_gdm() && !args.no_context {
            "on"
        } else {
            "off"
        }
    )?;
    outln!(
        "instance accuracy (G-EM)   {:6.2} %",
        100.0 * e.instance_accuracy
    )?;
    outln!(
        "category accuracy (G-EM)   {:6.2} %",
        100.0 * e.category_accuracy_em
    )?;
    outln!(
        "category accuracy (G-SM)   {:6.2} %",
        100.0 * e.category_accuracy_sm
    )?;
    outln!(
        "{}{episodic_nodes} / {semantic_nodes}",
        if model.kind().is_gdm() {
            "nodes G-EM / G-SM          "
        } else {
            "class means inst. / cat.   "
        }
    )?;
    outln!("model size                 {size_mb:.3} MB")?;
    outln!(
        "inference time             {:.4} ms/sample",
        e.ms_per_sample
    )?;
    outln!(
        "confusion matrix           {}",
        out.join("confusion.csv").display()
    )?;
    Ok(())
}
