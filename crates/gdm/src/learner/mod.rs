//! The learner seam: what a trial trains, sample by sample, and scores — the dual memory
//! ([`Gdm`]) or one of two baselines on the same features ([`Baseline`]: streaming LDA and a
//! nearest class mean), chosen by [`LearnerKind`].
//!
//! Every learner predicts an instance and a category per sample, so that a run of any learner
//! fills the same records: the GDM's episodic memory (G-EM) gives the instance and its category,
//! the semantic memory (G-SM) the category answer; a baseline learns one head per instance
//! (its "G-EM" figures: the instance, and the category of that instance) and one per category
//! (its "G-SM" figures). Replay and temporal context are the GDM's alone.
//!
//! ```
//! use lgdm_gdm::learner::{Learner, LearnerKind, Model};
//! use lgdm_gdm::{PredictOptions, Sample};
//!
//! let xs = [[0.0f32, 0.0], [0.1, 0.0], [3.0, 3.0], [3.1, 3.0]];
//! let samples: Vec<Sample> = xs
//!     .iter()
//!     .enumerate()
//!     .map(|(i, x)| Sample::labelled(x, i as u64 / 2, i as u32 / 2, i as u32 / 2))
//!     .collect();
//! let kind: LearnerKind = "ncm".parse()?;
//! let mut model = Model::new(kind, &Default::default(), 2)?;
//! model.learn(&samples)?;
//! model.end_step(false)?;
//! let scores = model.evaluate(&samples, PredictOptions::default())?;
//! assert_eq!(scores.category_accuracy_sm, 1.0);
//! assert!("lda".parse::<LearnerKind>().unwrap_err().contains("\"lda\""));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod baseline;

pub use baseline::{Baseline, MAGIC as BASELINE_MAGIC, MAX_SLDA_DIM, SLDA_SHRINKAGE};

use std::path::Path;

use crate::{CheckpointError, Gdm, GdmConfig, GdmError, PredictOptions, Prediction, Sample};
use crate::{Scores, TrainStats};

/// Which learner a trial trains.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum LearnerKind {
    /// The Growing Dual-Memory network (default).
    #[default]
    Gdm,
    /// Streaming linear discriminant analysis (Hayes & Kanan): a running mean per class and one
    /// shared covariance, updated one sample at a time.
    Slda,
    /// Nearest class mean: a running mean per class, the nearest by Euclidean distance.
    Ncm,
}

impl LearnerKind {
    /// Every learner, in the order listed to users.
    pub const ALL: [LearnerKind; 3] = [LearnerKind::Gdm, LearnerKind::Slda, LearnerKind::Ncm];

    /// The name used in flags, `config.toml` and `metrics.json`.
    pub fn name(self) -> &'static str {
        match self {
            LearnerKind::Gdm => "gdm",
            LearnerKind::Slda => "slda",
            LearnerKind::Ncm => "ncm",
        }
    }

    /// Whether this is the dual memory (the learner with replay and temporal context).
    pub fn is_gdm(self) -> bool {
        self == LearnerKind::Gdm
    }
}

impl std::fmt::Display for LearnerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for LearnerKind {
    type Err = String;

    /// Parses a learner name; the error names the value and the learners there are.
    fn from_str(s: &str) -> Result<LearnerKind, String> {
        LearnerKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = LearnerKind::ALL.iter().map(|k| k.name()).collect();
                format!("unknown learner {s:?}: one of {}", names.join(", "))
            })
    }
}

/// What a trial needs of a learner: learn samples one at a time in order, close a step, predict
/// an instance and a category per sample.
pub trait Learner {
    /// Which learner this is.
    fn kind(&self) -> LearnerKind;
    /// Input dimension.
    fn dim(&self) -> usize;
    /// One pass over the samples in order, each learnt as it comes. The batch is validated
    /// before any learning: on error the model is unchanged.
    fn learn(&mut self, samples: &[Sample<'_>]) -> Result<TrainStats, GdmError>;
    /// The end of a step (an episode, a mini-batch, an epoch): the GDM replays when `replay`
    /// and ends its episode; a baseline has nothing to do and refuses `replay`.
    fn end_step(&mut self, replay: bool) -> Result<(), GdmError>;
    /// Instance and category of each sample (labels ignored); the model is not changed.
    fn predict(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Vec<Prediction>, GdmError>;
    /// Accuracies against the samples' labels (see [`Gdm::evaluate`]).
    fn evaluate(&self, samples: &[Sample<'_>], opts: PredictOptions) -> Result<Scores, GdmError>;
    /// [`Learner::evaluate`] and the predictions it scored, from one pass.
    fn evaluate_with_predictions(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<(Scores, Vec<Prediction>), GdmError>;
    /// (instance-level, category-level) units: the GDM's episodic and semantic nodes, a
    /// baseline's instance and category means.
    fn nodes(&self) -> (usize, usize);
    /// The model file's bytes.
    fn to_bytes(&self) -> Vec<u8>;
    /// Size of the model file in bytes.
    fn size_bytes(&self) -> usize {
        self.to_bytes().len()
    }
}

impl Learner for Gdm {
    fn kind(&self) -> LearnerKind {
        LearnerKind::Gdm
    }
    fn dim(&self) -> usize {
        Gdm::dim(self)
    }
    fn learn(&mut self, samples: &[Sample<'_>]) -> Result<TrainStats, GdmError> {
        self.train(samples)
    }
    fn end_step(&mut self, replay: bool) -> Result<(), GdmError> {
        if replay {
            self.replay()?;
        }
        self.end_episode();
        Ok(())
    }
    fn predict(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Vec<Prediction>, GdmError> {
        Gdm::predict(self, samples, opts)
    }
    fn evaluate(&self, samples: &[Sample<'_>], opts: PredictOptions) -> Result<Scores, GdmError> {
        Gdm::evaluate(self, samples, opts)
    }
    fn evaluate_with_predictions(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<(Scores, Vec<Prediction>), GdmError> {
        Gdm::evaluate_with_predictions(self, samples, opts)
    }
    fn nodes(&self) -> (usize, usize) {
        (self.episodic().len(), self.semantic().len())
    }
    fn to_bytes(&self) -> Vec<u8> {
        Gdm::to_bytes(self)
    }
    fn size_bytes(&self) -> usize {
        Gdm::size_bytes(self)
    }
}

/// A trained model of any learner: what a trial returns and a run directory saves.
#[derive(Clone, Debug, PartialEq)]
pub enum Model {
    /// The dual memory (boxed: it is much larger than a baseline's handle).
    Gdm(Box<Gdm>),
    /// A baseline (streaming LDA or nearest class mean).
    Baseline(Baseline),
}

impl Model {
    /// An untrained model of `kind` for `dim`-dimensional features; `config` (seed included)
    /// is the GDM's and unused by the baselines.
    pub fn new(kind: LearnerKind, config: &GdmConfig, dim: usize) -> Result<Model, GdmError> {
        Ok(match kind {
            LearnerKind::Gdm => Model::Gdm(Box::new(Gdm::new(config.clone(), dim)?)),
            other => Model::Baseline(Baseline::new(other, dim)?),
        })
    }

    /// The dual memory, if this is one.
    pub fn into_gdm(self) -> Option<Gdm> {
        match self {
            Model::Gdm(g) => Some(*g),
            Model::Baseline(_) => None,
        }
    }

    fn inner(&self) -> &dyn Learner {
        match self {
            Model::Gdm(g) => g.as_ref(),
            Model::Baseline(b) => b,
        }
    }

    fn inner_mut(&mut self) -> &mut dyn Learner {
        match self {
            Model::Gdm(g) => g.as_mut(),
            Model::Baseline(b) => b,
        }
    }

    /// Reads a model file of any learner (a GDM checkpoint or a baseline's file).
    pub fn from_bytes(bytes: &[u8]) -> Result<Model, CheckpointError> {
        if bytes.starts_with(&BASELINE_MAGIC) {
            Baseline::from_bytes(bytes).map(Model::Baseline)
        } else {
            Gdm::from_bytes(bytes).map(|g| Model::Gdm(Box::new(g)))
        }
    }

    /// Reads a model file of any learner.
    pub fn load(path: &Path) -> Result<Model, CheckpointError> {
        Model::from_bytes(&std::fs::read(path)?)
    }

    /// The model file's bytes (a GDM checkpoint, or a baseline's file naming its learner).
    pub fn to_bytes(&self) -> Vec<u8> {
        self.inner().to_bytes()
    }

    /// Writes the model file atomically (temporary file and rename).
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        lgdm_base::fs::write_bytes(path, &self.to_bytes())?;
        Ok(())
    }
}

impl Learner for Model {
    fn kind(&self) -> LearnerKind {
        self.inner().kind()
    }
    fn dim(&self) -> usize {
        self.inner().dim()
    }
    fn learn(&mut self, samples: &[Sample<'_>]) -> Result<TrainStats, GdmError> {
        self.inner_mut().learn(samples)
    }
    fn end_step(&mut self, replay: bool) -> Result<(), GdmError> {
        self.inner_mut().end_step(replay)
    }
    fn predict(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Vec<Prediction>, GdmError> {
        self.inner().predict(samples, opts)
    }
    fn evaluate(&self, samples: &[Sample<'_>], opts: PredictOptions) -> Result<Scores, GdmError> {
        self.inner().evaluate(samples, opts)
    }
    fn evaluate_with_predictions(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<(Scores, Vec<Prediction>), GdmError> {
        self.inner().evaluate_with_predictions(samples, opts)
    }
    fn nodes(&self) -> (usize, usize) {
        self.inner().nodes()
    }
    fn to_bytes(&self) -> Vec<u8> {
        self.inner().to_bytes()
    }
    fn size_bytes(&self) -> usize {
        self.inner().size_bytes()
    }
}
