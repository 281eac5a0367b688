//! The run-directory format, and the merge of single-trial runs of one experiment.
//!
//! A run directory holds `config.toml` ([`RunConfig`]: the exact settings and
//! hyperparameters, written first), one checkpoint per trial, `model-trial<t>.lgdm`
//! ([`model_file`]) and its record `trials/trial-<t>.json` ([`trial_file`]), each written the
//! moment the trial ends (model first), and at the end `metrics.json` ([`RunMetrics`], format
//! [`METRICS_FORMAT_VERSION`]) with its renderings, `summary.txt` ([`super::report`]) and the
//! plots ([`super::plots`]). Every file is written atomically.
//!
//! A [`RunDir`] owns its directory: it is created fresh (or an old run in it is removed first,
//! when asked), and a lock file keeps a second process out while one writes. A run stopped part
//! way (killed, out of power) keeps its finished trials; [`RunDir::resume`] reopens it and
//! [`RunDir::finished_trials`] says which trials are left. Taking a directory is the last check
//! of a run: a directory that is refused is left as it was found (no lock file, no new
//! directory), so front ends check everything else first.
//!
//! Trial t of an experiment with base seed S uses seed S + t, so a 5-trial experiment can run as
//! five single-trial runs and be [`merge`]d: runs merge only when they are one experiment
//! (scenario, encoder — for the autoencoder the checkpoint's bytes —, dataset, replay, epochs,
//! evaluation settings and every hyperparameter but the seed agree) and no seed appears twice.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{Experiment, ExperimentError, RunMetrics, Scenario, Summary, TrialRecord};
use crate::GdmConfig;

/// Version of the `metrics.json` layout.
pub const METRICS_FORMAT_VERSION: u32 = 1;
/// The settings file of a run.
pub const CONFIG_FILE: &str = "config.toml";
/// The metrics file of a run.
pub const METRICS_FILE: &str = "metrics.json";

/// The summary table of a finished run ([`super::report::summary_table`]).
pub const SUMMARY_FILE: &str = "summary.txt";

pub use lgdm_base::fs::LOCK_FILE;
/// The folder of per-trial records.
pub const TRIALS_DIR: &str = "trials";

/// The record of trial `t`, under [`TRIALS_DIR`].
pub fn trial_file(trial: usize) -> String {
    format!("trial-{trial}.json")
}

/// The checkpoint file of trial `t` in a run directory.
pub fn model_file(trial: usize) -> String {
    format!("model-trial{trial}.lgdm")
}

/// The settings of a run, as written to `config.toml`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
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
    /// The learner (absent in earlier runs' files: `gdm`).
    #[serde(default)]
    pub learner: crate::learner::LearnerKind,
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

/// Where a run's features came from: recorded in `config.toml` and `metrics.json`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Provenance {
    /// Encoder name (`good`, `ae`).
    pub encoder: String,
    /// Dataset directory.
    pub dataset: String,
    /// Where the hyperparameters came from (a preset, a file).
    pub hyperparameters_from: String,
    /// The autoencoder checkpoint's path, for `ae`.
    pub ae_checkpoint: Option<String>,
    /// FNV-1a of the autoencoder checkpoint's bytes (16 hex digits), for `ae`.
    pub ae_checkpoint_fnv1a: Option<String>,
}

impl RunConfig {
    /// The `config.toml` of an experiment.
    pub fn new(experiment: &Experiment<'_>, provenance: &Provenance) -> RunConfig {
        let s = experiment.settings();
        RunConfig {
            scenario: s.scenario,
            encoder: provenance.encoder.clone(),
            dataset: provenance.dataset.clone(),
            trials: s.trials,
            seed: s.seed,
            replay: s.replay,
            epochs: s.epochs,
            eval_every: experiment.eval_every(),
            eval_samples: s.eval_samples,
            train_samples: s.train_samples,
            validate: s.validate,
            learner: s.learner,
            hyperparameters_from: provenance.hyperparameters_from.clone(),
            ae_checkpoint: provenance.ae_checkpoint.clone(),
            ae_checkpoint_fnv1a: provenance.ae_checkpoint_fnv1a.clone(),
            gdm: s.config.clone(),
        }
    }

    /// As TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a run config serialises to TOML")
    }

    /// Parses `config.toml` text; an error names the offending key and line.
    pub fn from_toml(text: &str) -> Result<RunConfig, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    /// Reads the `config.toml` of the run directory `dir` (nothing is locked or written). A
    /// directory without one is not a run directory; one that is not a run's is an error naming
    /// the offending key and line.
    pub fn read(dir: &Path) -> Result<RunConfig, ExperimentError> {
        let cpath = dir.join(CONFIG_FILE);
        if !cpath.is_file() {
            return Err(run_dir_error(
                dir,
                "is not a run directory (no config.toml)",
            ));
        }
        let text = std::fs::read_to_string(&cpath).map_err(|e| run_dir_error(&cpath, e))?;
        RunConfig::from_toml(&text).map_err(|e| run_dir_error(&cpath, e))
    }

    /// The experiment settings this run used.
    pub fn settings(&self) -> super::Settings {
        super::Settings {
            scenario: self.scenario,
            config: self.gdm.clone(),
            trials: self.trials,
            seed: self.seed,
            replay: self.replay,
            epochs: self.epochs,
            eval_every: Some(self.eval_every),
            eval_samples: self.eval_samples,
            train_samples: self.train_samples,
            validate: self.validate,
            learner: self.learner,
        }
    }
}

impl RunMetrics {
    /// As pretty JSON text (floats round-trip exactly).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("run metrics serialise to JSON")
    }
}

fn run_dir_error(path: &Path, message: impl std::fmt::Display) -> ExperimentError {
    ExperimentError::RunDir {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so a
/// reader never sees half a file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    lgdm_base::fs::write_bytes(path, bytes).map_err(|e| run_dir_error(path, e))
}

/// A finished run read back from its directory.
#[derive(Clone, Debug)]
pub struct Run {
    /// The directory.
    pub dir: PathBuf,
    /// Its `metrics.json`.
    pub metrics: RunMetrics,
    /// Its `config.toml`.
    pub config: RunConfig,
}

impl Run {
    /// Reads a run directory's `metrics.json` and `config.toml`.
    pub fn read(dir: &Path) -> Result<Run, ExperimentError> {
        let mpath = dir.join(METRICS_FILE);
        let text = std::fs::read_to_string(&mpath).map_err(|e| {
            let hint = if dir.join(CONFIG_FILE).is_file() {
                format!(
                    "{} is an unfinished run: `lgdm train --resume {}` finishes it",
                    dir.display(),
                    dir.display()
                )
            } else {
                format!("is {} a finished run?", dir.display())
            };
            run_dir_error(&mpath, format!("{e} ({hint})"))
        })?;
        let metrics: RunMetrics =
            serde_json::from_str(&text).map_err(|e| run_dir_error(&mpath, e))?;
        if metrics.format_version != METRICS_FORMAT_VERSION {
            return Err(run_dir_error(
                &mpath,
                format!(
                    "format version {}, this lgdm reads version {METRICS_FORMAT_VERSION}",
                    metrics.format_version
                ),
            ));
        }
        let cpath = dir.join(CONFIG_FILE);
        let text = std::fs::read_to_string(&cpath).map_err(|e| run_dir_error(&cpath, e))?;
        let config = RunConfig::from_toml(&text).map_err(|e| run_dir_error(&cpath, e))?;
        Ok(Run {
            dir: dir.to_path_buf(),
            metrics,
            config,
        })
    }

    /// Writes `config.toml` and `metrics.json` into `dir` (each atomically).
    pub fn write_files(
        dir: &Path,
        config: &RunConfig,
        metrics: &RunMetrics,
    ) -> Result<(), ExperimentError> {
        write_atomic(&dir.join(CONFIG_FILE), config.to_toml().as_bytes())?;
        write_atomic(&dir.join(METRICS_FILE), metrics.to_json().as_bytes())
    }
}

/// The folder `lgdm eval` writes into beside the model it scores (so inside a training run
/// directory: `--force` replaces it with the run whose model it scored).
pub const EVAL_DIR: &str = "eval";
/// The files `lgdm eval` writes into its output directory.
pub const EVAL_FILES: [&str; 3] = ["confusion.csv", "confusion.png", "eval.json"];

/// A temporary file of an atomic write whose target `ours` accepts.
fn is_temporary_of(name: &str, ours: impl Fn(&str) -> bool) -> bool {
    lgdm_base::fs::temporary_target(name).is_some_and(ours)
}

/// What an evaluation directory holds: [`EVAL_FILES`] and nothing else.
fn classify_eval(name: &str, is_dir: bool) -> lgdm_base::fs::Entry {
    let ours = |n: &str| EVAL_FILES.contains(&n);
    if !is_dir && (ours(name) || is_temporary_of(name, ours) || name == LOCK_FILE) {
        lgdm_base::fs::Entry::Ours
    } else {
        lgdm_base::fs::Entry::Foreign
    }
}

/// The ownership policy of `lgdm eval` output directories.
const EVAL_OWNERSHIP: lgdm_base::fs::Ownership<'static> = lgdm_base::fs::Ownership {
    kind: "an lgdm evaluation (confusion.csv, confusion.png, eval.json)",
    occupied: "holds another evaluation",
    classify: &classify_eval,
};

/// Creates and locks `dir` for the output of `lgdm eval`, removing an earlier evaluation's
/// files ([`EVAL_FILES`]). A directory holding anything else (a training run, someone's files)
/// is refused and left as it was found, lock file included.
pub fn claim_eval_dir(dir: &Path) -> Result<lgdm_base::fs::DirLock, ExperimentError> {
    lgdm_base::fs::claim(dir, true, &EVAL_OWNERSHIP).map_err(|e| run_dir_error(&e.path, e.reason))
}

/// `<prefix><digits><suffix>`, the way a run names its numbered files.
fn numbered(name: &str, prefix: &str, suffix: &str) -> bool {
    name.strip_prefix(prefix)
        .and_then(|n| n.strip_suffix(suffix))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// What a training run directory holds (what `--force` may remove): its own files, and an
/// [`EVAL_DIR`] holding only an evaluation's files (anything else in it is not removed).
fn classify(name: &str, is_dir: bool) -> lgdm_base::fs::Entry {
    if name == EVAL_DIR {
        return lgdm_base::fs::Entry::Folder;
    }
    if let Some(inner) = name.strip_prefix("eval/") {
        return classify_eval(inner, is_dir);
    }
    if name == TRIALS_DIR {
        return if is_dir {
            lgdm_base::fs::Entry::Folder
        } else {
            lgdm_base::fs::Entry::Foreign
        };
    }
    if let Some(inner) = name.strip_prefix("trials/") {
        let record = |n: &str| numbered(n, "trial-", ".json");
        return if !is_dir && (record(inner) || is_temporary_of(inner, record)) {
            lgdm_base::fs::Entry::Ours
        } else {
            lgdm_base::fs::Entry::Foreign
        };
    }
    let ours = |n: &str| {
        matches!(n, CONFIG_FILE | METRICS_FILE | SUMMARY_FILE)
            || super::plots::RUN_PLOTS.contains(&n)
            || numbered(n, "model-trial", ".lgdm")
    };
    if !is_dir && (ours(name) || is_temporary_of(name, ours)) {
        lgdm_base::fs::Entry::Ours
    } else {
        lgdm_base::fs::Entry::Foreign
    }
}

/// The ownership policy of training run directories ([`lgdm_base::fs::claim`]).
const OWNERSHIP: lgdm_base::fs::Ownership<'static> = lgdm_base::fs::Ownership {
    kind: "an lgdm run",
    occupied: "holds another run; choose another directory, pass --force to replace it, \
               or --resume to finish it",
    classify: &classify,
};

/// A run directory owned by this process: locked against other writers while it lives.
#[derive(Debug)]
pub struct RunDir {
    dir: PathBuf,
    /// Holds the lock (released when the process ends, however it ends).
    _lock: lgdm_base::fs::DirLock,
}

impl RunDir {
    fn lock(dir: &Path) -> Result<RunDir, ExperimentError> {
        let lock = lgdm_base::fs::DirLock::try_acquire(dir)
            .map_err(|e| run_dir_error(dir, e))?
            .ok_or_else(|| {
                run_dir_error(dir, "another lgdm process is writing this run directory")
            })?;
        Ok(RunDir {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// Creates `dir` as a fresh run directory and locks it. A directory that already holds
    /// files is refused, unless `force` is set and every file in it belongs to a run (those are
    /// removed first); a directory holding anything else is never cleared, and a refused one is
    /// left as it was found ([`lgdm_base::fs::claim`]).
    pub fn create(dir: &Path, force: bool) -> Result<RunDir, ExperimentError> {
        let lock = lgdm_base::fs::claim(dir, force, &OWNERSHIP)
            .map_err(|e| run_dir_error(&e.path, e.reason))?;
        Ok(RunDir {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// Reopens the run directory `dir` to finish it as `expected` (the settings the resumed run
    /// has, made from the [`RunConfig::read`] of `dir` and the data as they are now) and locks
    /// it. A directory whose `config.toml` is missing, is not a run's, or no longer matches
    /// `expected` (the dataset or the autoencoder checkpoint changed) is refused before the lock
    /// is taken, so it is left as it was found.
    pub fn resume(dir: &Path, expected: &RunConfig) -> Result<RunDir, ExperimentError> {
        if RunConfig::read(dir)? != *expected {
            return Err(run_dir_error(
                dir,
                "cannot be resumed as it was started: its config.toml no longer matches (the \
                 dataset or the autoencoder checkpoint changed?)",
            ));
        }
        RunDir::lock(dir)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes `config.toml`.
    pub fn write_config(&self, config: &RunConfig) -> Result<(), ExperimentError> {
        write_atomic(&self.dir.join(CONFIG_FILE), config.to_toml().as_bytes())
    }

    /// Records a finished trial: its model, then its record (so a record always has its model).
    pub fn save_trial(
        &self,
        trial: usize,
        gdm: &crate::learner::Model,
        record: &TrialRecord,
    ) -> Result<(), ExperimentError> {
        let model = self.dir.join(model_file(trial));
        gdm.save(&model)
            .map_err(|source| ExperimentError::Checkpoint {
                path: model.display().to_string(),
                source,
            })?;
        let dir = self.dir.join(TRIALS_DIR);
        std::fs::create_dir_all(&dir).map_err(|e| run_dir_error(&dir, e))?;
        let json = serde_json::to_string_pretty(record).expect("a trial record serialises");
        write_atomic(&dir.join(trial_file(trial)), json.as_bytes())
    }

    /// The records of trials `0..trials` that finished (record and model present), `None` for
    /// the others. A record whose trial index or model does not match is an error.
    pub fn finished_trials(
        &self,
        trials: usize,
    ) -> Result<Vec<Option<TrialRecord>>, ExperimentError> {
        (0..trials)
            .map(|t| {
                let path = self.dir.join(TRIALS_DIR).join(trial_file(t));
                if !path.is_file() || !self.dir.join(model_file(t)).is_file() {
                    return Ok(None);
                }
                let text = std::fs::read_to_string(&path).map_err(|e| run_dir_error(&path, e))?;
                let record: TrialRecord =
                    serde_json::from_str(&text).map_err(|e| run_dir_error(&path, e))?;
                if record.trial != t {
                    return Err(run_dir_error(
                        &path,
                        format!("records trial {}, expected {t}", record.trial),
                    ));
                }
                Ok(Some(record))
            })
            .collect()
    }

    /// Writes `metrics.json` (the run is finished).
    pub fn write_metrics(&self, metrics: &RunMetrics) -> Result<(), ExperimentError> {
        write_atomic(&self.dir.join(METRICS_FILE), metrics.to_json().as_bytes())
    }

    /// Plays the trials of `experiment` that `finished` has no record of (`jobs` at a time),
    /// each saved here as it ends — so a run stopped at any point resumes from its finished
    /// trials — then writes `metrics.json`, `summary.txt` ([`super::report::summary_table`])
    /// and the plots ([`super::plots::write_run_plots`]) from all the trials' records: what
    /// `lgdm train` and `lgdm.run_scenario(out=…)` leave in a run directory. `finished` comes from
    /// [`RunDir::finished_trials`] (all `None` for a new run).
    #[allow(clippy::too_many_arguments)]
    pub fn play(
        &self,
        experiment: &Experiment<'_>,
        finished: Vec<Option<TrialRecord>>,
        jobs: usize,
        progress: &(dyn Fn(super::StepProgress) + Sync),
        encoder: &str,
        dataset: &str,
    ) -> Result<RunMetrics, ExperimentError> {
        let todo: Vec<usize> = (0..finished.len())
            .filter(|&t| finished[t].is_none())
            .collect();
        let mut new = experiment
            .run_with(&todo, jobs, progress, &|t, gdm, record| {
                self.save_trial(t, &gdm, &record)?;
                Ok(record)
            })?
            .into_iter();
        let trials = finished
            .into_iter()
            .map(|r| r.or_else(|| new.next()).expect("one record per trial"))
            .collect();
        let metrics = experiment.metrics(trials, encoder, dataset);
        self.write_metrics(&metrics)?;
        write_atomic(
            &self.dir.join(SUMMARY_FILE),
            super::report::summary_table(&metrics).as_bytes(),
        )?;
        super::plots::write_run_plots(&self.dir, &metrics)?;
        Ok(metrics)
    }
}

/// The first setting in which `b` differs from `a`, if any (seeds and trial counts may differ).
fn difference(a: &Run, b: &Run) -> Option<String> {
    let (ma, mb) = (&a.metrics, &b.metrics);
    let (ca, cb) = (&a.config, &b.config);
    macro_rules! same {
        ($name:literal, $x:expr, $y:expr) => {
            if $x != $y {
                return Some(format!("{}: {:?} vs {:?}", $name, $x, $y));
            }
        };
    }
    same!("scenario", ma.scenario, mb.scenario);
    same!("learner", ma.learner, mb.learner);
    same!("encoder", ma.encoder, mb.encoder);
    same!("dataset", ma.dataset, mb.dataset);
    same!("replay", ma.replay, mb.replay);
    same!("temporal context", ma.context, mb.context);
    same!("epochs", ma.epochs, mb.epochs);
    same!("categories", ma.categories, mb.categories);
    same!("eval_every", ca.eval_every, cb.eval_every);
    same!("eval_samples", ca.eval_samples, cb.eval_samples);
    same!("train_samples", ca.train_samples, cb.train_samples);
    same!("validate", ca.validate, cb.validate);
    // The checkpoint's bytes, not its path: a copy elsewhere is the same encoder.
    same!(
        "autoencoder checkpoint (FNV-1a)",
        ca.ae_checkpoint_fnv1a,
        cb.ae_checkpoint_fnv1a
    );
    let mut ga = ca.gdm.clone();
    let mut gb = cb.gdm.clone();
    ga.seed = 0;
    gb.seed = 0;
    if ga != gb {
        return Some("hyperparameters (config.toml [gdm]) differ".into());
    }
    None
}

/// The merged run: metrics and config, and each trial's model file with its new trial index.
#[derive(Clone, Debug)]
pub struct Merged {
    /// The merged `metrics.json`.
    pub metrics: RunMetrics,
    /// The merged `config.toml`.
    pub config: RunConfig,
    /// (source model file, trial index in the merged run).
    pub models: Vec<(PathBuf, usize)>,
}

impl Merged {
    /// Writes the merged run into the run directory `out` (see [`RunDir::create`]):
    /// `config.toml`, each trial's model, hard-linked (copied where links fail) under its new
    /// trial index, with its record, `metrics.json`, `summary.txt` and the plots. Returns how many source
    /// models were missing (not linked). A source run may not be `out` itself.
    pub fn write(&self, out: &RunDir) -> Result<usize, ExperimentError> {
        out.write_config(&self.config)?;
        let mut missing = 0;
        for ((src, t), record) in self.models.iter().zip(&self.metrics.trials) {
            let dst = out.path().join(model_file(*t));
            if !src.exists() {
                missing += 1;
                continue;
            }
            if std::fs::hard_link(src, &dst).is_err() {
                std::fs::copy(src, &dst)
                    .map_err(|e| run_dir_error(&dst, format!("copying {}: {e}", src.display())))?;
            }
            let dir = out.path().join(TRIALS_DIR);
            std::fs::create_dir_all(&dir).map_err(|e| run_dir_error(&dir, e))?;
            let json = serde_json::to_string_pretty(record).expect("a trial record serialises");
            write_atomic(&dir.join(trial_file(*t)), json.as_bytes())?;
        }
        out.write_metrics(&self.metrics)?;
        write_atomic(
            &out.path().join(SUMMARY_FILE),
            super::report::summary_table(&self.metrics).as_bytes(),
        )?;
        super::plots::write_run_plots(out.path(), &self.metrics)?;
        Ok(missing)
    }
}

/// `lgdm merge` and `lgdm.merge_runs`: reads the run directories `runs`, checks that they are
/// one experiment ([`merge`]) and writes the merged run into `out` ([`RunDir::create`] with
/// `force`; never one of the inputs). Everything is checked before anything is written. Returns
/// the merged run and how many source models were missing ([`Merged::write`]).
pub fn merge_into(
    runs: &[PathBuf],
    out: &Path,
    force: bool,
) -> Result<(Merged, usize), ExperimentError> {
    let read = runs
        .iter()
        .map(|d| Run::read(d))
        .collect::<Result<Vec<_>, _>>()?;
    let merged = merge(&read)?;
    let resolved = |p: &Path| std::fs::canonicalize(p).unwrap_or(p.to_path_buf());
    if let Some(input) = runs.iter().find(|r| resolved(r) == resolved(out)) {
        return Err(run_dir_error(
            out,
            format!(
                "is one of the runs being merged ({}): the merge would overwrite its own input; \
                 choose a new directory",
                input.display()
            ),
        ));
    }
    let run_dir = RunDir::create(out, force)?;
    let missing = merged.write(&run_dir)?;
    Ok((merged, missing))
}

/// Checks that the runs are one experiment and merges them, trials sorted by seed. Nothing is
/// written.
pub fn merge(runs: &[Run]) -> Result<Merged, ExperimentError> {
    let Some(first) = runs.first() else {
        return Err(ExperimentError::Merge("no runs to merge".into()));
    };
    for r in &runs[1..] {
        if let Some(d) = difference(first, r) {
            return Err(ExperimentError::Merge(format!(
                "{} and {} are different experiments ({d}); only runs of one experiment merge",
                first.dir.display(),
                r.dir.display()
            )));
        }
    }
    // (seed, run index, trial record)
    let mut all: Vec<(u64, usize, TrialRecord)> = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        for t in &r.metrics.trials {
            if let Some((_, j, _)) = all.iter().find(|(s, _, _)| *s == t.seed) {
                return Err(ExperimentError::Merge(format!(
                    "seed {} appears in both {} and {}: the same trial twice would count double",
                    t.seed,
                    runs[*j].dir.display(),
                    r.dir.display()
                )));
            }
            all.push((t.seed, i, t.clone()));
        }
    }
    if all.is_empty() {
        return Err(ExperimentError::Merge("the runs hold no trials".into()));
    }
    all.sort_by_key(|(s, _, _)| *s);
    let mut models = Vec::new();
    let mut trials = Vec::new();
    for (new_index, (_, i, mut t)) in all.into_iter().enumerate() {
        models.push((runs[i].dir.join(model_file(t.trial)), new_index));
        t.trial = new_index;
        trials.push(t);
    }
    let seed = trials[0].seed;
    let summary = Summary::of(&trials);
    let metrics = RunMetrics {
        seed,
        trials,
        summary,
        ..first.metrics.clone()
    };
    let mut config = first.config.clone();
    config.trials = metrics.trials.len();
    config.seed = seed;
    config.gdm.seed = seed;
    Ok(Merged {
        metrics,
        config,
        models,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policies_know_their_files_by_name_and_nothing_else() {
        use lgdm_base::fs::Entry;
        for (name, is_dir, want) in [
            ("config.toml", false, Entry::Ours),
            ("metrics.json", false, Entry::Ours),
            ("accuracy.png", false, Entry::Ours),
            ("model-trial3.lgdm", false, Entry::Ours),
            (".metrics.json.a1B2c3.tmp", false, Entry::Ours),
            ("trials", true, Entry::Folder),
            ("trials/trial-0.json", false, Entry::Ours),
            ("trials/.trial-0.json.a1B2c3.tmp", false, Entry::Ours),
            ("eval", true, Entry::Folder),
            ("eval/confusion.png", false, Entry::Ours),
            ("holiday.png", false, Entry::Foreign),
            (".holiday.png.a1B2c3.tmp", false, Entry::Foreign),
            (".notes.tmp", false, Entry::Foreign),
            ("model-trial-notes.lgdm", false, Entry::Foreign),
            ("trials/holiday.png", false, Entry::Foreign),
            ("trials", false, Entry::Foreign),
            ("eval/holiday.png", false, Entry::Foreign),
            ("metrics.json", true, Entry::Foreign),
        ] {
            assert_eq!(classify(name, is_dir), want, "{name} (dir: {is_dir})");
        }
    }
    use crate::experiment::Figures;

    fn figures(a: f64) -> Figures {
        Figures {
            n: 10,
            instance_accuracy: a,
            category_accuracy_em: a,
            category_accuracy_sm: a,
        }
    }

    fn run(dir: &str, seeds: &[u64], replay: bool) -> Run {
        let trials: Vec<TrialRecord> = seeds
            .iter()
            .enumerate()
            .map(|(i, &s)| TrialRecord {
                trial: i,
                seed: s,
                held_out_instances: vec![],
                step_labels: vec!["a".into()],
                steps: vec![],
                test: figures(0.5 + s as f64 / 10.0),
                test_no_context: figures(0.5),
                new_instance: None,
                per_category_test_accuracy: vec![],
                episodic_nodes: 10,
                semantic_nodes: 5,
                model_size_bytes: 1000,
                inference_ms_per_sample: 0.1,
                train_seconds: 1.0,
                forgetting: None,
            })
            .collect();
        let summary = Summary::of(&trials);
        let metrics = RunMetrics {
            format_version: METRICS_FORMAT_VERSION,
            scenario: "ni".into(),
            encoder: "good".into(),
            dataset: "/d".into(),
            seed: seeds[0],
            learner: Default::default(),
            replay,
            context: true,
            epochs: 1,
            categories: vec!["mug".into()],
            instances: vec![],
            trials,
            summary,
        };
        let config = RunConfig {
            scenario: Scenario::Ni,
            encoder: "good".into(),
            dataset: "/d".into(),
            trials: seeds.len(),
            seed: seeds[0],
            replay,
            epochs: 1,
            eval_every: 1,
            eval_samples: 3000,
            train_samples: 0,
            validate: false,
            learner: Default::default(),
            hyperparameters_from: "preset".into(),
            ae_checkpoint: None,
            ae_checkpoint_fnv1a: None,
            gdm: GdmConfig {
                seed: seeds[0],
                ..Default::default()
            },
        };
        Run {
            dir: dir.into(),
            metrics,
            config,
        }
    }

    #[test]
    fn merges_trials_in_seed_order_and_summarises_all() {
        let Merged {
            metrics: m,
            config: c,
            models,
        } = merge(&[run("b", &[2, 3], true), run("a", &[0, 1], true)]).unwrap();
        let seeds: Vec<u64> = m.trials.iter().map(|t| t.seed).collect();
        assert_eq!(seeds, [0, 1, 2, 3]);
        assert_eq!(m.summary.trials, 4);
        assert!((m.summary.test_category_accuracy_sm.mean - 0.65).abs() < 1e-12);
        assert_eq!((c.trials, c.seed, m.seed), (4, 0, 0));
        assert_eq!(models[0].0, Path::new("a").join("model-trial0.lgdm"));
        assert_eq!(models[2].0, Path::new("b").join("model-trial0.lgdm"));
        assert_eq!(models[3].1, 3);
    }

    #[test]
    fn refuses_different_experiments_and_duplicate_seeds() {
        let err = |runs: &[Run]| merge(runs).expect_err("refused").to_string();
        let e = err(&[run("a", &[0], true), run("b", &[1], false)]);
        assert!(e.contains("replay"), "{e}");
        let e = err(&[run("a", &[0, 1], true), run("b", &[1], true)]);
        assert!(e.contains("seed 1"), "{e}");
        let mut other = run("c", &[5], true);
        other.config.gdm.episodic.activation_threshold = 0.9;
        let e = err(&[run("a", &[0], true), other]);
        assert!(e.contains("hyperparameters"), "{e}");
        let mut slda = run("d", &[6], true);
        slda.metrics.learner = crate::learner::LearnerKind::Slda;
        let e = err(&[run("a", &[0], true), slda]);
        assert!(e.contains("learner: Gdm vs Slda"), "{e}");
        assert!(err(&[]).contains("no runs"));
    }

    fn ae_run(dir: &str, seed: u64, path: &str, hash: &str) -> Run {
        let mut r = run(dir, &[seed], true);
        r.metrics.encoder = "ae".into();
        r.config.encoder = "ae".into();
        r.config.ae_checkpoint = Some(path.into());
        r.config.ae_checkpoint_fnv1a = Some(hash.into());
        r
    }

    #[test]
    fn autoencoder_runs_merge_only_with_the_same_checkpoint_bytes() {
        let e = merge(&[
            ae_run("a", 0, "/x/cpu.pt", "00000000000000aa"),
            ae_run("b", 1, "/x/cpu.pt", "00000000000000bb"),
        ])
        .expect_err("refused")
        .to_string();
        assert!(e.contains("checkpoint"), "{e}");
        // Same bytes under another path merge, and the merged config keeps the checkpoint.
        let m = merge(&[
            ae_run("a", 0, "/x/cpu.pt", "00000000000000aa"),
            ae_run("b", 1, "/y/copy.pt", "00000000000000aa"),
        ])
        .unwrap();
        assert_eq!(m.config.ae_checkpoint.as_deref(), Some("/x/cpu.pt"));
        assert_eq!(
            m.config.ae_checkpoint_fnv1a.as_deref(),
            Some("00000000000000aa")
        );
        let text = m.config.to_toml();
        assert!(
            text.contains("ae_checkpoint_fnv1a = \"00000000000000aa\""),
            "{text}"
        );
    }

    #[test]
    fn a_refused_resume_leaves_the_directory_as_found() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let listing = || {
            let mut names: Vec<String> = std::fs::read_dir(dir)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        };
        let config = run("x", &[0], true).config;
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let e = RunDir::resume(dir, &config).unwrap_err().to_string();
        assert!(e.contains("not a run directory"), "{e}");
        assert_eq!(listing(), ["notes.txt"]);
        // Another tool's config.toml.
        std::fs::write(dir.join(CONFIG_FILE), "[build]\njobs = 2\n").unwrap();
        let e = RunDir::resume(dir, &config).unwrap_err().to_string();
        assert!(e.contains("unknown field"), "{e}");
        assert_eq!(listing(), [CONFIG_FILE, "notes.txt"]);
        // A run whose data changed since.
        let mut started = config.clone();
        started.dataset = "/elsewhere".into();
        std::fs::write(dir.join(CONFIG_FILE), started.to_toml()).unwrap();
        let e = RunDir::resume(dir, &config).unwrap_err().to_string();
        assert!(e.contains("no longer matches"), "{e}");
        assert_eq!(listing(), [CONFIG_FILE, "notes.txt"]);
        // The run's own settings: taken.
        std::fs::write(dir.join(CONFIG_FILE), config.to_toml()).unwrap();
        let _run = RunDir::resume(dir, &config).unwrap();
        assert!(lgdm_base::fs::DirLock::is_held(dir));
    }

    #[test]
    fn written_runs_read_back_equal() {
        let dir = tempfile::tempdir().unwrap();
        let r = run("x", &[3, 4], true);
        Run::write_files(dir.path(), &r.config, &r.metrics).unwrap();
        let back = Run::read(dir.path()).unwrap();
        assert_eq!(back.config, r.config);
        // NaN (no train step evaluated here) is written as null and read back as NaN.
        assert!(back.metrics.summary.train_instance_accuracy.mean.is_nan());
        assert_eq!(back.metrics.to_json(), r.metrics.to_json());
        let e = Run::read(&dir.path().join("missing"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("finished run"), "{e}");
    }
}
