//! Forgetting made visible: per trial, the accuracy matrix of the continual-learning literature
//! and its three numbers — average accuracy (ACC), backward transfer (BWT) and average
//! forgetting (F) — for the semantic memory's categories and the episodic memory's instances.
//!
//! **Tasks.** A task is what one step brings that no earlier step did: the categories (for
//! G-SM) or the instances (for G-EM) first trained at that step. In `nc` every step is a task
//! of new categories (and their instances); in `incremental` every step is one category; in
//! `nic` a task starts at every step that brings a new category (resp. instance), and the steps
//! after it up to the next task's are part of it; in `ni` and `batch` the first step brings
//! every category and instance, so there is one task (the later steps show new views of the
//! same objects: the learning curve shows those).
//!
//! **The matrix.** `R[i][j]` is the accuracy on task `j`'s test samples (the test rows of its
//! labels) measured after task `i` — after the last step before task `i + 1` starts, or after
//! the trial's last step for the last task — for `j ≤ i`; `None` above the diagonal (a task not
//! yet learnt) and for a task without test samples. G-SM's matrix scores the category answer on
//! category tasks, G-EM's the instance answer on instance tasks. With `T` tasks
//! (Lopez-Paz & Ranzato 2017; Chaudhry et al. 2018):
//!
//! - ACC = (1/T) · Σ_j R[T−1][j]
//! - BWT = (1/(T−1)) · Σ_{j<T−1} (R[T−1][j] − R[j][j])
//! - F = (1/(T−1)) · Σ_{j<T−1} max_{j≤l<T−1} (R[l][j] − R[T−1][j])
//!
//! Tasks without a value are left out of the sums and the counts; BWT and F need two tasks and
//! are `None` with one (and so is anything with nothing to average): no NaN.
//!
//! ```
//! use lgdm_gdm::experiment::forgetting::{average_accuracy, average_forgetting, backward_transfer};
//! let r = vec![
//!     vec![Some(0.9), None],
//!     vec![Some(0.6), Some(0.8)],
//! ];
//! assert!((average_accuracy(&r).unwrap() - 0.7).abs() < 1e-12);
//! assert!((backward_transfer(&r).unwrap() + 0.3).abs() < 1e-12);
//! assert!((average_forgetting(&r).unwrap() - 0.3).abs() < 1e-12);
//! ```

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::plan::Plan;
use super::records::{MeanStd, TrialRecord};
use super::{ExperimentError, Table, subsample};
use crate::learner::Learner;
use crate::{PredictOptions, Prediction};

/// Mixed into the trial seed to draw the test sequences the matrix scores.
const SUBSET_SEED: u64 = 0x666f_7267_6574_7469;

/// The labels (category or instance ids) one step trained first.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Task {
    /// The step (from 1) that first trained the task's labels.
    pub step: usize,
    /// The labels first trained at that step, ascending.
    pub labels: Vec<u32>,
    /// Test samples of these labels that the matrix scores.
    pub test_samples: usize,
}

/// The accuracy matrix of one memory's tasks and its three numbers.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AccuracyMatrix {
    /// The tasks, in the order they were learnt.
    pub tasks: Vec<Task>,
    /// Per row `i`, the step (from 1) after which it was measured: the last step of task `i`.
    pub measured_after_step: Vec<usize>,
    /// `R[i][j]`: accuracy on task `j`'s test samples after task `i` (`T × T`; `None` for
    /// `j > i` and for a task without test samples).
    pub accuracy: Vec<Vec<Option<f64>>>,
    /// ACC: mean of the last row.
    pub average_accuracy: Option<f64>,
    /// BWT: mean over the tasks before the last of (final − just-learnt) accuracy.
    pub backward_transfer: Option<f64>,
    /// F: mean over the tasks before the last of (best earlier − final) accuracy.
    pub average_forgetting: Option<f64>,
}

impl AccuracyMatrix {
    /// The matrix `r` of `tasks` measured after `measured_after_step`, with its numbers.
    pub fn new(
        tasks: Vec<Task>,
        measured_after_step: Vec<usize>,
        accuracy: Vec<Vec<Option<f64>>>,
    ) -> AccuracyMatrix {
        AccuracyMatrix {
            average_accuracy: average_accuracy(&accuracy),
            backward_transfer: backward_transfer(&accuracy),
            average_forgetting: average_forgetting(&accuracy),
            tasks,
            measured_after_step,
            accuracy,
        }
    }
}

/// A trial's forgetting: G-SM on category tasks, G-EM on instance tasks.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Forgetting {
    /// Category accuracy of the semantic memory (the system's category answer) on the tasks of
    /// new categories.
    pub categories: AccuracyMatrix,
    /// Instance accuracy of the episodic memory on the tasks of new instances.
    pub instances: AccuracyMatrix,
}

/// `R[i][j]` where it exists and is finite.
fn cell(r: &[Vec<Option<f64>>], i: usize, j: usize) -> Option<f64> {
    r.get(i)?
        .get(j)
        .copied()
        .flatten()
        .filter(|v| v.is_finite())
}

/// Mean of some values; `None` for none.
fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// ACC = (1/T) Σ_j R[T−1][j], over the tasks with a value; `None` for an empty matrix.
pub fn average_accuracy(r: &[Vec<Option<f64>>]) -> Option<f64> {
    let last = r.len().checked_sub(1)?;
    mean((0..r.len()).filter_map(|j| cell(r, last, j)))
}

/// BWT = (1/(T−1)) Σ_{j<T−1} (R[T−1][j] − R[j][j]), over the tasks with both values; `None`
/// with fewer than two tasks.
pub fn backward_transfer(r: &[Vec<Option<f64>>]) -> Option<f64> {
    let last = r.len().checked_sub(1).filter(|&l| l > 0)?;
    mean((0..last).filter_map(|j| Some(cell(r, last, j)? - cell(r, j, j)?)))
}

/// F = (1/(T−1)) Σ_{j<T−1} max_{j≤l<T−1} (R[l][j] − R[T−1][j]), over the tasks with values;
/// `None` with fewer than two tasks. Negative where a task ends better than it ever was.
pub fn average_forgetting(r: &[Vec<Option<f64>>]) -> Option<f64> {
    let last = r.len().checked_sub(1).filter(|&l| l > 0)?;
    mean((0..last).filter_map(|j| {
        let best = (j..last)
            .filter_map(|l| cell(r, l, j))
            .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))?;
        Some(best - cell(r, last, j)?)
    }))
}

/// The tasks of one kind of label and the rows measured so far.
struct Partition {
    tasks: Vec<Task>,
    /// Label → its task.
    task_of: BTreeMap<u32, usize>,
    /// Per task, the step index (from 0) after which its row is measured.
    ends: Vec<usize>,
    rows: Vec<Vec<Option<f64>>>,
}

impl Partition {
    /// Tasks from the labels each step trains (in step order).
    fn new(step_labels: &[BTreeSet<u32>]) -> Partition {
        let mut tasks: Vec<Task> = Vec::new();
        let mut task_of = BTreeMap::new();
        for (k, labels) in step_labels.iter().enumerate() {
            let new: Vec<u32> = labels
                .iter()
                .copied()
                .filter(|l| !task_of.contains_key(l))
                .collect();
            if new.is_empty() {
                continue;
            }
            for &l in &new {
                task_of.insert(l, tasks.len());
            }
            tasks.push(Task {
                step: k + 1,
                labels: new,
                test_samples: 0,
            });
        }
        let ends = (0..tasks.len())
            .map(|i| tasks.get(i + 1).map_or(step_labels.len(), |t| t.step - 1) - 1)
            .collect();
        Partition {
            tasks,
            task_of,
            ends,
            rows: Vec::new(),
        }
    }

    /// The row measured after step `k` (from 0), if one is.
    fn row_due(&self, k: usize) -> Option<usize> {
        self.ends.iter().position(|&e| e == k)
    }

    /// Whether `label`'s task has been learnt by the end of step `k` (from 0).
    fn learnt(&self, label: u32, k: usize) -> bool {
        self.task_of
            .get(&label)
            .is_some_and(|&t| self.tasks[t].step <= k + 1)
    }

    fn into_matrix(self) -> AccuracyMatrix {
        let steps = self.ends.iter().map(|e| e + 1).collect();
        AccuracyMatrix::new(self.tasks, steps, self.rows)
    }
}

/// Hits and totals per task for one row.
struct Tally {
    row: usize,
    hits: Vec<usize>,
    totals: Vec<usize>,
}

impl Tally {
    fn new(row: usize, tasks: usize) -> Tally {
        Tally {
            row,
            hits: vec![0; tasks],
            totals: vec![0; tasks],
        }
    }

    fn add(&mut self, task: Option<&usize>, right: bool) {
        if let Some(&j) = task.filter(|&&j| j <= self.row) {
            self.totals[j] += 1;
            self.hits[j] += usize::from(right);
        }
    }

    fn into_row(self) -> Vec<Option<f64>> {
        (0..self.totals.len())
            .map(|j| {
                (j <= self.row && self.totals[j] > 0)
                    .then(|| self.hits[j] as f64 / self.totals[j] as f64)
            })
            .collect()
    }
}

/// Builds a trial's [`Forgetting`] as the runner steps through the plan: after every step that
/// ends a task it scores the test sequences of the labels learnt so far — taking the step's
/// own test predictions when they cover them, predicting otherwise.
pub(crate) struct Tracker {
    categories: Partition,
    instances: Partition,
    /// The test sequences scored: the plan's, subsampled once per trial to the evaluation cap.
    subset: Vec<Vec<usize>>,
}

impl Tracker {
    /// The tasks of `plan` on `data`; at most `eval_samples` test samples (whole sequences
    /// drawn with `seed`; 0 = all) are scored.
    pub(crate) fn new(data: &Table<'_>, plan: &Plan, eval_samples: usize, seed: u64) -> Tracker {
        let labels = |column: &[u32]| -> Vec<BTreeSet<u32>> {
            plan.steps
                .iter()
                .map(|st| st.sequences.iter().flatten().map(|&r| column[r]).collect())
                .collect()
        };
        let mut categories = Partition::new(&labels(data.category));
        let mut instances = Partition::new(&labels(data.instance));
        let subset = subsample(&plan.test, eval_samples, seed ^ SUBSET_SEED);
        for &r in subset.iter().flatten() {
            if let Some(&j) = categories.task_of.get(&data.category[r]) {
                categories.tasks[j].test_samples += 1;
            }
            if let Some(&j) = instances.task_of.get(&data.instance[r]) {
                instances.tasks[j].test_samples += 1;
            }
        }
        Tracker {
            categories,
            instances,
            subset,
        }
    }

    /// After step `k` (from 0): measures the rows due. `evaluated` is the step's own test
    /// evaluation, if it had one (the sequences and their predictions, in order).
    pub(crate) fn after_step(
        &mut self,
        k: usize,
        gdm: &dyn Learner,
        data: &Table<'_>,
        evaluated: Option<(&[Vec<usize>], &[Prediction])>,
    ) -> Result<(), ExperimentError> {
        let (cat_row, inst_row) = (self.categories.row_due(k), self.instances.row_due(k));
        if cat_row.is_none() && inst_row.is_none() {
            return Ok(());
        }
        let needed: Vec<Vec<usize>> = self
            .subset
            .iter()
            .filter(|q| {
                self.categories.learnt(data.category[q[0]], k)
                    || self.instances.learnt(data.instance[q[0]], k)
            })
            .cloned()
            .collect();
        let predicted;
        let predictions: Vec<&[Prediction]> = match evaluated.and_then(|e| reuse(e, &needed)) {
            Some(p) => p,
            None => {
                predicted = gdm
                    .predict(&data.samples(&needed), PredictOptions::default())
                    .map_err(ExperimentError::gdm("scoring the tasks learnt so far"))?;
                let mut rest = &predicted[..];
                needed
                    .iter()
                    .map(|q| {
                        let (head, tail) = rest.split_at(q.len());
                        rest = tail;
                        head
                    })
                    .collect()
            }
        };
        let mut cat = cat_row.map(|i| Tally::new(i, self.categories.tasks.len()));
        let mut inst = inst_row.map(|i| Tally::new(i, self.instances.tasks.len()));
        for (q, preds) in needed.iter().zip(&predictions) {
            for (&r, p) in q.iter().zip(preds.iter()) {
                let (c, i) = (data.category[r], data.instance[r]);
                if let Some(t) = cat.as_mut() {
                    t.add(self.categories.task_of.get(&c), p.category == Some(c));
                }
                if let Some(t) = inst.as_mut() {
                    t.add(self.instances.task_of.get(&i), p.instance == Some(i));
                }
            }
        }
        if let Some(t) = cat {
            self.categories.rows.push(t.into_row());
        }
        if let Some(t) = inst {
            self.instances.rows.push(t.into_row());
        }
        Ok(())
    }

    /// The trial's matrices and numbers (after the last step).
    pub(crate) fn finish(self) -> Forgetting {
        Forgetting {
            categories: self.categories.into_matrix(),
            instances: self.instances.into_matrix(),
        }
    }
}

/// The predictions of `needed`'s sequences taken from an evaluation of `seqs`, if it holds
/// every one of them whole.
fn reuse<'p>(
    (seqs, predictions): (&[Vec<usize>], &'p [Prediction]),
    needed: &[Vec<usize>],
) -> Option<Vec<&'p [Prediction]>> {
    let mut at = BTreeMap::new();
    let mut offset = 0;
    for q in seqs {
        at.insert(q.first()?, (offset, q.len()));
        offset += q.len();
    }
    if offset != predictions.len() {
        return None;
    }
    needed
        .iter()
        .map(|q| {
            let &(o, n) = at.get(q.first()?)?;
            (n == q.len()).then(|| &predictions[o..o + n])
        })
        .collect()
}

/// ACC, BWT and F of one memory over trials (the trials that have them).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ForgettingNumbers {
    /// Average accuracy ACC.
    pub average_accuracy: MeanStd,
    /// Backward transfer BWT.
    pub backward_transfer: MeanStd,
    /// Average forgetting F.
    pub average_forgetting: MeanStd,
}

impl ForgettingNumbers {
    fn of<'a>(matrices: impl Iterator<Item = &'a AccuracyMatrix> + Clone) -> ForgettingNumbers {
        let col = |f: fn(&AccuracyMatrix) -> Option<f64>| {
            MeanStd::of(&matrices.clone().filter_map(f).collect::<Vec<_>>())
        };
        ForgettingNumbers {
            average_accuracy: col(|m| m.average_accuracy),
            backward_transfer: col(|m| m.backward_transfer),
            average_forgetting: col(|m| m.average_forgetting),
        }
    }
}

/// [`Forgetting`]'s numbers over trials.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ForgettingSummary {
    /// G-SM, category tasks.
    pub categories: ForgettingNumbers,
    /// G-EM, instance tasks.
    pub instances: ForgettingNumbers,
}

impl ForgettingSummary {
    /// The summary of the trials that recorded forgetting; `None` if none did.
    pub fn of(trials: &[TrialRecord]) -> Option<ForgettingSummary> {
        let recorded = trials.iter().filter_map(|t| t.forgetting.as_ref());
        recorded.clone().next()?;
        Some(ForgettingSummary {
            categories: ForgettingNumbers::of(recorded.clone().map(|f| &f.categories)),
            instances: ForgettingNumbers::of(recorded.map(|f| &f.instances)),
        })
    }
}

/// `summary.txt`'s lines for the forgetting numbers (empty without them): ACC in per cent,
/// BWT and F in percentage points.
pub fn summary_lines(summary: Option<&ForgettingSummary>) -> String {
    let Some(s) = summary else {
        return String::new();
    };
    let fmt = |m: &MeanStd, signed: bool| {
        if m.mean.is_nan() {
            "—".to_string()
        } else if signed {
            format!("{:+5.1} ± {:4.1} pp", 100.0 * m.mean, 100.0 * m.std)
        } else {
            format!("{:5.1} ± {:4.1} %", 100.0 * m.mean, 100.0 * m.std)
        }
    };
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<34} {:>16} {:>16}",
        "tasks (new per step):", "categories G-SM", "instances G-EM"
    );
    let rows = [
        (
            "  average accuracy ACC",
            &s.categories.average_accuracy,
            &s.instances.average_accuracy,
            false,
        ),
        (
            "  backward transfer BWT",
            &s.categories.backward_transfer,
            &s.instances.backward_transfer,
            true,
        ),
        (
            "  average forgetting F",
            &s.categories.average_forgetting,
            &s.instances.average_forgetting,
            true,
        ),
    ];
    for (name, categories, instances, signed) in rows {
        let _ = writeln!(
            out,
            "{:<34} {:>16} {:>16}",
            name,
            fmt(categories, signed),
            fmt(instances, signed)
        );
    }
    out
}

/// The plots [`write_plots`] writes.
pub const PLOTS: [&str; 2] = ["forgetting_categories.png", "forgetting_instances.png"];

/// Cell-wise mean of matrices over the trials that have the cell (`None` where none has).
pub fn mean_matrix<'a>(
    matrices: impl Iterator<Item = &'a AccuracyMatrix> + Clone,
) -> Vec<Vec<Option<f64>>> {
    let size = matrices
        .clone()
        .map(|m| m.accuracy.len())
        .max()
        .unwrap_or(0);
    (0..size)
        .map(|i| {
            (0..size)
                .map(|j| mean(matrices.clone().filter_map(|m| cell(&m.accuracy, i, j))))
                .collect()
        })
        .collect()
}

/// Draws [`PLOTS`] into `dir`: the accuracy matrices (mean over the trials) as heat maps, the
/// three numbers in the title.
pub fn write_plots(dir: &Path, trials: &[TrialRecord]) -> Result<(), ExperimentError> {
    let summary = ForgettingSummary::of(trials);
    let recorded: Vec<&Forgetting> = trials
        .iter()
        .filter_map(|t| t.forgetting.as_ref())
        .collect();
    let [categories, instances] = PLOTS;
    heat_map(
        &dir.join(categories),
        "G-SM categories",
        recorded.iter().map(|f| &f.categories).collect(),
        summary.as_ref().map(|s| &s.categories),
    )?;
    heat_map(
        &dir.join(instances),
        "G-EM instances",
        recorded.iter().map(|f| &f.instances).collect(),
        summary.as_ref().map(|s| &s.instances),
    )
}

/// One memory's mean accuracy matrix as a heat map.
fn heat_map(
    path: &Path,
    kind: &str,
    matrices: Vec<&AccuracyMatrix>,
    numbers: Option<&ForgettingNumbers>,
) -> Result<(), ExperimentError> {
    let pct = |m: &MeanStd, unit: &str| {
        if m.mean.is_nan() {
            "—".to_string()
        } else {
            format!("{:.1}{unit}", 100.0 * m.mean)
        }
    };
    let title = match numbers {
        Some(s) => format!(
            "{kind}, {} trial(s): ACC {} · BWT {} · F {}",
            matrices.len(),
            pct(&s.average_accuracy, " %"),
            pct(&s.backward_transfer, " pp"),
            pct(&s.average_forgetting, " pp"),
        ),
        None => format!("{kind}: no accuracy matrix recorded"),
    };
    let r = mean_matrix(matrices.into_iter());
    let names: Vec<String> = (1..=r.len().max(1)).map(|t| t.to_string()).collect();
    let r = if r.is_empty() { vec![vec![None]] } else { r };
    lgdm_base::plot::value_heat_map(
        path,
        &title,
        "tested on task j",
        "after learning task i",
        &names,
        &names,
        &r,
    )
    .map_err(|e| ExperimentError::RunDir {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Option<f64>, b: f64) -> bool {
        a.is_some_and(|a| (a - b).abs() < 1e-12)
    }

    #[test]
    fn the_three_numbers_match_a_hand_computed_3x3_matrix() {
        // Task 0 rises to 0.95 after task 1, then falls to 0.5; task 1 falls from 0.8 to 0.7.
        let r = vec![
            vec![Some(0.9), None, None],
            vec![Some(0.95), Some(0.8), None],
            vec![Some(0.5), Some(0.7), Some(0.95)],
        ];
        // ACC = (0.5 + 0.7 + 0.95) / 3.
        assert!(close(average_accuracy(&r), 2.15 / 3.0));
        // BWT = ((0.5 − 0.9) + (0.7 − 0.8)) / 2: against the just-learnt value.
        assert!(close(backward_transfer(&r), -0.25));
        // F = ((0.95 − 0.5) + (0.8 − 0.7)) / 2: against the best earlier value.
        assert!(close(average_forgetting(&r), 0.275));
    }

    #[test]
    fn one_task_has_an_accuracy_but_no_transfer_or_forgetting() {
        let r = vec![vec![Some(0.6)]];
        assert!(close(average_accuracy(&r), 0.6));
        assert_eq!(backward_transfer(&r), None);
        assert_eq!(average_forgetting(&r), None);
        assert_eq!(average_accuracy(&[]), None);
        assert_eq!(backward_transfer(&[]), None);
    }

    #[test]
    fn a_task_without_test_samples_is_left_out_not_nan() {
        // Task 1 has no test samples: its column is empty.
        let r = vec![
            vec![Some(0.8), None, None],
            vec![Some(0.6), None, None],
            vec![Some(0.4), None, Some(1.0)],
        ];
        assert!(close(average_accuracy(&r), 0.7));
        assert!(close(backward_transfer(&r), -0.4));
        assert!(close(average_forgetting(&r), 0.4));
        // No task before the last with a value: nothing to average.
        let r = vec![vec![None, None], vec![None, Some(0.5)]];
        assert_eq!(backward_transfer(&r), None);
        assert_eq!(average_forgetting(&r), None);
        let m = AccuracyMatrix::new(vec![], vec![], r);
        let json = serde_json::to_string(&m).unwrap();
        assert!(!json.contains("NaN") && json.contains("\"backward_transfer\":null"));
    }

    #[test]
    fn improving_tasks_have_negative_forgetting_and_positive_transfer() {
        let r = vec![vec![Some(0.5), None], vec![Some(0.7), Some(0.9)]];
        assert!(close(backward_transfer(&r), 0.2));
        assert!(close(average_forgetting(&r), -0.2));
    }

    #[test]
    fn tasks_start_where_new_labels_appear_and_end_before_the_next() {
        let steps: Vec<BTreeSet<u32>> = vec![
            [0, 1].into(),
            [1].into(),
            [2].into(),
            [0, 2].into(),
            [3, 0].into(),
        ];
        let p = Partition::new(&steps);
        let firsts: Vec<(usize, Vec<u32>)> =
            p.tasks.iter().map(|t| (t.step, t.labels.clone())).collect();
        assert_eq!(firsts, vec![(1, vec![0, 1]), (3, vec![2]), (5, vec![3])]);
        assert_eq!(p.ends, vec![1, 3, 4]);
        assert_eq!(p.row_due(1), Some(0));
        assert_eq!(p.row_due(2), None);
        assert!(p.learnt(2, 2) && !p.learnt(2, 1) && !p.learnt(9, 4));
    }

    /// 4 collections (3 train, 1 test) × 8 categories × 3 instances × 3 frames of 2-D features.
    struct Toy {
        x: Vec<f32>,
        collection: Vec<u32>,
        category: Vec<u32>,
        instance: Vec<u32>,
        sequence: Vec<u64>,
        frame: Vec<u32>,
        names: Vec<String>,
    }

    impl Toy {
        fn new() -> Toy {
            let mut t = Toy {
                x: vec![],
                collection: vec![],
                category: vec![],
                instance: vec![],
                sequence: vec![],
                frame: vec![],
                names: (0..8).map(|c| format!("c{c}")).collect(),
            };
            for c in 0..4u32 {
                for i in 0..24u32 {
                    for f in 0..3u32 {
                        let wobble = 0.05 * ((c * 7 + i * 3 + f) % 5) as f32;
                        t.x.extend([(i / 3) as f32 + wobble, 0.3 * (i % 3) as f32]);
                        t.collection.push(c);
                        t.category.push(i / 3);
                        t.instance.push(i);
                        t.sequence.push(u64::from(c * 100 + i));
                        t.frame.push(f);
                    }
                }
            }
            t
        }

        fn table(&self) -> Table<'_> {
            Table {
                features: &self.x,
                dim: 2,
                collection: &self.collection,
                category: &self.category,
                instance: &self.instance,
                sequence: &self.sequence,
                frame: &self.frame,
                train_collections: &[0, 1, 2],
                test_collections: &[3],
                category_names: &self.names,
                instance_names: &[],
            }
        }
    }

    fn run(settings: super::super::Settings) -> TrialRecord {
        let toy = Toy::new();
        let experiment = super::super::Experiment::new(toy.table(), settings).unwrap();
        experiment.run_trial(0, &|_| {}).unwrap().1
    }

    #[test]
    fn nc_tasks_are_the_steps_and_the_last_row_is_the_final_test() {
        let mut settings = super::super::Settings::new(super::super::Scenario::Nc);
        settings.trials = 1;
        let trial = run(settings.clone());
        let f = trial.forgetting.clone().unwrap();
        // 8 categories: steps of 4, 2, 2 categories, each a task.
        let tasks: Vec<(usize, usize)> = f
            .categories
            .tasks
            .iter()
            .map(|t| (t.step, t.labels.len()))
            .collect();
        assert_eq!(tasks, vec![(1, 4), (2, 2), (3, 2)]);
        assert_eq!(f.categories.measured_after_step, vec![1, 2, 3]);
        // The instances arrive with their categories (two trained per category).
        let sizes: Vec<usize> = f.instances.tasks.iter().map(|t| t.labels.len()).collect();
        assert_eq!(sizes, vec![8, 4, 4]);
        for m in [&f.categories, &f.instances] {
            assert_eq!(m.accuracy.len(), 3);
            for (i, row) in m.accuracy.iter().enumerate() {
                assert!(row.iter().enumerate().all(|(j, v)| v.is_some() == (j <= i)));
            }
        }
        // Every test sample belongs to a task, so the last row weighted by the tasks' test
        // samples is the final test accuracy.
        let weighted = |m: &AccuracyMatrix| {
            let n: usize = m.tasks.iter().map(|t| t.test_samples).sum();
            let hits: f64 = m
                .tasks
                .iter()
                .zip(&m.accuracy[2])
                .map(|(t, v)| t.test_samples as f64 * v.unwrap())
                .sum();
            (n, hits / n as f64)
        };
        let (n, acc) = weighted(&f.categories);
        assert_eq!(n, trial.test.n);
        assert!((acc - trial.test.category_accuracy_sm).abs() < 1e-12);
        let (_, acc) = weighted(&f.instances);
        assert!((acc - trial.test.instance_accuracy).abs() < 1e-12);
        assert_eq!(
            f.categories.backward_transfer,
            backward_transfer(&f.categories.accuracy)
        );
        // Predicting anew where no step evaluation serves gives the same matrices.
        settings.eval_every = Some(100);
        let alone = run(settings);
        assert!(alone.steps[0].test.is_none());
        assert_eq!(alone.forgetting, Some(f));
    }

    #[test]
    fn ni_has_one_task_whose_row_is_the_final_test() {
        let mut settings = super::super::Settings::new(super::super::Scenario::Ni);
        settings.trials = 1;
        let trial = run(settings);
        let f = trial.forgetting.unwrap();
        assert_eq!(f.categories.tasks.len(), 1);
        assert_eq!(f.categories.measured_after_step, vec![3]);
        assert!(close(
            f.categories.average_accuracy,
            trial.test.category_accuracy_sm
        ));
        assert_eq!(f.categories.backward_transfer, None);
        assert_eq!(f.instances.average_forgetting, None);
    }

    #[test]
    fn mean_matrix_averages_the_trials_that_have_a_cell() {
        let m = |r: Vec<Vec<Option<f64>>>| AccuracyMatrix::new(vec![], vec![], r);
        let a = m(vec![vec![Some(0.2), None], vec![Some(0.4), Some(1.0)]]);
        let b = m(vec![vec![Some(0.4)]]);
        let r = mean_matrix([&a, &b].into_iter());
        assert!(close(r[0][0], 0.3) && close(r[1][0], 0.4) && close(r[1][1], 1.0));
        assert_eq!(r[0][1], None);
    }
}
