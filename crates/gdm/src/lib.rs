//! The Growing Dual-Memory network (GDM): an episodic and a semantic Gamma-GWR memory for
//! lifelong, open-ended recognition of instances and categories from sequences of feature
//! vectors, with intrinsic replay against catastrophic forgetting (docs/DESIGN.md §3).
//!
//! - [`config`]: hyperparameters ([`GdmConfig`], presets, validation) and the size limits
//!   (`MAX_DIM`, `MAX_CONTEXT_DEPTH`, `MAX_NODES`, `MAX_CHAIN_LENGTH`) every reader enforces.
//! - [`network`]: the Gamma-GWR network ([`GammaGwr`]).
//! - [`memory`]: [`EpisodicMemory`] and [`SemanticMemory`].
//! - [`dual`]: the dual model [`Gdm`]: train, predict, evaluate.
//! - [`replay`]: RNATs and intrinsic replay.
//! - [`metric`]: distance metrics and the best-node search.
//! - [`scores`]: accuracy and quantization-error helpers.
//! - [`checkpoint`]: the versioned, checksummed, atomically written model file.
//! - [`experiment`]: the paper's scenarios run over trials on a labelled feature table (plans,
//!   runner, records, run directories) — what `lgdm train` and `lgdm.run_scenario` call.
//! - [`learner`]: the learner seam ([`learner::Learner`]): the GDM or a baseline on the same
//!   features (streaming LDA, nearest class mean), chosen by [`learner::LearnerKind`].
//! - [`error`]: typed errors.
//!
//! Labels are open-ended `u32`s (no class count declared); samples may be unlabelled. Each
//! memory starts empty and makes its first two nodes from its first two training samples.
//!
//! ```
//! use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample};
//!
//! // Two objects, each seen as a short sequence of 2-D feature vectors.
//! let a: Vec<[f32; 2]> = (0..8).map(|t| [0.1 * t as f32, 0.0]).collect();
//! let b: Vec<[f32; 2]> = (0..8).map(|t| [0.1 * t as f32, 3.0]).collect();
//! let mut samples: Vec<Sample> = a.iter().map(|x| Sample::labelled(x, 0, 10, 1)).collect();
//! samples.extend(b.iter().map(|x| Sample::labelled(x, 1, 20, 2)));
//!
//! let mut gdm = Gdm::new(GdmConfig::paper_batch(), 2)?;
//! for _epoch in 0..5 {
//!     gdm.train(&samples)?;
//!     gdm.end_episode();
//! }
//! gdm.replay()?;
//! let predictions = gdm.predict(&samples, PredictOptions::default())?;
//! assert_eq!(predictions[0].category_em, Some(1));
//! assert_eq!(predictions[15].instance, Some(20));
//! let scores = gdm.evaluate(&samples, PredictOptions::default())?;
//! assert!(scores.category_accuracy_sm > 0.5);
//!
//! let restored = Gdm::from_bytes(&gdm.to_bytes())?;
//! assert_eq!(restored.to_bytes(), gdm.to_bytes());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod checkpoint;
pub mod config;
pub mod dual;
pub mod error;
pub mod experiment;
pub mod learner;
pub mod memory;
pub mod metric;
pub mod network;
pub mod replay;
pub mod scores;

pub use config::{GdmConfig, MemoryParams, Metric, ReplayParams};
pub use dual::{Gdm, PredictOptions, Prediction, Sample, TrainStats};
pub use error::{CheckpointError, ConfigError, GdmError};
pub use memory::{EpisodicMemory, SemanticMemory};
pub use network::{Edge, GammaGwr, Histogram, StepOutcome, Supervision};
pub use replay::ReplayStats;
pub use scores::Scores;
