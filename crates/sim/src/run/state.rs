//! Where a run is after its finished rounds ([`RunState`]): what a job checkpoints after every
//! round and resumes from.

use serde::{Deserialize, Serialize};

use crate::recognition::recognizer::{MemoryPoint, Recognizer, RecognizerState};
use crate::run::error::SimError;
use crate::run::results::{AttemptRecord, RoundRecord, RunWall};
use crate::tasks::arrival::Evaluation;

/// Where a run is after its finished rounds: everything the rest of it depends on besides the
/// recognizer's model (saved beside it). A job writes it after every round
/// ([`crate::run::run_dir::PROGRESS_FILE`]) and resumes from it: the resumed run's results, model
/// and recordings equal those of a run that was never stopped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// Rounds finished.
    pub rounds_done: usize,
    /// Their attempts.
    pub attempts: Vec<AttemptRecord>,
    /// Their records.
    pub rounds: Vec<RoundRecord>,
    /// Node counts at the start and after each round (with recognition).
    pub memory: Vec<MemoryPoint>,
    /// The recognizer beyond its model (with recognition).
    pub recognizer: Option<RecognizerState>,
    /// The grasp source's state, when it has one ([`crate::grasping::source::GraspSource::state`]).
    pub source: Option<serde_json::Value>,
    /// Categories arriving over time: the evaluation when the late ones arrived, once made.
    pub at_switch: Option<Evaluation>,
    /// Simulated seconds of the finished rounds.
    pub sim_s: f64,
    /// Wall seconds so far (not deterministic): setting tables, replay, evaluations.
    pub wall: RunWall,
}

/// Called after every round with the run's state and the recognizer (whose model goes with it).
pub(crate) type Checkpoint<'a> =
    &'a mut dyn FnMut(&RunState, Option<&Recognizer>) -> Result<(), SimError>;
