//! The plots of a run directory ([`write_run_plots`]), in the style of the paper's figures: a
//! mean line per series over steps with a shaded ± std band across trials, and per-category test
//! accuracy bars. [`super::run_dir::RunDir::play`] and [`super::run_dir::Merged::write`] draw
//! them, so `lgdm train`, `lgdm merge`, `lgdm.run_scenario(out=…)` and `lgdm.merge_runs` all
//! leave the same pictures. The charts themselves are [`lgdm_base::plot`]'s.

use std::path::Path;

use lgdm_base::plot::{Bar, Line, bar_chart, line_chart};

use super::ExperimentError;
use super::records::{MeanStd, RunMetrics, StepRecord};

/// The plots [`write_run_plots`] writes, in order.
pub const RUN_PLOTS: [&str; 6] = [
    "nodes.png",
    "accuracy.png",
    "quantization_error.png",
    "category_accuracy.png",
    super::forgetting::PLOTS[0],
    super::forgetting::PLOTS[1],
];

/// One figure over steps across trials: (step, mean, std) where every trial measured it.
fn series(m: &RunMetrics, name: &str, f: impl Fn(&StepRecord) -> Option<f64>) -> Line {
    let steps = m.trials.iter().map(|t| t.steps.len()).min().unwrap_or(0);
    let mut points = Vec::new();
    for k in 0..steps {
        let vals: Option<Vec<f64>> = m.trials.iter().map(|t| f(&t.steps[k])).collect();
        if let Some(vals) = vals {
            let s = MeanStd::of(&vals);
            points.push(((k + 1) as f64, s.mean, s.std));
        }
    }
    Line {
        name: name.to_string(),
        points,
    }
}

/// Writes [`RUN_PLOTS`] into `dir`: the nodes of both memories, the accuracies, the
/// quantization errors (over steps, or epochs for `batch`), the per-category test accuracy and
/// the accuracy matrices ([`super::forgetting::write_plots`]).
pub fn write_run_plots(dir: &Path, m: &RunMetrics) -> Result<(), ExperimentError> {
    let x_desc = if m.scenario == "batch" {
        "epoch"
    } else {
        "step (episode / mini-batch)"
    };
    let error = |name: &str, e: std::io::Error| ExperimentError::RunDir {
        path: dir.join(name).display().to_string(),
        message: e.to_string(),
    };
    let [nodes, accuracy, quantization, categories, ..] = RUN_PLOTS;
    line_chart(
        &dir.join(nodes),
        "Number of nodes",
        x_desc,
        "nodes",
        &[
            series(m, "G-EM", |s| Some(s.episodic_nodes as f64)),
            series(m, "G-SM", |s| Some(s.semantic_nodes as f64)),
        ],
        false,
    )
    .map_err(|e| error(nodes, e))?;
    line_chart(
        &dir.join(accuracy),
        "Accuracy",
        x_desc,
        "accuracy",
        &[
            series(m, "train instance (G-EM)", |s| {
                s.train.as_ref().map(|f| f.instance_accuracy)
            }),
            series(m, "train category (G-SM)", |s| {
                s.train.as_ref().map(|f| f.category_accuracy_sm)
            }),
            series(m, "test instance (G-EM)", |s| {
                s.test.as_ref().map(|f| f.instance_accuracy)
            }),
            series(m, "test category (G-EM)", |s| {
                s.test.as_ref().map(|f| f.category_accuracy_em)
            }),
            series(m, "test category (G-SM)", |s| {
                s.test.as_ref().map(|f| f.category_accuracy_sm)
            }),
        ],
        true,
    )
    .map_err(|e| error(accuracy, e))?;
    line_chart(
        &dir.join(quantization),
        "Average quantization error",
        x_desc,
        "quantization error",
        &[
            series(m, "G-EM", |s| Some(s.quantization_error_em)),
            series(m, "G-SM", |s| Some(s.quantization_error_sm)),
        ],
        false,
    )
    .map_err(|e| error(quantization, e))?;
    let bars: Vec<Bar> = m
        .categories
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let vals: Vec<f64> = m
                .trials
                .iter()
                .filter_map(|t| t.per_category_test_accuracy.get(c).copied().flatten())
                .collect();
            // A category no trial tested leaves its place empty (NaN).
            let s = MeanStd::of(&vals);
            Bar {
                label: name.clone(),
                value: s.mean,
                interval: (!vals.is_empty())
                    .then(|| ((s.mean - s.std).max(0.0), (s.mean + s.std).min(1.05))),
            }
        })
        .collect();
    bar_chart(
        &dir.join(categories),
        "Test category accuracy (G-SM) per category",
        "accuracy",
        &bars,
        1.05,
    )
    .map_err(|e| error(categories, e))?;
    super::forgetting::write_plots(dir, &m.trials)
}
