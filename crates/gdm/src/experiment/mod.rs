//! Lifelong-learning experiments: the paper's scenarios run over trials on a labelled feature
//! table, with every figure recorded — the one implementation behind `lgdm train`, `lgdm merge`
//! and the Python `lgdm.run_scenario`.
//!
//! - [`plan`]: the scenarios (batch, incremental, NI, NC, NIC) as per-trial plans, the
//!   held-out-instance split and the NIC step rule.
//! - [`records`]: what a run measures (per step, per trial, summary over trials), i.e. the
//!   contents of `metrics.json`.
//! - [`evaluation`]: a trained model scored on some collections (`lgdm eval`).
//! - [`forgetting`]: the accuracy matrix over tasks and ACC, BWT, F.
//! - [`run_dir`]: the run-directory format (`config.toml`, `metrics.json`, `model-trial<t>.lgdm`)
//!   and the merge of single-trial runs.
//!
//! The data is a [`Table`]: features plus collection / category / instance / sequence / frame
//! ids per row, the manifest's train and test collections and the category names. The crate
//! knows nothing of point clouds: where the features come from is the caller's business.
//!
//! ```
//! use lgdm_gdm::experiment::{Experiment, Scenario, Settings, Table};
//!
//! // 4 collections (3 train, 1 test) × 2 categories × 2 instances × 3 frames of 2-D features.
//! let (mut x, mut collection, mut category, mut instance, mut sequence, mut frame) =
//!     (vec![], vec![], vec![], vec![], vec![], vec![]);
//! for c in 0..4u32 {
//!     for i in 0..4u32 {
//!         for f in 0..3u32 {
//!             x.extend([(i / 2) as f32 + 0.01 * f as f32, 0.1 * (i % 2) as f32]);
//!             collection.push(c);
//!             category.push(i / 2);
//!             instance.push(i);
//!             sequence.push(u64::from(c * 10 + i));
//!             frame.push(f);
//!         }
//!     }
//! }
//! let names = vec!["mug".to_string(), "bowl".to_string()];
//! let table = Table {
//!     features: &x, dim: 2, collection: &collection, category: &category,
//!     instance: &instance, sequence: &sequence, frame: &frame,
//!     train_collections: &[0, 1, 2], test_collections: &[3], category_names: &names,
//!     instance_names: &[],
//! };
//! let mut settings = Settings::new(Scenario::Ni);
//! settings.trials = 2;
//! let experiment = Experiment::new(table, settings)?;
//! let trials = experiment.run(2, &|_progress| {})?;
//! let metrics = experiment.metrics(trials.into_iter().map(|(_, t)| t).collect(), "toy", "");
//! assert_eq!(metrics.trials.len(), 2);
//! assert!(metrics.summary.test_category_accuracy_sm.mean > 0.5);
//! # Ok::<(), lgdm_gdm::experiment::ExperimentError>(())
//! ```

pub mod evaluation;
pub mod forgetting;
pub mod plan;
pub mod plots;
pub mod records;
pub mod report;
pub mod run_dir;
mod runner;

use rayon::prelude::*;

pub use evaluation::{Evaluation, evaluate, rows_in_sequence_order};
pub use plan::{EvalScope, Plan, Rows, Scenario, Step};
pub use records::{Figures, MeanStd, RunMetrics, StepRecord, Summary, TrialRecord};
pub use runner::{stratified_subset, subsample};

use crate::learner::{LearnerKind, Model};
use crate::{CheckpointError, GdmConfig, GdmError, Sample};
use runner::TrialSettings;

/// Trials per experiment unless the caller says otherwise.
pub const DEFAULT_TRIALS: usize = 3;
/// Per-step evaluations use at most this many samples per set unless the caller says otherwise.
pub const DEFAULT_EVAL_SAMPLES: usize = 3000;
/// Per-step evaluations aim at about this many points per trial when `eval_every` is not given.
pub const EVAL_POINTS: usize = 25;

/// Trials run at the same time unless the caller says otherwise: the number of cores.
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// What went wrong in an experiment.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The settings cannot run (zero trials, a seed that overflows, ...).
    #[error("{0}")]
    Settings(String),
    /// The feature table is inconsistent or lacks what the scenario needs.
    #[error("feature table: {0}")]
    Table(String),
    /// The dual memory refused a step.
    #[error("{context}: {source}")]
    Gdm {
        /// What the runner was doing.
        context: String,
        /// The model's error.
        #[source]
        source: GdmError,
    },
    /// A model file could not be written or read.
    #[error("{path}: {source}")]
    Checkpoint {
        /// The file.
        path: String,
        /// The checkpoint error.
        #[source]
        source: CheckpointError,
    },
    /// A run directory's file could not be read or written.
    #[error("{path}: {message}")]
    RunDir {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// Runs that are not one experiment were given to [`run_dir::merge`].
    #[error("{0}")]
    Merge(String),
}

impl ExperimentError {
    /// Wraps a model error with what the runner was doing (for `map_err`).
    pub(crate) fn gdm(context: impl Into<String>) -> impl Fn(GdmError) -> ExperimentError {
        let context = context.into();
        move |source| ExperimentError::Gdm {
            context: context.clone(),
            source,
        }
    }
}

/// A labelled feature table, borrowed column-wise: one row per view.
#[derive(Clone, Copy, Debug)]
pub struct Table<'a> {
    /// Row-major features, `rows × dim`.
    pub features: &'a [f32],
    /// Feature dimension.
    pub dim: usize,
    /// Collection index of each row.
    pub collection: &'a [u32],
    /// Category id of each row.
    pub category: &'a [u32],
    /// Global instance id of each row.
    pub instance: &'a [u32],
    /// Sequence id of each row (one object in one collection).
    pub sequence: &'a [u64],
    /// Frame index of each row within its sequence.
    pub frame: &'a [u32],
    /// Training collections (the dataset manifest's split).
    pub train_collections: &'a [u32],
    /// Test collections (the dataset manifest's split).
    pub test_collections: &'a [u32],
    /// Category names by id (step labels, `metrics.json`).
    pub category_names: &'a [String],
    /// Instance names by id (`metrics.json`); may be empty.
    pub instance_names: &'a [String],
}

impl Table<'_> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.sequence.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Features of row `i`.
    pub fn row(&self, i: usize) -> &[f32] {
        &self.features[i * self.dim..(i + 1) * self.dim]
    }

    /// The label columns.
    pub fn rows(&self) -> Rows<'_> {
        Rows {
            collection: self.collection,
            category: self.category,
            instance: self.instance,
            sequence: self.sequence,
            frame: self.frame,
        }
    }

    /// The samples of some sequences (lists of row indices), in order, with labels.
    pub fn samples(&self, sequences: &[Vec<usize>]) -> Vec<Sample<'_>> {
        sequences
            .iter()
            .flatten()
            .map(|&i| Sample {
                x: self.row(i),
                sequence: self.sequence[i],
                instance: Some(self.instance[i]),
                category: Some(self.category[i]),
            })
            .collect()
    }

    /// Checks that the columns agree in length and the features are finite.
    pub fn check(&self) -> Result<(), ExperimentError> {
        let n = self.len();
        if self.dim == 0 {
            return Err(ExperimentError::Table("feature dimension 0".into()));
        }
        if self.is_empty() {
            return Err(ExperimentError::Table("no rows".into()));
        }
        let cols = [
            ("collection", self.collection.len()),
            ("category", self.category.len()),
            ("instance", self.instance.len()),
            ("frame", self.frame.len()),
        ];
        if let Some((name, len)) = cols.iter().find(|(_, len)| *len != n) {
            return Err(ExperimentError::Table(format!(
                "{name} has {len} rows, sequence has {n}"
            )));
        }
        if n.checked_mul(self.dim) != Some(self.features.len()) {
            return Err(ExperimentError::Table(format!(
                "{} feature values are not {n} rows × {} columns",
                self.features.len(),
                self.dim
            )));
        }
        if let Some(p) = self.features.iter().position(|v| !v.is_finite()) {
            return Err(ExperimentError::Table(format!(
                "row {} column {} is not finite",
                p / self.dim,
                p % self.dim
            )));
        }
        Ok(())
    }
}

/// The settings of an experiment. [`Settings::new`] gives a scenario's defaults (the same as
/// `lgdm train`'s); change fields before [`Experiment::new`] checks them.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The protocol.
    pub scenario: Scenario,
    /// Dual-memory hyperparameters (default: the scenario's paper preset). The seed field is
    /// replaced by each trial's seed.
    pub config: GdmConfig,
    /// Trials, trial t with seed `seed + t` (default: [`DEFAULT_TRIALS`]).
    pub trials: usize,
    /// Base seed (default: 0).
    pub seed: u64,
    /// Intrinsic replay after every step (default: on, except for batch).
    pub replay: bool,
    /// Learning epochs per step (default: batch 35, others 1).
    pub epochs: usize,
    /// Evaluate on the test set after every n-th step (default `None`: about [`EVAL_POINTS`]
    /// points per trial; the last step always).
    pub eval_every: Option<usize>,
    /// Per-step evaluations use at most this many samples per set, whole sequences drawn with
    /// the trial's seed; 0 = all (default: [`DEFAULT_EVAL_SAMPLES`]). The final figures always
    /// use the whole test set.
    pub eval_samples: usize,
    /// Batch only: about this many training samples per epoch, a fixed per-trial subset of whole
    /// sequences, stratified by category; 0 = all (default).
    pub train_samples: usize,
    /// Validation mode: the last two training collections stand in for the test set and the
    /// test collections are not read; the instances each trial holds out for the test are not
    /// read either, and one more instance per category (where two are left) stands in for
    /// them (default: off).
    pub validate: bool,
    /// The learner trained (default: the GDM). A baseline has neither replay (`replay` must be
    /// off) nor temporal context (the `config`'s context depth is unused), and `config` does not
    /// apply to it.
    pub learner: LearnerKind,
}

impl Settings {
    /// The defaults of a scenario.
    pub fn new(scenario: Scenario) -> Settings {
        Settings {
            scenario,
            config: GdmConfig::preset(scenario.default_preset())
                .expect("every scenario's default preset exists"),
            trials: DEFAULT_TRIALS,
            seed: 0,
            replay: scenario.replay_by_default(),
            epochs: scenario.default_epochs(),
            eval_every: None,
            eval_samples: DEFAULT_EVAL_SAMPLES,
            train_samples: 0,
            validate: false,
            learner: LearnerKind::Gdm,
        }
    }

    /// The defaults of a scenario for `learner`: [`Settings::new`], with replay off for a
    /// baseline.
    pub fn for_learner(scenario: Scenario, learner: LearnerKind) -> Settings {
        let mut s = Settings::new(scenario);
        s.learner = learner;
        s.replay &= learner.is_gdm();
        s
    }

    /// Temporal context off (K = 0 in both memories), in training and prediction.
    pub fn without_context(mut self) -> Settings {
        self.config.episodic.context_depth = 0;
        self.config.semantic.context_depth = 0;
        self
    }
}

/// Progress of a run: one event per finished step of a trial.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepProgress {
    /// Trial index.
    pub trial: usize,
    /// Step index within the trial (1-based).
    pub step: usize,
    /// Steps in the trial.
    pub steps: usize,
    /// Step label.
    pub label: String,
    /// Test category accuracy of the semantic memory after the step, if evaluated.
    pub test_category_accuracy: Option<f64>,
    /// Episodic nodes after the step.
    pub episodic_nodes: usize,
}

/// A checked experiment: settings that can run on a table.
#[derive(Debug)]
pub struct Experiment<'a> {
    table: Table<'a>,
    settings: Settings,
    /// Train / test collections after the validation split.
    train_collections: Vec<u32>,
    test_collections: Vec<u32>,
    steps: usize,
    eval_every: usize,
}

impl<'a> Experiment<'a> {
    /// Checks the settings against the table and builds trial 0's plan (for the step count).
    pub fn new(table: Table<'a>, settings: Settings) -> Result<Experiment<'a>, ExperimentError> {
        let bad = |m: String| Err(ExperimentError::Settings(m));
        if settings.trials == 0 {
            return bad("trials must be at least 1".into());
        }
        if settings.epochs == 0 {
            return bad("epochs must be at least 1".into());
        }
        if settings.eval_every == Some(0) {
            return bad("eval_every must be at least 1".into());
        }
        if settings.replay && !settings.learner.is_gdm() {
            return bad(format!(
                "replay applies to the gdm learner only: the {} learner has none (turn replay off)",
                settings.learner
            ));
        }
        if settings.train_samples > 0 && settings.scenario != Scenario::Batch {
            return bad("train_samples applies to the batch scenario only".into());
        }
        if settings
            .seed
            .checked_add(settings.trials as u64 - 1)
            .is_none()
        {
            return bad(format!(
                "seed {} with {} trials: trial seeds seed + t would overflow",
                settings.seed, settings.trials
            ));
        }
        settings
            .config
            .validate()
            .map_err(|e| ExperimentError::Settings(format!("invalid hyperparameters: {e}")))?;
        table.check()?;
        let mut train_collections = table.train_collections.to_vec();
        let mut test_collections = table.test_collections.to_vec();
        if settings.validate {
            if train_collections.len() < 3 {
                return bad("validation mode needs at least three training collections".into());
            }
            let k = train_collections.len() - 2;
            test_collections = train_collections.split_off(k);
        }
        if train_collections.is_empty() || test_collections.is_empty() {
            return Err(ExperimentError::Table(
                "the data needs both training and test collections (see the dataset's manifest)"
                    .into(),
            ));
        }
        let mut experiment = Experiment {
            table,
            settings,
            train_collections,
            test_collections,
            steps: 0,
            eval_every: 1,
        };
        let plan = experiment.plan(0);
        if plan.steps.is_empty() {
            return Err(ExperimentError::Table(
                "no training sequences in the training collections".into(),
            ));
        }
        experiment.steps = plan.steps.len();
        experiment.eval_every = experiment
            .settings
            .eval_every
            .unwrap_or_else(|| experiment.steps.div_ceil(EVAL_POINTS).max(1));
        Ok(experiment)
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The table.
    pub fn table(&self) -> &Table<'a> {
        &self.table
    }

    /// Steps per trial (trial 0's plan; every trial has as many, except where a category's
    /// held-out instance changes the sequence count).
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The evaluation period in steps (resolved from the settings).
    pub fn eval_every(&self) -> usize {
        self.eval_every
    }

    /// The collections the steps are evaluated on (the test collections, or in validation mode
    /// the last two training collections).
    pub fn test_collections(&self) -> &[u32] {
        &self.test_collections
    }

    /// The training collections (without the validation ones in validation mode).
    pub fn train_collections(&self) -> &[u32] {
        &self.train_collections
    }

    /// Trial `t`'s seed.
    pub fn trial_seed(&self, trial: usize) -> u64 {
        self.settings.seed + trial as u64
    }

    fn trial_settings(&self, trial: usize) -> TrialSettings {
        TrialSettings {
            scenario: self.settings.scenario,
            config: self.settings.config.clone(),
            epochs: self.settings.epochs,
            replay: self.settings.replay,
            eval_every: self.eval_every,
            eval_samples: self.settings.eval_samples,
            train_samples: self.settings.train_samples,
            seed: self.trial_seed(trial),
            validate: self.settings.validate,
            learner: self.settings.learner,
        }
    }

    fn split_table(&self) -> Table<'_> {
        Table {
            train_collections: &self.train_collections,
            test_collections: &self.test_collections,
            ..self.table
        }
    }

    /// Trial `t`'s plan.
    pub fn plan(&self, trial: usize) -> Plan {
        runner::plan_trial(&self.split_table(), &self.trial_settings(trial))
    }

    /// Runs trial `t`: its plan's steps in order, measuring after each; the trained model (of
    /// the settings' learner) and the trial's record. `progress` is called after every step.
    pub fn run_trial(
        &self,
        trial: usize,
        progress: &dyn Fn(StepProgress),
    ) -> Result<(Model, TrialRecord), ExperimentError> {
        runner::run_trial(
            &self.split_table(),
            &self.trial_settings(trial),
            trial,
            progress,
        )
    }

    /// Runs the trials `trials` (indices below `settings.trials`), up to `jobs` at a time in
    /// parallel threads (rayon), and hands each finished trial to `finish` (e.g. to save its
    /// model) as soon as it ends; the results come back in the order of `trials`. Trials are
    /// independent and seeded by index, so the results depend neither on `jobs` nor on which
    /// other trials run (a resumed run equals an uninterrupted one). `progress` is called from
    /// the worker threads.
    pub fn run_with<T: Send>(
        &self,
        trials: &[usize],
        jobs: usize,
        progress: &(dyn Fn(StepProgress) + Sync),
        finish: &(dyn Fn(usize, Model, TrialRecord) -> Result<T, ExperimentError> + Sync),
    ) -> Result<Vec<T>, ExperimentError> {
        if jobs == 0 {
            return Err(ExperimentError::Settings("jobs must be at least 1".into()));
        }
        if let Some(&t) = trials.iter().find(|&&t| t >= self.settings.trials) {
            return Err(ExperimentError::Settings(format!(
                "trial {t} does not exist (the experiment has {} trials)",
                self.settings.trials
            )));
        }
        let one = |&t: &usize| {
            let (gdm, record) = self.run_trial(t, progress)?;
            finish(t, gdm, record)
        };
        let jobs = jobs.min(trials.len()).max(1);
        if jobs == 1 {
            return trials.iter().map(one).collect();
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(jobs)
            .build()
            .map_err(|e| ExperimentError::Settings(format!("starting {jobs} threads: {e}")))?;
        pool.install(|| trials.par_iter().map(one).collect())
    }

    /// Runs every trial (see [`Experiment::run_with`]); the models and records in trial order.
    pub fn run(
        &self,
        jobs: usize,
        progress: &(dyn Fn(StepProgress) + Sync),
    ) -> Result<Vec<(Model, TrialRecord)>, ExperimentError> {
        let all: Vec<usize> = (0..self.settings.trials).collect();
        self.run_with(&all, jobs, progress, &|_, gdm, record| Ok((gdm, record)))
    }

    /// The run's `metrics.json` contents from its trial records.
    pub fn metrics(&self, trials: Vec<TrialRecord>, encoder: &str, dataset: &str) -> RunMetrics {
        RunMetrics {
            format_version: run_dir::METRICS_FORMAT_VERSION,
            scenario: self.settings.scenario.name().into(),
            encoder: encoder.into(),
            dataset: dataset.into(),
            seed: self.settings.seed,
            learner: self.settings.learner,
            replay: self.settings.replay,
            context: self.settings.learner.is_gdm()
                && self.settings.config.episodic.context_depth > 0,
            epochs: self.settings.epochs,
            categories: self.table.category_names.to_vec(),
            instances: self.table.instance_names.to_vec(),
            summary: Summary::of(&trials),
            trials,
        }
    }
}
