//! `lgdm._lgdm.Model`: the native dual-memory model behind the Python class `lgdm.GDM`.
//!
//! The Python layer (`lgdm/_gdm.py`) turns whatever the user passes into C-contiguous arrays
//! (`float32` features, `int64` labels and sequence ids); this layer checks shapes and label
//! ranges, builds [`Sample`]s that borrow the arrays' memory (no copy), and runs the model with
//! the GIL released.
//!
//! Conventions shared with the Python API:
//! - label arrays: `-1` means "no label"; any other value must be in `0..=u32::MAX`.
//! - sequence ids: `≥ 0`; no sequence array means "this call is one new sequence", realised
//!   with an id from the reserved range `2⁶³..` that differs from the last trained sample's.
//!
//! ```ignore
//! let mut m = Model::new(r#"{"preset": "paper_batch"}"#, 2)?;   // from Python: Model(json, 2)
//! ```

use std::path::PathBuf;
use std::time::Instant;

use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample, Scores};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::errors::{self, Kind};

/// First id of the range used for automatic sequence ids (user ids are int64 ≥ 0, below it).
pub const AUTO_SEQUENCE_BASE: u64 = 1 << 63;

/// Parses and validates a config given as JSON (optionally with a `"preset"` key).
pub fn config_from_json(text: &str) -> PyResult<GdmConfig> {
    let config: GdmConfig =
        serde_json::from_str(text).map_err(|e| errors::new(Kind::Config, e.to_string()))?;
    config.validate().map_err(|e| {
        let field = e.field().map(str::to_string);
        let err = errors::new(Kind::Config, e.to_string());
        if let Some(field) = field {
            Python::attach(|py| {
                // Best effort: the exception still carries the message if this fails.
                let _ = err.value(py).setattr("field", field);
            });
        }
        err
    })?;
    Ok(config)
}

/// The full config of `text` as JSON (every field, no `preset` key).
#[pyfunction]
pub fn config_json(text: &str) -> PyResult<String> {
    let config = config_from_json(text)?;
    Ok(serde_json::to_string(&config).expect("a config serialises to JSON"))
}

/// An id for "a new sequence" that differs from `last`.
pub fn auto_sequence(last: Option<u64>) -> u64 {
    match last {
        Some(s) if s >= AUTO_SEQUENCE_BASE => s.wrapping_add(1).max(AUTO_SEQUENCE_BASE),
        _ => AUTO_SEQUENCE_BASE,
    }
}

/// The features as one slice plus (n, d), checked against the model's dimension.
pub(crate) fn features<'a>(
    x: &'a PyReadonlyArray2<'_, f32>,
    dim: Option<usize>,
) -> PyResult<(&'a [f32], usize, usize)> {
    let shape = x.shape();
    let (n, d) = (shape[0], shape[1]);
    if n == 0 {
        return Err(errors::input("X holds no samples (shape (0, d))"));
    }
    if let Some(dim) = dim
        && d != dim
    {
        return Err(errors::input(format!(
            "X has {d} features per sample, but the model was fitted with {dim}"
        )));
    }
    let slice = x
        .as_slice()
        .map_err(|e| errors::input(format!("X must be C-contiguous: {e}")))?;
    Ok((slice, n, d))
}

/// A label array: `-1` → none, `0..=u32::MAX` → the label, anything else → `InputError`.
fn labels(
    name: &str,
    arr: Option<&PyReadonlyArray1<'_, i64>>,
    n: usize,
) -> PyResult<Vec<Option<u32>>> {
    let Some(arr) = arr else {
        return Ok(vec![None; n]);
    };
    let values = arr
        .as_slice()
        .map_err(|e| errors::input(format!("{name} must be C-contiguous: {e}")))?;
    if values.len() != n {
        return Err(errors::input(format!(
            "{name} has {} entries but X has {n} samples",
            values.len()
        )));
    }
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| match v {
            -1 => Ok(None),
            v => u32::try_from(v).map(Some).map_err(|_| {
                errors::input(format!(
                    "{name}[{i}] = {v} is not a label: labels are integers in 0..={}, or -1 for \
                     \"no label\"",
                    u32::MAX
                ))
            }),
        })
        .collect()
}

/// Sequence ids: the given array (values ≥ 0), or `auto` for every sample.
fn sequences(arr: Option<&PyReadonlyArray1<'_, i64>>, n: usize, auto: u64) -> PyResult<Vec<u64>> {
    let Some(arr) = arr else {
        return Ok(vec![auto; n]);
    };
    let values = arr
        .as_slice()
        .map_err(|e| errors::input(format!("sequence must be C-contiguous: {e}")))?;
    if values.len() != n {
        return Err(errors::input(format!(
            "sequence has {} entries but X has {n} samples",
            values.len()
        )));
    }
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            u64::try_from(v).map_err(|_| {
                errors::input(format!("sequence[{i}] = {v}: sequence ids must be ≥ 0"))
            })
        })
        .collect()
}

/// Owned per-sample metadata; [`Batch::samples`] borrows it together with the features.
struct Batch {
    sequence: Vec<u64>,
    instance: Vec<Option<u32>>,
    category: Vec<Option<u32>>,
}

impl Batch {
    fn samples<'a>(&'a self, x: &'a [f32], d: usize) -> Vec<Sample<'a>> {
        x.chunks_exact(d)
            .zip(&self.sequence)
            .zip(self.instance.iter().zip(&self.category))
            .map(|((x, &sequence), (&instance, &category))| Sample {
                x,
                sequence,
                instance,
                category,
            })
            .collect()
    }
}

fn scores_dict<'py>(py: Python<'py>, s: &Scores) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n", s.n)?;
    d.set_item("instance_accuracy", s.instance_accuracy)?;
    d.set_item("category_accuracy_em", s.category_accuracy_em)?;
    d.set_item("category_accuracy_sm", s.category_accuracy_sm)?;
    d.set_item("quantization_error_em", s.quantization_error_em)?;
    d.set_item("quantization_error_sm", s.quantization_error_sm)?;
    Ok(d)
}

fn label_array(labels: impl Iterator<Item = Option<u32>>) -> Vec<i64> {
    labels.map(|l| l.map_or(-1, i64::from)).collect()
}

/// Predictions as arrays: instance, category (semantic), activation, category (episodic).
type PredictArrays<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<i64>>,
);

/// The native Growing Dual-Memory model. Use `lgdm.GDM`; this class is its engine.
#[pyclass(module = "lgdm._lgdm", name = "Model")]
#[derive(Debug, Clone)]
pub struct Model {
    gdm: Gdm,
}

impl Model {
    /// The wrapped model.
    pub fn gdm(&self) -> &Gdm {
        &self.gdm
    }

    /// Wraps a model (e.g. one trained by `lgdm.run_scenario`).
    pub fn from_gdm(gdm: Gdm) -> Model {
        Model { gdm }
    }

    fn batch(
        &self,
        n: usize,
        instance: Option<&PyReadonlyArray1<'_, i64>>,
        category: Option<&PyReadonlyArray1<'_, i64>>,
        sequence: Option<&PyReadonlyArray1<'_, i64>>,
        auto: u64,
    ) -> PyResult<Batch> {
        Ok(Batch {
            instance: labels("instance", instance, n)?,
            category: labels("category", category, n)?,
            sequence: sequences(sequence, n, auto)?,
        })
    }
}

#[pymethods]
impl Model {
    /// A new, untrained model: `config` is JSON (see `lgdm.GDM`), `dim` the feature count.
    #[new]
    fn new(config: &str, dim: usize) -> PyResult<Model> {
        let config = config_from_json(config)?;
        let gdm = Gdm::new(config, dim).map_err(errors::gdm)?;
        Ok(Model { gdm })
    }

    /// Reads a model from checkpoint bytes.
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Model> {
        let gdm = py
            .detach(|| Gdm::from_bytes(data))
            .map_err(|e| errors::checkpoint(e, None))?;
        Ok(Model::from_gdm(gdm))
    }

    /// Reads a checkpoint file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        let gdm = py
            .detach(|| Gdm::load(&path))
            .map_err(|e| errors::checkpoint(e, Some(&path)))?;
        Ok(Model::from_gdm(gdm))
    }

    /// The checkpoint bytes (identical to the file `save` writes).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let bytes = py.detach(|| self.gdm.to_bytes());
        PyBytes::new(py, &bytes)
    }

    /// Writes the checkpoint file atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.gdm.save(&path))
            .map_err(|e| errors::checkpoint(e, Some(&path)))
    }

    /// A deep copy.
    fn copy(&self) -> Model {
        self.clone()
    }

    /// Input dimension.
    #[getter]
    fn dim(&self) -> usize {
        self.gdm.dim()
    }

    /// Episodic node count.
    #[getter]
    fn n_episodic(&self) -> usize {
        self.gdm.episodic().len()
    }

    /// Semantic node count.
    #[getter]
    fn n_semantic(&self) -> usize {
        self.gdm.semantic().len()
    }

    /// Checkpoint size in bytes.
    #[getter]
    fn size_bytes(&self) -> usize {
        self.gdm.size_bytes()
    }

    /// The full config as JSON.
    #[getter]
    fn config_json(&self) -> String {
        serde_json::to_string(self.gdm.config()).expect("a config serialises to JSON")
    }

    /// Sequence id of the last trained sample, if the next sample could continue it.
    #[getter]
    fn last_sequence(&self) -> Option<u64> {
        self.gdm.current_sequence()
    }

    /// `epochs` passes over the samples (ending an episode after each if `end_episodes`);
    /// returns the last pass's statistics.
    #[pyo3(signature = (x, instance=None, category=None, sequence=None, epochs=1, end_episodes=false))]
    #[allow(clippy::too_many_arguments)]
    fn train<'py>(
        &mut self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f32>,
        instance: Option<PyReadonlyArray1<'py, i64>>,
        category: Option<PyReadonlyArray1<'py, i64>>,
        sequence: Option<PyReadonlyArray1<'py, i64>>,
        epochs: usize,
        end_episodes: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        if epochs == 0 {
            return Err(errors::input("epochs must be at least 1"));
        }
        let (xs, n, d) = features(&x, Some(self.gdm.dim()))?;
        let auto = auto_sequence(self.gdm.current_sequence());
        let batch = self.batch(
            n,
            instance.as_ref(),
            category.as_ref(),
            sequence.as_ref(),
            auto,
        )?;
        let gdm = &mut self.gdm;
        let result = py.detach(|| {
            let samples = batch.samples(xs, d);
            let mut stats = None;
            for _ in 0..epochs {
                stats = Some(gdm.train(&samples)?);
                if end_episodes {
                    gdm.end_episode();
                }
            }
            Ok(stats.expect("epochs ≥ 1"))
        });
        let stats = result.map_err(errors::gdm)?;
        let out = PyDict::new(py);
        out.set_item("samples", stats.samples)?;
        out.set_item("episodic_nodes", stats.episodic_nodes)?;
        out.set_item("semantic_nodes", stats.semantic_nodes)?;
        out.set_item("quantization_error_em", stats.quantization_error_em)?;
        out.set_item("quantization_error_sm", stats.quantization_error_sm)?;
        Ok(out)
    }

    /// Predictions: (instance, category, activation, category_em); -1 where no label.
    #[pyo3(signature = (x, sequence=None, no_context=false))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f32>,
        sequence: Option<PyReadonlyArray1<'py, i64>>,
        no_context: bool,
    ) -> PyResult<PredictArrays<'py>> {
        let (xs, n, d) = features(&x, Some(self.gdm.dim()))?;
        let batch = self.batch(n, None, None, sequence.as_ref(), 0)?;
        let gdm = &self.gdm;
        let predictions = py
            .detach(|| gdm.predict(&batch.samples(xs, d), PredictOptions { no_context }))
            .map_err(errors::gdm)?;
        let instance = label_array(predictions.iter().map(|p| p.instance));
        let category = label_array(predictions.iter().map(|p| p.category));
        let category_em = label_array(predictions.iter().map(|p| p.category_em));
        let activation: Vec<f32> = predictions.iter().map(|p| p.activation).collect();
        Ok((
            instance.into_pyarray(py),
            category.into_pyarray(py),
            activation.into_pyarray(py),
            category_em.into_pyarray(py),
        ))
    }

    /// Scores against the given labels (see `GDM.evaluate`).
    #[pyo3(signature = (x, instance=None, category=None, sequence=None, no_context=false))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f32>,
        instance: Option<PyReadonlyArray1<'py, i64>>,
        category: Option<PyReadonlyArray1<'py, i64>>,
        sequence: Option<PyReadonlyArray1<'py, i64>>,
        no_context: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (xs, n, d) = features(&x, Some(self.gdm.dim()))?;
        let batch = self.batch(
            n,
            instance.as_ref(),
            category.as_ref(),
            sequence.as_ref(),
            0,
        )?;
        let gdm = &self.gdm;
        let scores = py
            .detach(|| gdm.evaluate(&batch.samples(xs, d), PredictOptions { no_context }))
            .map_err(errors::gdm)?;
        scores_dict(py, &scores)
    }

    /// Ends an episode: isolated-node removal; the next sample starts a new sequence.
    fn end_episode(&mut self, py: Python<'_>) {
        let gdm = &mut self.gdm;
        py.detach(|| gdm.end_episode());
    }

    /// Intrinsic replay; returns `{"chains": …, "samples": …}`.
    fn replay<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let gdm = &mut self.gdm;
        let stats = py.detach(|| gdm.replay()).map_err(errors::gdm)?;
        let out = PyDict::new(py);
        out.set_item("chains", stats.chains)?;
        out.set_item("samples", stats.samples)?;
        Ok(out)
    }

    /// Benchmark helper: seconds of each of `repeats` native `predict` calls on the same
    /// prepared samples (array conversion and sample construction not timed).
    #[pyo3(signature = (x, repeats=1))]
    fn _bench_predict(
        &self,
        py: Python<'_>,
        x: PyReadonlyArray2<'_, f32>,
        repeats: usize,
    ) -> PyResult<Vec<f64>> {
        let (xs, n, d) = features(&x, Some(self.gdm.dim()))?;
        let batch = self.batch(n, None, None, None, 0)?;
        let gdm = &self.gdm;
        py.detach(|| {
            let samples = batch.samples(xs, d);
            (0..repeats)
                .map(|_| {
                    let t0 = Instant::now();
                    let p = gdm.predict(&samples, PredictOptions::default());
                    let dt = t0.elapsed().as_secs_f64();
                    p.map(|p| {
                        std::hint::black_box(p);
                        dt
                    })
                })
                .collect::<Result<Vec<f64>, _>>()
        })
        .map_err(errors::gdm)
    }

    /// Benchmark helper: seconds of each of `repeats` native `train` calls (one pass, one new
    /// sequence), each on a fresh copy of this model (copying not timed); the model is unchanged.
    #[pyo3(signature = (x, instance=None, category=None, repeats=1))]
    fn _bench_train<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f32>,
        instance: Option<PyReadonlyArray1<'py, i64>>,
        category: Option<PyReadonlyArray1<'py, i64>>,
        repeats: usize,
    ) -> PyResult<Vec<f64>> {
        let (xs, n, d) = features(&x, Some(self.gdm.dim()))?;
        let auto = auto_sequence(self.gdm.current_sequence());
        let batch = self.batch(n, instance.as_ref(), category.as_ref(), None, auto)?;
        let gdm = &self.gdm;
        py.detach(|| {
            let samples = batch.samples(xs, d);
            (0..repeats)
                .map(|_| {
                    let mut fresh = gdm.clone();
                    let t0 = Instant::now();
                    let stats = fresh.train(&samples);
                    let dt = t0.elapsed().as_secs_f64();
                    stats.map(|s| {
                        std::hint::black_box(s);
                        dt
                    })
                })
                .collect::<Result<Vec<f64>, _>>()
        })
        .map_err(errors::gdm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_sequence_differs_from_the_last() {
        for last in [
            None,
            Some(0),
            Some(5),
            Some(AUTO_SEQUENCE_BASE),
            Some(u64::MAX),
        ] {
            let a = auto_sequence(last);
            assert!(a >= AUTO_SEQUENCE_BASE);
            assert_ne!(Some(a), last);
        }
    }
}
