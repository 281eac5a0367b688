//! The plots of a sim run directory, drawn from the numbers of its [`RunResults`] (the summary,
//! [`RunResults::learning_curve`], [`crate::tasks::arrival::Evaluation::per_category`]) with
//! [`lgdm_base::plot`]'s charts. [`crate::run::run_dir::SimRunDir::write_results`] draws them
//! beside `results.json`, so the binary and `lgdm.sim` leave the same pictures ([`write_plots`]).

use std::path::Path;

use lgdm_base::plot::{Bar, Line, bar_chart, line_chart};

use crate::recognition::recognizer::MemoryPoint;
use crate::run::error::SimError;
use crate::run::results::{Rate, RunResults};
use crate::tasks::packing::basket_name;

/// Every run's plots: grasp success per category and the failure reasons.
pub const GRASP_PLOTS: [&str; 2] = ["success_by_category.png", "failure_reasons.png"];
/// Runs with recognition in the loop add these: the learning curve and the memories' nodes.
pub const RECOGNITION_PLOTS: [&str; 2] = ["learning_curve.png", "nodes.png"];
/// Packing runs add this: success per category.
pub const PACKING_PLOT: &str = "packing_by_category.png";
/// Runs whose categories arrive over time add this: the first guesses at the end.
pub const ARRIVAL_PLOT: &str = "end_evaluation.png";

/// Writes the plots `r` has numbers for into `dir` and returns their names: always
/// [`GRASP_PLOTS`]; with recognition [`RECOGNITION_PLOTS`]; packing [`PACKING_PLOT`]; categories
/// arriving over time [`ARRIVAL_PLOT`].
pub fn write_plots(dir: &Path, r: &RunResults) -> Result<Vec<&'static str>, SimError> {
    let mut written = Vec::new();
    let mut draw = |name: &'static str, f: &dyn Fn(&Path) -> std::io::Result<()>| {
        let path = dir.join(name);
        f(&path).map_err(|e| SimError::RunDir {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        written.push(name);
        Ok::<(), SimError>(())
    };
    draw(GRASP_PLOTS[0], &|p| success_by_category(p, r))?;
    draw(GRASP_PLOTS[1], &|p| failure_reasons(p, r))?;
    if r.recognition.is_some() {
        draw(RECOGNITION_PLOTS[0], &|p| learning_curve(p, r))?;
        draw(RECOGNITION_PLOTS[1], &|p| nodes(p, r))?;
    }
    if r.run.packing.is_some() && r.summary.packing.is_some() {
        draw(PACKING_PLOT, &|p| packing_by_category(p, r))?;
    }
    if r.arrival_evaluation.is_some() {
        draw(ARRIVAL_PLOT, &|p| end_evaluation(p, r))?;
    }
    Ok(written)
}

/// Points without a band.
fn line(name: String, points: &[(f64, f64)]) -> Line {
    Line {
        name,
        points: points.iter().map(|&(x, y)| (x, y, 0.0)).collect(),
    }
}

/// A rate as a bar with its Wilson interval.
fn bar(label: String, rate: &Rate) -> Bar {
    Bar {
        label,
        value: rate.value.unwrap_or(0.0),
        interval: Some((rate.wilson_low, rate.wilson_high)),
    }
}

fn success_by_category(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let bars: Vec<Bar> = r
        .summary
        .per_category
        .iter()
        .map(|(c, cs)| bar(c.clone(), &cs.grasp_success_rate))
        .collect();
    let title = format!(
        "Grasp success by category ({}, {}; Wilson 95 %)",
        r.run.scenario, r.run.grasp_source
    );
    bar_chart(path, &title, "grasp success", &bars, 1.05)
}

fn failure_reasons(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let s = &r.summary;
    let bars: Vec<Bar> = s
        .failure_reasons
        .iter()
        .map(|(k, n)| Bar {
            label: k.replace('_', " "),
            value: *n as f64,
            interval: None,
        })
        .collect();
    let top = bars.iter().map(|b| b.value).fold(1.0, f64::max) * 1.1;
    let failed: usize = s.failure_reasons.values().sum();
    let title = format!("Failure reasons ({} attempts, {failed} failed)", s.attempts);
    bar_chart(path, &title, "attempts", &bars, top)
}

/// Packing: success by the true category of the object aimed at.
fn packing_by_category(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let (Some(spec), Some(p)) = (&r.run.packing, &r.summary.packing) else {
        return Ok(());
    };
    let bars: Vec<Bar> = p
        .per_category
        .iter()
        .map(|(c, rate)| {
            let side = if spec.targets.contains(c) { "R" } else { "L" };
            bar(format!("{c} ({side})"), rate)
        })
        .collect();
    let title = format!(
        "Packing success by category (R: {} basket, L: {}; Wilson 95 %)",
        basket_name(spec.target_basket),
        basket_name(spec.other_basket)
    );
    bar_chart(path, &title, "in its true category's basket", &bars, 1.05)
}

/// Categories arriving over time: first-guess category accuracy per category at the end,
/// early and late marked.
fn end_evaluation(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let Some(e) = &r.arrival_evaluation else {
        return Ok(());
    };
    let bars: Vec<Bar> = e
        .at_end
        .per_category()
        .iter()
        .map(|(c, early, rate)| {
            bar(
                format!("{c} ({})", if *early { "early" } else { "late" }),
                rate,
            )
        })
        .collect();
    let replay = r
        .recognition
        .as_ref()
        .map_or("?", |x| if x.config.replay { "on" } else { "off" });
    let title = format!(
        "First guess at the end, replay {replay} (late categories from round {})",
        e.arrival.after_round
    );
    bar_chart(path, &title, "category accuracy", &bars, 1.05)
}

/// First-guess accuracy and teacher interventions against objects seen, over the last 25
/// recognitions and over all so far.
fn learning_curve(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let c = r.learning_curve(25);
    let w = c.window;
    line_chart(
        path,
        "Recognition in the loop: first guess and teacher",
        "objects seen",
        "share",
        &[
            line(
                format!("first-guess category accuracy (last {w})"),
                &c.accuracy_windowed,
            ),
            line(
                format!("teacher interventions (last {w})"),
                &c.teacher_windowed,
            ),
            line(
                "first-guess category accuracy (all so far)".into(),
                &c.accuracy_cumulative,
            ),
            line(
                "teacher interventions (all so far)".into(),
                &c.teacher_cumulative,
            ),
        ],
        true,
    )
}

/// Both memories' nodes after each round.
fn nodes(path: &Path, r: &RunResults) -> std::io::Result<()> {
    let Some(rec) = &r.recognition else {
        return Ok(());
    };
    let nodes = |f: fn(&MemoryPoint) -> usize| -> Vec<(f64, f64)> {
        rec.memory
            .iter()
            .map(|m| (m.objects_seen as f64, f(m) as f64))
            .collect()
    };
    line_chart(
        path,
        "Nodes of the dual memory (after each round)",
        "objects seen",
        "nodes",
        &[
            line("G-EM".into(), &nodes(|m| m.episodic_nodes)),
            line("G-SM".into(), &nodes(|m| m.semantic_nodes)),
        ],
        false,
    )
}
