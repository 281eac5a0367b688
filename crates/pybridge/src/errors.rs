//! Rust errors → the Python exception hierarchy under `lgdm.LgdmError`.
//!
//! The exception classes are defined in Python (`lgdm/_errors.py`), because `InputError`,
//! `ConfigError` and `NotFittedError` also derive from `ValueError`, and pyo3's
//! `create_exception!` takes one base only. This module looks the classes up once and builds
//! errors carrying the Rust error's message:
//!
//! ```ignore
//! return Err(errors::input("X must be 2-D"));   // raises lgdm.InputError
//! ```

use lgdm_gdm::{CheckpointError, GdmError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;

/// The Python exception classes of `lgdm._errors`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `lgdm.LgdmError`: the base class.
    Lgdm,
    /// `lgdm.ConfigError`: a bad hyperparameter or preset name.
    Config,
    /// `lgdm.InputError`: bad data (shape, dtype, NaN, label range, empty batch).
    Input,
    /// `lgdm.NotFittedError`: the model has no nodes yet.
    NotFitted,
    /// `lgdm.CheckpointError`: a model file that cannot be read or written.
    Checkpoint,
    /// `lgdm.DatasetError`: a dataset that cannot be opened or read.
    Dataset,
    /// `lgdm._errors.InternalError` (an `LgdmError`): a bug (a Rust panic) interrupted a call;
    /// the model it was changing refuses further calls.
    Internal,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Lgdm => "LgdmError",
            Kind::Config => "ConfigError",
            Kind::Input => "InputError",
            Kind::NotFitted => "NotFittedError",
            Kind::Checkpoint => "CheckpointError",
            Kind::Dataset => "DatasetError",
            Kind::Internal => "InternalError",
        }
    }
}

static CLASSES: PyOnceLock<[Py<PyType>; 7]> = PyOnceLock::new();

fn class(py: Python<'_>, kind: Kind) -> PyResult<Bound<'_, PyType>> {
    let classes = CLASSES.get_or_try_init(py, || -> PyResult<[Py<PyType>; 7]> {
        let m = py.import("lgdm._errors")?;
        let get = |k: Kind| -> PyResult<Py<PyType>> {
            Ok(m.getattr(k.name())?.cast_into::<PyType>()?.unbind())
        };
        Ok([
            get(Kind::Lgdm)?,
            get(Kind::Config)?,
            get(Kind::Input)?,
            get(Kind::NotFitted)?,
            get(Kind::Checkpoint)?,
            get(Kind::Dataset)?,
            get(Kind::Internal)?,
        ])
    })?;
    Ok(classes[kind as usize].bind(py).clone())
}

/// A Python exception of `kind` with `message`. If the classes cannot be imported (a broken
/// install), the import error is returned instead, so nothing is silently lost.
pub fn new(kind: Kind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::attach(|py| match class(py, kind) {
        Ok(cls) => PyErr::from_type(cls, message),
        Err(e) => e,
    })
}

/// `lgdm.InputError(message)`.
pub fn input(message: impl Into<String>) -> PyErr {
    new(Kind::Input, message)
}

/// The exception class for a model error.
pub fn gdm_kind(err: &GdmError) -> Kind {
    match err {
        GdmError::Config(_) => Kind::Config,
        GdmError::ZeroDimension
        | GdmError::DimensionTooLarge { .. }
        | GdmError::EmptyBatch
        | GdmError::DimensionMismatch { .. }
        | GdmError::NonFinite { .. } => Kind::Input,
        GdmError::NotTrained => Kind::NotFitted,
        GdmError::Learner(_) => Kind::Config,
        GdmError::Checkpoint(_) => Kind::Checkpoint,
    }
}

/// A model error as the matching Python exception.
pub fn gdm(err: GdmError) -> PyErr {
    new(gdm_kind(&err), err.to_string())
}

/// A checkpoint error as `lgdm.CheckpointError`, with the file named when there is one.
pub fn checkpoint(err: CheckpointError, path: Option<&std::path::Path>) -> PyErr {
    match path {
        Some(p) => new(Kind::Checkpoint, format!("{}: {err}", p.display())),
        None => new(Kind::Checkpoint, err.to_string()),
    }
}
