//! `lgdm train`: run one of the paper's lifelong-learning scenarios over several trials and
//! write the model(s), `metrics.json`, `config.toml`, plots and a summary table.

use anyhow::{Context, Result};
use clap::Args as ClapArgs;
use lgdm_gdm::GdmConfig;
use lgdm_gdm::experiment::run_dir::{self, Provenance, Run, RunConfig};
use lgdm_gdm::experiment::{
    DEFAULT_EVAL_SAMPLES, DEFAULT_TRIALS, Experiment, Scenario, Settings, StepProgress,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::data::{self, Encoder};
use crate::progress::{ProgressMode, Reporter};
use crate::report;

/// Arguments of `lgdm train`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The learning protocol (see README, "Scenarios").
    #[arg(long, value_parser = scenario_parser())]
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
    #[arg(long, default_value_t = DEFAULT_TRIALS)]
    pub trials: usize,
    /// Trials run at the same time, in parallel threads (default: the number of cores). The
    /// results do not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
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
    #[arg(long, default_value_t = DEFAULT_EVAL_SAMPLES)]
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

/// `--scenario`'s parser: the library's names, listed in `--help`.
fn scenario_parser() -> impl clap::builder::TypedValueParser<Value = Scenario> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(Scenario::ALL.map(Scenario::name)).map(|s| {
        s.parse::<Scenario>()
            .expect("clap passes only listed names")
    })
}

/// The experiment settings of the arguments, and a note on where the hyperparameters came from.
fn settings(args: &Args) -> Result<(Settings, String)> {
    let mut settings = Settings::new(args.scenario);
    let from = if let Some(path) = &args.config {
        settings.config = read_config(path)?;
        format!("file {}", path.display())
    } else if let Some(name) = &args.preset {
        settings.config =
            GdmConfig::preset(name).with_context(|| format!("unknown preset {name:?}"))?;
        format!("preset {name}")
    } else {
        format!("preset {}", args.scenario.default_preset())
    };
    if args.no_context {
        settings = settings.without_context();
    }
    settings.trials = args.trials;
    settings.seed = args.seed;
    if args.no_replay {
        settings.replay = false;
    } else if args.replay {
        settings.replay = true;
    }
    if let Some(epochs) = args.epochs {
        settings.epochs = epochs;
    }
    settings.eval_every = args.eval_every;
    settings.eval_samples = args.eval_samples;
    settings.train_samples = args.train_samples;
    settings.validate = args.validate;
    Ok((settings, from))
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

/// `--jobs`, or the number of cores.
fn jobs(requested: Option<usize>) -> Result<usize> {
    match requested {
        Some(0) => anyhow::bail!("--jobs must be at least 1"),
        Some(n) => Ok(n),
        None => Ok(lgdm_gdm::experiment::default_jobs()),
    }
}

/// Runs `lgdm train`.
pub fn run(args: Args) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let (settings, from) = settings(&args)?;
    let jobs = jobs(args.jobs)?;
    let source = data::FeatureSource::resolve(args.encoder, args.ae_checkpoint.as_deref())?;
    let ds = data::open_dataset(args.dataset.as_deref(), &reporter)?;
    let features = data::features(&ds, &source, &reporter)?;
    let manifest = ds.manifest();
    let train_collections = manifest.collections_in(lgdm_pointcloud::dataset::Split::Train);
    let test_collections = manifest.collections_in(lgdm_pointcloud::dataset::Split::Test);
    let table = data::table(
        &features,
        &train_collections,
        &test_collections,
        &manifest.categories,
    );
    let experiment = Experiment::new(table, settings)?;
    if args.validate {
        reporter.message(&format!(
            "validation mode: collections {:?} are the evaluation set; the test collections are not used",
            experiment.test_collections()
        ));
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| default_run_dir(args.scenario));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let dataset = ds.dir().display().to_string();
    let provenance = Provenance {
        encoder: args.encoder.name().into(),
        dataset: dataset.clone(),
        hyperparameters_from: from,
        ae_checkpoint: source.ae_checkpoint().map(|p| p.display().to_string()),
        ae_checkpoint_fnv1a: source
            .ae_checkpoint()
            .map(|p| lgdm_pointcloud::cache::file_hash(p).map(|h| format!("{h:016x}")))
            .transpose()?,
    };
    let run_config = RunConfig::new(&experiment, &provenance);
    run_dir::write_atomic(
        &out.join(run_dir::CONFIG_FILE),
        run_config.to_toml().as_bytes(),
    )?;

    let s = experiment.settings();
    let steps = experiment.steps();
    reporter.message(&format!(
        "{}: {} trial(s) of {} steps on {} samples ({} features), replay {}, context {}, {} job(s)",
        s.scenario,
        s.trials,
        steps,
        features.len(),
        features.dim,
        if s.replay { "on" } else { "off" },
        if s.config.episodic.context_depth > 0 {
            "on"
        } else {
            "off"
        },
        jobs.min(s.trials),
    ));
    let total_steps = (steps * s.trials) as u64;
    let task = reporter.bar("train", total_steps);
    let done = AtomicU64::new(0);
    let on_step = |p: StepProgress| {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        task.update(&p.label, n.min(total_steps), total_steps);
        reporter.event(&serde_json::json!({ "event": "step", "progress": p }));
    };
    let trials = experiment.run_with(jobs, &on_step, &|t, gdm, record| {
        let model = out.join(run_dir::model_file(t));
        gdm.save(&model)
            .map_err(|e| lgdm_gdm::experiment::ExperimentError::Checkpoint {
                path: model.display().to_string(),
                source: e,
            })?;
        Ok(record)
    })?;
    task.finish();

    let metrics = experiment.metrics(trials, args.encoder.name(), &dataset);
    Run::write_files(&out, &run_config, &metrics)?;
    crate::plot::write_run_plots(&out, &metrics).context("drawing the plots")?;
    let table_text = report::summary_table(&metrics);
    run_dir::write_atomic(&out.join("summary.txt"), table_text.as_bytes())?;
    println!("{table_text}");
    println!("run directory: {}", out.display());
    Ok(())
}
