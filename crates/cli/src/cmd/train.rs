//! `lgdm train`: run one of the paper's lifelong-learning scenarios over several trials and
//! write the model(s), `metrics.json`, `config.toml`, plots and a summary table into a run
//! directory it owns (`lgdm_gdm::experiment::run_dir::RunDir`): a fresh one, an old run replaced
//! with `--force`, or an interrupted run finished with `--resume`.

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;
use lgdm_gdm::GdmConfig;
use lgdm_gdm::experiment::run_dir::{Provenance, RunConfig, RunDir};
use lgdm_gdm::experiment::{Experiment, Scenario, Settings, StepProgress};
use lgdm_gdm::learner::LearnerKind;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::data::{self, Encoder};
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};
use lgdm_gdm::experiment::report::summary_table;

/// Flags that describe the experiment: none of them may accompany `--resume`.
const EXPERIMENT_FLAGS: [&str; 18] = [
    "scenario",
    "learner",
    "dataset",
    "encoder",
    "ae_checkpoint",
    "config",
    "preset",
    "trials",
    "replay",
    "no_replay",
    "no_context",
    "epochs",
    "eval_every",
    "eval_samples",
    "train_samples",
    "validate",
    "seed",
    "out",
];

/// Arguments of `lgdm train`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The learning protocol (see docs/guide/training.md, "Scenarios"); may be left out with
    /// `--config` of a run's config.toml (the run's scenario) or `--resume`.
    #[arg(long, value_parser = scenario_parser())]
    pub scenario: Option<Scenario>,
    /// What learns: gdm (the Growing Dual-Memory network; default), slda (streaming linear
    /// discriminant analysis) or ncm (nearest class mean) — the baselines on the same features,
    /// plans, trials and seeds, with a per-instance and a per-category head (docs/guide/training.md,
    /// "Baselines"). Replay, temporal context and the hyperparameters are the GDM's only.
    #[arg(long, value_parser = learner_parser())]
    pub learner: Option<LearnerKind>,
    /// Dataset directory written by `lgdm gen-dataset` (default: the embedded small dataset,
    /// generated into the cache directory on first use).
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// Feature encoder: good (GOOD descriptor, Rust; default) or ae (the torch autoencoder;
    /// needs a build with `--features ae` and torch + python/train_ae in a venv).
    #[arg(long, value_enum)]
    pub encoder: Option<Encoder>,
    /// Autoencoder checkpoint for `--encoder ae` (default: the one shipped with train_ae,
    /// `train_ae.bridge.default_checkpoint()`).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
    /// Settings from a TOML file: a `GdmConfig` (hyperparameters only), or a run's
    /// `config.toml`, whose every setting (scenario, dataset, encoder, trials, seed, replay,
    /// epochs, evaluation, hyperparameters) is used unless a flag says otherwise.
    #[arg(long, conflicts_with = "preset")]
    pub config: Option<PathBuf>,
    /// A named hyperparameter preset: paper_batch or paper_incremental, exactly as in the paper
    /// (default: the scenario's preset).
    #[arg(long)]
    pub preset: Option<String>,
    /// Number of trials (different seeds, orders and held-out instances) to average over
    /// (default: 3).
    #[arg(long)]
    pub trials: Option<usize>,
    /// Trials run at the same time, in parallel threads (default: the number of cores). The
    /// results do not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Intrinsic replay after every step (default: on, except for batch).
    #[arg(long, conflicts_with = "no_replay")]
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
    /// the trial's seed); 0 = all (default: 3000). The final figures always use the whole test
    /// set.
    #[arg(long)]
    pub eval_samples: Option<usize>,
    /// Batch only: train on about N samples per epoch, the same per-trial subset of whole
    /// training sequences every epoch, N / categories per category (the paper's batch runs use
    /// 3000); 0 = all training sequences (default).
    #[arg(long)]
    pub train_samples: Option<usize>,
    /// Validation mode for choosing hyperparameters: the last two training collections (in
    /// manifest order) stand in for the test set and the test collections are not touched;
    /// the instances each trial holds out are not read either, and one more instance per
    /// category (where two are left) stands in for them.
    #[arg(long)]
    pub validate: bool,
    /// Base seed; trial t uses seed + t (default: 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Run directory (default: runs/<scenario>-<n>, the first free n). It must be new or empty.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the run already in `--out` (its files are removed first).
    #[arg(long, requires = "out")]
    pub force: bool,
    /// Finish the interrupted run in this directory with its own settings: the trials it
    /// recorded are kept, the others are run; the result is what an uninterrupted run gives.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = EXPERIMENT_FLAGS, conflicts_with = "force")]
    pub resume: Option<PathBuf>,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
}

/// What `--config` held.
enum ConfigFile {
    /// Hyperparameters only.
    Gdm(Box<GdmConfig>),
    /// A run's config.toml.
    Run(Box<RunConfig>),
}

/// Reads `--config`: a run's `config.toml` (it has a `[gdm]` table) or a bare `GdmConfig`;
/// errors name the offending key and line.
fn read_config(path: &Path) -> Result<ConfigFile> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let file = if table.contains_key("gdm") {
        let run = RunConfig::from_toml(&text)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .with_context(|| format!("parsing the run config {}", path.display()))?;
        ConfigFile::Run(Box::new(run))
    } else {
        ConfigFile::Gdm(Box::new(toml::from_str::<GdmConfig>(&text).with_context(
            || format!("parsing the hyperparameters in {}", path.display()),
        )?))
    };
    let gdm = match &file {
        ConfigFile::Gdm(g) => g,
        ConfigFile::Run(r) => &r.gdm,
    };
    gdm.validate()
        .with_context(|| format!("invalid hyperparameters in {}", path.display()))?;
    Ok(file)
}

/// `--scenario`'s parser: the library's names, listed in `--help`.
fn scenario_parser() -> impl clap::builder::TypedValueParser<Value = Scenario> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(Scenario::ALL.map(Scenario::name)).map(|s| {
        s.parse::<Scenario>()
            .expect("clap passes only listed names")
    })
}

/// `--learner`'s parser: the library's names, listed in `--help`.
fn learner_parser() -> impl clap::builder::TypedValueParser<Value = LearnerKind> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(LearnerKind::ALL.map(LearnerKind::name)).map(|s| {
        s.parse::<LearnerKind>()
            .expect("clap passes only listed names")
    })
}

/// What a run needs besides its settings: the data and where the settings came from.
struct Plan {
    settings: Settings,
    from: String,
    encoder: Encoder,
    dataset: Option<PathBuf>,
    ae_checkpoint: Option<PathBuf>,
}

/// The experiment of the arguments: defaults from the library (or a run's config.toml given
/// with `--config`), then the flags.
fn plan(args: &Args, reporter: &Reporter) -> Result<Plan> {
    let config = args.config.as_deref().map(read_config).transpose()?;
    let (mut settings, mut from, mut encoder, mut dataset, mut ae_checkpoint) = match config {
        Some(ConfigFile::Run(run)) => {
            let path = args.config.as_deref().expect("read from --config");
            if let Some(s) = args.scenario
                && s != run.scenario
            {
                bail!(
                    "{} is a {} run's config; --scenario {s} differs (leave --scenario out to \
                     use the run's)",
                    path.display(),
                    run.scenario
                );
            }
            let encoder = match run.encoder.as_str() {
                "good" => Encoder::Good,
                "ae" => Encoder::Ae,
                other => bail!("{}: unknown encoder {other:?}", path.display()),
            };
            reporter.message(&format!(
                "settings from the run config {}: scenario {}, {} trial(s), seed {}, replay {}, \
                 {} epoch(s), eval every {} step(s), encoder {}, dataset {} (flags override)",
                path.display(),
                run.scenario,
                run.trials,
                run.seed,
                if run.replay { "on" } else { "off" },
                run.epochs,
                run.eval_every,
                run.encoder,
                run.dataset
            ));
            (
                run.settings(),
                format!("run config {}", path.display()),
                encoder,
                Some(PathBuf::from(&run.dataset)),
                run.ae_checkpoint.as_ref().map(PathBuf::from),
            )
        }
        other => {
            let Some(scenario) = args.scenario else {
                bail!("--scenario is required (or --config with a run's config.toml, or --resume)");
            };
            let mut settings = Settings::new(scenario);
            let from = match (other, &args.preset) {
                (Some(ConfigFile::Gdm(gdm)), _) => {
                    settings.config = *gdm;
                    format!("file {}", args.config.as_deref().expect("read").display())
                }
                (_, Some(name)) => {
                    settings.config = GdmConfig::preset(name)
                        .with_context(|| format!("unknown preset {name:?}"))?;
                    format!("preset {name}")
                }
                _ => format!("preset {}", scenario.default_preset()),
            };
            (settings, from, Encoder::Good, None, None)
        }
    };
    if let Some(learner) = args.learner {
        settings.learner = learner;
    }
    if !settings.learner.is_gdm() {
        let learner = settings.learner;
        let gdm_only = [
            (args.replay, "--replay"),
            (args.preset.is_some(), "--preset"),
            (
                args.config.is_some() && !from.starts_with("run config"),
                "--config with hyperparameters",
            ),
        ];
        if let Some((_, flag)) = gdm_only.iter().find(|(given, _)| *given) {
            bail!(
                "{flag} applies to --learner gdm only: the {learner} learner has no replay,                  temporal context or hyperparameters"
            );
        }
        // A baseline has no replay: off unless asked for (refused above).
        settings.replay = false;
        if !from.starts_with("run config") {
            from = format!("none (the {learner} learner has no hyperparameters)");
        }
    }
    if args.no_context {
        settings = settings.without_context();
    }
    if let Some(t) = args.trials {
        settings.trials = t;
    }
    if let Some(seed) = args.seed {
        settings.seed = seed;
    }
    if args.no_replay {
        settings.replay = false;
    } else if args.replay {
        settings.replay = true;
    }
    if let Some(epochs) = args.epochs {
        settings.epochs = epochs;
    }
    if args.eval_every.is_some() {
        settings.eval_every = args.eval_every;
    }
    if let Some(n) = args.eval_samples {
        settings.eval_samples = n;
    }
    if let Some(n) = args.train_samples {
        settings.train_samples = n;
    }
    if args.validate {
        settings.validate = true;
    }
    if let Some(e) = args.encoder {
        if e != encoder {
            ae_checkpoint = None;
        }
        encoder = e;
    }
    if args.ae_checkpoint.is_some() {
        ae_checkpoint = args.ae_checkpoint.clone();
    }
    if args.dataset.is_some() {
        dataset = args.dataset.clone();
    }
    if encoder == Encoder::Good {
        if let Some(p) = &args.ae_checkpoint {
            bail!(
                "--ae-checkpoint {} only applies to --encoder ae (the encoder is good)",
                p.display()
            );
        }
        ae_checkpoint = None;
    }
    Ok(Plan {
        settings,
        from,
        encoder,
        dataset,
        ae_checkpoint,
    })
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
pub(crate) fn jobs(requested: Option<usize>) -> Result<usize> {
    match requested {
        Some(0) => bail!("--jobs must be at least 1"),
        Some(n) => Ok(n),
        None => Ok(lgdm_gdm::experiment::default_jobs()),
    }
}

/// The experiment of a run being resumed: its own settings, read from its `config.toml`.
fn resumed_plan(dir: &Path) -> Result<Plan> {
    let config = RunConfig::read(dir)?;
    let encoder = match config.encoder.as_str() {
        "good" => Encoder::Good,
        "ae" => Encoder::Ae,
        other => bail!("{}: unknown encoder {other:?}", dir.display()),
    };
    Ok(Plan {
        settings: config.settings(),
        from: config.hyperparameters_from,
        encoder,
        dataset: Some(PathBuf::from(config.dataset)),
        ae_checkpoint: config.ae_checkpoint.map(PathBuf::from),
    })
}

/// Runs `lgdm train`.
pub fn run(args: Args) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let jobs = jobs(args.jobs)?;
    // The settings, the encoder and the data are all checked before the run directory is taken
    // (created, replaced with --force, or locked to resume): a refused run leaves it as it was
    // found, and --force removes an old run only for a run that starts.
    let plan = match &args.resume {
        Some(dir) => resumed_plan(dir)?,
        None => plan(&args, &reporter)?,
    };
    let source = data::FeatureSource::resolve(plan.encoder, plan.ae_checkpoint.as_deref())?;
    let ds = data::open_dataset(plan.dataset.as_deref(), &reporter)?;
    let features = data::features(&ds, &source, &reporter)?;
    let manifest = ds.manifest();
    let train_collections = manifest.collections_in(lgdm_pointcloud::dataset::Split::Train);
    let test_collections = manifest.collections_in(lgdm_pointcloud::dataset::Split::Test);
    let instance_names: Vec<String> = manifest.instances.iter().map(|i| i.name.clone()).collect();
    let table = data::table(
        &features,
        &train_collections,
        &test_collections,
        &manifest.categories,
        &instance_names,
    );
    let experiment = Experiment::new(table, plan.settings)?;
    if experiment.settings().validate {
        reporter.message(&format!(
            "validation mode: collections {:?} are the evaluation set; the test collections are not used",
            experiment.test_collections()
        ));
    }
    let dataset = ds.dir().display().to_string();
    let provenance = Provenance {
        encoder: plan.encoder.name().into(),
        dataset: dataset.clone(),
        hyperparameters_from: plan.from,
        ae_checkpoint: source.ae_checkpoint().map(|p| p.display().to_string()),
        ae_checkpoint_fnv1a: source
            .ae_checkpoint()
            .map(|p| lgdm_pointcloud::cache::file_hash(p).map(|h| format!("{h:016x}")))
            .transpose()?,
    };
    let run_config = RunConfig::new(&experiment, &provenance);
    let s = experiment.settings();
    let (run_dir, finished) = match &args.resume {
        Some(dir) => {
            let run_dir = RunDir::resume(dir, &run_config)?;
            let finished = run_dir.finished_trials(s.trials)?;
            (run_dir, finished)
        }
        None => {
            let out = args
                .out
                .clone()
                .unwrap_or_else(|| default_run_dir(s.scenario));
            let run_dir = RunDir::create(&out, args.force)?;
            run_dir.write_config(&run_config)?;
            (run_dir, vec![None; s.trials])
        }
    };
    let todo: Vec<usize> = (0..s.trials).filter(|&t| finished[t].is_none()).collect();
    let steps = experiment.steps();
    if args.resume.is_some() {
        reporter.message(&format!(
            "resuming {}: {} of {} trial(s) recorded, running {:?}",
            run_dir.path().display(),
            s.trials - todo.len(),
            s.trials,
            todo
        ));
    }
    reporter.message(&format!(
        "{}: learner {}, {} trial(s) of {} steps on {} samples ({} features), replay {}, context {}, \
         {} job(s)",
        s.scenario,
        s.learner,
        todo.len(),
        steps,
        features.len(),
        features.dim,
        if s.replay {
            format!("on (chains of {})", s.config.replay_chain_length())
        } else {
            "off".into()
        },
        if s.learner.is_gdm() && s.config.episodic.context_depth > 0 {
            "on"
        } else {
            "off"
        },
        jobs.min(todo.len()).max(1),
    ));
    let total_steps = (steps * todo.len()) as u64;
    let task = reporter.bar("train", total_steps);
    let done = AtomicU64::new(0);
    let on_step = |p: StepProgress| {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        task.update(&p.label, n.min(total_steps), total_steps);
        reporter.event(&serde_json::json!({ "event": "step", "progress": p }));
    };
    let metrics = run_dir.play(
        &experiment,
        finished,
        jobs,
        &on_step,
        plan.encoder.name(),
        &dataset,
    );
    task.finish();
    let metrics = metrics?;
    let out = run_dir.path();
    let table_text = summary_table(&metrics);
    outln!("{table_text}")?;
    outln!("run directory: {}", out.display())?;
    Ok(())
}
