//! Typed errors of the crate: bad configuration, bad input, bad checkpoint.
//!
//! Every fallible public function returns one of these; none of them panics on bad input.
//!
//! ```
//! use lgdm_gdm::{Gdm, GdmConfig, GdmError, Sample};
//! let mut gdm = Gdm::new(GdmConfig::default(), 2).unwrap();
//! let x = [1.0, f32::NAN];
//! let err = gdm.train(&[Sample::unlabelled(&x, 0)]).unwrap_err();
//! assert!(matches!(err, GdmError::NonFinite { sample: 0, position: 1 }));
//! ```

use thiserror::Error;

/// A hyperparameter that fails validation, or an unknown preset name.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// A field holds a value outside its allowed range.
    #[error("invalid config field `{field}`: {reason}")]
    Invalid {
        /// Dotted path of the field, e.g. `episodic.activation_threshold`.
        field: String,
        /// What is wrong with the value.
        reason: String,
    },
    /// [`GdmConfig::preset`](crate::GdmConfig::preset) was given a name it does not know.
    #[error("unknown preset `{name}` (known: {known})")]
    UnknownPreset {
        /// The name asked for.
        name: String,
        /// Comma-separated list of the known presets.
        known: String,
    },
}

impl ConfigError {
    pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The dotted field path for [`ConfigError::Invalid`], `None` otherwise.
    pub fn field(&self) -> Option<&str> {
        match self {
            ConfigError::Invalid { field, .. } => Some(field),
            ConfigError::UnknownPreset { .. } => None,
        }
    }
}

/// Errors of training, prediction and evaluation.
#[derive(Debug, Error)]
pub enum GdmError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The model's input dimension must be at least 1.
    #[error("input dimension must be at least 1")]
    ZeroDimension,
    /// The model's input dimension exceeds [`MAX_DIM`](crate::config::MAX_DIM).
    #[error("input dimension {dim} is larger than {max}")]
    DimensionTooLarge {
        /// The dimension asked for.
        dim: usize,
        /// The largest dimension a model accepts.
        max: usize,
    },
    /// A call got no samples.
    #[error("empty batch: at least one sample is required")]
    EmptyBatch,
    /// A sample's feature vector has the wrong length.
    #[error("sample {sample}: expected {expected} features, found {found}")]
    DimensionMismatch {
        /// Index of the sample in the batch.
        sample: usize,
        /// The model's input dimension.
        expected: usize,
        /// Length of the sample's feature vector.
        found: usize,
    },
    /// A sample holds NaN or an infinity.
    #[error("sample {sample}: feature {position} is not finite")]
    NonFinite {
        /// Index of the sample in the batch.
        sample: usize,
        /// Index of the first non-finite feature.
        position: usize,
    },
    /// Prediction needs at least one trained node in each memory.
    #[error("the model has not been trained yet (no nodes)")]
    NotTrained,
    /// The learner cannot do what was asked (a baseline asked to replay), or its arithmetic
    /// failed (a covariance that no shrinkage makes invertible).
    #[error("{0}")]
    Learner(String),
    /// A checkpoint could not be written or read.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

/// Errors of writing and reading checkpoints.
#[derive(Debug, Error)]
pub enum CheckpointError {
    /// The file could not be read or written.
    #[error("checkpoint I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The data does not start with the checkpoint magic bytes.
    #[error("not an lgdm checkpoint (bad magic bytes)")]
    BadMagic,
    /// The checkpoint was written by a format version this build does not read.
    #[error("unsupported checkpoint version {found} (this build reads versions 1 to {supported})")]
    Version {
        /// Version found in the header.
        found: u32,
        /// The version this build writes (it reads it and the older ones down to
        /// [`OLDEST_VERSION`](crate::checkpoint::OLDEST_VERSION)).
        supported: u32,
    },
    /// The data ends before the header or the declared payload does.
    #[error("truncated checkpoint: expected {expected} bytes, found {found}")]
    Truncated {
        /// Bytes the header promises (header + payload).
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The payload does not match its CRC-32 checksum.
    #[error(
        "checkpoint checksum mismatch: header says {expected:#010x}, payload gives {found:#010x}"
    )]
    Checksum {
        /// Checksum stored in the header.
        expected: u32,
        /// Checksum of the payload as read.
        found: u32,
    },
    /// The payload passed the checksum but its content is inconsistent.
    #[error("corrupt checkpoint: {0}")]
    Corrupt(String),
    /// The file holds a model of another learner than the reader's (a baseline's model read
    /// as a GDM checkpoint).
    #[error("a model of the {found} learner, not of the {expected} learner")]
    OtherLearner {
        /// The learner that wrote the file.
        found: String,
        /// The learner the reader reads.
        expected: String,
    },
    /// The configuration stored in the checkpoint is invalid.
    #[error("checkpoint holds an invalid config: {0}")]
    Config(#[from] ConfigError),
}
