//! The run's summary as text — what `summary.txt` holds and the binary prints at the end: the
//! rates with their Wilson intervals, per category, the failure reasons and where the wall time
//! went; for pick-and-place also recognition and the teacher, packing and the end-of-run
//! evaluation of categories arriving over time.
//!
//! ```
//! use lgdm_sim::run::report::failure_list;
//! let reasons = [("missed".to_string(), 3), ("slipped_during_lift".to_string(), 0)];
//! assert_eq!(failure_list(&reasons.into_iter().collect()), "missed 3");
//! ```

use std::collections::BTreeMap;
use std::fmt::Write;

use crate::grasping::attempt::FailureReason;
use crate::run::results::RunResults;
use crate::tasks::packing::basket_name;

/// The summary of `r`: [`pick_place_table`] for a run with recognition, else
/// [`summary_table`].
pub fn summary_text(r: &RunResults) -> String {
    if r.recognition.is_some() {
        pick_place_table(r)
    } else {
        summary_table(r)
    }
}

/// The terminal summary: rates with Wilson intervals, per category, failure reasons, where the
/// wall time went.
pub fn summary_table(r: &RunResults) -> String {
    let s = &r.summary;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "sim grasp: {} scenario, {} grasps, {} rounds, seed {}, {} ({} objects)",
        r.run.scenario,
        r.run.grasp_source,
        r.run.rounds,
        r.run.seed,
        r.run.objects,
        r.run.library_size
    );
    let _ = writeln!(
        out,
        "{:<28} rate (95 % Wilson interval, n; clustered: 95 % bootstrap over rounds)",
        ""
    );
    for (name, rate) in [
        ("grasp success", &s.grasp_success_rate),
        ("placement success", &s.placement_success_rate),
        ("objects cleared", &s.cleared_fraction),
        ("contact-only (paper's test)", &s.contact_only_success_rate),
    ] {
        let _ = writeln!(out, "{name:<28} {}", rate.describe());
        if name == "placement success"
            && let Some(landed) = &s.landed_rate
        {
            let _ = writeln!(
                out,
                "{:<28} {}",
                "  of the objects grasped",
                landed.describe()
            );
        }
    }
    let _ = writeln!(out, "\nper category (object aimed at):");
    // As wide as the longest name (at least 12): YCB names such as `tomato_soup_can` are longer.
    let w = s
        .per_category
        .keys()
        .map(|c| c.chars().count())
        .fold(12, usize::max);
    // Failure reasons per category, from the attempts (those without an object: "unknown").
    let mut reasons: BTreeMap<&str, BTreeMap<String, usize>> = BTreeMap::new();
    for a in &r.attempts {
        if let Some(reason) = a.reason {
            let c = a.category.as_deref().unwrap_or("unknown");
            *reasons
                .entry(c)
                .or_default()
                .entry(reason.as_str().to_string())
                .or_default() += 1;
        }
    }
    let _ = writeln!(
        out,
        "  {:<w$} {:>8}  {:<32} {:<32} failures",
        "category", "attempts", "grasp success", "placement success"
    );
    for (c, cs) in &s.per_category {
        let failures = reasons
            .get(c.as_str())
            .map(failure_list)
            .unwrap_or_else(|| "none".into());
        let _ = writeln!(
            out,
            "  {c:<w$} {:>8}  {:<32} {:<32} {failures}",
            cs.attempts,
            cs.grasp_success_rate.describe(),
            cs.placement_success_rate.describe()
        );
    }
    let _ = writeln!(
        out,
        "\nfailure reasons: {}",
        failure_list(&s.failure_reasons)
    );
    let _ = writeln!(
        out,
        "grasp proposals refused before a try (a pad would close on air): {} of {} planned",
        s.proposals.refused, s.proposals.planned
    );
    let scenario = &r.config.scenario;
    let memory = match scenario.failed_grasp_radius_m > 0.0 {
        true => format!(
            "not tried again (within {} m and {}°): {} candidates skipped",
            scenario.failed_grasp_radius_m,
            scenario.failed_grasp_angle_deg,
            s.proposals.repeat_skipped
        ),
        false => "memory off".to_string(),
    };
    let _ = writeln!(
        out,
        "failed grasps {memory}; attempts that repeated one (within {} m and {}°): {} ({} failed \
         again)",
        s.repeats.radius_m, s.repeats.angle_deg, s.repeats.attempts, s.repeats.failed_again
    );
    let refused = s
        .failure_reasons
        .get(FailureReason::ArmCollision.as_str())
        .copied()
        .unwrap_or(0);
    let _ = writeln!(
        out,
        "attempts with a planned move that would have swept the arm, the gripper or the object \
         held through the table, a basket, the floor, the pedestal or a pile wall (or a link \
         through another): {} ({} re-planned with a lifted detour, {} turned down as \
         arm_collision); attempts that touched them anyway, on the way back: {}",
        s.avoided_contact_attempts, s.detour_attempts, refused, s.arm_contact_attempts
    );
    if s.proposals.checked > 0 {
        let _ = writeln!(
            out,
            "grasp proposals refused by the depth check ({}) before planning: {} of {} checked",
            r.config.attempt.proposal_check.unwrap_or_default().word(),
            s.proposals.check_refused,
            s.proposals.checked
        );
    }
    let w = &r.wall;
    let a = &w.attempts;
    let pct = |x: f64| {
        if a.total_s > 0.0 {
            100.0 * x / a.total_s
        } else {
            0.0
        }
    };
    let _ = writeln!(
        out,
        "wall time {:.1} s, {:.3} s per attempt (physics {:.0} %, rendering {:.0} %, perception \
         {:.0} %, grasp source {:.0} %, planning {:.0} %), {:.0}× real time",
        w.total_s,
        w.per_attempt_s,
        pct(a.physics_s),
        pct(a.render_s),
        pct(a.perception_s),
        pct(a.source_s),
        pct(a.planning_s),
        w.real_time_factor
    );
    out
}

/// The pick-and-place summary: packing (in a packing run) and the end-of-run evaluation (with
/// categories arriving over time) first, then recognition and teacher, then the grasp run's
/// table.
pub fn pick_place_table(r: &RunResults) -> String {
    let mut out = String::new();
    packing_section(&mut out, r);
    arrival_section(&mut out, r);
    recognition_section(&mut out, r);
    // The grasp table's first line names the command that made it.
    let grasp = summary_table(r);
    out.push_str(&grasp.replacen("sim grasp:", "grasp and placement:", 1));
    out
}

/// Packing runs: the targets, the packing rates, the failures, what chose the baskets.
fn packing_section(out: &mut String, r: &RunResults) {
    let s = &r.summary;
    if let (Some(spec), Some(p)) = (&r.run.packing, &s.packing) {
        let _ = writeln!(
            out,
            "sim packing: {} → {} basket, everything else → {} basket",
            spec.targets.join(", "),
            basket_name(spec.target_basket),
            basket_name(spec.other_basket)
        );
        let _ = writeln!(
            out,
            "{:<28} rate (95 % Wilson interval, n; clustered: 95 % bootstrap over rounds)",
            ""
        );
        let _ = writeln!(
            out,
            "{:<28} {}",
            "packing success (attempts)",
            p.success_rate.describe()
        );
        let _ = writeln!(
            out,
            "{:<28} {}",
            "objects packed correctly",
            p.packed_fraction.describe()
        );
        let _ = writeln!(
            out,
            "{:<28} {}",
            "objects cleared",
            s.cleared_fraction.describe()
        );
        let _ = writeln!(
            out,
            "failures by cause: {}",
            failure_list(&s.failure_reasons)
        );
        let decided: Vec<String> = p
            .decided_by
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        let _ = writeln!(out, "baskets chosen by: {}\n", decided.join(", "));
    }
}

/// Categories arriving over time: the first guesses at the switch and at the end.
fn arrival_section(out: &mut String, r: &RunResults) {
    if let Some(e) = &r.arrival_evaluation {
        let a = &e.arrival;
        let _ = writeln!(
            out,
            "categories arriving over time: {} before round {}, {} from it on",
            a.early_categories.join(", "),
            a.after_round,
            a.late_categories.join(", ")
        );
        for (when, ev) in [
            ("when the late categories arrived", e.at_switch.as_ref()),
            ("at the end", Some(&e.at_end)),
        ] {
            let Some(ev) = ev else { continue };
            let _ = writeln!(
                out,
                "first guess {when}, after {} rounds ({} fresh poses per object, no teacher):",
                ev.after_rounds, a.eval_poses
            );
            for (name, rate) in [
                ("early categories (category)", &ev.early_category_accuracy),
                ("early categories (instance)", &ev.early_instance_accuracy),
                (
                    "early, answer right (any conf.)",
                    &ev.early_category_answer_accuracy,
                ),
                ("late categories (category)", &ev.late_category_accuracy),
                ("late categories (instance)", &ev.late_instance_accuracy),
            ] {
                let _ = writeln!(out, "  {name:<32} {}", rate.describe());
            }
        }
        let _ = writeln!(out);
    }
}

/// Recognition and the teacher, the memory's growth, replay's time.
fn recognition_section(out: &mut String, r: &RunResults) {
    let s = &r.summary;
    if let Some(rec) = &r.recognition {
        let _ = writeln!(
            out,
            "{}: {} encoder, start model {}, replay {}, learns {}",
            if r.run.packing.is_some() {
                "recognition"
            } else {
                "sim pick-place"
            },
            rec.encoder,
            rec.start_model,
            if rec.config.replay { "on" } else { "off" },
            if rec.config.learn_known {
                "every object"
            } else {
                "the teacher's lessons"
            }
        );
        let _ = writeln!(
            out,
            "{:<28} rate (95 % Wilson interval, n; clustered: 95 % bootstrap over rounds)",
            ""
        );
        for (name, rate) in [
            ("recognition (category)", &s.recognition_accuracy),
            ("recognition (instance)", &s.instance_recognition_accuracy),
            ("teacher interventions", &s.teacher_intervention_rate),
        ] {
            if let Some(rate) = rate {
                let _ = writeln!(out, "{name:<28} {}", rate.describe());
            }
        }
        if let (Some(first), Some(last)) = (rec.memory.first(), rec.memory.last()) {
            let _ = writeln!(
                out,
                "nodes G-EM / G-SM            {} / {} at the start, {} / {} after {} rounds \
                 ({} lessons)",
                first.episodic_nodes,
                first.semantic_nodes,
                last.episodic_nodes,
                last.semantic_nodes,
                last.rounds,
                last.lessons
            );
        }
        let _ = writeln!(
            out,
            "replay at the rounds' ends {:.1} s, recognition {:.1} s\n",
            r.wall.replay_s, r.wall.attempts.recognition_s
        );
    }
}

/// The failure reasons that occurred, as `reason n, reason n` (`none` when none did).
pub fn failure_list(reasons: &BTreeMap<String, usize>) -> String {
    let failures: Vec<String> = reasons
        .iter()
        .filter(|(_, n)| **n > 0)
        .map(|(k, n)| format!("{k} {n}"))
        .collect();
    if failures.is_empty() {
        "none".to_string()
    } else {
        failures.join(", ")
    }
}
