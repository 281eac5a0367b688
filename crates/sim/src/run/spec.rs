//! What a run is: [`RunSpec`] (scenario, rounds, seed, attempt budget, packing, categories
//! arriving over time) with every constant in [`SimConfig`], checked once by
//! [`RunSpec::validate`] before anything is played or written; [`SimError`], every error of a
//! run; and the built-in grasp sources by name ([`builtin_source`]).
//!
//! ```
//! use lgdm_pointcloud::objects::{CATEGORIES, procedural_library};
//! use lgdm_sim::tasks::scenario::Scenario;
//! use lgdm_sim::run::spec::{RunSpec, SimError};
//! let library = procedural_library(&CATEGORIES[..2], 1, 0).unwrap();
//! let mut spec = RunSpec::new(Scenario::Isolated, 3, 0);
//! spec.validate(&library, None).unwrap();
//! spec.rounds = 0;
//! assert!(matches!(spec.validate(&library, None), Err(SimError::Setting { name: "rounds", .. })));
//! ```

use std::path::PathBuf;

use lgdm_base::seed::derive_seed;
use lgdm_pointcloud::objects::ObjectModel;
use serde::{Deserialize, Serialize};

use crate::grasping::attempt::AttemptError;
use crate::grasping::source::{AnalyticSource, GraspSource, RandomSource, SourceError};
use crate::perception::PerceptionError;
use crate::physics::world::WorldError;
use crate::recognition::model::ModelError;
use crate::recognition::recognize::{Labels, RecognitionError};
use crate::run::config::SimConfig;
use crate::run::observe::ObserverError;
use crate::run::record::RecordError;
use crate::tasks::arrival::{Arrival, ArrivalError};
use crate::tasks::packing::{PackingError, PackingSpec};
use crate::tasks::scenario::{Scenario, check_library};

/// Seed tag of a round's RNG.
pub(crate) const TAG_ROUND: u64 = 0x5133_0001;
/// Seed tag of the random grasp source.
const TAG_RANDOM_SOURCE: u64 = 0x5133_0002;

/// Checks every part of the config (here, with the run's errors, rather than in
/// [`crate::run::config`], which [`crate::run::results`] reads without them).
impl SimConfig {
    /// Checks every part.
    pub fn validate(&self) -> Result<(), SimError> {
        self.world.validate()?;
        self.robot.validate().map_err(AttemptError::from)?;
        self.cameras
            .validate()
            .map_err(|e| SimError::Perception(e.into()))?;
        self.attempt.validate()?;
        self.scenario.validate()?;
        Ok(())
    }
}

/// The most rounds a run may ask for (100,000 isolated rounds are ~10 h of this machine).
pub const MAX_ROUNDS: usize = 100_000;

/// The largest attempt budget a run may ask for (each attempt's record is ~2 KB in
/// `results.json`).
pub const MAX_ATTEMPTS: usize = 100_000;

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    /// The scenario.
    pub scenario: Scenario,
    /// Rounds to play (1 to [`MAX_ROUNDS`]).
    pub rounds: usize,
    /// Base seed.
    pub seed: u64,
    /// Where the objects came from (`procedural` or the meshes directory), for the record.
    pub objects: String,
    /// Stop after this many attempts in all (1 to [`MAX_ATTEMPTS`]; none: play every round).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_attempts: Option<usize>,
    /// Packing: each object goes to the basket of the category it is recognised as (none: every
    /// object to [`AttemptConfig::target_basket`]). Needs recognition ([`crate::run::runner::run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingSpec>,
    /// Categories arriving over time, and the end-of-run evaluation of the early ones (none: every
    /// round draws from the whole library). Needs recognition ([`crate::run::runner::run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival: Option<Arrival>,
    /// Every constant.
    pub config: SimConfig,
}

impl RunSpec {
    /// A run of the procedural objects with the default config.
    pub fn new(scenario: Scenario, rounds: usize, seed: u64) -> Self {
        Self {
            scenario,
            rounds,
            seed,
            objects: "procedural".into(),
            max_attempts: None,
            packing: None,
            arrival: None,
            config: SimConfig::default(),
        }
    }

    /// Checks the run before anything is played or written: rounds and attempt budget, the
    /// config, every object of `library` (its hull, its size on the table), and — with
    /// recognition, whose model knows `labels` — the packing targets and the arrival plan.
    /// Packing and arrival need recognition (`labels` is `None` without it).
    pub fn validate(
        &self,
        library: &[ObjectModel],
        labels: Option<&Labels>,
    ) -> Result<(), SimError> {
        if self.rounds == 0 {
            return Err(SimError::Setting {
                name: "rounds",
                value: "0".into(),
                reason: "at least one round is needed".into(),
            });
        }
        if self.rounds > MAX_ROUNDS {
            return Err(SimError::Setting {
                name: "rounds",
                value: self.rounds.to_string(),
                reason: format!("at most {MAX_ROUNDS} rounds a run"),
            });
        }
        if self.max_attempts.is_some_and(|a| a > MAX_ATTEMPTS) {
            return Err(SimError::Setting {
                name: "attempts",
                value: self.max_attempts.unwrap_or_default().to_string(),
                reason: format!("at most {MAX_ATTEMPTS} attempts a run"),
            });
        }
        if self.max_attempts == Some(0) {
            return Err(SimError::Setting {
                name: "attempts",
                value: "0".into(),
                reason: "at least one attempt is needed".into(),
            });
        }
        if library.is_empty() {
            return Err(SimError::EmptyLibrary);
        }
        self.config.validate()?;
        check_library(&self.config.world, library)?;
        if let Some(packing) = &self.packing {
            let Some(labels) = labels else {
                return Err(PackingError::NoRecognition.into());
            };
            let known = crate::tasks::packing::known_categories(library, labels);
            packing.validate(&known, &self.config.world)?;
        }
        if let Some(arrival) = &self.arrival {
            if labels.is_none() {
                return Err(ArrivalError::NoRecognition.into());
            }
            arrival.validate(self.rounds)?;
        }
        Ok(())
    }
}

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
    #[error("unknown grasp source `{0}` (known: analytic, random, network)")]
    UnknownSource(String),
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
    /// The run was asked to stop ([`StopToken`]); its run directory holds the rounds it
    /// finished, and `resume` plays the rest.
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

/// A built-in grasp source by name: `analytic` or `random` (seeded from the run's seed).
/// `network` is `lgdm_pybridge::ae::robot::NetworkSource` (feature `ae`).
pub fn builtin_source(name: &str, seed: u64) -> Result<Box<dyn GraspSource>, SimError> {
    match name {
        "analytic" => Ok(Box::new(AnalyticSource::new())),
        "random" => Ok(Box::new(RandomSource::new(derive_seed(
            seed,
            TAG_RANDOM_SOURCE,
            0,
            0,
        )))),
        other => Err(SimError::UnknownSource(other.to_string())),
    }
}

/// Asks a running job to stop: it finishes the round it is playing, writes that round's
/// checkpoint and returns [`SimError::Stopped`] — nothing half-written, and `resume` plays the
/// rest. Clones share the request (a signal handler or another thread holds one).
#[derive(Debug, Clone, Default)]
pub struct StopToken(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl StopToken {
    /// Asks the job to stop after its current round.
    pub fn stop(&self) {
        self.0.store(true, std::sync::atomic::Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    pub fn is_stopped(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// The shared flag, for a signal handler that sets it (`signal_hook::flag::register`):
    /// setting it is [`StopToken::stop`].
    pub fn flag(&self) -> std::sync::Arc<std::sync::atomic::AtomicBool> {
        std::sync::Arc::clone(&self.0)
    }
}
