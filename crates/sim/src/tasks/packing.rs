//! Packing (the paper's second robot task): objects of the target categories go to the right
//! basket, everything else to the left one, and an attempt succeeds only when the object lands
//! in the basket its **true** category belongs to.
//!
//! **Left and right** are the robot's, as it faces the table (its base looks along −y): the left
//! basket is the world's basket 0 at x = +0.7 m (where `sim grasp` and `sim pick-place` place),
//! the right one its mirror, basket 1 at x = −0.7 m. Both are reached with the same carry height
//! ([`crate::grasping::attempt::AttemptConfig::carry_height_m`], ≤ 1.03 m; see [`crate::robot`]).
//!
//! **Which basket: what the robot recognises.** The basket is chosen before the grasp from the
//! object's recognition ([`crate::recognition::recognizer`]), as the paper's robot packs by what it
//! recognises:
//! - the robot's first guess when it trusts it ([`crate::recognition::recognizer::Guess::known`]) —
//!   a confident wrong guess sends the object to the wrong basket; the teacher's correction is
//!   learnt for the next encounter but comes too late for this one (the robot acts on its own
//!   answer);
//! - the teacher's label when the robot said "I don't know this" (it asked, and was told);
//! - the other (left) basket when there is no recognition at all (no object aimed at).
//!
//! **Judging.** Grasp and placement are judged physically as in every attempt
//! ([`crate::grasping::attempt::execute`]); [`judge`] then compares the basket the object went to
//! with the one its true category belongs to. An object placed in the wrong basket is a failed
//! attempt with reason [`FailureReason::Misrecognised`], even though the grasp and the placement
//! physically succeeded (it has left the table: it counts as cleared, not as packed).
//!
//! ```
//! use lgdm_sim::tasks::packing::{DecidedBy, PackingSpec, LEFT_BASKET, RIGHT_BASKET};
//! let spec = PackingSpec::new(vec!["mug".into(), "can".into()]);
//! assert_eq!(spec.basket_for("mug"), RIGHT_BASKET);
//! assert_eq!(spec.basket_for("book"), LEFT_BASKET);
//! let choice = spec.choose(None);
//! assert_eq!((choice.basket, choice.decided_by), (LEFT_BASKET, DecidedBy::Nothing));
//! ```

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::grasping::attempt::FailureReason;
use crate::physics::config::WorldConfig;
use crate::recognition::labels::Labels;
use crate::recognition::recognizer::RecognitionRecord;
use lgdm_base::stats::Rate;
use lgdm_pointcloud::objects::ObjectModel;

/// The left basket as the robot sees it: the world's basket 0, at x = +0.7 m (the one `sim
/// grasp` and `sim pick-place` place into).
pub const LEFT_BASKET: usize = 0;

/// The right basket as the robot sees it: the world's basket 1, at x = −0.7 m.
pub const RIGHT_BASKET: usize = 1;

/// `left`, `right`, or `basket <i>` for another index.
pub fn basket_name(index: usize) -> String {
    match index {
        LEFT_BASKET => "left".into(),
        RIGHT_BASKET => "right".into(),
        i => format!("basket {i}"),
    }
}

/// Where objects go. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackingSpec {
    /// The target categories (packed into [`PackingSpec::target_basket`]).
    pub targets: Vec<String>,
    /// Basket of the target categories (default [`RIGHT_BASKET`]).
    pub target_basket: usize,
    /// Basket of every other category (default [`LEFT_BASKET`]).
    pub other_basket: usize,
}

/// Errors of a packing spec.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PackingError {
    /// No target category.
    #[error("packing needs at least one target category")]
    NoTargets,
    /// A target category the object set and the model do not know.
    #[error("unknown target category `{category}` (known: {})", known.join(", "))]
    UnknownTarget {
        /// The category given.
        category: String,
        /// The categories known (the object set's, then the model's).
        known: Vec<String>,
    },
    /// A basket index the world does not have, or the same basket for both.
    #[error("packing baskets: {0}")]
    Baskets(String),
    /// Packing without recognition (the basket is chosen by what the robot recognises).
    #[error("packing needs recognition in the loop (a recognizer)")]
    NoRecognition,
}

impl PackingSpec {
    /// `targets` to the right basket, everything else to the left one.
    pub fn new(targets: Vec<String>) -> Self {
        Self {
            targets,
            target_basket: RIGHT_BASKET,
            other_basket: LEFT_BASKET,
        }
    }

    /// Checks the targets against the categories `known` (each must be one of them; none empty)
    /// and the baskets against `world`.
    pub fn validate(&self, known: &[String], world: &WorldConfig) -> Result<(), PackingError> {
        if self.targets.is_empty() {
            return Err(PackingError::NoTargets);
        }
        for t in &self.targets {
            if !known.contains(t) {
                return Err(PackingError::UnknownTarget {
                    category: t.clone(),
                    known: known.to_vec(),
                });
            }
        }
        let n = world.baskets.len();
        if self.target_basket >= n || self.other_basket >= n {
            return Err(PackingError::Baskets(format!(
                "baskets {} and {} of a world with {n}",
                self.target_basket, self.other_basket
            )));
        }
        if self.target_basket == self.other_basket {
            return Err(PackingError::Baskets(format!(
                "targets and the rest both go to basket {}",
                self.target_basket
            )));
        }
        Ok(())
    }

    /// The basket objects of `category` belong in.
    pub fn basket_for(&self, category: &str) -> usize {
        if self.targets.iter().any(|t| t == category) {
            self.target_basket
        } else {
            self.other_basket
        }
    }

    /// The basket for an object recognised as `recognition` (see the module docs): the trusted
    /// first guess, else the teacher's label, else the other basket.
    pub fn choose(&self, recognition: Option<&RecognitionRecord>) -> BasketChoice {
        let (packed_as, decided_by) = match recognition {
            Some(r) if r.guess.known && r.guess.category.is_some() => {
                (r.guess.category.clone(), DecidedBy::Guess)
            }
            Some(r) if r.teacher => (Some(r.true_category.clone()), DecidedBy::Teacher),
            _ => (None, DecidedBy::Nothing),
        };
        let basket = packed_as
            .as_deref()
            .map_or(self.other_basket, |c| self.basket_for(c));
        BasketChoice {
            packed_as,
            decided_by,
            basket,
        }
    }
}

/// The categories a target may name: the object set's (in order of first appearance), then
/// those only the model's labels know.
pub fn known_categories(library: &[ObjectModel], labels: &Labels) -> Vec<String> {
    let mut known: Vec<String> = Vec::new();
    for c in library
        .iter()
        .map(|o| &o.category)
        .chain(labels.categories.iter())
    {
        if !known.contains(c) {
            known.push(c.clone());
        }
    }
    known
}

/// What the basket was chosen by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DecidedBy {
    /// The robot's trusted first guess.
    Guess,
    /// The teacher's label (the robot did not know the object).
    Teacher,
    /// Nothing was recognised: the other basket.
    Nothing,
}

impl DecidedBy {
    /// The snake_case name (as in results.json).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Guess => "guess",
            Self::Teacher => "teacher",
            Self::Nothing => "nothing",
        }
    }
}

/// The basket an attempt carries to, and why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BasketChoice {
    /// The category the object was packed as (none: nothing recognised).
    pub packed_as: Option<String>,
    /// Where that category came from.
    pub decided_by: DecidedBy,
    /// The basket chosen (index in the world's baskets).
    pub basket: usize,
}

/// One attempt's packing: the basket chosen, the one the object belongs in, the verdict.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PackingRecord {
    /// The choice.
    #[serde(flatten)]
    pub choice: BasketChoice,
    /// The true category of the object carried (the one pinched; else the one aimed at).
    pub true_category: Option<String>,
    /// The basket that category belongs in.
    pub true_basket: Option<usize>,
    /// Placed, and in the basket its true category belongs to.
    pub success: bool,
}

/// The verdict on an attempt that carried to `choice.basket`: success when it was placed there
/// (`placement_success`) and that basket is the one `true_category` belongs in. The reason of a
/// placement in the wrong basket is [`FailureReason::Misrecognised`]; otherwise the physical
/// `reason` stands.
pub fn judge(
    spec: &PackingSpec,
    choice: BasketChoice,
    true_category: Option<&str>,
    placement_success: bool,
    reason: Option<FailureReason>,
) -> (PackingRecord, Option<FailureReason>) {
    let true_basket = true_category.map(|c| spec.basket_for(c));
    let success = placement_success && true_basket == Some(choice.basket);
    let reason = if placement_success && !success {
        Some(FailureReason::Misrecognised)
    } else {
        reason
    };
    let record = PackingRecord {
        choice,
        true_category: true_category.map(str::to_string),
        true_basket,
        success,
    };
    (record, reason)
}

/// A packing run's summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackingSummary {
    /// Attempts that put an object into the basket its true category belongs to / attempts
    /// (the paper's packing success rate).
    pub success_rate: Rate,
    /// Objects packed into the basket of their true category / objects set on the table.
    pub packed_fraction: Rate,
    /// Objects placed in the wrong basket (attempts failed as `misrecognised`).
    pub misrecognised: usize,
    /// Attempts at an object by what chose their basket (`guess`, `teacher`, `nothing`; every
    /// key listed).
    pub decided_by: BTreeMap<String, usize>,
    /// Packing success by the true category of the object aimed at (attempts at an object).
    pub per_category: BTreeMap<String, Rate>,
}

/// The packing summary of a packing run of `attempts` attempts: `packed` holds, per attempt at
/// an object, the category aimed at and its packing record (attempts without one — at no
/// object — count as failures); `misrecognised` attempts were placed in the wrong basket;
/// `presented` objects were set on the tables.
pub fn summarize(
    packed: &[(Option<&str>, &PackingRecord)],
    attempts: usize,
    misrecognised: usize,
    presented: usize,
) -> PackingSummary {
    let successes = packed.iter().filter(|(_, p)| p.success).count();
    let mut decided_by: BTreeMap<String, usize> =
        [DecidedBy::Guess, DecidedBy::Teacher, DecidedBy::Nothing]
            .iter()
            .map(|d| (d.as_str().to_string(), 0))
            .collect();
    let mut per_category: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for (category, p) in packed {
        *decided_by
            .entry(p.choice.decided_by.as_str().to_string())
            .or_default() += 1;
        let c = per_category
            .entry(category.unwrap_or("unknown").to_string())
            .or_default();
        c.0 += usize::from(p.success);
        c.1 += 1;
    }
    PackingSummary {
        success_rate: Rate::new(successes, attempts),
        packed_fraction: Rate::new(successes, presented),
        misrecognised,
        decided_by,
        per_category: per_category
            .into_iter()
            .map(|(c, (k, n))| (c, Rate::new(k, n)))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recognition::recognizer::Guess;

    fn recognition(guess: Option<&str>, known: bool, truth: &str) -> RecognitionRecord {
        let category_correct = known && guess == Some(truth);
        RecognitionRecord {
            true_category: truth.into(),
            true_instance: format!("{truth}_01"),
            guess: Guess {
                category: guess.map(str::to_string),
                instance: None,
                confidence: if known { 1.0 } else { 0.2 },
                activation: None,
                views: 5,
                known,
            },
            category_correct,
            instance_correct: false,
            teacher: true,
            taught_views: 10,
            first_look: true,
        }
    }

    fn spec() -> PackingSpec {
        PackingSpec::new(vec!["mug".into(), "can".into()])
    }

    #[test]
    fn a_trusted_guess_chooses_the_basket_even_when_wrong() {
        // Seen as a mug (a target) but a book: carried to the right basket.
        let r = recognition(Some("mug"), true, "book");
        let choice = spec().choose(Some(&r));
        assert_eq!(choice.packed_as.as_deref(), Some("mug"));
        assert_eq!(choice.decided_by, DecidedBy::Guess);
        assert_eq!(choice.basket, RIGHT_BASKET);
    }

    #[test]
    fn an_object_the_robot_does_not_know_goes_by_the_teachers_label() {
        // An untrusted guess "book" for a can: the teacher says can → right.
        let r = recognition(Some("book"), false, "can");
        let choice = spec().choose(Some(&r));
        assert_eq!(choice.packed_as.as_deref(), Some("can"));
        assert_eq!(choice.decided_by, DecidedBy::Teacher);
        assert_eq!(choice.basket, RIGHT_BASKET);
        // No recognition at all: the other basket.
        assert_eq!(spec().choose(None).basket, LEFT_BASKET);
    }

    #[test]
    fn success_only_in_the_basket_of_the_true_category() {
        let s = spec();
        let to_right = s.choose(Some(&recognition(Some("mug"), true, "book")));
        // A book placed in the right basket: misrecognised, though physically placed.
        let (record, reason) = judge(&s, to_right.clone(), Some("book"), true, None);
        assert!(!record.success);
        assert_eq!(record.true_basket, Some(LEFT_BASKET));
        assert_eq!(reason, Some(FailureReason::Misrecognised));
        // A mug placed there: packed.
        let (record, reason) = judge(&s, to_right.clone(), Some("mug"), true, None);
        assert!(record.success && reason.is_none());
        // Not placed: the physical reason stands, whatever the basket.
        let (record, reason) = judge(
            &s,
            to_right,
            Some("book"),
            false,
            Some(FailureReason::SlippedDuringCarry),
        );
        assert!(!record.success);
        assert_eq!(reason, Some(FailureReason::SlippedDuringCarry));
        // A wrong guess between two non-targets still lands in the correct (left) basket.
        let other = s.choose(Some(&recognition(Some("apple"), true, "book")));
        let (record, reason) = judge(&s, other, Some("book"), true, None);
        assert!(record.success && reason.is_none());
    }

    #[test]
    fn unknown_targets_and_bad_baskets_are_refused() {
        let known: Vec<String> = ["mug", "can", "book"].map(String::from).to_vec();
        let world = WorldConfig::default();
        assert!(spec().validate(&known, &world).is_ok());
        let err = PackingSpec::new(vec!["mug".into(), "cup".into()])
            .validate(&known, &world)
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown target category `cup` (known: mug, can, book)"
        );
        assert_eq!(
            PackingSpec::new(vec![]).validate(&known, &world),
            Err(PackingError::NoTargets)
        );
        let same = PackingSpec {
            other_basket: RIGHT_BASKET,
            ..spec()
        };
        assert!(matches!(
            same.validate(&known, &world),
            Err(PackingError::Baskets(_))
        ));
        let missing = PackingSpec {
            target_basket: 2,
            ..spec()
        };
        assert!(matches!(
            missing.validate(&known, &world),
            Err(PackingError::Baskets(_))
        ));
    }
}
