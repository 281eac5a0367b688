//! `lgdm train`: run one of the paper's lifelong-learning scenarios over several trials and
//! write the model(s), `metrics.json`, `config.toml`, plots and a summary table.

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;
use lgdm_gdm::GdmConfig;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

use crate::data::{self, Encoder};
use crate::experiment::metrics::{RunMetrics, Summary};
use crate::experiment::scenario::Scenario;
use crate::experiment::{RunData, StepProgress, TrialSettings, run_trial};
use crate::progress::{ProgressMode, Reporter};
use crate::report;

/// Version of the `metrics.json` layout.
pub const METRICS_FORMAT_VERSION: u32 = 1;

/// Arguments of `lgdm train`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The learning protocol (see README, "Scenarios").
    #[arg(long, value_enum)]
    pub scenario: Scenario,
    /// Dataset directory written by `lgdm gen-dataset` (default: the embedded small dataset,
    /// generated into the cache directory on first use).
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// Feature encoder: good (GOOD descriptor, Rust) or ae (the torch autoencoder; needs a
    /// build with `--features ae` and torch + python/train_ae in a venv).
    #[arg(long, value_enum, default_value_t = Encoder::Good)]
    pub encoder: Encoder,
    /// Autoencoder checkpoint for `--encoder ae` (default: the one shipped with train_ae,
    /// `train_ae.bridge.default_checkpoint()`).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
    /// GDM hyperparameters from a TOML file (a `GdmConfig`, or a run's `config.toml`).
    #[arg(long, conflicts_with = "preset")]
    pub config: Option<PathBuf>,
    /// A named hyperparameter preset: paper_batch or paper_incremental, exactly as in the paper
    /// (default: the scenario's preset with thresholds calibrated for the encoder).
    #[arg(long)]
    pub preset: Option<String>,
    /// Number of trials (different seeds, orders and held-out instances) to average over.
    #[arg(long, default_value_t = 3)]
    pub trials: usize,
    /// Intrinsic replay after every step (default: on, except for batch).
    #[arg(long, overrides_with = "no_replay")]
    pub replay: bool,
    /// No intrinsic replay.
    #[arg(long)]
    pub no_replay: bool,
    /// Train without temporal context (K = 0).
    #[arg(long)]
    pub no_context: bool,
    /// Learning epochs per step (default: batch 35, others 1).
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Evaluate on the test set after every n-th step (default: often enough for ~25 points).
    #[arg(long)]
    pub eval_every: Option<usize>,
    /// Per-step evaluations use at most this many samples per set (whole sequences, drawn with
    /// the trial's seed); 0 = all. The final figures always use the whole test set.
    #[arg(long, default_value_t = 3000)]
    pub eval_samples: usize,
    /// Batch only: train on about N samples per epoch, the same per-trial subset of whole
    /// training sequences every epoch, N / categories per category (the paper's batch runs use
    /// 3000); 0 = all training sequences.
    #[arg(long, default_value_t = 0)]
    pub train_samples: usize,
    /// Validation mode for choosing hyperparameters: the last two training collections (in
    /// manifest order) stand in for the test set and the test collections are not touched.
    #[arg(long)]
    pub validate: bool,
    /// Base seed; trial t uses seed + t.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run directory (default: runs/<scenario>-<n>, the first free n).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
}

/// The settings of a run, as written to `config.toml`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunConfig {
    /// Scenario name.
    pub scenario: Scenario,
    /// Encoder name.
    pub encoder: String,
    /// Dataset directory.
    pub dataset: String,
    /// Trials.
    pub trials: usize,
    /// Base seed.
    pub seed: u64,
    /// Intrinsic replay.
    pub replay: bool,
    /// Epochs per step.
    pub epochs: usize,
    /// Evaluation period in steps.
    pub eval_every: usize,
    /// Per-step evaluation sample cap (0 = all).
    pub eval_samples: usize,
    /// Batch: training-sample cap per epoch (0 = all).
    #[serde(default)]
    pub train_samples: usize,
    /// Validation mode: the evaluation set is two training collections, not the test set.
    pub validate: bool,
    /// Where the hyperparameters came from.
    pub hyperparameters_from: String,
    /// `--encoder ae`: the checkpoint's path (absent for GOOD).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ae_checkpoint: Option<String>,
    /// `--encoder ae`: FNV-1a hash of the checkpoint's bytes, 16 hex digits (absent for GOOD).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ae_checkpoint_fnv1a: Option<String>,
    /// The dual memory's hyperparameters.
    pub gdm: GdmConfig,
}

#[derive(Deserialize)]
struct WithGdm {
    gdm: GdmConfig,
}

/// Reads hyperparameters from TOML: a bare `GdmConfig` or a run's `config.toml`.
pub fn read_config(path: &Path) -> Result<GdmConfig> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let config = match toml::from_str::<WithGdm>(&text) {
        Ok(w) => w.gdm,
        Err(_) => toml::from_str::<GdmConfig>(&text)
            .with_context(|| format!("parsing {}", path.display()))?,
    };
    config
        .validate()
        .with_context(|| format!("invalid hyperparameters in {}", path.display()))?;
    Ok(config)
}

/// The hyperparameters a run uses, and a note on where they came from.
pub fn resolve_config(args: &Args) -> Result<(GdmConfig, String)> {
    let (mut config, from) = if let Some(path) = &args.config {
        (read_config(path)?, format!("file {}", path.display()))
    } else if let Some(name) = &args.preset {
        (
            GdmConfig::preset(name).with_context(|| format!("unknown preset {name:?}"))?,
            format!("preset {name}"),
        )
    } else {
        let name = args.scenario.default_preset();
        let base = GdmConfig::preset(name).expect("built-in preset");
        (
            crate::calibration::calibrated(base, args.encoder),
            format!("preset {name}, calibrated for {}", args.encoder.name()),
        )
    };
    if args.no_context {
        config.episodic.context_depth = 0;
        config.semantic.context_depth = 0;
    }
    config.validate().context("invalid hyperparameters")?;
    Ok((config, from))
}

fn default_run_dir(scenario: Scenario) -> PathBuf {
    let mut n = 1;
    loop {
        let p = PathBuf::from("runs").join(format!("{}-{n}", scenario.name()));
        if !p.exists() {
            return p;
        }
        n += 1;
    }
}

/// Writes bytes to a file atomically (temp file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!(
        "{}.tmp",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Runs `lgdm train`.
pub fn run(args: Args) -> Result<()> {
    if args.trials == 0 {
        bail!("--trials must be at least 1");
    }
    if args.train_samples > 0 && args.scenario != Scenario::Batch {
        bail!("--train-samples applies to --scenario batch only");
    }
    if args.epochs == Some(0) {
        bail!("--epochs must be at least 1");
    }
    let reporter = Reporter::new(args.progress);
    let (config, from) = resolve_config(&args)?;
    let source = data::FeatureSource::resolve(args.encoder, args.ae_checkpoint.as_deref())?;
    let replay = if args.no_replay {
        false
    } else {
        args.replay || args.scenario.replay_by_default()
    };
    let ds = data::open_dataset(args.dataset.as_deref(), &reporter)?;
    let table = data::features(&ds, &source, &reporter)?;
    let manifest = ds.manifest();
    let split = |s| {
        manifest
            .collections
            .iter()
            .filter(|c| c.split == s)
            .map(|c| c.index)
            .collect::<Vec<u32>>()
    };
    let run_data = RunData {
        table: &table,
        train_collections: split(lgdm_pointcloud::dataset::Split::Train),
        test_collections: split(lgdm_pointcloud::dataset::Split::Test),
        category_names: manifest.categories.clone(),
    };
    let mut run_data = run_data;
    if args.validate {
        if run_data.train_collections.len() < 3 {
            bail!("--validate needs at least three training collections");
        }
        let k = run_data.train_collections.len() - 2;
        run_data.test_collections = run_data.train_collections.split_off(k);
        reporter.message(&format!(
            "validation mode: collections {:?} are the evaluation set; the test collections are not used",
            run_data.test_collections
        ));
    }
    if run_data.train_collections.is_empty() || run_data.test_collections.is_empty() {
        bail!("the dataset needs both training and test collections (see its manifest.json)");
    }
    let epochs = args
        .epochs
        .unwrap_or_else(|| args.scenario.default_epochs());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| default_run_dir(args.scenario));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;

    let base = TrialSettings {
        scenario: args.scenario,
        config: config.clone(),
        epochs,
        replay,
        eval_every: 1,
        eval_samples: args.eval_samples,
        train_samples: args.train_samples,
        seed: args.seed,
    };
    let steps = crate::experiment::plan_trial(&run_data, &base).steps.len();
    let eval_every = args.eval_every.unwrap_or_else(|| steps.div_ceil(25).max(1));
    let run_config = RunConfig {
        scenario: args.scenario,
        encoder: args.encoder.name().into(),
        dataset: ds.dir().display().to_string(),
        trials: args.trials,
        seed: args.seed,
        replay,
        epochs,
        eval_every,
        eval_samples: args.eval_samples,
        train_samples: args.train_samples,
        validate: args.validate,
        hyperparameters_from: from,
        ae_checkpoint: source.ae_checkpoint().map(|p| p.display().to_string()),
        ae_checkpoint_fnv1a: source
            .ae_checkpoint()
            .map(|p| data::file_hash(p).map(|h| format!("{h:016x}")))
            .transpose()?,
        gdm: config,
    };
    write_atomic(
        &out.join("config.toml"),
        toml::to_string_pretty(&run_config)?.as_bytes(),
    )?;

    reporter.message(&format!(
        "{}: {} trial(s) of {} steps on {} samples ({} features), replay {}, context {}",
        args.scenario.name(),
        args.trials,
        steps,
        table.len(),
        table.dim,
        if replay { "on" } else { "off" },
        if run_config.gdm.episodic.context_depth > 0 {
            "on"
        } else {
            "off"
        },
    ));
    let mut trials = Vec::with_capacity(args.trials);
    let total_steps = (steps * args.trials) as u64;
    let task = reporter.bar("train", total_steps);
    for t in 0..args.trials {
        let settings = TrialSettings {
            seed: args.seed + t as u64,
            eval_every,
            ..base.clone()
        };
        let mut on_step = |p: StepProgress| {
            task.update(&p.label, (t * steps + p.step) as u64, total_steps);
            reporter.event(&serde_json::json!({ "event": "step", "progress": p }));
        };
        let (gdm, record) = run_trial(&run_data, &settings, t, &mut on_step)?;
        let model = out.join(format!("model-trial{t}.lgdm"));
        gdm.save(&model)
            .with_context(|| format!("saving {}", model.display()))?;
        trials.push(record);
    }
    task.finish();

    let summary = Summary::of(&trials);
    let metrics = RunMetrics {
        format_version: METRICS_FORMAT_VERSION,
        scenario: args.scenario.name().into(),
        encoder: args.encoder.name().into(),
        dataset: ds.dir().display().to_string(),
        seed: args.seed,
        replay,
        context: run_config.gdm.episodic.context_depth > 0,
        epochs,
        categories: manifest.categories.clone(),
        trials,
        summary,
    };
    write_atomic(
        &out.join("metrics.json"),
        serde_json::to_string_pretty(&metrics)?.as_bytes(),
    )?;
    crate::plot::write_run_plots(&out, &metrics).context("drawing the plots")?;
    let table_text = report::summary_table(&metrics);
    write_atomic(&out.join("summary.txt"), table_text.as_bytes())?;
    println!("{table_text}");
    println!("run directory: {}", out.display());
    Ok(())
}
