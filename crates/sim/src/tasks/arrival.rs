//! Forgetting in the loop: categories that arrive over time, and what the robot still
//! recognises of the early ones at the end.
//!
//! [`Arrival::split`] splits the object set's categories (in order of first appearance) into the
//! early half (the first ⌈n/2⌉) and the late rest. Rounds before [`Arrival::after_round`] draw
//! their objects from the early categories only, rounds from it on from the late ones only — the
//! class-incremental shape (`nc`) of `lgdm train`, on the robot: after round K nothing rehearses
//! the early categories but intrinsic replay.
//!
//! Twice — when the late categories arrive (before round K) and at the end of the run —
//! [`evaluate`] asks the model about every object of the set from fresh views: each object alone
//! on a fresh table at the clutter centre, upright, turned to [`Arrival::eval_poses`] seeded yaws
//! (the same poses and views both times, so only the model differs), and the robot's first guess
//! ([`Recognizer::guess`]: the same views, temporal context and confidence as in the rounds) — no
//! teacher, no learning (prediction does not change the dual memory), and with a view stream of
//! its own ([`Recognizer::aside`]), so the rounds after it are those of a run without it. The
//! early categories' first-guess accuracy at the end, with and without replay, against the same
//! at the switch, is the measure of forgetting.
//!
//! ```
//! use lgdm_pointcloud::objects::procedural_library;
//! use lgdm_sim::tasks::arrival::Arrival;
//! let library = procedural_library(&["mug", "can", "book"], 2, 0).unwrap();
//! let arrival = Arrival::split(&library, 5).unwrap();
//! assert_eq!(arrival.early_categories, ["mug", "can"]);
//! assert_eq!(arrival.late_categories, ["book"]);
//! // mug_01, mug_02, can_01, can_02 before round 5; book_01, book_02 from it on.
//! assert_eq!(arrival.pool(&library, 4).len(), 4);
//! assert_eq!(arrival.pool(&library, 5).len(), 2);
//! ```

use lgdm_base::seed::derive_seed;
use lgdm_pointcloud::math::{rotation_z, translation};
use lgdm_pointcloud::objects::ObjectModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::physics::config::WorldConfig;
use crate::physics::world::World;
use crate::recognition::error::RecognitionError;
use crate::recognition::recognizer::{Guess, Recognizer};
use crate::timing::WallTimes;
use lgdm_base::stats::Rate;

/// Seed tag of the evaluation's yaws.
const TAG_EVAL_YAW: u64 = 0x5133_0020;

/// Which categories the rounds show when. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Arrival {
    /// Rounds before this one show the early categories only; it and later rounds the late
    /// ones only (at least 1).
    pub after_round: usize,
    /// The first ⌈n/2⌉ categories of the object set, in order of first appearance.
    pub early_categories: Vec<String>,
    /// The rest.
    pub late_categories: Vec<String>,
    /// Yaws each object is shown at in the end-of-run evaluation (default 4).
    pub eval_poses: usize,
}

/// Errors of an arrival plan.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ArrivalError {
    /// `after_round` is 0 (the late categories would arrive at once).
    #[error("categories arriving after round 0 arrive at once: give a round of at least 1")]
    NoEarlyRounds,
    /// The late categories would never arrive.
    #[error(
        "categories arriving after round {after_round} never arrive in a run of {rounds} rounds"
    )]
    NoLateRounds {
        /// The round given.
        after_round: usize,
        /// Rounds in the run.
        rounds: usize,
    },
    /// Fewer than two categories: nothing to split.
    #[error(
        "categories arriving over time need at least two categories in the object set, it has {0}"
    )]
    TooFewCategories(usize),
    /// `eval_poses` is 0 or over 100.
    #[error("eval_poses {0}: must be 1..=100")]
    EvalPoses(usize),
    /// Without recognition there is nothing to forget.
    #[error("categories arriving over time need recognition in the loop (a recognizer)")]
    NoRecognition,
}

impl Arrival {
    /// The early half of `library`'s categories before round `after_round`, the rest from it on;
    /// 4 poses per object in the end-of-run evaluation.
    pub fn split(library: &[ObjectModel], after_round: usize) -> Result<Self, ArrivalError> {
        if after_round == 0 {
            return Err(ArrivalError::NoEarlyRounds);
        }
        let mut categories: Vec<String> = Vec::new();
        for o in library {
            if !categories.contains(&o.category) {
                categories.push(o.category.clone());
            }
        }
        if categories.len() < 2 {
            return Err(ArrivalError::TooFewCategories(categories.len()));
        }
        let late_categories = categories.split_off(categories.len().div_ceil(2));
        Ok(Self {
            after_round,
            early_categories: categories,
            late_categories,
            eval_poses: 4,
        })
    }

    /// Checks the plan against a run of `rounds` rounds.
    pub fn validate(&self, rounds: usize) -> Result<(), ArrivalError> {
        if self.after_round == 0 {
            return Err(ArrivalError::NoEarlyRounds);
        }
        if self.after_round >= rounds {
            return Err(ArrivalError::NoLateRounds {
                after_round: self.after_round,
                rounds,
            });
        }
        if self.early_categories.is_empty() || self.late_categories.is_empty() {
            let n = self.early_categories.len() + self.late_categories.len();
            return Err(ArrivalError::TooFewCategories(n));
        }
        if !(1..=100).contains(&self.eval_poses) {
            return Err(ArrivalError::EvalPoses(self.eval_poses));
        }
        Ok(())
    }

    /// Whether `category` is an early one.
    pub fn is_early(&self, category: &str) -> bool {
        self.early_categories.iter().any(|c| c == category)
    }

    /// The library indices round `round` may show (ascending).
    pub fn pool(&self, library: &[ObjectModel], round: usize) -> Vec<usize> {
        let early = round < self.after_round;
        library
            .iter()
            .enumerate()
            .filter(|(_, o)| self.is_early(&o.category) == early)
            .map(|(i, _)| i)
            .collect()
    }
}

/// One look of the end-of-run evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvaluationLook {
    /// The object (instance name).
    pub object: String,
    /// Its category.
    pub category: String,
    /// Whether its category is an early one.
    pub early: bool,
    /// Its yaw on the table (rad).
    pub yaw_rad: f32,
    /// The robot's first guess.
    pub guess: Guess,
    /// The guess's category is right and trusted (as the rounds' `category_correct`).
    pub category_correct: bool,
    /// The guess's instance is right and trusted.
    pub instance_correct: bool,
}

/// The first guesses about every object of the set at one point of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// Rounds played when it was made.
    pub after_rounds: usize,
    /// Early objects' looks whose category was right and trusted / early looks.
    pub early_category_accuracy: Rate,
    /// Early objects' looks whose instance was right and trusted / early looks.
    pub early_instance_accuracy: Rate,
    /// Early looks whose answer named the right category, trusted or not / early looks.
    pub early_category_answer_accuracy: Rate,
    /// Late objects' looks whose category was right and trusted / late looks.
    pub late_category_accuracy: Rate,
    /// Late objects' looks whose instance was right and trusted / late looks.
    pub late_instance_accuracy: Rate,
    /// Every look, object by object (the library's order), pose by pose.
    pub looks: Vec<EvaluationLook>,
}

/// A run's evaluations of what it knows of the early and the late categories.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArrivalEvaluation {
    /// The arrival plan.
    pub arrival: Arrival,
    /// Before the first late round: what the early rounds taught (none when the run's attempt
    /// budget ended it before).
    pub at_switch: Option<Evaluation>,
    /// After the last round.
    pub at_end: Evaluation,
}

impl Evaluation {
    /// First-guess category accuracy per category (in order of first appearance among the
    /// looks), with whether the category is an early one: the numbers behind the binary's
    /// `end_evaluation.png`.
    pub fn per_category(&self) -> Vec<(String, bool, Rate)> {
        let mut categories: Vec<(String, bool)> = Vec::new();
        for l in &self.looks {
            if !categories.iter().any(|(c, _)| c == &l.category) {
                categories.push((l.category.clone(), l.early));
            }
        }
        categories
            .into_iter()
            .map(|(c, early)| {
                let of: Vec<&EvaluationLook> =
                    self.looks.iter().filter(|l| l.category == c).collect();
                let rate = Rate::of(&of, |l| l.category_correct);
                (c, early, rate)
            })
            .collect()
    }
}

/// An arrival plan at work in a run (the runner's policy for categories arriving over time):
/// the objects each round draws from, and the evaluations when the late categories arrive and
/// at the end.
#[derive(Debug)]
pub(crate) struct ArrivalRun<'a> {
    /// The plan.
    pub arrival: &'a Arrival,
    world: &'a WorldConfig,
    library: &'a [ObjectModel],
    at_xy_m: [f32; 2],
    seed: u64,
    at_switch: Option<Evaluation>,
    /// Wall seconds of the evaluations.
    pub evaluation_s: f64,
}

impl<'a> ArrivalRun<'a> {
    /// `arrival` on `library`, evaluating on tables of `world` at `at_xy_m`, seeded from `seed`.
    pub fn new(
        arrival: &'a Arrival,
        world: &'a WorldConfig,
        library: &'a [ObjectModel],
        at_xy_m: [f32; 2],
        seed: u64,
    ) -> Self {
        Self {
            arrival,
            world,
            library,
            at_xy_m,
            seed,
            at_switch: None,
            evaluation_s: 0.0,
        }
    }

    /// The evaluation when the late categories arrived, once made.
    pub fn at_switch(&self) -> Option<&Evaluation> {
        self.at_switch.as_ref()
    }

    /// Continues a resumed run: the evaluation at the switch its finished rounds made.
    pub fn restore(&mut self, at_switch: Option<Evaluation>) {
        self.at_switch = at_switch;
    }

    /// Before round `round`: when the late categories arrive with it, what the early rounds
    /// taught.
    pub fn before_round(
        &mut self,
        round: usize,
        recognizer: &mut Recognizer,
    ) -> Result<(), RecognitionError> {
        if self.arrival.after_round == round {
            self.at_switch = Some(self.evaluate(recognizer, round)?);
        }
        Ok(())
    }

    /// After the last of `rounds_played` rounds: what the model still knows of every object.
    pub fn finish(
        mut self,
        recognizer: &mut Recognizer,
        rounds_played: usize,
    ) -> Result<(ArrivalEvaluation, f64), RecognitionError> {
        let at_end = self.evaluate(recognizer, rounds_played)?;
        let evaluation = ArrivalEvaluation {
            arrival: self.arrival.clone(),
            at_switch: self.at_switch,
            at_end,
        };
        Ok((evaluation, self.evaluation_s))
    }

    fn evaluate(
        &mut self,
        recognizer: &mut Recognizer,
        rounds_played: usize,
    ) -> Result<Evaluation, RecognitionError> {
        let start = std::time::Instant::now();
        let e = evaluate(
            recognizer,
            self.world,
            self.library,
            self.arrival,
            self.at_xy_m,
            self.seed,
            rounds_played,
        );
        self.evaluation_s += start.elapsed().as_secs_f64();
        e
    }
}

/// The first guess of `recognizer` after `rounds_played` rounds about every object of `library`,
/// each alone on a fresh table of `world` at `at_xy_m`, upright at [`Arrival::eval_poses`] yaws
/// drawn from `seed`, with views drawn from `seed` too (see the module docs). Nothing is learnt
/// and the recognizer's view stream is left as it was.
pub fn evaluate(
    recognizer: &mut Recognizer,
    world: &WorldConfig,
    library: &[ObjectModel],
    arrival: &Arrival,
    at_xy_m: [f32; 2],
    seed: u64,
    rounds_played: usize,
) -> Result<Evaluation, RecognitionError> {
    recognizer.aside(seed, |r| {
        evaluate_here(r, world, library, arrival, at_xy_m, seed, rounds_played)
    })
}

fn evaluate_here(
    recognizer: &mut Recognizer,
    world: &WorldConfig,
    library: &[ObjectModel],
    arrival: &Arrival,
    at_xy_m: [f32; 2],
    seed: u64,
    rounds_played: usize,
) -> Result<Evaluation, RecognitionError> {
    use rand::RngExt;
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, TAG_EVAL_YAW, 0, 0));
    let mut wall = WallTimes::default();
    let mut looks = Vec::with_capacity(library.len() * arrival.eval_poses);
    for object in library {
        for _ in 0..arrival.eval_poses {
            let yaw_rad = rng.random_range(0.0..std::f32::consts::TAU);
            let mut table = World::new(world.clone())?;
            let top = table.config().table.top_z_m();
            let pose = translation([at_xy_m[0], at_xy_m[1], top]) * rotation_z(yaw_rad);
            let h = table.spawn_object(&object.name, &object.mesh, &pose)?;
            let guess = recognizer.guess(&table, h, &mut wall)?;
            looks.push(EvaluationLook {
                object: object.name.clone(),
                category: object.category.clone(),
                early: arrival.is_early(&object.category),
                yaw_rad,
                category_correct: guess.known
                    && guess.category.as_deref() == Some(object.category.as_str()),
                instance_correct: guess.known
                    && guess.instance.as_deref() == Some(object.name.as_str()),
                guess,
            });
        }
    }
    let rate = |early: bool, f: &dyn Fn(&EvaluationLook) -> bool| {
        let of: Vec<&EvaluationLook> = looks.iter().filter(|l| l.early == early).collect();
        Rate::new(of.iter().filter(|l| f(l)).count(), of.len())
    };
    Ok(Evaluation {
        after_rounds: rounds_played,
        early_category_accuracy: rate(true, &|l| l.category_correct),
        early_instance_accuracy: rate(true, &|l| l.instance_correct),
        early_category_answer_accuracy: rate(true, &|l| {
            l.guess.category.as_deref() == Some(l.category.as_str())
        }),
        late_category_accuracy: rate(false, &|l| l.category_correct),
        late_instance_accuracy: rate(false, &|l| l.instance_correct),
        looks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recognition::config::RecognitionConfig;
    use crate::recognition::labels::Labels;
    use lgdm_pointcloud::objects::procedural_library;

    #[test]
    fn rounds_show_the_early_half_then_the_rest() {
        let library = procedural_library(&["mug", "teapot", "can", "book", "apple"], 2, 0).unwrap();
        let a = Arrival::split(&library, 3).unwrap();
        assert_eq!(a.early_categories, ["mug", "teapot", "can"]);
        assert_eq!(a.late_categories, ["book", "apple"]);
        for round in 0..6 {
            let pool = a.pool(&library, round);
            assert!(!pool.is_empty());
            for i in pool {
                assert_eq!(a.is_early(&library[i].category), round < 3, "round {round}");
            }
        }
        assert_eq!(a.validate(4), Ok(()));
        assert!(matches!(
            a.validate(3),
            Err(ArrivalError::NoLateRounds { .. })
        ));
        assert_eq!(
            Arrival::split(&library, 0),
            Err(ArrivalError::NoEarlyRounds)
        );
        let one = procedural_library(&["mug"], 3, 0).unwrap();
        assert_eq!(
            Arrival::split(&one, 2),
            Err(ArrivalError::TooFewCategories(1))
        );
    }

    /// The evaluation learns nothing: an empty model stays empty and knows nothing; a taught
    /// object is recognised from the evaluation's fresh poses.
    #[test]
    fn the_end_evaluation_only_looks() {
        let library = procedural_library(&["can", "book"], 1, 0).unwrap();
        let arrival = Arrival {
            eval_poses: 2,
            ..Arrival::split(&library, 1).unwrap()
        };
        let world = WorldConfig::default();
        let labels = Labels::of_objects(&library);
        let mut r = Recognizer::empty(RecognitionConfig::default(), labels, 0).unwrap();
        let e = evaluate(&mut r, &world, &library, &arrival, [0.05, -0.52], 0, 0).unwrap();
        assert_eq!(e.looks.len(), 4);
        assert_eq!(e.early_category_accuracy.trials, 2);
        assert_eq!(e.early_category_accuracy.successes, 0);
        assert_eq!(r.model().episodic().len(), 0);
        // Teach both objects where the evaluation does not put them.
        let mut table = World::new(world.clone()).unwrap();
        let top = table.config().table.top_z_m();
        let mut wall = WallTimes::default();
        for (i, o) in library.iter().enumerate() {
            let h = table
                .spawn_object(
                    &o.name,
                    &o.mesh,
                    &translation([-0.1 + 0.25 * i as f32, -0.5, top]),
                )
                .unwrap();
            r.teach(&table, h, &o.category, &o.name, &mut wall).unwrap();
        }
        r.end_round(&mut wall).unwrap();
        let nodes = r.model().episodic().len();
        let e = evaluate(&mut r, &world, &library, &arrival, [0.05, -0.52], 0, 1).unwrap();
        assert_eq!(r.model().episodic().len(), nodes, "the evaluation learnt");
        // The same poses and views again: the same guesses (only the model could differ).
        let again = evaluate(&mut r, &world, &library, &arrival, [0.05, -0.52], 0, 1).unwrap();
        assert_eq!(e, again);
        assert!(e.looks.iter().all(|l| l.guess.category.is_some()), "{e:?}");
        assert!(e.early_category_answer_accuracy.successes >= 1, "{e:?}");
    }
}
