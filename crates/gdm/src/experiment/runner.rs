//! The trial runner: a scenario's plan fed to the dual memory step by step, measured after every
//! step, and the final figures of the trial.
//!
//! The algorithm lives in the learner ([`crate::learner`]: the GDM or a baseline); this module
//! only feeds it the plan's sequences in order (learn, end of step: replay and end of episode for
//! the GDM) and evaluates.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeSet;
use std::time::Instant;

use super::forgetting::Tracker;
use super::plan::{self, EvalScope, Plan, Scenario};
use super::records::{Figures, StepRecord, TrialRecord};
use super::{ExperimentError, StepProgress, Table};
use crate::learner::{Learner, LearnerKind, Model};
use crate::{GdmConfig, PredictOptions, Prediction, Sample, Scores, TrainStats};

/// Everything one trial needs besides the data.
#[derive(Clone, Debug)]
pub(crate) struct TrialSettings {
    /// The protocol.
    pub scenario: Scenario,
    /// Dual-memory hyperparameters.
    pub config: GdmConfig,
    /// Learning epochs per step (batch: the number of steps).
    pub epochs: usize,
    /// Intrinsic replay after every step.
    pub replay: bool,
    /// Evaluate on the test set after every n-th step (the last step always).
    pub eval_every: usize,
    /// Per-step evaluations use at most this many samples (whole sequences drawn with the
    /// trial's seed) from each set; 0 = all. The final figures always use every test sample.
    pub eval_samples: usize,
    /// Batch only: train on about this many samples, a fixed per-trial subset of whole training
    /// sequences stratified by category (the paper's batch runs use 3000); 0 = all.
    pub train_samples: usize,
    /// Trial seed: plan, held-out instances and the network's RNG.
    pub seed: u64,
    /// Validation mode: the test held-out instances are left out and others stand in for them.
    pub validate: bool,
    /// The learner trained.
    pub learner: LearnerKind,
}

/// Whole sequences holding at most `max_samples` samples, drawn at random (seeded) and kept in
/// their original order; all of them when they fit or `max_samples` is 0.
pub fn subsample(seqs: &[Vec<usize>], max_samples: usize, seed: u64) -> Vec<Vec<usize>> {
    let total: usize = seqs.iter().map(Vec::len).sum();
    if max_samples == 0 || total <= max_samples {
        return seqs.to_vec();
    }
    let mut order: Vec<usize> = (0..seqs.len()).collect();
    rand::seq::SliceRandom::shuffle(&mut order[..], &mut ChaCha8Rng::seed_from_u64(seed));
    let mut chosen = Vec::new();
    let mut n = 0;
    for i in order {
        if n >= max_samples {
            break;
        }
        n += seqs[i].len();
        chosen.push(i);
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|i| seqs[i].clone()).collect()
}

/// Builds the plan of one trial.
pub(crate) fn plan_trial(data: &Table<'_>, s: &TrialSettings) -> Plan {
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let mut plan = plan::plan(
        s.scenario,
        data.rows(),
        data.train_collections,
        data.test_collections,
        data.category_names,
        s.epochs,
        s.validate,
        &mut rng,
    );
    if s.scenario == Scenario::Batch
        && s.train_samples > 0
        && let Some(first) = plan.steps.first()
    {
        let keep = stratified_subset(
            &first.sequences,
            s.train_samples,
            |q| data.category[q[0]],
            s.seed ^ 0x7472_6169_6e5f_7375,
        );
        for step in &mut plan.steps {
            step.sequences.retain(|q| keep.contains(&q[0]));
        }
    }
    plan
}

/// First rows of whole sequences holding about `samples` samples, `samples / categories` per
/// category (sequences drawn at random per category until the category's share is reached; a
/// category with less data gives all it has).
pub fn stratified_subset(
    seqs: &[Vec<usize>],
    samples: usize,
    category: impl Fn(&Vec<usize>) -> u32,
    seed: u64,
) -> std::collections::BTreeSet<usize> {
    let mut by_category: std::collections::BTreeMap<u32, Vec<&Vec<usize>>> = Default::default();
    for q in seqs.iter().filter(|q| !q.is_empty()) {
        by_category.entry(category(q)).or_default().push(q);
    }
    let share = samples.div_ceil(by_category.len().max(1));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut keep = std::collections::BTreeSet::new();
    for group in by_category.values_mut() {
        group.sort_by_key(|q| q[0]);
        rand::seq::SliceRandom::shuffle(&mut group[..], &mut rng);
        let mut n = 0;
        for q in group.iter() {
            if n >= share {
                break;
            }
            n += q.len();
            keep.insert(q[0]);
        }
    }
    keep
}

fn figures(scores: &Scores) -> Figures {
    Figures {
        n: scores.n,
        instance_accuracy: scores.instance_accuracy,
        category_accuracy_em: scores.category_accuracy_em,
        category_accuracy_sm: scores.category_accuracy_sm,
    }
}

/// Runs one trial: the plan's steps in order, measuring after each; returns the trained model
/// and the trial's record.
pub(crate) fn run_trial(
    data: &Table<'_>,
    s: &TrialSettings,
    trial: usize,
    progress: &dyn Fn(StepProgress),
) -> Result<(Model, TrialRecord), ExperimentError> {
    let plan = plan_trial(data, s);
    let mut config = s.config.clone();
    config.seed = s.seed;
    let mut gdm = Model::new(s.learner, &config, data.dim).map_err(ExperimentError::gdm(
        format!("creating the {} learner", s.learner),
    ))?;
    let started = Instant::now();
    let mut steps = Vec::with_capacity(plan.steps.len());
    let mut seen = Seen::default();
    let mut tracker = Tracker::new(data, &plan, s.eval_samples, s.seed);
    let n_steps = plan.steps.len();
    for (k, step) in plan.steps.iter().enumerate() {
        let record = run_step(&mut gdm, data, s, &plan, k, &mut seen, &mut tracker)?;
        progress(StepProgress {
            trial,
            step: k + 1,
            steps: n_steps,
            label: step.label.clone(),
            test_category_accuracy: record.test.as_ref().map(|f| f.category_accuracy_sm),
            episodic_nodes: record.episodic_nodes,
        });
        steps.push(record);
    }
    let train_seconds = started.elapsed().as_secs_f64();
    let last = final_figures(&gdm, data, &plan)?;
    let record = TrialRecord {
        trial,
        seed: s.seed,
        held_out_instances: plan.held_out_instances.clone(),
        step_labels: plan.steps.iter().map(|st| st.label.clone()).collect(),
        steps,
        test: last.test,
        test_no_context: last.test_no_context,
        new_instance: last.new_instance,
        per_category_test_accuracy: last.per_category_test_accuracy,
        episodic_nodes: gdm.nodes().0,
        semantic_nodes: gdm.nodes().1,
        model_size_bytes: gdm.size_bytes(),
        inference_ms_per_sample: last.inference_ms_per_sample,
        train_seconds,
        forgetting: Some(tracker.finish()),
    };
    Ok((gdm, record))
}

/// What a trial has learned so far.
#[derive(Default)]
struct Seen {
    /// Categories of every step's sequences.
    categories: BTreeSet<u32>,
    /// Every step's sequences, in order (not kept in batch learning, whose steps are epochs).
    train: Vec<Vec<usize>>,
}

/// Step `k` of `plan`: learn it, then evaluate when due (every `eval_every`-th step and the
/// last) and let `tracker` score the tasks learnt so far (with the step's test predictions
/// when they serve); the step's record.
fn run_step(
    gdm: &mut Model,
    data: &Table<'_>,
    s: &TrialSettings,
    plan: &Plan,
    k: usize,
    seen: &mut Seen,
    tracker: &mut Tracker,
) -> Result<StepRecord, ExperimentError> {
    let step = &plan.steps[k];
    let step_started = Instant::now();
    let ts = learn_step(gdm, data, s, step)?;
    for seq in &step.sequences {
        seen.categories.insert(data.category[seq[0]]);
    }
    if s.scenario != Scenario::Batch {
        seen.train.extend(step.sequences.iter().cloned());
    }
    let last = k + 1 == plan.steps.len();
    let evaluate = last || (k + 1).is_multiple_of(s.eval_every.max(1));
    let (train, test) = if evaluate {
        let (train, test) = evaluate_step(gdm, data, s, plan, k, seen)?;
        (Some(train), test)
    } else {
        (None, None)
    };
    let evaluated = test
        .as_ref()
        .map(|t| (&t.sequences[..], &t.predictions[..]));
    tracker.after_step(k, gdm, data, evaluated)?;
    let test = test.map(|t| t.scores);
    Ok(StepRecord {
        step: k + 1,
        label: step.label.clone(),
        train_samples: ts.samples,
        episodic_nodes: gdm.nodes().0,
        semantic_nodes: gdm.nodes().1,
        quantization_error_em: ts.quantization_error_em,
        quantization_error_sm: ts.quantization_error_sm,
        train: train.as_ref().map(figures),
        test: test.as_ref().map(figures),
        seconds: step_started.elapsed().as_secs_f64(),
    })
}

/// Trains on the step's sequences (once in batch learning, whose steps are the epochs, else
/// `epochs` times), replays if asked, ends the episode; the last epoch's statistics.
fn learn_step(
    gdm: &mut Model,
    data: &Table<'_>,
    s: &TrialSettings,
    step: &plan::Step,
) -> Result<TrainStats, ExperimentError> {
    let samples = data.samples(&step.sequences);
    let epochs = if s.scenario == Scenario::Batch {
        1
    } else {
        s.epochs.max(1)
    };
    let mut train_stats = None;
    for _ in 0..epochs {
        train_stats = Some(
            gdm.learn(&samples)
                .map_err(ExperimentError::gdm(format!("training on {}", step.label)))?,
        );
    }
    gdm.end_step(s.replay)
        .map_err(ExperimentError::gdm("intrinsic replay"))?;
    Ok(train_stats.expect("at least one epoch"))
}

/// A step's test evaluation: the sequences scored, their predictions in order, the scores.
struct TestEvaluation {
    sequences: Vec<Vec<usize>>,
    predictions: Vec<Prediction>,
    scores: Scores,
}

/// Scores after step `k`: on the training data (the step's sequences in batch learning, else
/// everything seen) and on the test set (scoped as the plan says; `None` when empty), each
/// subsampled to `eval_samples` except the last step's test set.
fn evaluate_step(
    gdm: &Model,
    data: &Table<'_>,
    s: &TrialSettings,
    plan: &Plan,
    k: usize,
    seen: &Seen,
) -> Result<(Scores, Option<TestEvaluation>), ExperimentError> {
    let opts = PredictOptions::default();
    let step = &plan.steps[k];
    let last = k + 1 == plan.steps.len();
    let scoped = |seqs: &[Vec<usize>]| -> Vec<Vec<usize>> {
        match plan.scope {
            EvalScope::All => seqs.to_vec(),
            EvalScope::SeenCategories => seqs
                .iter()
                .filter(|q| seen.categories.contains(&data.category[q[0]]))
                .cloned()
                .collect(),
        }
    };
    let train_seqs = if s.scenario == Scenario::Batch {
        &step.sequences
    } else {
        &seen.train
    };
    let train_seqs = subsample(train_seqs, s.eval_samples, s.seed ^ ((k as u64) << 20));
    let train = gdm
        .evaluate(&data.samples(&train_seqs), opts)
        .map_err(ExperimentError::gdm("evaluating on training data"))?;
    let test_seqs = if last {
        scoped(&plan.test)
    } else {
        subsample(
            &scoped(&plan.test),
            s.eval_samples,
            s.seed ^ ((k as u64) << 21),
        )
    };
    let test_samples = data.samples(&test_seqs);
    let test = if test_samples.is_empty() {
        None
    } else {
        let (scores, predictions) = gdm
            .evaluate_with_predictions(&test_samples, opts)
            .map_err(ExperimentError::gdm("evaluating on test data"))?;
        Some(TestEvaluation {
            sequences: test_seqs,
            predictions,
            scores,
        })
    };
    Ok((train, test))
}

/// The figures of a trained trial, on every sample.
struct FinalFigures {
    test: Figures,
    test_no_context: Figures,
    new_instance: Option<Figures>,
    per_category_test_accuracy: Vec<Option<f64>>,
    inference_ms_per_sample: f64,
}

/// Final figures: test (with and without temporal context), new instances, per category, and
/// the inference time per test sample.
fn final_figures(
    gdm: &Model,
    data: &Table<'_>,
    plan: &Plan,
) -> Result<FinalFigures, ExperimentError> {
    let opts = PredictOptions::default();
    let test_samples = data.samples(&plan.test);
    let t0 = Instant::now();
    let predictions = gdm
        .predict(&test_samples, opts)
        .map_err(ExperimentError::gdm("predicting the test set"))?;
    let inference_ms_per_sample = if test_samples.is_empty() {
        0.0
    } else {
        t0.elapsed().as_secs_f64() * 1e3 / test_samples.len() as f64
    };
    let final_test = ExperimentError::gdm("evaluating the final test set");
    let test = figures(&gdm.evaluate(&test_samples, opts).map_err(&final_test)?);
    let test_no_context = figures(
        &gdm.evaluate(&test_samples, PredictOptions { no_context: true })
            .map_err(&final_test)?,
    );
    let new_samples = data.samples(&plan.new_instance);
    let new_instance = if new_samples.is_empty() {
        None
    } else {
        Some(figures(&gdm.evaluate(&new_samples, opts).map_err(
            ExperimentError::gdm("evaluating the held-out instances"),
        )?))
    };
    let per_category_test_accuracy =
        per_category_accuracy(&test_samples, &predictions, data.category_names.len());
    Ok(FinalFigures {
        test,
        test_no_context,
        new_instance,
        per_category_test_accuracy,
        inference_ms_per_sample,
    })
}

/// Category accuracy per category id below `n_categories` (`None` for a category without a
/// sample); an unlabelled sample counts as category 0.
fn per_category_accuracy(
    samples: &[Sample<'_>],
    predictions: &[Prediction],
    n_categories: usize,
) -> Vec<Option<f64>> {
    let mut hits = vec![0usize; n_categories];
    let mut totals = vec![0usize; n_categories];
    for (sample, p) in samples.iter().zip(predictions) {
        let c = sample.category.unwrap_or(0) as usize;
        if c < n_categories {
            totals[c] += 1;
            hits[c] += usize::from(p.category == sample.category);
        }
    }
    hits.iter()
        .zip(&totals)
        .map(|(&h, &t)| {
            if t == 0 {
                None
            } else {
                Some(h as f64 / t as f64)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{stratified_subset, subsample};

    #[test]
    fn stratified_subset_takes_each_categorys_share_in_whole_sequences() {
        // 3 categories: 0 and 1 with eight 10-row sequences, 2 with a single one.
        let seqs: Vec<Vec<usize>> = (0..17).map(|i| (i * 10..i * 10 + 10).collect()).collect();
        let cat = |q: &Vec<usize>| match q[0] / 10 {
            0..8 => 0,
            8..16 => 1,
            _ => 2,
        };
        let keep = stratified_subset(&seqs, 90, cat, 7);
        let count = |c| keep.iter().filter(|&&r| cat(&vec![r]) == c).count();
        assert_eq!((count(0), count(1), count(2)), (3, 3, 1));
        assert!(
            keep.iter().all(|r| r % 10 == 0),
            "whole sequences, by first row"
        );
        assert_eq!(keep, stratified_subset(&seqs, 90, cat, 7));
        assert_ne!(keep, stratified_subset(&seqs, 90, cat, 8));
        assert_eq!(stratified_subset(&seqs, 10_000, cat, 7).len(), 17);
    }

    #[test]
    fn subsample_keeps_whole_sequences_in_order_under_the_cap() {
        let seqs: Vec<Vec<usize>> = (0..10).map(|s| (s * 4..s * 4 + 4).collect()).collect();
        assert_eq!(subsample(&seqs, 0, 1), seqs);
        assert_eq!(subsample(&seqs, 40, 1), seqs);
        let sub = subsample(&seqs, 10, 1);
        assert_eq!(sub.len(), 3, "sequences are added until the cap is reached");
        assert!(sub.windows(2).all(|w| w[0][0] < w[1][0]));
        assert!(sub.iter().all(|s| seqs.contains(s)));
        assert_eq!(sub, subsample(&seqs, 10, 1));
        assert_ne!(sub, subsample(&seqs, 10, 2));
    }
}
