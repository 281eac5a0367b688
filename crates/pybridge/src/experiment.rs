//! `lgdm.run_scenario`: the paper's scenarios on a feature table, through the same library code
//! as `lgdm train` (`lgdm_gdm::experiment`), so the same table and seed give the same
//! `metrics.json` records, bit for bit.
//!
//! The Python layer (`lgdm/_experiment.py`) turns a table (the dict of `lgdm.good_features`, or
//! numpy arrays) into C-contiguous arrays; this layer checks the label columns, builds the
//! experiment and runs it with the GIL released.

use std::path::PathBuf;

use lgdm_gdm::experiment::run_dir::{self, Provenance, RunConfig, RunDir};
use lgdm_gdm::experiment::{self, Experiment, Scenario, Settings, Table};
use lgdm_gdm::learner::LearnerKind;
use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{self, Kind};
use crate::model::{Model, config_from_json, features};

fn experiment_error(e: experiment::ExperimentError) -> PyErr {
    match e {
        experiment::ExperimentError::Gdm { context, source } => {
            errors::new(errors::gdm_kind(&source), format!("{context}: {source}"))
        }
        experiment::ExperimentError::Settings(m) => errors::new(Kind::Config, m),
        other => errors::input(other.to_string()),
    }
}

fn scenario(name: &str) -> PyResult<Scenario> {
    name.parse()
        .map_err(|e: String| errors::new(Kind::Config, e))
}

/// An id column: integers in `0..=max`, as many as the table has rows.
fn ids<T: TryFrom<i64>>(name: &str, arr: &PyReadonlyArray1<'_, i64>, n: usize) -> PyResult<Vec<T>> {
    let values = arr
        .as_slice()
        .map_err(|e| errors::input(format!("{name} must be C-contiguous: {e}")))?;
    if values.len() != n {
        return Err(errors::input(format!(
            "{name} has {} entries but features has {n} rows",
            values.len()
        )));
    }
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            T::try_from(v).map_err(|_| {
                errors::input(format!(
                    "{name}[{i}] = {v} is not an id: ids are non-negative integers"
                ))
            })
        })
        .collect()
}

/// The defaults of a scenario: `{"preset", "replay", "epochs", "trials", "eval_samples",
/// "jobs"}` (what `lgdm train` uses when not told otherwise).
#[pyfunction]
pub fn scenario_defaults<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
    let scenario = scenario(name)?;
    let s = Settings::new(scenario);
    let out = PyDict::new(py);
    out.set_item("preset", scenario.default_preset())?;
    out.set_item("replay", s.replay)?;
    out.set_item("epochs", s.epochs)?;
    out.set_item("trials", s.trials)?;
    out.set_item("eval_samples", s.eval_samples)?;
    out.set_item("jobs", experiment::default_jobs())?;
    Ok(out)
}

/// Runs a scenario over trials on a feature table; returns (`metrics.json` as JSON text, the
/// final model of every trial). `config` is a GDM config document as JSON (see `lgdm.GDM`), or
/// `None` for the scenario's preset; `None` elsewhere means the scenario's default.
#[pyfunction]
#[pyo3(signature = (
    features_, collection, category, instance, sequence, frame, train_collections,
    test_collections, categories, scenario_name, *, instances=Vec::new(), config=None, trials=None, seed=0,
    replay=None, context=true, epochs=None, eval_every=None, eval_samples=None, train_samples=0,
    validate=false, jobs=None, encoder="good", dataset="", hyperparameters_from="",
    out=None, force=false, resume=false, learner=None, return_models=false
))]
#[allow(clippy::too_many_arguments)]
pub fn run_scenario(
    py: Python<'_>,
    features_: PyReadonlyArray2<'_, f32>,
    collection: PyReadonlyArray1<'_, i64>,
    category: PyReadonlyArray1<'_, i64>,
    instance: PyReadonlyArray1<'_, i64>,
    sequence: PyReadonlyArray1<'_, i64>,
    frame: PyReadonlyArray1<'_, i64>,
    train_collections: Vec<u32>,
    test_collections: Vec<u32>,
    categories: Vec<String>,
    scenario_name: &str,
    instances: Vec<String>,
    config: Option<&str>,
    trials: Option<usize>,
    seed: u64,
    replay: Option<bool>,
    context: bool,
    epochs: Option<usize>,
    eval_every: Option<usize>,
    eval_samples: Option<usize>,
    train_samples: usize,
    validate: bool,
    jobs: Option<usize>,
    encoder: &str,
    dataset: &str,
    hyperparameters_from: &str,
    out: Option<PathBuf>,
    force: bool,
    resume: bool,
    learner: Option<&str>,
    return_models: bool,
) -> PyResult<(String, Vec<Model>)> {
    let learner = learner
        .map(|name| name.parse::<LearnerKind>().map_err(errors::input))
        .transpose()?;
    // Resuming: the run's own settings, from its config.toml.
    let recorded = match (&out, resume) {
        (Some(dir), true) => Some(RunConfig::read(dir).map_err(experiment_error)?),
        (None, true) => return Err(errors::input("resume needs the run directory: out=…")),
        _ => None,
    };
    let (settings, hyperparameters_from) = match &recorded {
        Some(config) => (config.settings(), config.hyperparameters_from.clone()),
        None => {
            let learner = learner.unwrap_or_default();
            let mut settings = Settings::for_learner(scenario(scenario_name)?, learner);
            if !learner.is_gdm() && config.is_some() {
                return Err(errors::input(format!(
                    "a preset or hyperparameters apply to learner=\"gdm\" only: the {learner} \
                     learner has none"
                )));
            }
            if let Some(text) = config {
                settings.config = config_from_json(text)?;
            }
            if !context {
                settings = settings.without_context();
            }
            settings.trials = trials.unwrap_or(settings.trials);
            settings.seed = seed;
            settings.replay = replay.unwrap_or(settings.replay);
            settings.epochs = epochs.unwrap_or(settings.epochs);
            settings.eval_every = eval_every;
            settings.eval_samples = eval_samples.unwrap_or(settings.eval_samples);
            settings.train_samples = train_samples;
            settings.validate = validate;
            (settings, hyperparameters_from.to_string())
        }
    };
    if let (Some(_), Some(l)) = (&recorded, learner) {
        return Err(errors::input(format!(
            "learner={:?} with resume: a run resumes with its own learner",
            l.name()
        )));
    }
    let learner = settings.learner;
    if return_models && !learner.is_gdm() {
        return Err(errors::input(format!(
            "return_models=True gives GDM objects: the {learner} learner's models are not GDMs \
             (its figures are in the metrics; with out= its model files are in the run directory)"
        )));
    }
    let jobs = jobs.unwrap_or_else(experiment::default_jobs);

    let (x, n, dim) = features(&features_, None)?;
    let collection: Vec<u32> = ids("collection", &collection, n)?;
    let category: Vec<u32> = ids("category", &category, n)?;
    let instance: Vec<u32> = ids("instance", &instance, n)?;
    let sequence: Vec<u64> = ids("sequence", &sequence, n)?;
    let frame: Vec<u32> = ids("frame", &frame, n)?;
    let table = Table {
        features: x,
        dim,
        collection: &collection,
        category: &category,
        instance: &instance,
        sequence: &sequence,
        frame: &frame,
        train_collections: &train_collections,
        test_collections: &test_collections,
        category_names: &categories,
        instance_names: &instances,
    };
    let experiment = Experiment::new(table, settings).map_err(experiment_error)?;
    let Some(dir) = out else {
        let runs = py
            .detach(|| experiment.run(jobs, &|_| {}))
            .map_err(experiment_error)?;
        let (models, records): (Vec<_>, Vec<_>) = runs.into_iter().unzip();
        let models = if return_models {
            models
                .into_iter()
                .filter_map(|m| m.into_gdm().map(Model::from_gdm))
                .collect()
        } else {
            Vec::new()
        };
        let metrics = experiment.metrics(records, encoder, dataset);
        return Ok((metrics.to_json(), models));
    };
    // A run directory, as `lgdm train --out` (or `--resume`) leaves it, plots included.
    let provenance = Provenance {
        encoder: encoder.into(),
        dataset: dataset.into(),
        hyperparameters_from,
        ae_checkpoint: None,
        ae_checkpoint_fnv1a: None,
    };
    let run_config = RunConfig::new(&experiment, &provenance);
    let trials = experiment.settings().trials;
    let (run_dir, finished) = if resume {
        let run_dir = RunDir::resume(&dir, &run_config).map_err(experiment_error)?;
        let finished = run_dir.finished_trials(trials).map_err(experiment_error)?;
        (run_dir, finished)
    } else {
        let run_dir = RunDir::create(&dir, force).map_err(experiment_error)?;
        run_dir
            .write_config(&run_config)
            .map_err(experiment_error)?;
        (run_dir, vec![None; trials])
    };
    let metrics = py
        .detach(|| run_dir.play(&experiment, finished, jobs, &|_| {}, encoder, dataset))
        .map_err(experiment_error)?;
    let models = (0..if return_models { trials } else { 0 })
        .map(|t| {
            let path = dir.join(run_dir::model_file(t));
            lgdm_gdm::Gdm::load(&path)
                .map(Model::from_gdm)
                .map_err(|e| errors::input(format!("{}: {e}", path.display())))
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok((metrics.to_json(), models))
}

/// `lgdm merge` for Python (`lgdm.merge_runs`): the run directories `runs`, checked to be one
/// experiment, merged into the new run directory `out`; returns `metrics.json`'s text.
#[pyfunction]
#[pyo3(signature = (runs, out, *, force=false))]
pub fn merge_runs(
    py: Python<'_>,
    runs: Vec<PathBuf>,
    out: PathBuf,
    force: bool,
) -> PyResult<String> {
    let (merged, _missing) = py
        .detach(|| run_dir::merge_into(&runs, &out, force))
        .map_err(experiment_error)?;
    Ok(merged.metrics.to_json())
}
