//! Terminal tables of a run's results (mean ± std over trials).

use super::{MeanStd, RunMetrics};
use std::fmt::Write;

fn pct(m: &MeanStd) -> String {
    if m.mean.is_nan() {
        "—".into()
    } else {
        format!("{:5.1} ± {:4.1} %", 100.0 * m.mean, 100.0 * m.std)
    }
}

fn num(m: &MeanStd, digits: usize) -> String {
    format!("{:.*} ± {:.*}", digits, m.mean, digits, m.std)
}

/// The summary table printed at the end of `lgdm train` and saved as `summary.txt` (also by
/// `lgdm merge` and `lgdm.run_scenario(out=…)`).
pub fn summary_table(m: &RunMetrics) -> String {
    let s = &m.summary;
    let mut out = String::new();
    let epochs = if m.scenario == "batch" {
        format!("{} epochs", m.epochs)
    } else {
        format!("{} epoch(s) per step", m.epochs)
    };
    let _ = writeln!(
        out,
        "scenario {} · encoder {} · {} trial(s) · replay {} · temporal context {} · {epochs}",
        m.scenario,
        m.encoder,
        s.trials,
        if m.replay { "on" } else { "off" },
        if m.context { "on" } else { "off" },
    );
    if !m.learner.is_gdm() {
        let _ = writeln!(
            out,
            "learner {}: G-EM rows = its per-instance means, G-SM rows = its per-category means",
            m.learner
        );
    }
    let _ = writeln!(out, "{:<34} {:>16} {:>16}", "", "train", "test");
    let _ = writeln!(
        out,
        "{:<34} {:>16} {:>16}",
        "instance accuracy (G-EM)",
        pct(&s.train_instance_accuracy),
        pct(&s.test_instance_accuracy)
    );
    let _ = writeln!(
        out,
        "{:<34} {:>16} {:>16}",
        "category accuracy (G-EM)",
        pct(&s.train_category_accuracy_em),
        pct(&s.test_category_accuracy_em)
    );
    let _ = writeln!(
        out,
        "{:<34} {:>16} {:>16}",
        "category accuracy (G-SM)",
        pct(&s.train_category_accuracy_sm),
        pct(&s.test_category_accuracy_sm)
    );
    let _ = writeln!(
        out,
        "{:<34} {:>16} {:>16}",
        "  without context at test (G-SM)",
        "",
        pct(&s.test_no_context_category_accuracy_sm)
    );
    if let Some(n) = &s.new_instance_category_accuracy_sm {
        let _ = writeln!(
            out,
            "{:<34} {:>16} {:>16}",
            "new-instance category acc. (G-SM)",
            "",
            pct(n)
        );
    }
    let _ = writeln!(
        out,
        "{:<34} {:>16} / {}",
        "nodes G-EM / G-SM",
        num(&s.episodic_nodes, 0),
        num(&s.semantic_nodes, 0)
    );
    let _ = writeln!(
        out,
        "{:<34} {:>16} MB",
        "model size",
        num(&s.model_size_mb, 3)
    );
    let _ = writeln!(
        out,
        "{:<34} {:>16} ms/sample",
        "inference time",
        num(&s.inference_ms_per_sample, 3)
    );
    out.push_str(&super::forgetting::summary_lines(s.forgetting.as_ref()));
    out
}
