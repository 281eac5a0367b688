//! What the recordings say in words: the storyboard caption of an attempt, the `/events` line
//! and the `/labels` billboard of a recognition, and the line that ends a round. Pure functions
//! of the records, so the recording observer ([`crate::run::record`]) and anything else that wants
//! the same words share them.
//!
//! ```
//! use lgdm_sim::run::captions::round_summary;
//! use lgdm_sim::run::results::{RoundEnd, RoundRecord};
//! let round = RoundRecord {
//!     round: 0,
//!     objects: vec!["mug_01".into()],
//!     attempts: 1,
//!     placed: 1,
//!     left_table: Vec::new(),
//!     ended_by: RoundEnd::Cleared,
//!     sim_time_s: 12.0,
//!     wall: Default::default(),
//! };
//! assert_eq!(round_summary(&round), "cleared, placed 1 of 1, 1 attempts");
//! ```

use crate::grasping::attempt::FailureReason;
use crate::recognition::recognizer::RecognitionRecord;
use crate::run::results::{AttemptRecord, RoundRecord};

/// A storyboard caption of an attempt: `attempt 2 (try 1, rank 1) mug_01: grasp failed (missed)`.
pub fn attempt_caption(a: &AttemptRecord) -> String {
    let object = a.object.as_deref().unwrap_or("no object");
    let outcome = match (a.grasp_success, a.placement_success, a.reason) {
        (true, true, Some(FailureReason::Misrecognised)) => {
            "grasp ok, placed in the wrong basket (misrecognised)".to_string()
        }
        (true, true, _) => "grasp ok, placed".to_string(),
        (true, false, r) => format!(
            "grasp ok, not placed ({})",
            r.map_or("unknown", FailureReason::as_str)
        ),
        (false, _, r) => format!(
            "grasp failed ({})",
            r.map_or("unknown", FailureReason::as_str)
        ),
    };
    let rank = a
        .grasp
        .as_ref()
        .map_or(String::new(), |g| format!(", rank {}", g.rank));
    let grasped = a
        .grasped_object
        .as_deref()
        .map_or(String::new(), |g| format!(" (pinched {g})"));
    let recognition = a.recognition.as_ref().map_or(String::new(), |r| {
        let g = &r.guess;
        match (g.known, r.teacher) {
            (true, false) => format!(
                ", knew it: {}",
                g.instance.as_deref().unwrap_or(&r.true_instance)
            ),
            (false, _) => format!(", did not know it, taught {}", r.true_instance),
            (true, true) => format!(
                ", took it for {}, taught {}",
                g.instance.as_deref().unwrap_or("?"),
                r.true_instance
            ),
        }
    });
    format!(
        "attempt {} (try {}{rank}) {object}{grasped}{recognition}: {outcome}",
        a.index, a.try_in_round
    )
}

/// A recording's line about a recognition: `mug_01 (mug): guessed teapot/teapot_02 at 40 %,
/// teacher: mug/mug_01 (10 views)`.
pub fn recognition_caption(r: &RecognitionRecord) -> String {
    let g = &r.guess;
    let guess = match (&g.category, &g.instance) {
        (Some(c), i) => format!(
            "guessed {c}/{} at {:.0} %{}",
            i.as_deref().unwrap_or("?"),
            100.0 * g.confidence,
            if g.known { "" } else { " (I don't know this)" }
        ),
        (None, _) => "I don't know this".to_string(),
    };
    let teacher = if r.teacher {
        format!(
            ", teacher: {}/{} ({} views learnt)",
            r.true_category, r.true_instance, r.taught_views
        )
    } else {
        ", right".to_string()
    };
    format!(
        "recognition of {} ({}): {guess}{teacher}",
        r.true_instance, r.true_category
    )
}

/// A recognition as the label above the object on `/labels`: the true instance, the first
/// guess with its confidence, and the teacher's part.
pub fn recognition_label(r: &RecognitionRecord) -> ObjectLabel {
    let g = &r.guess;
    let guess = match (&g.category, &g.instance) {
        (Some(c), i) if g.known => format!(
            "{c}/{} {:.0} %",
            i.as_deref().unwrap_or("?"),
            100.0 * g.confidence
        ),
        _ => "I don't know this".to_string(),
    };
    let mut text = format!("{}\n{guess}", r.true_instance);
    if r.teacher {
        text.push_str(&format!(
            "\nteacher: {}/{}",
            r.true_category, r.true_instance
        ));
    }
    let tone = match (g.known, r.teacher) {
        (false, _) => LabelTone::Unknown,
        (true, true) => LabelTone::Wrong,
        (true, false) => LabelTone::Right,
    };
    ObjectLabel {
        text,
        tone,
        metadata: vec![
            ("true_category", r.true_category.clone()),
            ("true_instance", r.true_instance.clone()),
            ("guess_category", g.category.clone().unwrap_or_default()),
            ("guess_instance", g.instance.clone().unwrap_or_default()),
            ("confidence", format!("{:.3}", g.confidence)),
            ("known", g.known.to_string()),
            ("teacher", r.teacher.to_string()),
        ],
    }
}

/// How a round ended, for its recording: `cleared, placed 1 of 1`.
pub fn round_summary(r: &RoundRecord) -> String {
    let ended = serde_json::to_value(r.ended_by)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    let mut text = format!(
        "{ended}, placed {} of {}, {} attempts",
        r.placed,
        r.objects.len(),
        r.attempts
    );
    if !r.left_table.is_empty() {
        text.push_str(&format!(", left the table: {}", r.left_table.join(", ")));
    }
    text
}

/// What the robot made of an object, shown above it on `/labels`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectLabel {
    /// The text (lines separated by `\n`).
    pub text: String,
    /// How the recognition went (the colour).
    pub tone: LabelTone,
    /// Key–value pairs for the entity's metadata (true labels, guess, confidence, teacher).
    pub metadata: Vec<(&'static str, String)>,
}

/// How a recognition went, as a label's colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LabelTone {
    /// The robot knew the object (green).
    Right,
    /// The robot said it did not know (amber): the teacher taught it.
    Unknown,
    /// The robot was sure and wrong (red): the teacher corrected it.
    Wrong,
}
