//! Grasp trials: rounds of a [`Scenario`] with one [`GraspSource`], every attempt recorded, and
//! the results written as `results.json` into a run directory.
//!
//! [`run_trials`] plays `rounds` rounds (round r seeded with `derive_seed(seed, …, r)`, so the
//! same seed gives the same rounds): set the table ([`crate::scenario`]), look with the overview
//! camera, take a close-up crop per object ([`crate::perception`]), ask the source for ranked
//! grasps, and run attempts ([`crate::attempt`]) until the round ends. It returns
//! [`RunResults`]: one [`AttemptRecord`] per attempt, one [`RoundRecord`] per round and a
//! [`Summary`] — grasp success, placement success, the fraction of objects cleared and the
//! paper's contact-only success, each with its Wilson 95 % interval, per category and per
//! failure reason. Everything is deterministic except the fields named `wall` (wall-clock
//! seconds), which a comparison of two runs drops.
//!
//! [`run_pick_place`] adds recognition in the loop ([`crate::recognize`]); with
//! [`RunSpec::packing`] each object goes to the basket of the category the robot recognises it as
//! and is judged against its true one ([`crate::packing`]), with [`RunSpec::arrival`] the
//! categories arrive over time and the run ends with the model's first guess about every object
//! ([`crate::arrival`], [`RunResults::arrival_evaluation`]). One runner plays them all.
//!
//! [`SimRunDir`] owns the output directory the way `lgdm train --out` does: a fresh or empty
//! directory, or with `force` one that holds only a previous run's files; it is locked while
//! the run writes; files are written atomically (temporary file, then rename).
//!
//! ```no_run
//! use lgdm_pointcloud::objects::{CATEGORIES, procedural_library};
//! use lgdm_sim::run::{RunSpec, SimRunDir, run_trials};
//! use lgdm_sim::scenario::Scenario;
//! use lgdm_sim::source::AnalyticSource;
//! let library = procedural_library(&CATEGORIES, 5, 0).unwrap();
//! let spec = RunSpec::new(Scenario::Isolated, 10, 0);
//! let results = run_trials(&spec, &library, &mut AnalyticSource::new(), |_| {}).unwrap();
//! println!("grasp success {:?}", results.summary.grasp_success_rate);
//! let dir = SimRunDir::create(std::path::Path::new("runs/sim-0"), false).unwrap();
//! dir.write_results(&results).unwrap();
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use lgdm_pointcloud::DirLock;
use lgdm_pointcloud::grasp::GraspSpec;
use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::math::{Pose, derive_seed};
use lgdm_pointcloud::objects::ObjectModel;
use nalgebra::UnitQuaternion;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::arrival::{Arrival, ArrivalError, ArrivalEvaluation, evaluate};
use crate::attempt::{
    AttemptConfig, AttemptError, Cell, Execution, FailureReason, GraspPlan, Measurements,
    WallTimes, Work, execute, park, plan_grasp,
};
use crate::camera::CameraConfig;
use crate::packing::{PackingError, PackingRecord, PackingSpec, PackingSummary};
use crate::perception::{ObjectView, Perception, PerceptionError, SceneView, WorldGrasp};
use crate::recognize::{
    Labels, MemoryPoint, RecognitionConfig, RecognitionError, RecognitionRecord, Recognizer,
};
use crate::record::{
    GraspShown, LabelTone, ObjectLabel, RecordCamera, RecordConfig, RecordError, Recorder,
    RoundRecording, RoundSink, basket_camera,
};
use crate::robot::RobotConfig;
use crate::scenario::{
    PlacedObject, Scenario, ScenarioConfig, check_library, on_table, round_objects_among, set_table,
};
use crate::shapes::{LibraryShapes, ShapeConfig};
use crate::source::{AnalyticSource, GraspQuery, GraspSource, RandomSource, SourceError};
use crate::world::{ObjectHandle, World, WorldConfig, WorldError};

/// Version of the `results.json` layout.
pub const RESULTS_FORMAT_VERSION: u32 = 1;

/// The results file in a run directory.
pub const RESULTS_FILE: &str = "results.json";

/// Seed tag of a round's RNG.
const TAG_ROUND: u64 = 0x5133_0001;
/// Seed tag of the random grasp source.
const TAG_RANDOM_SOURCE: u64 = 0x5133_0002;

/// Every constant of a sim run. Defaults are each part's.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// The physics world.
    pub world: WorldConfig,
    /// The robot (arm and gripper).
    pub robot: RobotConfig,
    /// Cameras, crop and segmentation.
    pub cameras: CameraConfig,
    /// Motions and judging of one attempt.
    pub attempt: AttemptConfig,
    /// How tables are set and rounds end.
    pub scenario: ScenarioConfig,
    /// Objects' collider shapes (default: a convex decomposition of each mesh).
    pub shapes: ShapeConfig,
}

impl SimConfig {
    /// The gripper as grasp sources see it: the robot's stroke and finger width, the dataset's
    /// finger reach, clearance and friction.
    pub fn grasp_spec(&self) -> GraspSpec {
        GraspSpec {
            max_opening_m: self.robot.gripper.stroke_m,
            finger_width_m: self.robot.gripper.finger_width_m,
            ..GraspSpec::default()
        }
    }

    /// Checks every part.
    pub fn validate(&self) -> Result<(), SimError> {
        self.world.validate()?;
        self.robot.validate().map_err(AttemptError::from)?;
        self.cameras
            .validate()
            .map_err(|e| SimError::Perception(e.into()))?;
        self.attempt.validate()?;
        self.scenario.validate()?;
        Ok(())
    }
}

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    /// The scenario.
    pub scenario: Scenario,
    /// Rounds to play (at least 1).
    pub rounds: usize,
    /// Base seed.
    pub seed: u64,
    /// Where the objects came from (`procedural` or the meshes directory), for the record.
    pub objects: String,
    /// Stop after this many attempts in all (none: play every round).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_attempts: Option<usize>,
    /// Packing: each object goes to the basket of the category it is recognised as (none: every
    /// object to [`AttemptConfig::target_basket`]). Needs recognition ([`run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingSpec>,
    /// Categories arriving over time, and the end-of-run evaluation of the early ones (none: every
    /// round draws from the whole library). Needs recognition ([`run_pick_place`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival: Option<Arrival>,
    /// Every constant.
    pub config: SimConfig,
}

impl RunSpec {
    /// A run of the procedural objects with the default config.
    pub fn new(scenario: Scenario, rounds: usize, seed: u64) -> Self {
        Self {
            scenario,
            rounds,
            seed,
            objects: "procedural".into(),
            max_attempts: None,
            packing: None,
            arrival: None,
            config: SimConfig::default(),
        }
    }
}

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// `rounds` is 0.
    #[error("rounds must be at least 1")]
    NoRounds,
    /// `max_attempts` is 0.
    #[error("the attempt budget must be at least 1")]
    NoAttempts,
    /// The object library is empty.
    #[error("the object library is empty")]
    EmptyLibrary,
    /// An unknown grasp source name.
    #[error("unknown grasp source `{0}` (known: analytic, random, network)")]
    UnknownSource(String),
    /// A world error (a config field, an object whose hull cannot be built, an object larger
    /// than the table, a NaN state).
    #[error(transparent)]
    World(#[from] WorldError),
    /// Perception failed (a config field, a frame without a table).
    #[error(transparent)]
    Perception(#[from] PerceptionError),
    /// An attempt failed to run (not a failed grasp: an error).
    #[error(transparent)]
    Attempt(#[from] AttemptError),
    /// The grasp source failed.
    #[error("grasp source: {0}")]
    Source(#[from] SourceError),
    /// Recording a round failed.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// Recognition or learning failed.
    #[error("recognition: {0}")]
    Recognition(#[from] RecognitionError),
    /// A bad packing spec (an unknown target category, a missing basket).
    #[error("packing: {0}")]
    Packing(#[from] PackingError),
    /// A bad arrival plan.
    #[error("categories arriving over time: {0}")]
    Arrival(#[from] ArrivalError),
    /// The run directory cannot be used or written.
    #[error("run directory {}: {reason}", path.display())]
    RunDir {
        /// The path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// A built-in grasp source by name: `analytic` or `random` (seeded from the run's seed).
/// `network` lives in the cli (feature `ae`).
pub fn builtin_source(name: &str, seed: u64) -> Result<Box<dyn GraspSource>, SimError> {
    match name {
        "analytic" => Ok(Box::new(AnalyticSource::new())),
        "random" => Ok(Box::new(RandomSource::new(derive_seed(
            seed,
            TAG_RANDOM_SOURCE,
            0,
            0,
        )))),
        other => Err(SimError::UnknownSource(other.to_string())),
    }
}

/// A pose as position and quaternion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseRecord {
    /// Position (m, world).
    pub position_m: [f32; 3],
    /// Orientation as a unit quaternion (x, y, z, w).
    pub quaternion_xyzw: [f32; 4],
}

impl From<&Pose> for PoseRecord {
    fn from(pose: &Pose) -> Self {
        let q = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        Self {
            position_m: pose.translation.vector.into(),
            quaternion_xyzw: [q.i, q.j, q.k, q.w],
        }
    }
}

/// The grasp an attempt tried.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspRecord {
    /// Its rank among the source's grasps on the crop (0 = best).
    pub rank: usize,
    /// The grasp in crop pixels (decode conventions).
    pub crop: DecodedGrasp,
    /// The grasp in the world and the tool targets planned from it.
    pub plan: GraspPlan,
}

/// One attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptRecord {
    /// Attempt number in the run.
    pub index: usize,
    /// Round number.
    pub round: usize,
    /// Attempt number in the round.
    pub try_in_round: usize,
    /// The object aimed at (its instance name), when known.
    pub object: Option<String>,
    /// Its category.
    pub category: Option<String>,
    /// Its pose when the attempt started.
    pub object_pose: Option<PoseRecord>,
    /// The object the fingers pinched, when it differs from the one aimed at.
    pub grasped_object: Option<String>,
    /// The grasp tried (none when no grasp was found).
    pub grasp: Option<GraspRecord>,
    /// Grasp success, strict criterion.
    pub grasp_success: bool,
    /// The paper's contact-only criterion.
    pub contact_only_success: bool,
    /// Placed in the basket.
    pub placement_success: bool,
    /// Why it failed.
    pub reason: Option<FailureReason>,
    /// Recognition of the object aimed at, and the teacher's part (pick-and-place runs only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recognition: Option<RecognitionRecord>,
    /// Packing runs: the basket chosen, the one the object belongs in, the verdict.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingRecord>,
    /// Measurements.
    pub measured: Measurements,
    /// Simulated seconds the attempt took (including parking the arm after it).
    pub sim_time_s: f64,
    /// Wall-clock seconds (not deterministic). The rendering, perception and grasp-source time
    /// of one prediction tried with several ranked grasps (isolated) counts in its first try.
    pub wall: WallTimes,
}

/// Why a round ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RoundEnd {
    /// Every object was placed (or left the table).
    Cleared,
    /// Too many failed attempts in a row.
    ConsecutiveFailures,
    /// The isolated scenario's ranked grasps were all tried.
    GraspsExhausted,
    /// The per-round attempt cap.
    AttemptCap,
    /// The run's attempt budget ([`RunSpec::max_attempts`]) was spent.
    AttemptBudget,
    /// The camera saw no object on the table.
    NothingSeen,
}

/// One round.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoundRecord {
    /// Round number.
    pub round: usize,
    /// The objects set on the table (names).
    pub objects: Vec<String>,
    /// Attempts made.
    pub attempts: usize,
    /// Objects placed in the basket.
    pub placed: usize,
    /// Objects that left the table other than by a placement (fell off, knocked away).
    pub left_table: Vec<String>,
    /// Why it ended.
    pub ended_by: RoundEnd,
    /// Simulated seconds.
    pub sim_time_s: f64,
    /// Wall-clock seconds (not deterministic).
    pub wall: WallTimes,
}

/// A success rate with its Wilson 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rate {
    /// Successes.
    pub successes: usize,
    /// Trials.
    pub trials: usize,
    /// successes / trials (`null` when there were no trials).
    pub value: Option<f64>,
    /// Lower end of the Wilson 95 % interval.
    pub wilson_low: f64,
    /// Upper end.
    pub wilson_high: f64,
}

impl Rate {
    /// The rate of `successes` in `trials`.
    pub fn new(successes: usize, trials: usize) -> Self {
        let (wilson_low, wilson_high) = wilson_interval(successes, trials);
        Self {
            successes,
            trials,
            value: (trials > 0).then(|| successes as f64 / trials as f64),
            wilson_low,
            wilson_high,
        }
    }

    /// `80.0 % (74.1–85.0 %, 120/150)`.
    pub fn describe(&self) -> String {
        match self.value {
            Some(v) => format!(
                "{:.1} % ({:.1}–{:.1} %, {}/{})",
                100.0 * v,
                100.0 * self.wilson_low,
                100.0 * self.wilson_high,
                self.successes,
                self.trials
            ),
            None => "– (0 trials)".into(),
        }
    }
}

/// The Wilson score interval of a binomial proportion at 95 % (z = 1.95996); (0, 1) for no
/// trials.
///
/// ```
/// let (lo, hi) = lgdm_sim::run::wilson_interval(8, 10);
/// assert!((lo - 0.4902).abs() < 1e-4 && (hi - 0.9433).abs() < 1e-4);
/// assert_eq!(lgdm_sim::run::wilson_interval(0, 6).0, 0.0);
/// ```
pub fn wilson_interval(successes: usize, trials: usize) -> (f64, f64) {
    if trials == 0 {
        return (0.0, 1.0);
    }
    let z = 1.959_963_984_540_054_f64;
    let n = trials as f64;
    let p = successes.min(trials) as f64 / n;
    let z2 = z * z;
    let denom = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / denom;
    let half = z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / denom;
    // Exact at the ends: no successes → 0, no failures → 1 (rounding would miss them).
    let low = if successes == 0 {
        0.0
    } else {
        (centre - half).max(0.0)
    };
    let high = if successes >= trials {
        1.0
    } else {
        (centre + half).min(1.0)
    };
    (low, high)
}

/// Counts of one category.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CategorySummary {
    /// Attempts on objects of this category.
    pub attempts: usize,
    /// Grasp success.
    pub grasp_success_rate: Rate,
    /// Placement success.
    pub placement_success_rate: Rate,
    /// The paper's contact-only success.
    pub contact_only_success_rate: Rate,
}

/// The run's summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Attempts.
    pub attempts: usize,
    /// Grasp successes / attempts (strict criterion).
    pub grasp_success_rate: Rate,
    /// Placements / attempts.
    pub placement_success_rate: Rate,
    /// Objects placed / objects set on the table.
    pub cleared_fraction: Rate,
    /// The paper's contact-only successes / attempts.
    pub contact_only_success_rate: Rate,
    /// Per category of the object aimed at (attempts with no object aimed at are `unknown`).
    pub per_category: BTreeMap<String, CategorySummary>,
    /// Failed attempts per reason (every reason listed).
    pub failure_reasons: BTreeMap<String, usize>,
    /// Pick-and-place: first guesses whose category was right (and trusted) / recognitions
    /// (one per object per round: the first attempt at it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recognition_accuracy: Option<Rate>,
    /// Pick-and-place: first guesses whose instance was right (and trusted) / recognitions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instance_recognition_accuracy: Option<Rate>,
    /// Pick-and-place: recognitions in which the teacher stepped in.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub teacher_interventions: Option<usize>,
    /// Pick-and-place: teacher interventions / recognitions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub teacher_intervention_rate: Option<Rate>,
    /// Packing: success (the right basket for the true category), objects packed, failures.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingSummary>,
    /// Categories arriving over time: the early categories' first-guess category accuracy at
    /// the end of the run ([`ArrivalEvaluation::at_end`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub early_category_accuracy_at_end: Option<Rate>,
    /// The same for instances.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub early_instance_accuracy_at_end: Option<Rate>,
    /// The early categories' first-guess category accuracy when the late ones arrived
    /// ([`ArrivalEvaluation::at_switch`]): the baseline of the forgetting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub early_category_accuracy_at_switch: Option<Rate>,
}

/// Summarises attempts and rounds.
pub fn summarize(attempts: &[AttemptRecord], rounds: &[RoundRecord]) -> Summary {
    let count = |f: &dyn Fn(&AttemptRecord) -> bool, of: &[&AttemptRecord]| {
        of.iter().filter(|a| f(a)).count()
    };
    let all: Vec<&AttemptRecord> = attempts.iter().collect();
    let n = all.len();
    let mut categories: BTreeMap<String, Vec<&AttemptRecord>> = BTreeMap::new();
    for a in attempts {
        categories
            .entry(a.category.clone().unwrap_or_else(|| "unknown".into()))
            .or_default()
            .push(a);
    }
    let per_category = categories
        .into_iter()
        .map(|(c, of)| {
            let k = of.len();
            (
                c,
                CategorySummary {
                    attempts: k,
                    grasp_success_rate: Rate::new(count(&|a| a.grasp_success, &of), k),
                    placement_success_rate: Rate::new(count(&|a| a.placement_success, &of), k),
                    contact_only_success_rate: Rate::new(
                        count(&|a| a.contact_only_success, &of),
                        k,
                    ),
                },
            )
        })
        .collect();
    // `misrecognised` is a packing verdict: listed in packing runs only.
    let packing = attempts.iter().any(|a| a.packing.is_some())
        || attempts
            .iter()
            .any(|a| a.reason == Some(FailureReason::Misrecognised));
    let mut failure_reasons: BTreeMap<String, usize> = FailureReason::ALL
        .iter()
        .filter(|r| packing || **r != FailureReason::Misrecognised)
        .map(|r| (r.as_str().to_string(), 0))
        .collect();
    for a in attempts {
        if let Some(r) = a.reason {
            *failure_reasons.entry(r.as_str().to_string()).or_default() += 1;
        }
    }
    let presented: usize = rounds.iter().map(|r| r.objects.len()).sum();
    let placed: usize = rounds.iter().map(|r| r.placed).sum();
    let looks: Vec<&RecognitionRecord> = attempts
        .iter()
        .filter_map(|a| a.recognition.as_ref())
        .filter(|r| r.first_look)
        .collect();
    let any = attempts.iter().any(|a| a.recognition.is_some());
    let looked = |f: &dyn Fn(&RecognitionRecord) -> bool| {
        any.then(|| Rate::new(looks.iter().filter(|r| f(r)).count(), looks.len()))
    };
    Summary {
        recognition_accuracy: looked(&|r| r.category_correct),
        instance_recognition_accuracy: looked(&|r| r.instance_correct),
        teacher_interventions: any.then(|| looks.iter().filter(|r| r.teacher).count()),
        teacher_intervention_rate: looked(&|r| r.teacher),
        attempts: n,
        grasp_success_rate: Rate::new(count(&|a| a.grasp_success, &all), n),
        placement_success_rate: Rate::new(count(&|a| a.placement_success, &all), n),
        cleared_fraction: Rate::new(placed, presented),
        contact_only_success_rate: Rate::new(count(&|a| a.contact_only_success, &all), n),
        per_category,
        failure_reasons,
        packing: packing.then(|| crate::packing::summarize(attempts, presented)),
        early_category_accuracy_at_end: None,
        early_instance_accuracy_at_end: None,
        early_category_accuracy_at_switch: None,
    }
}

/// What was run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The scenario.
    pub scenario: Scenario,
    /// The grasp source's name.
    pub grasp_source: String,
    /// The source as it describes itself (the network: its checkpoint, input size and jaw).
    pub grasp_source_detail: String,
    /// Rounds played.
    pub rounds: usize,
    /// Base seed.
    pub seed: u64,
    /// Where the objects came from.
    pub objects: String,
    /// Objects in the library.
    pub library_size: usize,
    /// Packing runs: the target categories and the baskets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packing: Option<PackingSpec>,
    /// Categories arriving over time: the plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival: Option<Arrival>,
}

/// Wall-clock totals of a run (not deterministic).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RunWall {
    /// Seconds of the whole run.
    pub total_s: f64,
    /// Seconds setting tables (dropping and settling objects).
    pub setup_s: f64,
    /// The attempts' times, summed by kind of work.
    pub attempts: WallTimes,
    /// Mean wall seconds per attempt.
    pub per_attempt_s: f64,
    /// Simulated seconds per wall second over the whole run.
    pub real_time_factor: f64,
    /// Seconds of intrinsic replay at the rounds' ends (pick-and-place).
    #[serde(default)]
    pub replay_s: f64,
    /// Seconds of the evaluations (categories arriving over time).
    #[serde(default)]
    pub evaluation_s: f64,
}

/// Everything `results.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResults {
    /// [`RESULTS_FORMAT_VERSION`].
    pub format_version: u32,
    /// What was run.
    pub run: RunInfo,
    /// The summary.
    pub summary: Summary,
    /// Every attempt, in order.
    pub attempts: Vec<AttemptRecord>,
    /// Every round, in order.
    pub rounds: Vec<RoundRecord>,
    /// Every constant.
    pub config: SimConfig,
    /// Pick-and-place: the recognition's setup, labels and memory over the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recognition: Option<RecognitionRun>,
    /// Categories arriving over time: the first guesses about every object of the set when the
    /// late categories arrived and at the end of the run (no teacher, no learning).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival_evaluation: Option<ArrivalEvaluation>,
    /// Wall-clock totals (not deterministic).
    pub wall: RunWall,
}

/// The recognition side of a pick-and-place run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecognitionRun {
    /// The feature encoder (`good`, `ae`).
    pub encoder: String,
    /// The model the run started from (`empty`, or the checkpoint given).
    pub start_model: String,
    /// Recognition constants.
    pub config: RecognitionConfig,
    /// Category and instance names by id at the end of the run (the model's ids).
    pub labels: Labels,
    /// Node counts of both memories at the start and after every round.
    pub memory: Vec<MemoryPoint>,
}

impl RunResults {
    /// Pretty JSON with a trailing newline.
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("results serialise");
        s.push('\n');
        s
    }
}

/// Progress after each attempt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunProgress {
    /// Rounds finished.
    pub rounds_done: usize,
    /// Rounds in the run.
    pub rounds: usize,
    /// Attempts so far.
    pub attempts: usize,
    /// Grasp successes so far.
    pub grasp_successes: usize,
    /// Placements so far.
    pub placements: usize,
}

/// A grasp candidate on one view.
struct Candidate {
    view: usize,
    rank: usize,
    crop: DecodedGrasp,
    world: WorldGrasp,
}

struct Runner<'a, F: FnMut(&RunProgress)> {
    spec: &'a RunSpec,
    library: &'a [ObjectModel],
    source: &'a mut dyn GraspSource,
    perception: Perception,
    gripper: GraspSpec,
    shapes: LibraryShapes,
    attempts: Vec<AttemptRecord>,
    rounds_done: usize,
    on_progress: F,
    /// What to record and where (none: recording off).
    record: Option<(&'a RecordConfig, &'a mut dyn RoundSink)>,
    /// The recorder of the round in progress, when it is recorded.
    recorder: Option<Recorder>,
    /// Recognition in the loop (pick-and-place), when on.
    recognizer: Option<&'a mut Recognizer>,
    /// Node counts after each round (with a recognizer).
    memory: Vec<MemoryPoint>,
    /// Seconds of the rounds' end (replay).
    replay_s: f64,
    /// The round's recognitions so far, by object.
    recognised: Vec<(ObjectHandle, RecognitionRecord)>,
    /// The recognition of the attempt in progress, for its record.
    pending_recognition: Option<RecognitionRecord>,
}

/// The timer and counters of one attempt in progress.
struct AttemptClock {
    start: Instant,
    sim_start_s: f64,
    wall: WallTimes,
}

impl AttemptClock {
    fn start(world: &World) -> Self {
        Self {
            start: Instant::now(),
            sim_start_s: world.time_s(),
            wall: WallTimes::default(),
        }
    }
}

impl<F: FnMut(&RunProgress)> Runner<'_, F> {
    fn progress(&mut self) {
        let p = RunProgress {
            rounds_done: self.rounds_done,
            rounds: self.spec.rounds,
            attempts: self.attempts.len(),
            grasp_successes: self.attempts.iter().filter(|a| a.grasp_success).count(),
            placements: self.attempts.iter().filter(|a| a.placement_success).count(),
        };
        (self.on_progress)(&p);
    }

    fn look(&self, cell: &Cell, clock: &mut AttemptClock) -> Result<SceneView, SimError> {
        let shot = clock.wall.time(Work::Render, || {
            self.perception.config().render_overview(&cell.world)
        });
        let shot = shot.map_err(PerceptionError::from)?;
        if let Some(r) = &self.recorder {
            r.camera_shot(&cell.world, RecordCamera::Overview, &shot);
        }
        Ok(clock
            .wall
            .time(Work::Perception, || self.perception.segment_scene(shot))?)
    }

    /// The close-up of segment `index`; `None` when it shows nothing usable.
    fn close_up(
        &self,
        cell: &Cell,
        scene: &SceneView,
        index: usize,
        clock: &mut AttemptClock,
    ) -> Result<Option<ObjectView>, SimError> {
        let Ok(point) = self.perception.table_point_m(scene, index) else {
            return Ok(None);
        };
        let shot = clock.wall.time(Work::Render, || {
            self.perception.config().render_closeup(&cell.world, point)
        });
        let shot = shot.map_err(PerceptionError::from)?;
        if let Some(r) = &self.recorder {
            r.camera_shot(&cell.world, RecordCamera::Closeup, &shot);
        }
        match clock.wall.time(Work::Perception, || {
            self.perception.view_from(shot, index, point)
        }) {
            Ok(view) => Ok(Some(view)),
            Err(PerceptionError::NothingInCloseup { .. } | PerceptionError::Crop(_)) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// The source's ranked grasps on `view` that can be placed in the world.
    fn candidates(
        &mut self,
        view: &ObjectView,
        view_index: usize,
        clock: &mut AttemptClock,
    ) -> Result<Vec<Candidate>, SimError> {
        let k = self.spec.config.scenario.ranked_grasps;
        let query = GraspQuery {
            crop: &view.crop,
            intrinsics: &view.shot.camera.intrinsics,
            gripper: &self.gripper,
        };
        let source = &mut *self.source;
        let grasps = clock.wall.time(Work::Source, || source.grasps(&query, k))?;
        let decode = &self.spec.config.attempt.decode;
        Ok(clock.wall.time(Work::Perception, || {
            grasps
                .iter()
                .take(k)
                .enumerate()
                .filter_map(|(rank, g)| {
                    view.grasp_in_world(g, decode).ok().map(|world| Candidate {
                        view: view_index,
                        rank,
                        crop: *g,
                        world,
                    })
                })
                .collect()
        }))
    }

    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        cell: &Cell,
        round: usize,
        try_in_round: usize,
        objects: &[PlacedObject],
        target: Option<ObjectHandle>,
        grasp: Option<GraspRecord>,
        exec: Execution,
        target_pose: Option<Pose>,
        mut clock: AttemptClock,
    ) {
        let find = |h: ObjectHandle| objects.iter().find(|o| o.handle == h);
        let aimed = target.and_then(find);
        let grasped = exec
            .pinched_object
            .filter(|h| Some(*h) != target)
            .and_then(find)
            .map(|o| o.name.clone());
        // Packing: the basket [`Runner::attempt`] carried to (the same choice from the same
        // recognition), judged against the true category of the object carried.
        let (packing, reason) = match &self.spec.packing {
            // Attempts at no object (nothing seen, no grasp anywhere) carry no packing record.
            Some(spec) if target.is_some() || grasp.is_some() => {
                let choice = spec.choose(self.pending_recognition.as_ref());
                let carried = exec.pinched_object.or(target).and_then(find);
                let (record, reason) = crate::packing::judge(
                    spec,
                    choice,
                    carried.map(|o| o.category.as_str()),
                    exec.placement_success,
                    exec.reason,
                );
                (Some(record), reason)
            }
            _ => (None, exec.reason),
        };
        clock.wall.finish(clock.start);
        self.attempts.push(AttemptRecord {
            index: self.attempts.len(),
            round,
            try_in_round,
            object: aimed.map(|o| o.name.clone()),
            category: aimed.map(|o| o.category.clone()),
            object_pose: target_pose.as_ref().map(PoseRecord::from),
            grasped_object: grasped,
            grasp,
            grasp_success: exec.grasp_success,
            contact_only_success: exec.contact_only_success,
            placement_success: exec.placement_success,
            reason,
            recognition: self.pending_recognition.take(),
            packing,
            measured: exec.measured,
            sim_time_s: cell.world.time_s() - clock.sim_start_s,
            wall: clock.wall,
        });
        if let (Some(r), Some(a)) = (&self.recorder, self.attempts.last()) {
            r.attempt_recorded(attempt_caption(a));
        }
        self.progress();
    }

    /// Recognition in the loop: the first guess about `target` (once per object and round; later
    /// attempts at it repeat that record), the teacher's lesson when needed. Kept for the
    /// attempt's record. Nothing without a recognizer or a known target.
    fn recognise(
        &mut self,
        cell: &Cell,
        target: Option<ObjectHandle>,
        objects: &[PlacedObject],
        clock: &mut AttemptClock,
    ) -> Result<(), SimError> {
        self.pending_recognition = None;
        let (Some(recognizer), Some(h)) = (self.recognizer.as_deref_mut(), target) else {
            return Ok(());
        };
        let Some(object) = objects.iter().find(|o| o.handle == h) else {
            return Ok(());
        };
        if let Some((_, earlier)) = self.recognised.iter().find(|(k, _)| *k == h) {
            self.pending_recognition = Some(RecognitionRecord {
                first_look: false,
                ..earlier.clone()
            });
            return Ok(());
        }
        let instance = &self.library[object.library_index].name;
        let record =
            recognizer.encounter(&cell.world, h, &object.category, instance, &mut clock.wall)?;
        if let Some(r) = &self.recorder {
            r.log(
                &cell.world,
                crate::record::LogLevel::Info,
                &recognition_caption(&record),
            );
            r.label_object(&cell.world, h, &recognition_label(&record));
        }
        self.recognised.push((h, record.clone()));
        self.pending_recognition = Some(record);
        Ok(())
    }

    /// Whether the run's attempt budget is spent.
    fn budget_spent(&self) -> bool {
        self.spec
            .max_attempts
            .is_some_and(|max| self.attempts.len() >= max)
    }

    fn no_grasp() -> Execution {
        Execution {
            reason: Some(FailureReason::NoGraspFound),
            ..Execution::default()
        }
    }

    /// Tries `candidate` from `views`; parks the arm after.
    fn attempt(
        &mut self,
        cell: &mut Cell,
        views: &[ObjectView],
        candidate: &Candidate,
        clock: &mut AttemptClock,
    ) -> Result<(Option<ObjectHandle>, GraspRecord, Execution), SimError> {
        let view = &views[candidate.view];
        let spec = self.spec;
        // Packing: the basket of the category the robot recognised (see [`crate::packing`]).
        let choice = spec
            .packing
            .as_ref()
            .map(|p| p.choose(self.pending_recognition.as_ref()));
        let packing_cfg;
        let cfg = match &choice {
            Some(c) if c.basket != spec.config.attempt.target_basket => {
                packing_cfg = AttemptConfig {
                    target_basket: c.basket,
                    ..spec.config.attempt.clone()
                };
                &packing_cfg
            }
            _ => &spec.config.attempt,
        };
        if let (Some(r), Some(c)) = (&self.recorder, &choice) {
            r.log(
                &cell.world,
                crate::record::LogLevel::Info,
                &format!(
                    "packing as {} ({}): {} basket",
                    c.packed_as.as_deref().unwrap_or("nothing recognised"),
                    c.decided_by.as_str(),
                    crate::packing::basket_name(c.basket)
                ),
            );
        }
        let plan = clock.wall.time(Work::Planning, || {
            plan_grasp(cell, view, &candidate.world, cfg)
        });
        let object = view
            .object
            .and_then(|h| cell.world.object_name(h).ok())
            .map(str::to_string);
        let gripper = cell.robot.gripper().config().clone();
        let shown = GraspShown {
            plan: &plan,
            rank: candidate.rank,
            object: object.as_deref(),
            gripper: &gripper,
            crop: Some((&view.crop, candidate.crop.rectangle())),
        };
        if let Some(r) = &self.recorder {
            r.grasp_planned(&cell.world, &shown);
        }
        let exec = execute(cell, &plan, view.object, cfg, &mut clock.wall)?;
        park(cell, plan.pregrasp_z_m, cfg, &mut clock.wall)?;
        if let Some(r) = &self.recorder {
            // The outcome as the cameras see it, before the table is reset.
            let cameras = self.perception.config();
            let mut after = vec![(
                RecordCamera::Overview,
                cameras
                    .render_overview(&cell.world)
                    .map_err(PerceptionError::from)?,
            )];
            if let Some(camera) = basket_camera(&cell.world, cfg.target_basket) {
                let shot = crate::camera::render_world(&cell.world, &camera, cameras.draw)
                    .map_err(PerceptionError::from)?;
                after.push((RecordCamera::Basket, shot));
            }
            r.grasp_done(&cell.world, &shown, &exec, &after);
        }
        let record = GraspRecord {
            rank: candidate.rank,
            crop: candidate.crop,
            plan,
        };
        Ok((view.object, record, exec))
    }

    fn round(&mut self, round: usize) -> Result<(RoundRecord, f64), SimError> {
        let round_start = Instant::now();
        let cfg = &self.spec.config;
        let scenario = self.spec.scenario;
        let mut rng = round_rng(self.spec, round);
        let picks = round_picks(self.spec, self.library, round, &mut rng);
        let setup_start = Instant::now();
        let mut world = World::new(cfg.world.clone())?;
        self.recorder = match &self.record {
            Some((config, _)) if config.records_round(round) => {
                let metadata = BTreeMap::from([
                    ("scenario".to_string(), scenario.as_str().to_string()),
                    ("grasp_source".to_string(), self.source.name().to_string()),
                    ("seed".to_string(), self.spec.seed.to_string()),
                    ("objects".to_string(), self.spec.objects.clone()),
                ]);
                Some(Recorder::start(&mut world, config, round, metadata)?)
            }
            _ => None,
        };
        let objects = set_table(
            &mut world,
            scenario,
            self.library,
            &mut self.shapes,
            &picks,
            &cfg.scenario,
            &mut rng,
        )?;
        let mut cell = Cell::at_ready(world, cfg.robot.clone(), &cfg.attempt)?;
        if let Some(r) = &self.recorder {
            r.add_robot(&cell.world, &cell.robot);
            let names: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
            r.log(
                &cell.world,
                crate::record::LogLevel::Info,
                &format!("table set: {}", names.join(", ")),
            );
        }
        let setup_s = setup_start.elapsed().as_secs_f64();
        let sim_start = cell.world.time_s();
        let first_attempt = self.attempts.len();
        self.recognised.clear();
        let mut placed = 0usize;
        let mut left_table = Vec::new();
        let ended_by = match scenario {
            Scenario::Isolated => self.isolated(&mut cell, round, &objects, &mut placed)?,
            Scenario::Packed | Scenario::Pile | Scenario::Scattered => {
                self.clutter(&mut cell, round, &objects, &mut placed, &mut left_table)?
            }
        };
        let mut wall = WallTimes::default();
        for a in &self.attempts[first_attempt..] {
            wall.add(&a.wall);
        }
        if let Some(recognizer) = self.recognizer.as_deref_mut() {
            let start = Instant::now();
            let point = recognizer.end_round(&mut wall)?;
            self.replay_s += start.elapsed().as_secs_f64();
            self.memory.push(point);
        }
        wall.finish(round_start);
        let record = RoundRecord {
            round,
            objects: objects.iter().map(|o| o.name.clone()).collect(),
            attempts: self.attempts.len() - first_attempt,
            placed,
            left_table,
            ended_by,
            sim_time_s: cell.world.time_s() - sim_start,
            wall,
        };
        if let Some(recorder) = self.recorder.take() {
            let recording = recorder.finish(&mut cell.world, &round_summary(&record))?;
            if let Some((_, sink)) = self.record.as_mut() {
                sink.write_round(recording)?;
            }
        }
        Ok((record, setup_s))
    }

    fn isolated(
        &mut self,
        cell: &mut Cell,
        round: usize,
        objects: &[PlacedObject],
        placed: &mut usize,
    ) -> Result<RoundEnd, SimError> {
        let object = &objects[0];
        let mut clock = AttemptClock::start(&cell.world);
        let scene = self.look(cell, &mut clock)?;
        let view = match scene.segments.is_empty() {
            true => None,
            // The largest segment: the object (the isolated table holds one).
            false => self.close_up(cell, &scene, 0, &mut clock)?,
        };
        let Some(view) = view else {
            let pose = cell.world.object_pose(object.handle).ok();
            self.record(
                cell,
                round,
                0,
                objects,
                Some(object.handle),
                None,
                Self::no_grasp(),
                pose,
                clock,
            );
            return Ok(RoundEnd::NothingSeen);
        };
        let candidates = self.candidates(&view, 0, &mut clock)?;
        if candidates.is_empty() {
            let pose = cell.world.object_pose(object.handle).ok();
            self.record(
                cell,
                round,
                0,
                objects,
                view.object.or(Some(object.handle)),
                None,
                Self::no_grasp(),
                pose,
                clock,
            );
            return Ok(RoundEnd::GraspsExhausted);
        }
        let views = [view];
        let mut first = Some(clock);
        for (i, candidate) in candidates.iter().enumerate() {
            if self.budget_spent() {
                return Ok(RoundEnd::AttemptBudget);
            }
            let mut clock = first
                .take()
                .unwrap_or_else(|| AttemptClock::start(&cell.world));
            let pose = cell.world.object_pose(object.handle).ok();
            let aimed = views[0].object.or(Some(object.handle));
            self.recognise(cell, aimed, objects, &mut clock)?;
            let (target, grasp, exec) = self.attempt(cell, &views, candidate, &mut clock)?;
            let done = exec.placement_success;
            if done {
                *placed += 1;
                cell.world.remove_object(object.handle)?;
            } else {
                // Put the object back where it rested.
                clock.wall.time(Work::Physics, || {
                    cell.world
                        .reset_object_pose(object.handle, &object.rest_pose)
                        .map(|()| cell.world.settle())
                })?;
            }
            self.record(
                cell,
                round,
                i,
                objects,
                target.or(Some(object.handle)),
                Some(grasp),
                exec,
                pose,
                clock,
            );
            if done {
                return Ok(RoundEnd::Cleared);
            }
        }
        Ok(RoundEnd::GraspsExhausted)
    }

    fn clutter(
        &mut self,
        cell: &mut Cell,
        round: usize,
        objects: &[PlacedObject],
        placed: &mut usize,
        left_table: &mut Vec<String>,
    ) -> Result<RoundEnd, SimError> {
        let cfg = self.spec.config.scenario.clone();
        let mut consecutive = 0usize;
        let mut tries = 0usize;
        loop {
            // Objects that left the table (knocked off, dropped in a basket) leave the round.
            let live: Vec<ObjectHandle> = cell.world.objects().collect();
            for h in live {
                if !on_table(&cell.world, h)? {
                    if let Some(o) = objects.iter().find(|o| o.handle == h) {
                        left_table.push(o.name.clone());
                    }
                    cell.world.remove_object(h)?;
                }
            }
            if cell.world.objects().next().is_none() {
                return Ok(RoundEnd::Cleared);
            }
            if consecutive >= cfg.max_consecutive_failures {
                return Ok(RoundEnd::ConsecutiveFailures);
            }
            if tries >= cfg.max_attempts_per_round {
                return Ok(RoundEnd::AttemptCap);
            }
            if self.budget_spent() {
                return Ok(RoundEnd::AttemptBudget);
            }
            let mut clock = AttemptClock::start(&cell.world);
            let scene = self.look(cell, &mut clock)?;
            let mut views = Vec::new();
            let mut candidates = Vec::new();
            for index in 0..scene.segments.len() {
                if let Some(view) = self.close_up(cell, &scene, index, &mut clock)? {
                    candidates.extend(self.candidates(&view, views.len(), &mut clock)?);
                    views.push(view);
                }
            }
            // Best first; ties by view, then rank.
            candidates.sort_by(|a, b| {
                b.world
                    .quality
                    .total_cmp(&a.world.quality)
                    .then(a.view.cmp(&b.view))
                    .then(a.rank.cmp(&b.rank))
            });
            tries += 1;
            let Some(candidate) =
                candidates.get(consecutive.min(candidates.len().saturating_sub(1)))
            else {
                self.record(
                    cell,
                    round,
                    tries - 1,
                    objects,
                    None,
                    None,
                    Self::no_grasp(),
                    None,
                    clock,
                );
                consecutive += 1;
                continue;
            };
            let target = views[candidate.view].object;
            let pose = target.and_then(|h| cell.world.object_pose(h).ok());
            self.recognise(cell, target, objects, &mut clock)?;
            let (target, grasp, exec) = self.attempt(cell, &views, candidate, &mut clock)?;
            if exec.placement_success {
                *placed += 1;
                consecutive = 0;
                if let Some(h) = exec.pinched_object {
                    cell.world.remove_object(h)?;
                }
            } else {
                consecutive += 1;
            }
            clock.wall.time(Work::Physics, || cell.world.settle());
            self.record(
                cell,
                round,
                tries - 1,
                objects,
                target,
                Some(grasp),
                exec,
                pose,
                clock,
            );
        }
    }
}

/// Plays `spec.rounds` rounds of `spec.scenario` on `library` with `source`, calling
/// `on_progress` after every attempt. Checks the config and every library object (its hull, its
/// size) before the first round.
pub fn run_trials(
    spec: &RunSpec,
    library: &[ObjectModel],
    source: &mut dyn GraspSource,
    on_progress: impl FnMut(&RunProgress),
) -> Result<RunResults, SimError> {
    play(spec, library, source, on_progress, None, None)
}

/// Pick-and-place with lifelong recognition: rounds of `spec.scenario` (packed or pile) as
/// [`run_trials`] plays them, where before each attempt the object aimed at is recognised by
/// `recognizer` (once per object and round) and taught when the robot did not know it or was
/// wrong, with replay after each round (see [`crate::recognize`]). The recognizer keeps the
/// model it learnt; the results hold every recognition, the first-guess accuracy, the teacher
/// interventions and the node counts after each round. `record` as in [`run_trials_recorded`].
pub fn run_pick_place<'a>(
    spec: &'a RunSpec,
    library: &'a [ObjectModel],
    source: &'a mut dyn GraspSource,
    recognizer: &'a mut Recognizer,
    on_progress: impl FnMut(&RunProgress),
    record: Option<(&'a RecordConfig, &'a mut dyn RoundSink)>,
) -> Result<RunResults, SimError> {
    if let Some((config, _)) = &record {
        config.validate()?;
    }
    play(spec, library, source, on_progress, record, Some(recognizer))
}

/// [`run_trials`], recording the rounds `record` selects into `sink` as they end (see
/// [`crate::record`]). The results are those of [`run_trials`], bit for bit.
pub fn run_trials_recorded(
    spec: &RunSpec,
    library: &[ObjectModel],
    source: &mut dyn GraspSource,
    on_progress: impl FnMut(&RunProgress),
    record: &RecordConfig,
    sink: &mut dyn RoundSink,
) -> Result<RunResults, SimError> {
    record.validate()?;
    play(
        spec,
        library,
        source,
        on_progress,
        Some((record, sink)),
        None,
    )
}

fn play<'a>(
    spec: &'a RunSpec,
    library: &'a [ObjectModel],
    source: &'a mut dyn GraspSource,
    on_progress: impl FnMut(&RunProgress),
    record: Option<(&'a RecordConfig, &'a mut dyn RoundSink)>,
    recognizer: Option<&'a mut Recognizer>,
) -> Result<RunResults, SimError> {
    let start = Instant::now();
    if spec.rounds == 0 {
        return Err(SimError::NoRounds);
    }
    if spec.max_attempts == Some(0) {
        return Err(SimError::NoAttempts);
    }
    if library.is_empty() {
        return Err(SimError::EmptyLibrary);
    }
    spec.config.validate()?;
    check_library(&spec.config.world, library)?;
    if let Some(packing) = &spec.packing {
        let Some(r) = recognizer.as_deref() else {
            return Err(PackingError::NoRecognition.into());
        };
        let known = crate::packing::known_categories(library, r.labels());
        packing.validate(&known, &spec.config.world)?;
    }
    if let Some(arrival) = &spec.arrival {
        if recognizer.is_none() {
            return Err(ArrivalError::NoRecognition.into());
        }
        arrival.validate(spec.rounds)?;
    }
    let perception = Perception::new(spec.config.cameras.clone())?;
    let mut runner = Runner {
        spec,
        library,
        gripper: spec.config.grasp_spec(),
        shapes: LibraryShapes::new(spec.config.shapes.clone(), library.len()),
        source,
        perception,
        attempts: Vec::new(),
        rounds_done: 0,
        on_progress,
        record,
        recorder: None,
        memory: recognizer.iter().map(|r| r.memory_point()).collect(),
        recognizer,
        replay_s: 0.0,
        recognised: Vec::new(),
        pending_recognition: None,
    };
    // Decompose every object the rounds will show ahead, in parallel (the picks are the
    // rounds' first draws; the same seeds draw them again in each round).
    let used: Vec<usize> = (0..spec.rounds)
        .flat_map(|round| {
            let mut rng = round_rng(spec, round);
            round_picks(spec, library, round, &mut rng)
        })
        .collect();
    runner.shapes.prepare(library, &used);
    let mut rounds = Vec::with_capacity(spec.rounds);
    let mut setup_s = 0.0;
    let mut sim_s = 0.0;
    let mut evaluation_s = 0.0;
    let mut at_switch = None;
    for r in 0..spec.rounds {
        if runner.budget_spent() {
            break;
        }
        // Categories arriving over time: what the early rounds taught, before the late ones.
        if let (Some(arrival), Some(recognizer)) = (&spec.arrival, runner.recognizer.as_deref_mut())
            && arrival.after_round == r
        {
            let start = Instant::now();
            at_switch = Some(evaluate(
                recognizer,
                &spec.config.world,
                library,
                arrival,
                spec.config.scenario.clutter_center_xy_m,
                spec.seed,
                r,
            )?);
            evaluation_s += start.elapsed().as_secs_f64();
        }
        let (record, setup) = runner.round(r)?;
        setup_s += setup;
        sim_s += record.sim_time_s;
        rounds.push(record);
        runner.rounds_done = r + 1;
        runner.progress();
    }
    // Categories arriving over time: what the model still knows of every object at the end.
    let evaluation_start = Instant::now();
    let arrival_evaluation = match (&spec.arrival, runner.recognizer.as_deref_mut()) {
        (Some(arrival), Some(r)) => Some(ArrivalEvaluation {
            arrival: arrival.clone(),
            at_switch,
            at_end: evaluate(
                r,
                &spec.config.world,
                library,
                arrival,
                spec.config.scenario.clutter_center_xy_m,
                spec.seed,
                rounds.len(),
            )?,
        }),
        _ => None,
    };
    evaluation_s += evaluation_start.elapsed().as_secs_f64();
    let recognition = runner.recognizer.as_deref().map(|r| RecognitionRun {
        encoder: r.encoder_name().to_string(),
        start_model: r.origin().to_string(),
        config: r.config().clone(),
        labels: r.labels().clone(),
        memory: runner.memory.clone(),
    });
    let replay_s = runner.replay_s;
    let attempts = runner.attempts;
    let n_attempts = attempts.len();
    let mut summary = summarize(&attempts, &rounds);
    if spec.packing.is_some() && summary.packing.is_none() {
        // No attempt reached an object: packing's rates are still reported (all failures).
        let presented = rounds.iter().map(|r| r.objects.len()).sum();
        summary.packing = Some(crate::packing::summarize(&attempts, presented));
        summary
            .failure_reasons
            .entry(FailureReason::Misrecognised.as_str().to_string())
            .or_insert(0);
    }
    if let Some(e) = &arrival_evaluation {
        summary.early_category_accuracy_at_end = Some(e.at_end.early_category_accuracy);
        summary.early_instance_accuracy_at_end = Some(e.at_end.early_instance_accuracy);
        summary.early_category_accuracy_at_switch =
            e.at_switch.as_ref().map(|s| s.early_category_accuracy);
    }
    let mut attempt_wall = WallTimes::default();
    for a in &attempts {
        attempt_wall.add(&a.wall);
    }
    let total_s = start.elapsed().as_secs_f64();
    Ok(RunResults {
        format_version: RESULTS_FORMAT_VERSION,
        run: RunInfo {
            scenario: spec.scenario,
            grasp_source: runner.source.name().to_string(),
            grasp_source_detail: runner.source.describe(),
            rounds: rounds.len(),
            seed: spec.seed,
            objects: spec.objects.clone(),
            library_size: library.len(),
            packing: spec.packing.clone(),
            arrival: spec.arrival.clone(),
        },
        summary,
        attempts,
        rounds,
        config: spec.config.clone(),
        recognition,
        arrival_evaluation,
        wall: RunWall {
            total_s,
            setup_s,
            attempts: attempt_wall,
            per_attempt_s: attempt_wall.total_s / n_attempts.max(1) as f64,
            real_time_factor: if total_s > 0.0 { sim_s / total_s } else { 0.0 },
            replay_s,
            evaluation_s,
        },
    })
}

/// The library indices of round `round`'s objects: drawn from the whole library, or from the
/// categories of the round's stage when they arrive over time.
fn round_picks(
    spec: &RunSpec,
    library: &[ObjectModel],
    round: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let pool: Vec<usize> = match &spec.arrival {
        Some(a) => a.pool(library, round),
        None => (0..library.len()).collect(),
    };
    round_objects_among(
        spec.scenario,
        library,
        &pool,
        round,
        &spec.config.scenario,
        rng,
    )
}

/// The random stream of round `round`: it draws the round's objects, then their poses.
fn round_rng(spec: &RunSpec, round: usize) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(derive_seed(
        spec.seed,
        TAG_ROUND,
        round as u64,
        spec.scenario as u64,
    ))
}

/// A storyboard caption of an attempt: `attempt 2 (try 1, rank 1) mug_01: grasp failed (missed)`.
fn attempt_caption(a: &AttemptRecord) -> String {
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
fn recognition_caption(r: &RecognitionRecord) -> String {
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
fn recognition_label(r: &RecognitionRecord) -> ObjectLabel {
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
fn round_summary(r: &RoundRecord) -> String {
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

/// The model a pick-and-place run learnt, as a dual-memory checkpoint (`lgdm eval --model`,
/// `lgdm.GDM.load`, `--model` of another run).
pub const MODEL_FILE: &str = "model.lgdm";

/// Beside [`MODEL_FILE`]: its encoder and label names (`{"encoder", "categories",
/// "instances"}`, the fields of `lgdm train`'s `metrics.json` that say what the ids mean).
pub const MODEL_LABELS_FILE: &str = "model.json";

/// The folder of a run directory that holds the recorded rounds.
pub const ROUNDS_DIR: &str = "rounds";

/// Whether `name` is a file of [`ROUNDS_DIR`] (`round-NNNN.mcap` or `.png`, or a temporary file).
fn is_round_entry(name: &str) -> bool {
    (name.starts_with("round-") && (name.ends_with(".mcap") || name.ends_with(".png")))
        || (name.starts_with('.') && name.ends_with(".tmp"))
}

/// Whether `name` is a file a sim run directory holds (what `force` may remove).
fn is_run_entry(name: &str) -> bool {
    matches!(
        name,
        RESULTS_FILE | "summary.txt" | MODEL_FILE | MODEL_LABELS_FILE | lgdm_pointcloud::LOCK_FILE
    ) || name.ends_with(".png")
        || (name.starts_with('.') && name.ends_with(".tmp"))
}

/// A sim run directory owned by this process: locked while it lives.
#[derive(Debug)]
pub struct SimRunDir {
    dir: PathBuf,
    _lock: DirLock,
}

fn dir_error(path: &Path, reason: impl std::fmt::Display) -> SimError {
    SimError::RunDir {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

impl SimRunDir {
    /// Creates and locks `dir`. A directory that already holds files is refused, unless `force`
    /// is set and every file in it belongs to a sim run (those are removed first); a directory
    /// holding anything else is never cleared.
    pub fn create(dir: &Path, force: bool) -> Result<SimRunDir, SimError> {
        let lock = DirLock::try_acquire(dir)
            .map_err(|e| dir_error(dir, e))?
            .ok_or_else(|| dir_error(dir, "another lgdm process is writing this run directory"))?;
        let mut old = Vec::new();
        let mut old_dirs = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(|e| dir_error(dir, e))? {
            let entry = entry.map_err(|e| dir_error(dir, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if name == lgdm_pointcloud::LOCK_FILE {
                continue;
            }
            if name == ROUNDS_DIR && entry.path().is_dir() {
                // Recorded rounds: only round files may be in there.
                let rounds = entry.path();
                for inner in std::fs::read_dir(&rounds).map_err(|e| dir_error(&rounds, e))? {
                    let inner = inner.map_err(|e| dir_error(&rounds, e))?;
                    let inner_name = inner.file_name().to_string_lossy().into_owned();
                    if !is_round_entry(&inner_name) || inner.path().is_dir() {
                        return Err(dir_error(
                            dir,
                            format!(
                                "holds {ROUNDS_DIR}/{inner_name}, which is not part of an lgdm sim run; choose another directory"
                            ),
                        ));
                    }
                    old.push(inner.path());
                }
                old_dirs.push(rounds);
                continue;
            }
            if !is_run_entry(&name) || entry.path().is_dir() {
                return Err(dir_error(
                    dir,
                    format!(
                        "holds {name}, which is not part of an lgdm sim run; choose another directory"
                    ),
                ));
            }
            old.push(entry.path());
        }
        if !old.is_empty() || !old_dirs.is_empty() {
            if !force {
                return Err(dir_error(
                    dir,
                    "holds another run; choose another directory or pass --force to replace it",
                ));
            }
            old.sort();
            for path in old {
                std::fs::remove_file(&path).map_err(|e| dir_error(&path, e))?;
            }
            for path in old_dirs {
                std::fs::remove_dir(&path).map_err(|e| dir_error(&path, e))?;
            }
        }
        Ok(SimRunDir {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes `name` (a file name, or a path such as `rounds/round-0000.mcap` whose folders
    /// are created) in the directory atomically (temporary file, then rename).
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), SimError> {
        use std::io::Write;
        let path = self.dir.join(name);
        let folder = path.parent().unwrap_or(&self.dir);
        std::fs::create_dir_all(folder).map_err(|e| dir_error(folder, e))?;
        let file_name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| dir_error(&path, "not a file name"))?;
        let prefix = format!(".{file_name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let mut tmp = builder
            .tempfile_in(folder)
            .map_err(|e| dir_error(&path, e))?;
        tmp.write_all(bytes).map_err(|e| dir_error(&path, e))?;
        tmp.as_file().sync_all().map_err(|e| dir_error(&path, e))?;
        tmp.persist(&path).map_err(|e| dir_error(&path, e.error))?;
        Ok(())
    }

    /// Writes `results.json`.
    pub fn write_results(&self, results: &RunResults) -> Result<(), SimError> {
        self.write_file(RESULTS_FILE, results.to_json().as_bytes())
    }
}

/// A run directory stores recorded rounds as `rounds/round-NNNN.mcap` and `.png`.
impl RoundSink for SimRunDir {
    fn write_round(&mut self, round: RoundRecording) -> Result<(), RecordError> {
        let stem = format!("{ROUNDS_DIR}/{}", round.file_stem());
        let failed = |e: SimError| RecordError::Write {
            path: self.dir.join(&stem).display().to_string(),
            reason: e.to_string(),
        };
        self.write_file(&format!("{stem}.mcap"), &round.mcap)
            .map_err(failed)?;
        let png = round
            .storyboard
            .encode_png()
            .map_err(|e| failed(dir_error(&self.dir, e)))?;
        self.write_file(&format!("{stem}.png"), &png)
            .map_err(failed)?;
        Ok(())
    }
}
