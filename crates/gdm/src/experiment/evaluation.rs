//! Scoring a trained model of any learner on some collections of a table, as `lgdm eval` reports
//! it: accuracies of both memories (a baseline's instance and category heads), a category
//! confusion matrix and the prediction time per sample.

use std::collections::BTreeMap;
use std::time::Instant;

use super::{ExperimentError, Table};
use crate::learner::Learner;
use crate::{PredictOptions, Sample};

/// What [`evaluate`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// Samples scored.
    pub n: usize,
    /// Instance accuracy of the episodic memory (G-EM).
    pub instance_accuracy: f64,
    /// Category accuracy of the episodic memory (G-EM).
    pub category_accuracy_em: f64,
    /// Category accuracy of the semantic memory (G-SM): the model's answer.
    pub category_accuracy_sm: f64,
    /// Category confusion of the semantic memory: `confusion[truth][predicted]`, one row per
    /// category of the table, one column per category plus a last "none" column (no label, or a
    /// label the table does not name).
    pub confusion: Vec<Vec<u64>>,
    /// Prediction time per sample (both memories), in milliseconds.
    pub ms_per_sample: f64,
}

/// The rows of `collections`, grouped by sequence (ascending id), frames in order: the order in
/// which the temporal context runs as in training.
pub fn rows_in_sequence_order(table: &Table<'_>, collections: &[u32]) -> Vec<usize> {
    let mut by_seq: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for i in 0..table.len() {
        if collections.contains(&table.collection[i]) {
            by_seq.entry(table.sequence[i]).or_default().push(i);
        }
    }
    let mut rows = Vec::new();
    for mut seq in by_seq.into_values() {
        seq.sort_by_key(|&i| table.frame[i]);
        rows.extend(seq);
    }
    rows
}

/// Scores `model` (the GDM, or a baseline through the same seam) on the rows of `collections`
/// (see [`rows_in_sequence_order`]).
pub fn evaluate(
    model: &dyn Learner,
    table: &Table<'_>,
    collections: &[u32],
    opts: PredictOptions,
) -> Result<Evaluation, ExperimentError> {
    table.check()?;
    if table.dim != model.dim() {
        return Err(ExperimentError::Table(format!(
            "the model expects {}-d features, the table has {}-d",
            model.dim(),
            table.dim
        )));
    }
    let rows = rows_in_sequence_order(table, collections);
    if rows.is_empty() {
        return Err(ExperimentError::Table(
            "no samples in the selected collections".into(),
        ));
    }
    let samples: Vec<Sample<'_>> = rows
        .iter()
        .map(|&i| Sample {
            x: table.row(i),
            sequence: table.sequence[i],
            instance: Some(table.instance[i]),
            category: Some(table.category[i]),
        })
        .collect();
    let t0 = Instant::now();
    let predictions = model
        .predict(&samples, opts)
        .map_err(ExperimentError::gdm("predicting"))?;
    let ms_per_sample = t0.elapsed().as_secs_f64() * 1e3 / samples.len() as f64;

    let n_cat = table.category_names.len();
    let mut confusion = vec![vec![0u64; n_cat + 1]; n_cat];
    let (mut inst_hits, mut cat_em_hits, mut cat_sm_hits) = (0usize, 0usize, 0usize);
    for (s, p) in samples.iter().zip(&predictions) {
        inst_hits += usize::from(p.instance == s.instance);
        cat_em_hits += usize::from(p.category_em == s.category);
        cat_sm_hits += usize::from(p.category == s.category);
        let truth = s.category.unwrap_or(0) as usize;
        let predicted = p.category.map_or(n_cat, |c| (c as usize).min(n_cat));
        if truth < n_cat {
            confusion[truth][predicted] += 1;
        }
    }
    let n = samples.len() as f64;
    Ok(Evaluation {
        n: samples.len(),
        instance_accuracy: inst_hits as f64 / n,
        category_accuracy_em: cat_em_hits as f64 / n,
        category_accuracy_sm: cat_sm_hits as f64 / n,
        confusion,
        ms_per_sample,
    })
}
