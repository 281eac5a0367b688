//! `lgdm._lgdm.Model`: the native dual-memory model behind the Python class `lgdm.GDM`.
//!
//! The Python layer (`lgdm/_gdm.py`) turns whatever the user passes into C-contiguous arrays
//! (`float32` features, `int64` labels and sequence ids); this layer checks shapes and label
//! ranges, builds [`Sample`]s that borrow the arrays' memory (no copy), and runs the model with
//! the GIL released.
//!
//! Threads: one `Model` may be used from several Python threads. The model sits behind a
//! read-write lock taken with the GIL released: calls that change it (`train`, `end_episode`,
//! `replay`) run one at a time and wait for the calls that read it (`predict`, `evaluate`,
//! `to_bytes`, …), which run in parallel with each other. Every call is applied whole, in the
//! order the lock grants it; none is lost or interleaved with another. A Rust panic inside a
//! call (a bug) becomes `InternalError` (an `lgdm.LgdmError`); if the call was changing the
//! model, the model (possibly half-updated) then refuses every later call with that error.
//!
//! Conventions shared with the Python API:
//! - label arrays: `-1` means "no label"; any other value must be in `0..=u32::MAX`.
//! - sequence ids: `≥ 0`; no sequence array means "this call is one new sequence", realised
//!   with an id from the reserved range `2⁶³..` that differs from the last trained sample's.
//!
//! ```ignore
//! let m = Model::new(r#"{"preset": "paper_batch"}"#, 2)?;   // from Python: Model(json, 2)
//! ```

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::RwLock;
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

/// Sequence ids: the given array (values ≥ 0), or `None` when there is none (the caller then
/// picks one new id for the whole batch).
fn sequences(arr: Option<&PyReadonlyArray1<'_, i64>>, n: usize) -> PyResult<Option<Vec<u64>>> {
    let Some(arr) = arr else {
        return Ok(None);
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
        .collect::<PyResult<Vec<u64>>>()
        .map(Some)
}

/// Owned per-sample metadata; [`Batch::samples`] borrows it together with the features.
struct Batch {
    /// Per-sample sequence ids; `None`: the batch is one new sequence.
    sequence: Option<Vec<u64>>,
    instance: Vec<Option<u32>>,
    category: Vec<Option<u32>>,
}

impl Batch {
    /// Checks the label and sequence arrays of a batch of `n` samples.
    fn new(
        n: usize,
        instance: Option<&PyReadonlyArray1<'_, i64>>,
        category: Option<&PyReadonlyArray1<'_, i64>>,
        sequence: Option<&PyReadonlyArray1<'_, i64>>,
    ) -> PyResult<Batch> {
        Ok(Batch {
            instance: labels("instance", instance, n)?,
            category: labels("category", category, n)?,
            sequence: sequences(sequence, n)?,
        })
    }

    /// The samples; without sequence ids, every sample gets the new id `auto`.
    fn samples<'a>(&'a self, x: &'a [f32], d: usize, auto: u64) -> Vec<Sample<'a>> {
        x.chunks_exact(d)
            .enumerate()
            .zip(self.instance.iter().zip(&self.category))
            .map(|((i, x), (&instance, &category))| Sample {
                x,
                sequence: self.sequence.as_ref().map_or(auto, |s| s[i]),
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
///
/// Safe to share between threads (see the module docs): `frozen`, so pyo3 keeps no borrow flag
/// ("Already borrowed" cannot occur); the model sits behind [`RwLock`], always taken with the
/// GIL released.
#[pyclass(module = "lgdm._lgdm", name = "Model", frozen)]
#[derive(Debug)]
pub struct Model {
    /// Input dimension (fixed for the model's life; read without the lock).
    dim: usize,
    gdm: RwLock<Gdm>,
}

/// Why a call could not run.
enum Refusal {
    /// The call panicked (the message); `changing`: while holding the model exclusively.
    Panic { msg: String, changing: bool },
    /// An earlier call panicked while changing the model.
    Poisoned,
}

impl Refusal {
    fn into_err(self) -> PyErr {
        match self {
            Refusal::Panic { msg, changing } => errors::new(
                Kind::Internal,
                if changing {
                    format!(
                        "internal error (a bug in lgdm, please report it): {msg}; the model may \
                         be half-updated and refuses further calls: load it again from a \
                         checkpoint"
                    )
                } else {
                    format!("internal error (a bug in lgdm, please report it): {msg}")
                },
            ),
            Refusal::Poisoned => errors::new(
                Kind::Internal,
                "an earlier call on this model failed with an internal error and may have left \
                 it half-updated; it refuses further calls: load it again from a checkpoint",
            ),
        }
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_string())
}

impl Model {
    /// Wraps a model (e.g. one trained by `lgdm.run_scenario`).
    pub fn from_gdm(gdm: Gdm) -> Model {
        Model {
            dim: gdm.dim(),
            gdm: RwLock::new(gdm),
        }
    }

    /// Runs `f` on the wrapped model under the read lock, with the GIL released.
    pub fn with_gdm<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&Gdm) -> R + Send,
    ) -> PyResult<R> {
        self.read(py, f)
    }

    /// `f` on the model under the shared (read) lock, GIL released while waiting and running.
    fn read<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&Gdm) -> R + Send) -> PyResult<R> {
        py.detach(|| {
            catch_unwind(AssertUnwindSafe(|| {
                let gdm = self.gdm.read().map_err(|_| Refusal::Poisoned)?;
                Ok(f(&gdm))
            }))
            .unwrap_or_else(|p| {
                Err(Refusal::Panic {
                    msg: panic_message(&*p),
                    changing: false,
                })
            })
        })
        .map_err(Refusal::into_err)
    }

    /// `f` on the model under the exclusive (write) lock, GIL released while waiting and
    /// running. A panic in `f` unwinds through the guard, which poisons the lock.
    fn write<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut Gdm) -> R + Send) -> PyResult<R> {
        py.detach(|| {
            catch_unwind(AssertUnwindSafe(|| {
                let mut gdm = self.gdm.write().map_err(|_| Refusal::Poisoned)?;
                Ok(f(&mut gdm))
            }))
            .unwrap_or_else(|p| {
                Err(Refusal::Panic {
                    msg: panic_message(&*p),
                    changing: true,
                })
            })
        })
        .map_err(Refusal::into_err)
    }
}

#[pymethods]
impl Model {
    /// A new, untrained model: `config` is JSON (see `lgdm.GDM`), `dim` the feature count.
    #[new]
    fn new(config: &str, dim: usize) -> PyResult<Model> {
        let config = config_from_json(config)?;
        let gdm = Gdm::new(config, dim).map_err(errors::gdm)?;
        Ok(Model::from_gdm(gdm))
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
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.read(py, |gdm| gdm.to_bytes())?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Writes the checkpoint file atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.read(py, |gdm| gdm.save(&path))?
            .map_err(|e| errors::checkpoint(e, Some(&path)))
    }

    /// A deep copy.
    fn copy(&self, py: Python<'_>) -> PyResult<Model> {
        Ok(Model::from_gdm(self.read(py, Gdm::clone)?))
    }

    /// Input dimension.
    #[getter]
    fn dim(&self) -> usize {
        self.dim
    }

    /// Episodic node count.
    #[getter]
    fn n_episodic(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, |gdm| gdm.episodic().len())
    }

    /// Semantic node count.
    #[getter]
    fn n_semantic(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, |gdm| gdm.semantic().len())
    }

    /// Checkpoint size in bytes.
    #[getter]
    fn size_bytes(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, Gdm::size_bytes)
    }

    /// The full config as JSON.
    #[getter]
    fn config_json(&self, py: Python<'_>) -> PyResult<String> {
        self.read(py, |gdm| {
            serde_json::to_string(gdm.config()).expect("a config serialises to JSON")
        })
    }

    /// Sequence id of the last trained sample, if the next sample could continue it.
    #[getter]
    fn last_sequence(&self, py: Python<'_>) -> PyResult<Option<u64>> {
        self.read(py, Gdm::current_sequence)
    }

    /// `epochs` passes over the samples (ending an episode after each if `end_episodes`);
    /// returns the last pass's statistics. The whole call holds the model: calls from other
    /// threads come before or after it, never in between.
    #[pyo3(signature = (x, instance=None, category=None, sequence=None, epochs=1, end_episodes=false))]
    #[allow(clippy::too_many_arguments)]
    fn train<'py>(
        &self,
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
        let (xs, n, d) = features(&x, Some(self.dim))?;
        let batch = Batch::new(n, instance.as_ref(), category.as_ref(), sequence.as_ref())?;
        let result = self.write(py, |gdm| {
            // Under the lock: the new sequence differs from whatever was trained last.
            let auto = auto_sequence(gdm.current_sequence());
            let samples = batch.samples(xs, d, auto);
            let mut stats = None;
            for _ in 0..epochs {
                stats = Some(gdm.train(&samples)?);
                if end_episodes {
                    gdm.end_episode();
                }
            }
            Ok(stats.expect("epochs ≥ 1"))
        })?;
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
        let (xs, n, d) = features(&x, Some(self.dim))?;
        let batch = Batch::new(n, None, None, sequence.as_ref())?;
        let predictions = self
            .read(py, |gdm| {
                gdm.predict(&batch.samples(xs, d, 0), PredictOptions { no_context })
            })?
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
        let (xs, n, d) = features(&x, Some(self.dim))?;
        let batch = Batch::new(n, instance.as_ref(), category.as_ref(), sequence.as_ref())?;
        let scores = self
            .read(py, |gdm| {
                gdm.evaluate(&batch.samples(xs, d, 0), PredictOptions { no_context })
            })?
            .map_err(errors::gdm)?;
        scores_dict(py, &scores)
    }

    /// Ends an episode: isolated-node removal; the next sample starts a new sequence.
    fn end_episode(&self, py: Python<'_>) -> PyResult<()> {
        self.write(py, Gdm::end_episode)
    }

    /// Intrinsic replay; returns `{"chains": …, "samples": …}`.
    fn replay<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let stats = self.write(py, Gdm::replay)?.map_err(errors::gdm)?;
        let out = PyDict::new(py);
        out.set_item("chains", stats.chains)?;
        out.set_item("samples", stats.samples)?;
        Ok(out)
    }

    /// Test hook: panics while holding the model exclusively, as a bug inside a training call
    /// would. Raises `InternalError`; the model then refuses every call.
    fn _panic_for_tests(&self, py: Python<'_>) -> PyResult<()> {
        self.write(py, |_| -> () {
            panic!("panic requested by _panic_for_tests")
        })
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
        let (xs, n, d) = features(&x, Some(self.dim))?;
        let batch = Batch::new(n, None, None, None)?;
        self.read(py, |gdm| {
            let samples = batch.samples(xs, d, 0);
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
        })?
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
        let (xs, n, d) = features(&x, Some(self.dim))?;
        let batch = Batch::new(n, instance.as_ref(), category.as_ref(), None)?;
        self.read(py, |gdm| {
            let auto = auto_sequence(gdm.current_sequence());
            let samples = batch.samples(xs, d, auto);
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
        })?
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
