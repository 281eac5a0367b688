//! The records a run writes to `metrics.json`, and their summary over trials. NaN (an accuracy
//! over no labelled sample) is written as `null` and read back as NaN.
//!
//! Accuracies are fractions in [0, 1]; times in seconds unless the name says `ms`.

use serde::{Deserialize, Deserializer, Serialize};

/// Reads a number that JSON stores as `null` when it is NaN (serde_json writes NaN as `null`),
/// so a `metrics.json` with an undefined accuracy reads back.
fn nan_from_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Accuracies on one set of samples.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Figures {
    /// Number of samples scored.
    pub n: usize,
    /// Instance accuracy of the episodic memory (G-EM).
    #[serde(deserialize_with = "nan_from_null")]
    pub instance_accuracy: f64,
    /// Category accuracy of the episodic memory (G-EM).
    #[serde(deserialize_with = "nan_from_null")]
    pub category_accuracy_em: f64,
    /// Category accuracy of the semantic memory (G-SM): the system's category answer.
    #[serde(deserialize_with = "nan_from_null")]
    pub category_accuracy_sm: f64,
}

/// What was measured after one learning step (epoch, episode or mini-batch).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StepRecord {
    /// Step number, from 1.
    pub step: usize,
    /// What the step learned.
    pub label: String,
    /// Samples presented in the step's last epoch.
    pub train_samples: usize,
    /// Episodic-memory nodes after the step.
    pub episodic_nodes: usize,
    /// Semantic-memory nodes after the step.
    pub semantic_nodes: usize,
    /// Average quantization error of G-EM over the step's last epoch.
    pub quantization_error_em: f64,
    /// Average quantization error of G-SM over the step's last epoch.
    pub quantization_error_sm: f64,
    /// Accuracy on the training data seen so far (batch: this epoch's), when evaluated.
    pub train: Option<Figures>,
    /// Accuracy on the test data in scope, when evaluated.
    pub test: Option<Figures>,
    /// Wall time of the step (training, replay, evaluation).
    pub seconds: f64,
}

/// One trial.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TrialRecord {
    /// Trial index.
    pub trial: usize,
    /// The trial's seed.
    pub seed: u64,
    /// Instances never trained on in this trial.
    pub held_out_instances: Vec<u32>,
    /// Labels of the steps, in order.
    pub step_labels: Vec<String>,
    /// Per-step measurements.
    pub steps: Vec<StepRecord>,
    /// Final accuracy on the test collections (all categories).
    pub test: Figures,
    /// Final test accuracy predicting without temporal context (K = 0 at test time).
    pub test_no_context: Figures,
    /// Final accuracy on the held-out instances (category figures are the meaningful ones).
    pub new_instance: Option<Figures>,
    /// Final test category accuracy (G-SM) per category id; null where a category has no test data.
    pub per_category_test_accuracy: Vec<Option<f64>>,
    /// Final episodic-memory nodes.
    pub episodic_nodes: usize,
    /// Final semantic-memory nodes.
    pub semantic_nodes: usize,
    /// Size of the model checkpoint in bytes.
    pub model_size_bytes: usize,
    /// Prediction time per test sample (both memories), in milliseconds.
    pub inference_ms_per_sample: f64,
    /// Wall time of learning and per-step evaluation.
    pub train_seconds: f64,
    /// The accuracy matrices of the tasks (new categories, new instances) and ACC, BWT, F
    /// ([`super::forgetting`]); absent in runs recorded before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forgetting: Option<super::forgetting::Forgetting>,
}

/// Mean and (sample) standard deviation.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct MeanStd {
    /// Mean over trials.
    #[serde(deserialize_with = "nan_from_null")]
    pub mean: f64,
    /// Sample standard deviation over trials (0 for one trial).
    #[serde(deserialize_with = "nan_from_null")]
    pub std: f64,
}

impl MeanStd {
    /// Mean and standard deviation of some values.
    pub fn of(values: &[f64]) -> MeanStd {
        let n = values.len();
        if n == 0 {
            return MeanStd {
                mean: f64::NAN,
                std: f64::NAN,
            };
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let std = if n < 2 {
            0.0
        } else {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        };
        MeanStd { mean, std }
    }
}

/// Final figures averaged over trials.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Summary {
    /// Trials averaged.
    pub trials: usize,
    /// Final training accuracy (last evaluated step), instance, G-EM.
    pub train_instance_accuracy: MeanStd,
    /// Final training category accuracy, G-EM.
    pub train_category_accuracy_em: MeanStd,
    /// Final training category accuracy, G-SM.
    pub train_category_accuracy_sm: MeanStd,
    /// Final test instance accuracy, G-EM.
    pub test_instance_accuracy: MeanStd,
    /// Final test category accuracy, G-EM.
    pub test_category_accuracy_em: MeanStd,
    /// Final test category accuracy, G-SM.
    pub test_category_accuracy_sm: MeanStd,
    /// Final test category accuracy (G-SM) without temporal context at test time.
    pub test_no_context_category_accuracy_sm: MeanStd,
    /// Category accuracy (G-SM) on the held-out instances.
    pub new_instance_category_accuracy_sm: Option<MeanStd>,
    /// Final episodic nodes.
    pub episodic_nodes: MeanStd,
    /// Final semantic nodes.
    pub semantic_nodes: MeanStd,
    /// Checkpoint size in MB (10^6 bytes).
    pub model_size_mb: MeanStd,
    /// Inference time per sample in ms.
    pub inference_ms_per_sample: MeanStd,
    /// ACC, BWT and F over the trials that recorded them ([`super::forgetting`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forgetting: Option<super::forgetting::ForgettingSummary>,
}

impl Summary {
    /// Summarises trials.
    pub fn of(trials: &[TrialRecord]) -> Summary {
        let col = |f: &dyn Fn(&TrialRecord) -> f64| {
            MeanStd::of(&trials.iter().map(f).collect::<Vec<_>>())
        };
        let last_train = |t: &TrialRecord| t.steps.iter().rev().find_map(|s| s.train.clone());
        let new_instance: Vec<f64> = trials
            .iter()
            .filter_map(|t| t.new_instance.as_ref().map(|f| f.category_accuracy_sm))
            .collect();
        Summary {
            trials: trials.len(),
            train_instance_accuracy: col(&|t| {
                last_train(t).map_or(f64::NAN, |f| f.instance_accuracy)
            }),
            train_category_accuracy_em: col(&|t| {
                last_train(t).map_or(f64::NAN, |f| f.category_accuracy_em)
            }),
            train_category_accuracy_sm: col(&|t| {
                last_train(t).map_or(f64::NAN, |f| f.category_accuracy_sm)
            }),
            test_instance_accuracy: col(&|t| t.test.instance_accuracy),
            test_category_accuracy_em: col(&|t| t.test.category_accuracy_em),
            test_category_accuracy_sm: col(&|t| t.test.category_accuracy_sm),
            test_no_context_category_accuracy_sm: col(&|t| t.test_no_context.category_accuracy_sm),
            new_instance_category_accuracy_sm: (!new_instance.is_empty())
                .then(|| MeanStd::of(&new_instance)),
            episodic_nodes: col(&|t| t.episodic_nodes as f64),
            semantic_nodes: col(&|t| t.semantic_nodes as f64),
            model_size_mb: col(&|t| t.model_size_bytes as f64 / 1e6),
            inference_ms_per_sample: col(&|t| t.inference_ms_per_sample),
            forgetting: super::forgetting::ForgettingSummary::of(trials),
        }
    }
}

/// The whole `metrics.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunMetrics {
    /// Format version of this file.
    pub format_version: u32,
    /// Scenario name.
    pub scenario: String,
    /// Feature encoder.
    pub encoder: String,
    /// Dataset directory.
    pub dataset: String,
    /// Base seed (trial t uses seed + t).
    pub seed: u64,
    /// The learner (`gdm`, `slda`, `ncm`; absent in files of earlier versions: `gdm`). A
    /// baseline's instance figures and node counts are those of its per-instance head, its
    /// G-SM figures those of its per-category head (see [`crate::learner`]).
    #[serde(default)]
    pub learner: crate::learner::LearnerKind,
    /// Whether intrinsic replay was on.
    pub replay: bool,
    /// Whether temporal context was used in training (K > 0).
    pub context: bool,
    /// Epochs per step.
    pub epochs: usize,
    /// Category names by id.
    pub categories: Vec<String>,
    /// Instance names by id (empty when the data gave none); with `categories`, what
    /// `lgdm eval` checks a dataset against before scoring a model of this run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub instances: Vec<String>,
    /// Every trial.
    pub trials: Vec<TrialRecord>,
    /// Averages over trials.
    pub summary: Summary,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_std_matches_hand_computation() {
        let m = MeanStd::of(&[1.0, 2.0, 3.0, 4.0]);
        assert!((m.mean - 2.5).abs() < 1e-12);
        assert!((m.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(MeanStd::of(&[0.7]).std, 0.0);
    }
}
