//! The dual model [`Gdm`]: an episodic and a semantic memory trained together on labelled
//! (or unlabelled) sequences, with prediction, evaluation, episode ends and replay.
//!
//! Per training sample, in order: if the sample's `sequence` differs from the previous sample's,
//! both memories start a new sequence (contexts zero); the episodic memory takes a step on `x`
//! with the instance and category labels; the semantic memory takes a regulated step on the
//! weight of the episodic node that now represents the sample (the new node after an insertion,
//! else the updated best node) with the category label.
//!
//! ```
//! use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample};
//! let mut gdm = Gdm::new(GdmConfig::default(), 2).unwrap();
//! let xs = [[0.0, 0.0], [0.05, 0.0], [3.0, 3.0], [3.05, 3.0]];
//! let samples = [
//!     Sample::labelled(&xs[0], 0, 0, 0),
//!     Sample::labelled(&xs[1], 0, 0, 0),
//!     Sample::labelled(&xs[2], 1, 1, 1),
//!     Sample::labelled(&xs[3], 1, 1, 1),
//! ];
//! for _ in 0..3 {
//!     gdm.train(&samples).unwrap();
//! }
//! let scores = gdm.evaluate(&samples, PredictOptions::default()).unwrap();
//! assert_eq!(scores.n, 4);
//! assert!(scores.category_accuracy_em >= 0.5);
//! ```

use crate::config::{GdmConfig, MAX_DIM};
use crate::error::GdmError;
use crate::memory::{EpisodicMemory, SemanticMemory};
use crate::scores::{Scores, accuracy};

/// One input sample: a feature vector, the id of the sequence it belongs to, and optional labels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<'a> {
    /// Feature vector (length = the model's `dim`, finite values).
    pub x: &'a [f32],
    /// Sequence id: contexts reset whenever it differs from the previous sample's.
    pub sequence: u64,
    /// Instance label (any u32), if known.
    pub instance: Option<u32>,
    /// Category label (any u32), if known.
    pub category: Option<u32>,
}

impl<'a> Sample<'a> {
    /// A sample with both labels.
    pub fn labelled(x: &'a [f32], sequence: u64, instance: u32, category: u32) -> Self {
        Sample {
            x,
            sequence,
            instance: Some(instance),
            category: Some(category),
        }
    }

    /// A sample without labels.
    pub fn unlabelled(x: &'a [f32], sequence: u64) -> Self {
        Sample {
            x,
            sequence,
            instance: None,
            category: None,
        }
    }
}

/// Options of [`Gdm::predict`] and [`Gdm::evaluate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PredictOptions {
    /// Predict with K = 0 (input weights only, no temporal context), for the paper's "without
    /// TC at test time" condition (default: false).
    pub no_context: bool,
}

/// Prediction for one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prediction {
    /// Instance label of the episodic best node.
    pub instance: Option<u32>,
    /// Category label of the episodic best node.
    pub category_em: Option<u32>,
    /// Category label of the semantic best node (the model's category answer).
    pub category: Option<u32>,
    /// Episodic activity exp(−d_b) in (0, 1].
    pub activation: f32,
}

/// Summary of one [`Gdm::train`] call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrainStats {
    /// Samples processed.
    pub samples: usize,
    /// Episodic node count after the call.
    pub episodic_nodes: usize,
    /// Semantic node count after the call.
    pub semantic_nodes: usize,
    /// Mean episodic best-node distance d_b over the samples (the two initial-node samples
    /// excluded; 0 if none had a best node).
    pub quantization_error_em: f64,
    /// Mean semantic best-node distance d_b, as above.
    pub quantization_error_sm: f64,
}

/// The Growing Dual-Memory model (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Gdm {
    pub(crate) config: GdmConfig,
    pub(crate) dim: usize,
    pub(crate) episodic: EpisodicMemory,
    pub(crate) semantic: SemanticMemory,
    /// Sequence id of the last trained sample; `None`: the next sample starts a sequence.
    pub(crate) sequence: Option<u64>,
    /// Number of [`Gdm::replay`] calls so far (seeds the replay order).
    pub(crate) replays: u64,
    /// Samples trained on (counting every pass) since the last [`Gdm::replay`]: what a
    /// [`ReplayBudget::Learnt`](crate::config::ReplayBudget::Learnt) budget is measured against.
    pub(crate) learnt: u64,
}

/// Checks an input dimension: 1 ≤ `dim` ≤ [`MAX_DIM`].
pub(crate) fn check_dim(dim: usize) -> Result<(), GdmError> {
    if dim == 0 {
        return Err(GdmError::ZeroDimension);
    }
    if dim > MAX_DIM {
        return Err(GdmError::DimensionTooLarge { dim, max: MAX_DIM });
    }
    Ok(())
}

/// Checks a batch: non-empty, right dimension, finite values.
pub(crate) fn validate_batch(samples: &[Sample<'_>], dim: usize) -> Result<(), GdmError> {
    if samples.is_empty() {
        return Err(GdmError::EmptyBatch);
    }
    for (i, s) in samples.iter().enumerate() {
        if s.x.len() != dim {
            return Err(GdmError::DimensionMismatch {
                sample: i,
                expected: dim,
                found: s.x.len(),
            });
        }
        if let Some(p) = s.x.iter().position(|v| !v.is_finite()) {
            return Err(GdmError::NonFinite {
                sample: i,
                position: p,
            });
        }
    }
    Ok(())
}

/// Full prediction detail for one sample.
pub(crate) struct Detail {
    pub prediction: Prediction,
    pub distance_em: f32,
    pub distance_sm: f32,
}

impl Gdm {
    /// An untrained model for `dim`-dimensional features (1 ≤ `dim` ≤
    /// [`MAX_DIM`] = 2²⁰). Each memory starts empty and takes its first
    /// two training samples as its first two nodes.
    pub fn new(config: GdmConfig, dim: usize) -> Result<Gdm, GdmError> {
        config.validate()?;
        check_dim(dim)?;
        Ok(Gdm {
            episodic: EpisodicMemory::new(config.episodic.clone(), config.metric, dim)?,
            semantic: SemanticMemory::new(config.semantic.clone(), config.metric, dim)?,
            config,
            dim,
            sequence: None,
            replays: 0,
            learnt: 0,
        })
    }

    /// Input dimension D.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The hyperparameters.
    pub fn config(&self) -> &GdmConfig {
        &self.config
    }

    /// The episodic memory.
    pub fn episodic(&self) -> &EpisodicMemory {
        &self.episodic
    }

    /// The semantic memory.
    pub fn semantic(&self) -> &SemanticMemory {
        &self.semantic
    }

    /// The sequence id of the last trained sample, or `None` when the next sample starts a new
    /// sequence (a fresh model, or after [`Gdm::end_episode`] / [`Gdm::replay`]). A sample with
    /// this id continues that sequence's temporal context.
    pub fn current_sequence(&self) -> Option<u64> {
        self.sequence
    }

    /// One pass over the samples in order (contexts reset whenever `sequence` changes; a
    /// sequence may continue across calls). The whole batch is validated before any learning:
    /// on error the model is unchanged.
    pub fn train(&mut self, samples: &[Sample<'_>]) -> Result<TrainStats, GdmError> {
        validate_batch(samples, self.dim)?;
        self.learnt = self.learnt.saturating_add(samples.len() as u64);
        let (mut qe_em, mut n_em, mut qe_sm, mut n_sm) = (0.0f64, 0usize, 0.0f64, 0usize);
        for s in samples {
            if self.sequence != Some(s.sequence) {
                self.begin_sequence();
                self.sequence = Some(s.sequence);
            }
            let em = self.episodic.train_step(s.x, s.instance, s.category);
            if let Some((_, d)) = em.best {
                qe_em += d as f64;
                n_em += 1;
            }
            let w = self.episodic.net.weight(em.node);
            let sm = self.semantic.train_step(w, s.category);
            if let Some((_, d)) = sm.best {
                qe_sm += d as f64;
                n_sm += 1;
            }
        }
        let stats = TrainStats {
            samples: samples.len(),
            episodic_nodes: self.episodic.len(),
            semantic_nodes: self.semantic.len(),
            quantization_error_em: if n_em > 0 { qe_em / n_em as f64 } else { 0.0 },
            quantization_error_sm: if n_sm > 0 { qe_sm / n_sm as f64 } else { 0.0 },
        };
        tracing::debug!(
            samples = stats.samples,
            episodic_nodes = stats.episodic_nodes,
            semantic_nodes = stats.semantic_nodes,
            qe_em = stats.quantization_error_em,
            qe_sm = stats.quantization_error_sm,
            "gdm train pass"
        );
        Ok(stats)
    }

    pub(crate) fn begin_sequence(&mut self) {
        self.episodic.net.begin_sequence();
        self.semantic.net.begin_sequence();
    }

    /// End of an epoch/episode: isolated-node removal in both memories (never below 2 nodes).
    /// The next training sample starts a new sequence.
    pub fn end_episode(&mut self) {
        let removed_em = self.episodic.net.remove_isolated_nodes();
        let removed_sm = self.semantic.net.remove_isolated_nodes();
        self.begin_sequence();
        self.sequence = None;
        tracing::debug!(
            removed_em,
            removed_sm,
            episodic_nodes = self.episodic.len(),
            semantic_nodes = self.semantic.len(),
            "gdm end of episode"
        );
    }

    pub(crate) fn predict_details(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Vec<Detail>, GdmError> {
        validate_batch(samples, self.dim)?;
        if self.episodic.is_empty() || self.semantic.is_empty() {
            return Err(GdmError::NotTrained);
        }
        let em = &self.episodic.net;
        let sm = &self.semantic.net;
        let mut ctx_em = em.new_context();
        let mut ctx_sm = sm.new_context();
        let mut sequence = None;
        let mut out = Vec::with_capacity(samples.len());
        for s in samples {
            if sequence != Some(s.sequence) {
                ctx_em.reset();
                ctx_sm.reset();
                sequence = Some(s.sequence);
            }
            let (b, d_em) = em
                .predict_step(&mut ctx_em, s.x, opts.no_context)
                .ok_or(GdmError::NotTrained)?;
            let (bs, d_sm) = sm
                .predict_step(&mut ctx_sm, em.weight(b), opts.no_context)
                .ok_or(GdmError::NotTrained)?;
            out.push(Detail {
                prediction: Prediction {
                    instance: self.episodic.instance_of(b),
                    category_em: self.episodic.category_of(b),
                    category: self.semantic.category_of(bs),
                    activation: (-d_em).exp(),
                },
                distance_em: d_em,
                distance_sm: d_sm,
            });
        }
        Ok(out)
    }

    /// Predicts instance and category for each sample (labels in the samples are ignored), with
    /// the same context recursion as training, reset whenever `sequence` changes. Pure: the model
    /// is not changed and the result depends only on the model and the samples.
    pub fn predict(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Vec<Prediction>, GdmError> {
        Ok(self
            .predict_details(samples, opts)?
            .into_iter()
            .map(|d| d.prediction)
            .collect())
    }

    /// Accuracy against the samples' labels (samples without a label are skipped for that
    /// score; a score with no labelled sample is NaN) and mean quantization errors.
    pub fn evaluate(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<Scores, GdmError> {
        Ok(self.evaluate_with_predictions(samples, opts)?.0)
    }

    /// [`Gdm::evaluate`] and the predictions it scored ([`Gdm::predict`]'s), from one pass.
    pub fn evaluate_with_predictions(
        &self,
        samples: &[Sample<'_>],
        opts: PredictOptions,
    ) -> Result<(Scores, Vec<Prediction>), GdmError> {
        let details = self.predict_details(samples, opts)?;
        let n = details.len();
        let qe_em = details.iter().map(|d| d.distance_em as f64).sum::<f64>() / n as f64;
        let qe_sm = details.iter().map(|d| d.distance_sm as f64).sum::<f64>() / n as f64;
        let pairs = |f: fn(&Prediction) -> Option<u32>, g: fn(&Sample<'_>) -> Option<u32>| {
            accuracy(
                details
                    .iter()
                    .zip(samples)
                    .map(|(d, s)| (f(&d.prediction), g(s))),
            )
        };
        let scores = Scores {
            n,
            instance_accuracy: pairs(|p| p.instance, |s| s.instance),
            category_accuracy_em: pairs(|p| p.category_em, |s| s.category),
            category_accuracy_sm: pairs(|p| p.category, |s| s.category),
            quantization_error_em: qe_em,
            quantization_error_sm: qe_sm,
        };
        Ok((scores, details.into_iter().map(|d| d.prediction).collect()))
    }
}
