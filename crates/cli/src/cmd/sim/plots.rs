//! The plots of `lgdm sim` runs, drawn into the run directory from the numbers the library
//! computed ([`RunResults`]: the summary, [`RunResults::learning_curve`],
//! [`lgdm_sim::arrival::Evaluation::per_category`]).

use std::path::Path;

use anyhow::Result;
use lgdm_sim::packing::basket_name;
use lgdm_sim::recognize::MemoryPoint;
use lgdm_sim::results::{Rate, RunResults};

use crate::plot::{Bar, write_bar_chart, write_lines};

/// A rate as a bar with its Wilson interval.
fn bar(label: String, rate: &Rate) -> Bar {
    Bar {
        label,
        value: rate.value.unwrap_or(0.0),
        interval: Some((rate.wilson_low, rate.wilson_high)),
    }
}

/// `success_by_category.png` and `failure_reasons.png`.
pub fn write_plots(dir: &Path, r: &RunResults) -> Result<()> {
    let s = &r.summary;
    let bars: Vec<Bar> = s
        .per_category
        .iter()
        .map(|(c, cs)| bar(c.clone(), &cs.grasp_success_rate))
        .collect();
    let title = format!(
        "Grasp success by category ({}, {}; Wilson 95 %)",
        r.run.scenario, r.run.grasp_source
    );
    write_bar_chart(
        &dir.join("success_by_category.png"),
        &title,
        "grasp success",
        &bars,
        1.05,
    )?;
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
    write_bar_chart(
        &dir.join("failure_reasons.png"),
        &title,
        "attempts",
        &bars,
        top,
    )?;
    Ok(())
}

/// Packing: `packing_by_category.png` (success by the true category of the object aimed at).
/// Categories arriving over time: `end_evaluation.png` (first-guess category accuracy per
/// category at the end, early and late marked).
pub fn write_packing_plots(dir: &Path, r: &RunResults) -> Result<()> {
    if let (Some(spec), Some(p)) = (&r.run.packing, &r.summary.packing) {
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
        let path = dir.join("packing_by_category.png");
        write_bar_chart(&path, &title, "in its true category's basket", &bars, 1.05)?;
    }
    if let Some(e) = &r.arrival_evaluation {
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
        write_bar_chart(
            &dir.join("end_evaluation.png"),
            &title,
            "category accuracy",
            &bars,
            1.05,
        )?;
    }
    Ok(())
}

/// `learning_curve.png` (first-guess accuracy and teacher interventions against objects seen,
/// over the last 25 recognitions and over all so far) and `nodes.png` (both memories' nodes
/// after each round).
pub fn write_learning_plots(dir: &Path, r: &RunResults) -> Result<()> {
    let c = r.learning_curve(25);
    let w = c.window;
    write_lines(
        &dir.join("learning_curve.png"),
        "Recognition in the loop: first guess and teacher",
        "objects seen",
        "share",
        &[
            (
                format!("first-guess category accuracy (last {w})"),
                c.accuracy_windowed,
            ),
            (
                format!("teacher interventions (last {w})"),
                c.teacher_windowed,
            ),
            (
                "first-guess category accuracy (all so far)".into(),
                c.accuracy_cumulative,
            ),
            (
                "teacher interventions (all so far)".into(),
                c.teacher_cumulative,
            ),
        ],
        true,
    )?;
    if let Some(rec) = &r.recognition {
        let nodes = |f: fn(&MemoryPoint) -> usize| -> Vec<(f64, f64)> {
            rec.memory
                .iter()
                .map(|m| (m.objects_seen as f64, f(m) as f64))
                .collect()
        };
        write_lines(
            &dir.join("nodes.png"),
            "Nodes of the dual memory (after each round)",
            "objects seen",
            "nodes",
            &[
                ("G-EM".into(), nodes(|m| m.episodic_nodes)),
                ("G-SM".into(), nodes(|m| m.semantic_nodes)),
            ],
            false,
        )?;
    }
    Ok(())
}
