//! What a run produced: one [`AttemptRecord`] per attempt, one [`RoundRecord`] per round, the
//! [`Summary`] computed from them ([`summarize`]: grasp success, placement success, the
//! fraction of objects cleared and the paper's contact-only success, each a [`Rate`] with its
//! Wilson 95 % interval and, since the attempts of a round share a table and its retries an
//! object, a seeded bootstrap interval over rounds; per category and per failure reason;
//! recognition, packing and arrival rates when the run had them) and [`RunResults`], everything
//! `results.json` holds.
//! Also the numbers behind the plots ([`RunResults::learning_curve`]).
//!
//! Everything is deterministic except the fields named `wall` (wall-clock seconds), which a
//! comparison of two runs drops.
//!
//! ```
//! use lgdm_sim::run::results::{Rate, summarize};
//! use lgdm_sim::tasks::scenario::ScenarioConfig;
//! let summary = summarize(&[], &[], false, &ScenarioConfig::default(), 0);
//! assert_eq!(summary.attempts, 0);
//! assert_eq!(summary.grasp_success_rate, Rate::new(0, 0));
//! assert!(summary.packing.is_none());
//! ```

use std::collections::BTreeMap;

use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::math::Pose;
use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};

pub use lgdm_base::stats::{Rate, wilson_interval};

use crate::grasping::attempt::{FailureReason, GraspPlan, Measurements};
use crate::grasping::failed::FailedGrasps;
use crate::recognition::config::RecognitionConfig;
use crate::recognition::labels::Labels;
use crate::recognition::recognizer::{MemoryPoint, RecognitionRecord};
use crate::run::config::SimConfig;
use crate::tasks::arrival::{Arrival, ArrivalEvaluation};
use crate::tasks::packing::{PackingRecord, PackingSpec, PackingSummary};
use crate::tasks::scenario::{Scenario, ScenarioConfig};
use crate::timing::WallTimes;

/// Version of the `results.json` layout.
pub const RESULTS_FORMAT_VERSION: u32 = 1;

/// The results file in a run directory.
pub const RESULTS_FILE: &str = "results.json";

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
    /// The source's proposals planned to choose this attempt's grasp, and those the contact
    /// check refused.
    #[serde(default)]
    pub proposals: Proposals,
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
    /// The run's attempt budget ([`crate::run::spec::RunSpec::max_attempts`]) was spent.
    AttemptBudget,
    /// The camera saw no object on the table.
    NothingSeen,
    /// A look found no grasp on anything left on the table
    /// ([`crate::tasks::scenario::ScenarioConfig::end_round_without_grasp`]).
    NoGrasp,
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
    /// Placements / grasp successes: of the objects held, the share that landed in the basket
    /// (none when nothing was grasped; absent in results written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub landed_rate: Option<Rate>,
    /// Objects placed / objects set on the table.
    pub cleared_fraction: Rate,
    /// The paper's contact-only successes / attempts.
    pub contact_only_success_rate: Rate,
    /// Per category of the object aimed at (attempts with no object aimed at are `unknown`).
    pub per_category: BTreeMap<String, CategorySummary>,
    /// Failed attempts per reason (every reason listed).
    pub failure_reasons: BTreeMap<String, usize>,
    /// Every attempt's [`AttemptRecord::proposals`], summed.
    #[serde(default)]
    pub proposals: Proposals,
    /// Attempts that tried a grasp that had failed earlier in their round.
    #[serde(default)]
    pub repeats: Repeats,
    /// Attempts in which an arm link touched the scenery or another link
    /// ([`crate::grasping::attempt::Measurements::arm_contacts`]: on the way back to the ready
    /// pose, which is made even when no clear way is found).
    #[serde(default)]
    pub arm_contact_attempts: usize,
    /// Attempts with a planned move whose links would have touched the scenery or another link
    /// ([`crate::grasping::attempt::Measurements::avoided_contacts`]): re-planned, left out or
    /// turned down (`arm_collision` in the failure reasons).
    #[serde(default)]
    pub avoided_contact_attempts: usize,
    /// Attempts with at least one move replaced by a lifted detour
    /// ([`crate::grasping::attempt::Measurements::detours`]).
    #[serde(default)]
    pub detour_attempts: usize,
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

/// Grasp proposals planned, and those refused before they were tried because a pad would close on
/// air ([`crate::grasping::attempt::GraspPlan::reaches_contacts`]; every source's proposals are
/// checked). Isolated rounds plan a look's ranked grasps together (counted in its first attempt);
/// cluttered ones plan best first, as far as the grasp tried.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Proposals {
    /// Proposals planned.
    pub planned: usize,
    /// Of those, refused.
    pub refused: usize,
    /// Proposals checked against the close-up's depth before planning (`[attempt]
    /// proposal_check` other than `contacts`; 0 otherwise).
    #[serde(default)]
    pub checked: usize,
    /// Of those, refused by that check (and never planned).
    #[serde(default)]
    pub check_refused: usize,
    /// Candidates skipped, before planning, because a grasp at the same place and angle had
    /// failed earlier in the round ([`crate::grasping::failed`]; `[scenario]
    /// failed_grasp_radius_m`). Cluttered rounds count them in the attempt whose choice skipped
    /// them; isolated ones in the failed attempt after which they were skipped.
    #[serde(default)]
    pub repeat_skipped: usize,
}

impl Proposals {
    /// Refused / planned.
    pub fn refused_rate(&self) -> Rate {
        Rate::new(self.refused, self.planned)
    }
}

/// Attempts that tried a grasp at the place and angle of one that failed (was not placed)
/// earlier in their round, as [`crate::grasping::failed::FailedGrasps`] judges it with
/// `radius_m` and `angle_deg`: with the memory on, none.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Repeats {
    /// The radius they were judged with (m): the run's `[scenario] failed_grasp_radius_m`, or
    /// its default when the run had the memory off.
    pub radius_m: f64,
    /// The angle they were judged with (degrees), likewise.
    pub angle_deg: f64,
    /// Attempts whose grasp was within that radius and angle of a grasp that failed earlier in
    /// the round.
    pub attempts: usize,
    /// Of those, attempts that failed again.
    pub failed_again: usize,
}

/// Counts the attempts that repeated a failed grasp of their round (see [`Repeats`]), judged
/// with `radius_m` and `angle_deg`.
pub fn count_repeats(attempts: &[AttemptRecord], radius_m: f64, angle_deg: f64) -> Repeats {
    let mut repeats = Repeats {
        radius_m,
        angle_deg,
        ..Repeats::default()
    };
    let mut failed = FailedGrasps::new(radius_m, angle_deg);
    let mut round = None;
    for a in attempts {
        if round != Some(a.round) {
            failed.clear();
            round = Some(a.round);
        }
        let Some(grasp) = &a.grasp else { continue };
        let g = &grasp.plan.grasp;
        if failed.covers(g.position_m, g.yaw_rad) {
            repeats.attempts += 1;
            repeats.failed_again += usize::from(!a.placement_success);
        }
        if !a.placement_success {
            failed.remember(g.position_m, g.yaw_rad);
        }
    }
    repeats
}

/// Summarises attempts and rounds; `packing`: the run is a packing run (its summary then holds
/// the packing rates and `misrecognised` among the failure reasons, even when no attempt
/// reached an object); `scenario`: the run's, whose failed-grasp memory judges the repeats
/// ([`Repeats`]; the default memory's when the run's was off). The run's overall rates carry a
/// bootstrap interval over its rounds ([`Rate::with_clusters`], seeded by the run's `seed`).
pub fn summarize(
    attempts: &[AttemptRecord],
    rounds: &[RoundRecord],
    packing: bool,
    scenario: &ScenarioConfig,
    seed: u64,
) -> Summary {
    let mut summary = summarize_pooled(attempts, rounds, packing, scenario);
    // Per round (in round order): (successes, trials) of a rate over attempts, over first
    // looks, or over the objects set on the table.
    let mut order: BTreeMap<usize, usize> = BTreeMap::new();
    for r in rounds {
        let next = order.len();
        order.entry(r.round).or_insert(next);
    }
    for a in attempts {
        let next = order.len();
        order.entry(a.round).or_insert(next);
    }
    let per_round = |hit: &dyn Fn(&AttemptRecord) -> Option<bool>| {
        let mut c = vec![(0usize, 0usize); order.len()];
        for a in attempts {
            if let Some(h) = hit(a) {
                let i = order[&a.round];
                c[i].0 += usize::from(h);
                c[i].1 += 1;
            }
        }
        c
    };
    let per_object = |hit: &dyn Fn(&AttemptRecord) -> bool| {
        let mut c = vec![(0usize, 0usize); order.len()];
        for r in rounds {
            c[order[&r.round]].1 += r.objects.len();
        }
        for a in attempts.iter().filter(|a| hit(a)) {
            c[order[&a.round]].0 += 1;
        }
        c
    };
    let s = &mut summary;
    let cluster = |rate: Rate, c: Vec<(usize, usize)>| rate.with_clusters(&c, seed);
    s.grasp_success_rate = cluster(s.grasp_success_rate, per_round(&|a| Some(a.grasp_success)));
    s.placement_success_rate = cluster(
        s.placement_success_rate,
        per_round(&|a| Some(a.placement_success)),
    );
    s.landed_rate = s.landed_rate.map(|r| {
        cluster(
            r,
            per_round(&|a| a.grasp_success.then_some(a.placement_success)),
        )
    });
    s.contact_only_success_rate = cluster(
        s.contact_only_success_rate,
        per_round(&|a| Some(a.contact_only_success)),
    );
    s.cleared_fraction = cluster(s.cleared_fraction, {
        let mut c = vec![(0usize, 0usize); order.len()];
        for r in rounds {
            c[order[&r.round]] = (r.placed, r.objects.len());
        }
        c
    });
    fn first_look(a: &AttemptRecord) -> Option<&RecognitionRecord> {
        a.recognition.as_ref().filter(|r| r.first_look)
    }
    s.recognition_accuracy = s
        .recognition_accuracy
        .map(|r| cluster(r, per_round(&|a| first_look(a).map(|l| l.category_correct))));
    s.instance_recognition_accuracy = s
        .instance_recognition_accuracy
        .map(|r| cluster(r, per_round(&|a| first_look(a).map(|l| l.instance_correct))));
    s.teacher_intervention_rate = s
        .teacher_intervention_rate
        .map(|r| cluster(r, per_round(&|a| first_look(a).map(|l| l.teacher))));
    let packed = |a: &AttemptRecord| a.packing.as_ref().is_some_and(|p| p.success);
    if let Some(p) = s.packing.as_mut() {
        p.success_rate = cluster(p.success_rate, per_round(&|a| Some(packed(a))));
        p.packed_fraction = cluster(p.packed_fraction, per_object(&packed));
    }
    summary
}

/// [`summarize`] without the intervals over rounds.
fn summarize_pooled(
    attempts: &[AttemptRecord],
    rounds: &[RoundRecord],
    packing: bool,
    scenario: &ScenarioConfig,
) -> Summary {
    let judge = match scenario.failed_grasp_radius_m > 0.0 {
        true => scenario,
        false => &ScenarioConfig::default(),
    };
    let (repeats_radius_m, repeats_angle_deg) =
        (judge.failed_grasp_radius_m, judge.failed_grasp_angle_deg);
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
        landed_rate: {
            let grasped = count(&|a| a.grasp_success, &all);
            (grasped > 0).then(|| {
                Rate::new(
                    count(&|a| a.grasp_success && a.placement_success, &all),
                    grasped,
                )
            })
        },
        cleared_fraction: Rate::new(placed, presented),
        contact_only_success_rate: Rate::new(count(&|a| a.contact_only_success, &all), n),
        per_category,
        failure_reasons,
        proposals: Proposals {
            planned: attempts.iter().map(|a| a.proposals.planned).sum(),
            refused: attempts.iter().map(|a| a.proposals.refused).sum(),
            checked: attempts.iter().map(|a| a.proposals.checked).sum(),
            check_refused: attempts.iter().map(|a| a.proposals.check_refused).sum(),
            repeat_skipped: attempts.iter().map(|a| a.proposals.repeat_skipped).sum(),
        },
        repeats: count_repeats(attempts, repeats_radius_m, repeats_angle_deg),
        arm_contact_attempts: attempts
            .iter()
            .filter(|a| !a.measured.arm_contacts.is_empty())
            .count(),
        avoided_contact_attempts: attempts
            .iter()
            .filter(|a| !a.measured.avoided_contacts.is_empty())
            .count(),
        detour_attempts: attempts.iter().filter(|a| a.measured.detours > 0).count(),
        packing: packing.then(|| {
            let packed: Vec<(Option<&str>, &PackingRecord)> = attempts
                .iter()
                .filter_map(|a| a.packing.as_ref().map(|p| (a.category.as_deref(), p)))
                .collect();
            let misrecognised = attempts
                .iter()
                .filter(|a| a.reason == Some(FailureReason::Misrecognised))
                .count();
            crate::tasks::packing::summarize(&packed, attempts.len(), misrecognised, presented)
        }),
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

/// A learning curve: per object seen (its first look, in order), the share of first guesses
/// whose category was right and of looks the teacher stepped in, over the last `window`
/// looks and over all so far. Points are (objects seen, share).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LearningCurve {
    /// The window of the windowed curves (looks).
    pub window: usize,
    /// First-guess category accuracy over the last `window` looks.
    pub accuracy_windowed: Vec<(f64, f64)>,
    /// Teacher interventions over the last `window` looks.
    pub teacher_windowed: Vec<(f64, f64)>,
    /// First-guess category accuracy over every look so far.
    pub accuracy_cumulative: Vec<(f64, f64)>,
    /// Teacher interventions over every look so far.
    pub teacher_cumulative: Vec<(f64, f64)>,
}

impl RunResults {
    /// The recognitions that were first looks (one per object and round), in order.
    pub fn first_looks(&self) -> Vec<&RecognitionRecord> {
        self.attempts
            .iter()
            .filter_map(|a| a.recognition.as_ref())
            .filter(|r| r.first_look)
            .collect()
    }

    /// The learning curve of a pick-and-place run (empty for a run without recognition).
    ///
    /// ```
    /// # use lgdm_sim::run::results::RunResults;
    /// # fn show(results: &RunResults) {
    /// let curve = results.learning_curve(25);
    /// if let Some(&(seen, share)) = curve.accuracy_windowed.last() {
    ///     println!("after {seen} objects: {:.0} % right", 100.0 * share);
    /// }
    /// # }
    /// ```
    pub fn learning_curve(&self, window: usize) -> LearningCurve {
        let looks = self.first_looks();
        let window = window.max(1);
        let windowed = |f: fn(&RecognitionRecord) -> bool| -> Vec<(f64, f64)> {
            (0..looks.len())
                .map(|i| {
                    let part = &looks[(i + 1).saturating_sub(window)..=i];
                    let k = part.iter().filter(|x| f(x)).count();
                    ((i + 1) as f64, k as f64 / part.len() as f64)
                })
                .collect()
        };
        let cumulative = |f: fn(&RecognitionRecord) -> bool| -> Vec<(f64, f64)> {
            let mut k = 0;
            looks
                .iter()
                .enumerate()
                .map(|(i, x)| {
                    k += usize::from(f(x));
                    ((i + 1) as f64, k as f64 / (i + 1) as f64)
                })
                .collect()
        };
        LearningCurve {
            window,
            accuracy_windowed: windowed(|x| x.category_correct),
            teacher_windowed: windowed(|x| x.teacher),
            accuracy_cumulative: cumulative(|x| x.category_correct),
            teacher_cumulative: cumulative(|x| x.teacher),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::WorldGrasp;
    use crate::recognition::recognizer::Guess;

    fn look(correct: bool, teacher: bool) -> RecognitionRecord {
        RecognitionRecord {
            true_category: "mug".into(),
            true_instance: "mug_01".into(),
            guess: Guess {
                category: Some(if correct { "mug" } else { "can" }.into()),
                instance: None,
                confidence: 1.0,
                activation: None,
                views: 5,
                known: true,
            },
            category_correct: correct,
            instance_correct: false,
            teacher,
            taught_views: 0,
            first_look: true,
        }
    }

    fn attempt(
        index: usize,
        round: usize,
        placed: bool,
        recognition: Option<RecognitionRecord>,
    ) -> AttemptRecord {
        AttemptRecord {
            index,
            round,
            try_in_round: 0,
            object: Some("mug_01".into()),
            category: Some("mug".into()),
            object_pose: None,
            grasped_object: None,
            grasp: None,
            grasp_success: placed,
            contact_only_success: placed,
            placement_success: placed,
            reason: (!placed).then_some(FailureReason::Missed),
            recognition,
            packing: None,
            proposals: Proposals::default(),
            measured: Measurements::default(),
            sim_time_s: 1.0,
            wall: WallTimes::default(),
        }
    }

    fn round(round: usize, objects: usize, placed: usize) -> RoundRecord {
        RoundRecord {
            round,
            objects: (0..objects).map(|i| format!("o{i}")).collect(),
            attempts: 1,
            placed,
            left_table: Vec::new(),
            ended_by: RoundEnd::Cleared,
            sim_time_s: 1.0,
            wall: WallTimes::default(),
        }
    }

    #[test]
    fn summary_counts_attempts_objects_and_reasons() {
        let attempts = [
            attempt(0, 0, true, None),
            attempt(1, 0, false, None),
            attempt(2, 1, true, None),
        ];
        let rounds = [round(0, 2, 1), round(1, 3, 1)];
        let s = summarize(&attempts, &rounds, false, &ScenarioConfig::default(), 0);
        // The counts pooled, and the interval over the two rounds next to Wilson's.
        let pooled = |r: Rate| Rate {
            cluster_bootstrap: None,
            ..r
        };
        assert_eq!(pooled(s.grasp_success_rate), Rate::new(2, 3));
        assert_eq!(pooled(s.placement_success_rate), Rate::new(2, 3));
        assert_eq!(pooled(s.cleared_fraction), Rate::new(2, 5));
        // Rounds: grasps (1 of 2, 1 of 1), objects cleared (1 of 2, 1 of 3).
        let g = s.grasp_success_rate.cluster_bootstrap.unwrap();
        assert_eq!((g.clusters, g.low, g.high), (2, 0.5, 1.0));
        let c = s.cleared_fraction.cluster_bootstrap.unwrap();
        assert_eq!((c.clusters, c.low, c.high), (2, 1.0 / 3.0, 0.5));
        assert_eq!(
            s,
            summarize(&attempts, &rounds, false, &ScenarioConfig::default(), 0)
        );
        assert!(
            s.per_category["mug"]
                .grasp_success_rate
                .cluster_bootstrap
                .is_none()
        );
        assert_eq!(s.per_category["mug"].attempts, 3);
        assert_eq!(s.failure_reasons["missed"], 1);
        assert!(!s.failure_reasons.contains_key("misrecognised"));
        assert!(s.recognition_accuracy.is_none());
        // A packing run lists its verdict and rates even with no attempt at an object.
        let s = summarize(&attempts, &rounds, true, &ScenarioConfig::default(), 0);
        assert_eq!(s.failure_reasons["misrecognised"], 0);
        let p = s.packing.unwrap();
        assert_eq!(pooled(p.success_rate), Rate::new(0, 3));
        assert_eq!(pooled(p.packed_fraction), Rate::new(0, 5));
        assert_eq!(p.packed_fraction.cluster_bootstrap.unwrap().clusters, 2);
    }

    /// An attempt of round `round` at a grasp centred at `x_m` (world x) with yaw `yaw_rad`.
    fn tried(round: usize, placed: bool, x_m: f64, yaw_rad: f64) -> AttemptRecord {
        let grasp = WorldGrasp {
            position_m: [x_m, -0.52, 0.8],
            yaw_rad,
            opening_m: 0.05,
            quality: 1.0,
        };
        AttemptRecord {
            grasp: Some(GraspRecord {
                rank: 0,
                crop: DecodedGrasp {
                    center_px: [0.0, 0.0],
                    angle: 0.0,
                    width_px: 1.0,
                    jaw_px: 1.0,
                    quality: 1.0,
                },
                plan: GraspPlan {
                    grasp,
                    tcp_m: grasp.position_m,
                    pregrasp_z_m: 1.0,
                    opening_m: 0.05,
                    lane_height_m: 0.0,
                    palm_height_m: 0.0,
                    tip_height_m: 0.0,
                    contact_height_m: 0.0,
                },
            }),
            ..attempt(0, round, placed, None)
        }
    }

    #[test]
    fn repeats_are_failed_grasps_of_the_same_round_tried_again() {
        let pi = std::f64::consts::PI;
        let attempts = [
            tried(0, false, 0.0, 0.2),
            // The same grasp turned a half turn, 1 cm away: a repeat, failed again.
            tried(0, false, 0.01, 0.2 - pi),
            // 5 cm away: another grasp, placed.
            tried(0, true, 0.05, 0.2),
            // Where it failed, placed this time: a repeat that did not fail again.
            tried(0, true, 0.0, 0.25),
            // A new round forgets.
            tried(1, false, 0.0, 0.2),
        ];
        let r = count_repeats(&attempts, 0.02, 15.0);
        assert_eq!((r.attempts, r.failed_again), (2, 1));
        // Judged at a radius too small for the second: one repeat.
        let r = count_repeats(&attempts, 0.005, 15.0);
        assert_eq!((r.attempts, r.failed_again), (1, 0));
        // A run with the memory off is judged at the default memory.
        let off = ScenarioConfig {
            failed_grasp_radius_m: 0.0,
            ..ScenarioConfig::default()
        };
        let s = summarize(&attempts, &[round(0, 2, 2)], false, &off, 0);
        assert_eq!(
            s.repeats.radius_m,
            ScenarioConfig::default().failed_grasp_radius_m
        );
        assert_eq!((s.repeats.attempts, s.repeats.failed_again), (2, 1));
    }

    #[test]
    fn recognition_is_scored_on_first_looks_only() {
        let mut again = look(false, true);
        again.first_look = false;
        let attempts = [
            attempt(0, 0, true, Some(look(true, false))),
            attempt(1, 0, false, Some(look(false, true))),
            attempt(2, 0, true, Some(again)),
        ];
        let s = summarize(
            &attempts,
            &[round(0, 2, 2)],
            false,
            &ScenarioConfig::default(),
            0,
        );
        let r = s.recognition_accuracy.unwrap();
        assert_eq!((r.successes, r.trials), (1, 2));
        // One round: its rate at both ends.
        let c = r.cluster_bootstrap.unwrap();
        assert_eq!((c.clusters, c.low, c.high), (1, 0.5, 0.5));
        assert_eq!(s.teacher_interventions, Some(1));
    }

    #[test]
    fn the_learning_curve_windows_and_accumulates() {
        let looks = [(false, true), (true, false), (true, false), (true, false)];
        let attempts: Vec<AttemptRecord> = looks
            .iter()
            .enumerate()
            .map(|(i, &(c, t))| attempt(i, 0, true, Some(look(c, t))))
            .collect();
        let results = RunResults {
            format_version: RESULTS_FORMAT_VERSION,
            run: RunInfo {
                scenario: Scenario::Scattered,
                grasp_source: "analytic".into(),
                grasp_source_detail: String::new(),
                rounds: 1,
                seed: 0,
                objects: "procedural".into(),
                library_size: 1,
                packing: None,
                arrival: None,
            },
            summary: summarize(
                &attempts,
                &[round(0, 4, 4)],
                false,
                &ScenarioConfig::default(),
                0,
            ),
            attempts,
            rounds: vec![round(0, 4, 4)],
            config: SimConfig::default(),
            recognition: None,
            arrival_evaluation: None,
            wall: RunWall::default(),
        };
        let c = results.learning_curve(2);
        assert_eq!(
            c.accuracy_windowed,
            [(1.0, 0.0), (2.0, 0.5), (3.0, 1.0), (4.0, 1.0)]
        );
        assert_eq!(
            c.teacher_cumulative,
            [(1.0, 1.0), (2.0, 0.5), (3.0, 1.0 / 3.0), (4.0, 0.25)]
        );
        assert_eq!(results.first_looks().len(), 4);
    }
}
