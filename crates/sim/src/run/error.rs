//! Every error of a run: [`SimError`], one variant per part that can fail (a setting, the
//! objects, the world, perception, an attempt, the grasp source, recording, recognition, packing,
//! arrival, the start model, an observer, the run directory), and a stop asked for.

use std::path::PathBuf;

use crate::grasping::attempt::AttemptError;
use crate::grasping::source::{SourceError, UnknownSource};
use crate::perception::PerceptionError;
use crate::physics::error::WorldError;
use crate::recognition::error::RecognitionError;
use crate::recognition::model::ModelError;
use crate::run::observe::ObserverError;
use crate::run::record::RecordError;
use crate::tasks::arrival::ArrivalError;
use crate::tasks::packing::PackingError;

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A setting that cannot be used (named as the binary's option, without the dashes).
    #[error("{name} {value}: {reason}")]
    Setting {
        /// The setting (`rounds`, `attempts`, `objects`, `scenario`, `targets`, …).
        name: &'static str,
        /// Its value.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// The objects cannot be built or imported.
    #[error("the object library: {0}")]
    Objects(String),
    /// The object library is empty.
    #[error("the object library is empty")]
    EmptyLibrary,
    /// An unknown grasp source name.
    #[error(transparent)]
    UnknownSource(#[from] UnknownSource),
    /// A world error (a config field, an object whose hull cannot be built, an object larger
    /// than the table, a NaN state).
    #[error(transparent)]
    World(#[from] WorldError),
    /// Perception failed (a config field, a frame without a table).
    #[error(transparent)]
    Perception(#[from] PerceptionError),
    /// An attempt failed to run (not a failed grasp: an error).
    #[error(transparent)]
    Attempt(#[from] AttemptError),
    /// The grasp source failed.
    #[error("grasp source")]
    Source(#[from] SourceError),
    /// Recording a round failed.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// Recognition or learning failed.
    #[error("recognition")]
    Recognition(#[from] RecognitionError),
    /// A bad packing spec (an unknown target category, a missing basket).
    #[error("packing")]
    Packing(#[from] PackingError),
    /// A bad arrival plan.
    #[error("categories arriving over time")]
    Arrival(#[from] ArrivalError),
    /// The model to start from cannot be used (its file, its record, its encoder).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// An observer of the run failed (recording: a [`crate::run::record::RecordError`]).
    #[error(transparent)]
    Observer(ObserverError),
    /// The run was asked to stop ([`crate::run::job::StopToken`]); its run directory holds the
    /// rounds it finished, and `resume` plays the rest.
    #[error("stopped after {rounds_done} finished round(s)")]
    Stopped {
        /// Rounds finished and checkpointed.
        rounds_done: usize,
    },
    /// The run directory cannot be used or written.
    #[error("run directory {}: {reason}", path.display())]
    RunDir {
        /// The path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// A setting of a job that cannot be used.
pub(crate) fn setting(name: &'static str, value: impl ToString, reason: impl ToString) -> SimError {
    SimError::Setting {
        name,
        value: value.to_string(),
        reason: reason.to_string(),
    }
}
