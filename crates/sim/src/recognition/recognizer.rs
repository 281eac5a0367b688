//! Recognition in the loop: the robot looks at an object on the table, describes each view with
//! the dataset's feature code, asks the Growing Dual-Memory ([`lgdm_gdm::Gdm`]) what it is, and
//! is taught by a simulated teacher when it does not know or is wrong; intrinsic replay after
//! each round. The views come from [`crate::recognition::views`], their features from a
//! [`ViewEncoder`], the names from [`Labels`].
//!
//! **The first guess and its confidence.** The [`RecognitionConfig::look_views`] views are one
//! sequence for [`Gdm::predict`] (temporal context on). The answer is the majority over the
//! views of the semantic memory's category (ties: the later view), and of the episodic
//! memory's instance. Confidence = the share of views whose category is the answer: the views
//! of a known object agree, those of an unknown one scatter over its look-alikes. Below
//! [`RecognitionConfig::confidence_threshold`], or with an empty model, the robot answers
//! "I don't know this".
//!
//! **The teacher.** When the robot does not know, or its category or instance is wrong, the
//! teacher names the true category and instance; the robot gathers
//! [`RecognitionConfig::teach_views`] views (a full orbit) and learns them as one labelled
//! sequence: [`Gdm::train`] [`RecognitionConfig::teach_epochs`] times, then [`Gdm::end_episode`],
//! the calls `lgdm train` makes per step. With [`RecognitionConfig::learn_known`] it learns the
//! objects it knew as well, with its own (right) labels. [`Recognizer::end_round`] replays
//! ([`Gdm::replay`]) after each round unless [`RecognitionConfig::replay`] is off.
//!
//! ```
//! use lgdm_pointcloud::objects::procedural_library;
//! use lgdm_sim::recognition::config::RecognitionConfig;
//! use lgdm_sim::recognition::labels::Labels;
//! use lgdm_sim::recognition::recognizer::Recognizer;
//! let library = procedural_library(&["can", "book"], 1, 0).unwrap();
//! let recognizer = Recognizer::empty(RecognitionConfig::default(), Labels::of_objects(&library), 0).unwrap();
//! assert_eq!(recognizer.labels().categories, ["can", "book"]);
//! assert_eq!(recognizer.model().episodic().len(), 0);
//! ```

use lgdm_base::seed::derive_seed;
use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample};
use lgdm_pointcloud::sensor::DepthNoise;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::physics::object::ObjectHandle;
use crate::physics::world::World;
use crate::timing::{WallTimes, Work};

use crate::recognition::config::RecognitionConfig;
use crate::recognition::encoder::{GoodEncoder, ViewEncoder};
use crate::recognition::error::RecognitionError;
use crate::recognition::labels::Labels;
use crate::recognition::views::orbit_features;

/// Seed tag of the view subsampling stream.
pub(crate) const TAG_VIEWS: u64 = 0x5133_0010;
/// The robot's first guess about an object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Guess {
    /// The category answer (none: the model is empty or no view showed the object).
    pub category: Option<String>,
    /// The instance answer.
    pub instance: Option<String>,
    /// Share of the views whose category is the answer (0 without an answer).
    pub confidence: f64,
    /// Mean episodic activation exp(−d) over the views (none without an answer).
    pub activation: Option<f64>,
    /// Views that showed the object.
    pub views: usize,
    /// Whether the robot trusts it (confidence ≥ the threshold).
    pub known: bool,
}

/// One recognition of an object on the table, with the teacher's part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecognitionRecord {
    /// The true category.
    pub true_category: String,
    /// The true instance (the library object's name).
    pub true_instance: String,
    /// The first guess.
    pub guess: Guess,
    /// First guess's category is right (and the robot trusted it).
    pub category_correct: bool,
    /// First guess's instance is right (and the robot trusted it).
    pub instance_correct: bool,
    /// The teacher stepped in (not known, or a wrong category or instance).
    pub teacher: bool,
    /// Views learnt after this look: the teacher's lesson, or with
    /// [`RecognitionConfig::learn_known`] the robot's own (0 when nothing was learnt).
    pub taught_views: usize,
    /// Whether this attempt made the recognition (false: the object was recognised at an earlier
    /// attempt of the round, whose record this repeats).
    pub first_look: bool,
}

/// Node counts of both memories at a point of the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MemoryPoint {
    /// Rounds finished.
    pub rounds: usize,
    /// Recognitions made so far (objects seen).
    pub objects_seen: usize,
    /// Lessons given so far.
    pub lessons: usize,
    /// Episodic nodes.
    pub episodic_nodes: usize,
    /// Semantic nodes.
    pub semantic_nodes: usize,
}

/// The robot's recognition: the dual memory, the label names, the view stream.
#[derive(Debug)]
pub struct Recognizer {
    config: RecognitionConfig,
    sensor: DepthNoise,
    encoder: Box<dyn ViewEncoder>,
    gdm: Gdm,
    labels: Labels,
    rng: ChaCha8Rng,
    next_sequence: u64,
    objects_seen: usize,
    lessons: usize,
    rounds: usize,
    origin: String,
}

impl Recognizer {
    /// Recognition with GOOD ([`GoodEncoder`]) and `gdm` (e.g. loaded from `lgdm train`'s
    /// checkpoint) whose ids mean `labels`; the views' subsampling is seeded from `seed`. A model
    /// of another feature dimension than [`GOOD_DIM`](lgdm_pointcloud::cache::GOOD_DIM) is refused.
    pub fn new(
        config: RecognitionConfig,
        gdm: Gdm,
        labels: Labels,
        seed: u64,
    ) -> Result<Self, RecognitionError> {
        Self::with_encoder(config, Box::new(GoodEncoder), gdm, labels, seed)
    }

    /// [`Recognizer::new`] with `encoder`; a model of another feature dimension than the
    /// encoder's is refused.
    pub fn with_encoder(
        config: RecognitionConfig,
        encoder: Box<dyn ViewEncoder>,
        gdm: Gdm,
        labels: Labels,
        seed: u64,
    ) -> Result<Self, RecognitionError> {
        config.validate()?;
        if gdm.dim() != encoder.dim() {
            return Err(RecognitionError::Dimension {
                model: gdm.dim(),
                name: encoder.name().to_string(),
                encoder: encoder.dim(),
            });
        }
        let next_sequence = gdm.current_sequence().map_or(0, |s| s.wrapping_add(1));
        Ok(Self {
            config,
            sensor: DepthNoise::off(),
            encoder,
            gdm,
            labels,
            rng: ChaCha8Rng::seed_from_u64(derive_seed(seed, TAG_VIEWS, 0, 0)),
            next_sequence,
            objects_seen: 0,
            lessons: 0,
            rounds: 0,
            origin: "given".into(),
        })
    }

    /// Recognition with GOOD from an empty model (the paper's incremental hyperparameters,
    /// seeded with `seed`).
    pub fn empty(
        config: RecognitionConfig,
        labels: Labels,
        seed: u64,
    ) -> Result<Self, RecognitionError> {
        Self::empty_with_encoder(config, Box::new(GoodEncoder), labels, seed)
    }

    /// [`Recognizer::empty`] with `encoder`.
    pub fn empty_with_encoder(
        config: RecognitionConfig,
        encoder: Box<dyn ViewEncoder>,
        labels: Labels,
        seed: u64,
    ) -> Result<Self, RecognitionError> {
        let gdm_config = GdmConfig {
            seed,
            ..GdmConfig::paper_incremental()
        };
        let gdm = Gdm::new(gdm_config, encoder.dim())?;
        Ok(Self::with_encoder(config, encoder, gdm, labels, seed)?.with_origin("empty"))
    }

    /// The encoder's name (`good`, `ae`).
    pub fn encoder_name(&self) -> &str {
        self.encoder.name()
    }

    /// Names where the model came from (`empty`, a checkpoint's path), for the run's record.
    pub fn with_origin(mut self, origin: impl Into<String>) -> Self {
        self.origin = origin.into();
        self
    }

    /// Passes the views through a depth sensor model (default: none, the renderer's depth); a
    /// run gives its cameras' (`[cameras.noise]`).
    pub fn with_sensor(mut self, sensor: DepthNoise) -> Self {
        self.sensor = sensor;
        self
    }

    /// Where the model came from.
    pub fn origin(&self) -> &str {
        &self.origin
    }

    /// The constants.
    pub fn config(&self) -> &RecognitionConfig {
        &self.config
    }

    /// The dual memory as it stands.
    pub fn model(&self) -> &Gdm {
        &self.gdm
    }

    /// The label names.
    pub fn labels(&self) -> &Labels {
        &self.labels
    }

    /// Node counts now.
    pub fn memory_point(&self) -> MemoryPoint {
        MemoryPoint {
            rounds: self.rounds,
            objects_seen: self.objects_seen,
            lessons: self.lessons,
            episodic_nodes: self.gdm.episodic().len(),
            semantic_nodes: self.gdm.semantic().len(),
        }
    }

    fn sequence(&mut self) -> u64 {
        let s = self.next_sequence;
        self.next_sequence = self.next_sequence.wrapping_add(1);
        s
    }

    /// The encoder's features of `count` views of `object` from azimuths `k × view_step_rad`,
    /// k = 0, 1, … ([`orbit_features`]).
    pub fn views(
        &mut self,
        world: &World,
        object: ObjectHandle,
        count: usize,
        wall: &mut WallTimes,
    ) -> Result<Vec<Vec<f32>>, RecognitionError> {
        orbit_features(
            world,
            object,
            count,
            &self.config,
            &self.sensor,
            self.encoder.as_mut(),
            &mut self.rng,
            wall,
        )
    }

    /// The first guess about `object` from [`RecognitionConfig::look_views`] views.
    pub fn guess(
        &mut self,
        world: &World,
        object: ObjectHandle,
        wall: &mut WallTimes,
    ) -> Result<Guess, RecognitionError> {
        let views = self.views(world, object, self.config.look_views, wall)?;
        self.guess_from(&views, wall)
    }

    /// The first guess from the features of one look's views (the policy of [`Recognizer::guess`]
    /// on plain features: the dual memory's prediction with temporal context, the majority
    /// category and instance, the share of agreeing views as the confidence).
    pub fn guess_from(
        &mut self,
        views: &[Vec<f32>],
        wall: &mut WallTimes,
    ) -> Result<Guess, RecognitionError> {
        let none = Guess {
            category: None,
            instance: None,
            confidence: 0.0,
            activation: None,
            views: views.len(),
            known: false,
        };
        if views.is_empty() || self.gdm.episodic().len() < 2 || self.gdm.semantic().len() < 2 {
            return Ok(none);
        }
        let sequence = self.sequence();
        let samples: Vec<Sample<'_>> = views
            .iter()
            .map(|x| Sample::unlabelled(x, sequence))
            .collect();
        let predictions = wall.time(Work::Recognition, || {
            self.gdm.predict(&samples, PredictOptions::default())
        })?;
        let category = majority(predictions.iter().map(|p| p.category));
        let instance = majority(predictions.iter().map(|p| p.instance));
        let Some(category) = category else {
            return Ok(none);
        };
        let agree = predictions
            .iter()
            .filter(|p| p.category == Some(category))
            .count();
        let confidence = agree as f64 / predictions.len() as f64;
        let activation = predictions
            .iter()
            .map(|p| f64::from(p.activation))
            .sum::<f64>()
            / predictions.len() as f64;
        Ok(Guess {
            category: Some(self.labels.category_name(category)),
            instance: instance.map(|i| self.labels.instance_name(i)),
            confidence,
            activation: Some(activation),
            views: views.len(),
            known: confidence >= self.config.confidence_threshold,
        })
    }

    /// A lesson (the teacher's, or the robot's own with [`RecognitionConfig::learn_known`]):
    /// `object` is instance `instance` of `category`. Gathers
    /// [`RecognitionConfig::teach_views`] views and learns them (train × `teach_epochs`, episode
    /// end). Returns the number of views learnt.
    pub fn teach(
        &mut self,
        world: &World,
        object: ObjectHandle,
        category: &str,
        instance: &str,
        wall: &mut WallTimes,
    ) -> Result<usize, RecognitionError> {
        let views = self.views(world, object, self.config.teach_views, wall)?;
        self.learn(&views, category, instance, wall)
    }

    /// A lesson on plain features: `views` are instance `instance` of `category` (train ×
    /// [`RecognitionConfig::teach_epochs`], episode end); new names get the next ids. Returns
    /// the number of views learnt.
    pub fn learn(
        &mut self,
        views: &[Vec<f32>],
        category: &str,
        instance: &str,
        wall: &mut WallTimes,
    ) -> Result<usize, RecognitionError> {
        if views.is_empty() {
            return Ok(0);
        }
        let category = self.labels.category_id(category);
        let instance = self.labels.instance_id(instance);
        for _ in 0..self.config.teach_epochs {
            let sequence = self.sequence();
            let samples: Vec<Sample<'_>> = views
                .iter()
                .map(|x| Sample::labelled(x, sequence, instance, category))
                .collect();
            wall.time(Work::Recognition, || self.gdm.train(&samples))?;
        }
        wall.time(Work::Recognition, || self.gdm.end_episode());
        self.lessons += 1;
        Ok(views.len())
    }

    /// One encounter with `object`, whose truth the teacher knows: the first guess, then a
    /// lesson when the robot did not know it or was wrong.
    pub fn encounter(
        &mut self,
        world: &World,
        object: ObjectHandle,
        true_category: &str,
        true_instance: &str,
        wall: &mut WallTimes,
    ) -> Result<RecognitionRecord, RecognitionError> {
        let guess = self.guess(world, object, wall)?;
        self.objects_seen += 1;
        let category_correct = guess.known && guess.category.as_deref() == Some(true_category);
        let instance_correct = guess.known && guess.instance.as_deref() == Some(true_instance);
        let teacher = !(category_correct && instance_correct);
        let taught_views = if teacher || self.config.learn_known {
            self.teach(world, object, true_category, true_instance, wall)?
        } else {
            0
        };
        Ok(RecognitionRecord {
            true_category: true_category.to_string(),
            true_instance: true_instance.to_string(),
            guess,
            category_correct,
            instance_correct,
            teacher,
            taught_views,
            first_look: true,
        })
    }

    /// The end of a round: intrinsic replay (unless off) and an episode end. Returns the node
    /// counts after it.
    pub fn end_round(&mut self, wall: &mut WallTimes) -> Result<MemoryPoint, RecognitionError> {
        if self.config.replay && self.gdm.episodic().len() >= 2 {
            wall.time(Work::Recognition, || self.gdm.replay())?;
        }
        self.gdm.end_episode();
        self.rounds += 1;
        Ok(self.memory_point())
    }

    /// Runs `f` with a view stream of its own, seeded from `seed`, and gives the run's stream
    /// and sequence ids back untouched afterwards: looks that must leave the rest of a run as it
    /// would have been (an evaluation between rounds). Prediction does not change the model.
    pub fn aside<T>(&mut self, seed: u64, f: impl FnOnce(&mut Self) -> T) -> T {
        let own = ChaCha8Rng::seed_from_u64(derive_seed(seed, TAG_VIEWS, 1, 0));
        let rng = std::mem::replace(&mut self.rng, own);
        let next_sequence = self.next_sequence;
        let out = f(self);
        self.rng = rng;
        self.next_sequence = next_sequence;
        out
    }

    /// The model and its label names, for saving.
    pub fn into_parts(self) -> (Gdm, Labels) {
        (self.gdm, self.labels)
    }

    /// Everything beyond the model and its labels that the next round depends on: where the view
    /// stream is, the next sequence id, the counters, where the model came from. With the model
    /// saved beside it, [`Recognizer::restore`] continues exactly where this one is.
    pub fn state(&self) -> RecognizerState {
        RecognizerState {
            views_word_pos: self.rng.get_word_pos().to_string(),
            next_sequence: self.next_sequence,
            objects_seen: self.objects_seen,
            lessons: self.lessons,
            rounds: self.rounds,
            origin: self.origin.clone(),
        }
    }

    /// A recognizer built like this one (same config, encoder, seed) continued from `state`,
    /// with the model `gdm` whose ids mean `labels` (both saved when `state` was taken).
    pub fn restore(
        config: RecognitionConfig,
        encoder: Box<dyn ViewEncoder>,
        gdm: Gdm,
        labels: Labels,
        seed: u64,
        state: &RecognizerState,
    ) -> Result<Self, RecognitionError> {
        let word_pos: u128 =
            state
                .views_word_pos
                .parse()
                .map_err(|_| RecognitionError::InvalidConfig {
                    field: "views_word_pos",
                    reason: format!("`{}` is not a stream position", state.views_word_pos),
                })?;
        let mut r = Self::with_encoder(config, encoder, gdm, labels, seed)?;
        r.rng.set_word_pos(word_pos);
        r.next_sequence = state.next_sequence;
        r.objects_seen = state.objects_seen;
        r.lessons = state.lessons;
        r.rounds = state.rounds;
        r.origin = state.origin.clone();
        Ok(r)
    }
}

/// A recognizer's state beyond its model ([`Recognizer::state`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecognizerState {
    /// Where the view-subsampling stream is (a `u128` word position, as text).
    pub views_word_pos: String,
    /// The next sequence id.
    pub next_sequence: u64,
    /// Objects recognised so far.
    pub objects_seen: usize,
    /// Lessons so far.
    pub lessons: usize,
    /// Rounds ended so far.
    pub rounds: usize,
    /// Where the model came from.
    pub origin: String,
}

/// The most frequent `Some` value; ties go to the value seen last among the tied.
fn majority(values: impl Iterator<Item = Option<u32>>) -> Option<u32> {
    let mut counts: Vec<(u32, usize, usize)> = Vec::new();
    for (t, v) in values.enumerate() {
        let Some(v) = v else { continue };
        match counts.iter_mut().find(|c| c.0 == v) {
            Some(c) => {
                c.1 += 1;
                c.2 = t;
            }
            None => counts.push((v, 1, t)),
        }
    }
    counts
        .into_iter()
        .max_by(|a, b| a.1.cmp(&b.1).then(a.2.cmp(&b.2)))
        .map(|c| c.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;
    use crate::recognition::encoder::EncoderError;
    use lgdm_pointcloud::math::translation;
    use lgdm_pointcloud::objects::procedural_library;
    /// The guess-and-teach policy runs on plain features, without a world: a model taught two
    /// well-separated clusters names each from fresh samples of it.
    #[test]
    fn the_policy_runs_on_plain_features() {
        /// A 4-d encoder stand-in (never asked to encode here).
        #[derive(Debug)]
        struct Plain;
        impl ViewEncoder for Plain {
            fn name(&self) -> &str {
                "plain"
            }
            fn dim(&self) -> usize {
                4
            }
            fn encode(
                &mut self,
                _: &[lgdm_pointcloud::PointCloud],
                _: &lgdm_pointcloud::render::Camera,
            ) -> Result<Vec<Option<Vec<f32>>>, EncoderError> {
                Err("not used".into())
            }
        }
        let config = RecognitionConfig::default();
        let mut r =
            Recognizer::empty_with_encoder(config, Box::new(Plain), Labels::default(), 1).unwrap();
        let mut wall = WallTimes::default();
        let cluster = |at: f32, k: usize| -> Vec<Vec<f32>> {
            (0..k)
                .map(|i| vec![at + 0.01 * i as f32, at, 1.0 - at, 0.5])
                .collect()
        };
        let empty = r.guess_from(&cluster(0.1, 5), &mut wall).unwrap();
        assert!(!empty.known && empty.category.is_none());
        for _ in 0..3 {
            assert_eq!(
                r.learn(&cluster(0.1, 10), "mug", "mug_01", &mut wall)
                    .unwrap(),
                10
            );
            assert_eq!(
                r.learn(&cluster(0.9, 10), "can", "can_01", &mut wall)
                    .unwrap(),
                10
            );
        }
        for (at, name) in [(0.1, "mug"), (0.9, "can")] {
            let g = r.guess_from(&cluster(at, 5), &mut wall).unwrap();
            assert_eq!(g.category.as_deref(), Some(name), "{g:?}");
            assert!(g.known && g.confidence > 0.5, "{g:?}");
        }
        assert_eq!(r.labels().categories, ["mug", "can"]);
    }

    #[test]
    fn majority_prefers_count_then_the_later_view() {
        assert_eq!(majority([Some(1), Some(2), Some(2)].into_iter()), Some(2));
        assert_eq!(majority([Some(1), Some(2)].into_iter()), Some(2));
        assert_eq!(majority([Some(2), Some(1)].into_iter()), Some(1));
        assert_eq!(majority([None, None].into_iter()), None);
    }

    /// An empty model does not know; after a lesson it recognises the object it was taught.
    #[test]
    fn taught_objects_are_recognised() {
        let library = procedural_library(&["can", "book"], 1, 0).unwrap();
        let mut world = World::new(WorldConfig::default()).unwrap();
        let top = world.config().table.top_z_m();
        let can = world
            .spawn_object("can_01", &library[0].mesh, &translation([0.0, -0.5, top]))
            .unwrap();
        let book = world
            .spawn_object("book_01", &library[1].mesh, &translation([0.25, -0.5, top]))
            .unwrap();
        let mut r = Recognizer::empty(
            RecognitionConfig::default(),
            Labels::of_objects(&library),
            1,
        )
        .unwrap();
        let mut wall = WallTimes::default();
        let first = r
            .encounter(&world, can, "can", "can_01", &mut wall)
            .unwrap();
        assert!(!first.guess.known && first.teacher && first.taught_views == 10);
        r.encounter(&world, book, "book", "book_01", &mut wall)
            .unwrap();
        r.end_round(&mut wall).unwrap();
        let again = r
            .encounter(&world, can, "can", "can_01", &mut wall)
            .unwrap();
        assert_eq!(again.guess.category.as_deref(), Some("can"), "{again:?}");
        assert!(r.memory_point().episodic_nodes >= 2);
    }

    #[test]
    fn another_dimension_is_refused() {
        let gdm = Gdm::new(GdmConfig::default(), 256).unwrap();
        let err = Recognizer::new(RecognitionConfig::default(), gdm, Labels::default(), 0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("256-d") && err.contains("675-d"), "{err}");
    }
}
