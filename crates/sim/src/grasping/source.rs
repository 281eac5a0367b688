//! Grasp sources: what proposes grasps on an object-centred crop. One small trait,
//! [`GraspSource`], at the seam between perception and the robot; grasps come back in crop
//! pixels with the conventions of [`lgdm_pointcloud::grasp::decode`] (centre, angle θ
//! counter-clockwise on screen, opening and jaw in crop pixels, quality), best first, and the
//! robot places them with [`crate::perception::ObjectView::grasp_in_world`].
//!
//! - [`AnalyticSource`] (`analytic`): antipodal grasps from the crop's depth image
//!   ([`lgdm_pointcloud::grasp::analytic`]).
//! - [`RandomSource`] (`random`): a baseline — a random object pixel, a random angle and a random
//!   opening within the stroke, seeded.
//! - [`FixedSource`] (tests, benchmarks, replays): proposals given beforehand.
//! - `network`: the grasp autoencoder implements this trait in the bridge, behind its `ae`
//!   feature (`lgdm_pybridge::ae::robot::NetworkSource`, loaded once per run; the crop → maps →
//!   decoded grasps in crop pixels is `lgdm_pybridge::ae::grasps`), so this crate never needs
//!   torch.
//!
//! The built-in sources by name: [`builtin_source`]. How a source's proposals are checked
//! before the robot plans them — each source names its default — is a [`ProposalCheck`]
//! (applied by [`crate::grasping::proposals`]).
//!
//! ```
//! use lgdm_pointcloud::crop::ObjectCrop;
//! use lgdm_pointcloud::grasp::decode::InputCrop;
//! use lgdm_pointcloud::grasp::GraspSpec;
//! use lgdm_pointcloud::render::Intrinsics;
//! use lgdm_sim::grasping::source::{GraspQuery, GraspSource, RandomSource};
//! // A 64 px crop of a table 0.5 m away with a 2 cm tall square in the middle.
//! let n = 64;
//! let depth_m = (0..n * n)
//!     .map(|i| if (24..40).contains(&(i % n)) && (24..40).contains(&(i / n)) { 0.48 } else { 0.5 })
//!     .collect();
//! let crop = ObjectCrop {
//!     size_px: n as u32,
//!     rgb: vec![[0; 3]; n * n],
//!     depth_m,
//!     window: InputCrop::IDENTITY,
//!     table_depth_m: 0.5,
//! };
//! let intrinsics = Intrinsics::centered(64, 64, 100.0);
//! let gripper = GraspSpec::default();
//! let decode = Default::default();
//! let query = GraspQuery { crop: &crop, intrinsics: &intrinsics, gripper: &gripper, decode: &decode };
//! let mut random = RandomSource::new(7);
//! let grasps = random.grasps(&query, 3).unwrap();
//! assert_eq!(grasps.len(), 3);
//! assert!(grasps.iter().all(|g| (24.0..40.0).contains(&g.center_px[0])));
//! assert!(grasps[0].quality >= grasps[1].quality);
//! ```

use lgdm_base::seed::derive_seed;
use lgdm_pointcloud::crop::ObjectCrop;
use lgdm_pointcloud::grasp::GraspSpec;
use lgdm_pointcloud::grasp::analytic::{AnalyticError, AnalyticParams, analytic_grasps};
use lgdm_pointcloud::grasp::decode::{DecodedGrasp, GraspDecodeParams};
use lgdm_pointcloud::render::Intrinsics;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use serde::{Deserialize, Serialize};

/// What a grasp source is asked about: one object-centred crop.
#[derive(Debug, Clone, Copy)]
pub struct GraspQuery<'a> {
    /// The crop (224 px of 0.22 m by default): colour, depth (m) and where it sits in its frame.
    pub crop: &'a ObjectCrop,
    /// Intrinsics of the frame the crop was cut from (its `window` maps crop px to that frame).
    pub intrinsics: &'a Intrinsics,
    /// The gripper (stroke, finger width and length, friction).
    pub gripper: &'a GraspSpec,
    /// How a source that decodes grasp maps turns them into grasps: the run's
    /// `[attempt.decode]` (quality threshold, peak distance, smoothing). The count is the `k`
    /// asked for and the jaw the source's own (a checkpoint's); the analytic and random sources
    /// have no maps and ignore it.
    pub decode: &'a GraspDecodeParams,
}

impl GraspQuery<'_> {
    /// Crop pixels per metre at optical depth `depth_m`.
    pub fn crop_px_per_m(&self, depth_m: f32) -> f32 {
        self.intrinsics.fx / (depth_m * self.crop.window.image_px_per_map_px)
    }
}

/// Why a source gave no answer (an empty list is an answer: no grasp found).
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The analytic search failed.
    #[error("analytic grasps: {0}")]
    Analytic(#[from] AnalyticError),
    /// A saved state that is not this source's ([`GraspSource::restore`]).
    #[error("cannot restore the source's state: {0}")]
    State(String),
    /// The crop is malformed (buffer sizes, non-finite fields).
    #[error("bad crop: {0}")]
    BadCrop(String),
    /// Any other source's failure (e.g. the network's bridge), with the source's name and the
    /// error it gave (kept as the source of this one).
    #[error("the {source_name} source failed")]
    Failed {
        /// The source.
        source_name: String,
        /// What went wrong.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// Proposes grasps on an object-centred crop.
pub trait GraspSource {
    /// The source's name as the cli spells it (`analytic`, `random`, `network`).
    fn name(&self) -> &str;

    /// At most `k` grasps on the crop, best first (crop pixels, decode conventions). Same
    /// inputs and same internal state give the same grasps.
    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError>;

    /// The source's state between rounds, when it has one that later grasps depend on (a
    /// random stream's position), for a run that is resumed ([`GraspSource::restore`]).
    fn state(&self) -> Option<serde_json::Value> {
        None
    }

    /// Continues from a [`GraspSource::state`] of a source built the same way.
    fn restore(&mut self, _state: &serde_json::Value) -> Result<(), SourceError> {
        Ok(())
    }

    /// How the robot checks this source's proposals against the close-up's depth when the run does
    /// not say ([`crate::grasping::attempt::AttemptConfig::proposal_check`]): `contacts` (nothing
    /// before the planner's own check) by default.
    fn proposal_check(&self) -> ProposalCheck {
        ProposalCheck::Contacts
    }

    /// What a run records about the source beside its name (e.g. the network's checkpoint);
    /// the name by default.
    fn describe(&self) -> String {
        self.name().to_string()
    }
}

/// How a grasp source's proposals are checked against the close-up's depth before they are
/// planned ([`crate::grasping::proposals::checked_grasps`]); the planner's contact check
/// ([`crate::grasping::attempt::GraspPlan::reaches_contacts`]) follows in every case. A proposal
/// that fails is dropped and the next one taken — never another source's grasp. Each source
/// names its own default ([`GraspSource::proposal_check`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProposalCheck {
    /// No check before planning (the planner's contact check only).
    #[default]
    Contacts,
    /// The analytic source's test at the proposal's own centre and axis
    /// ([`lgdm_pointcloud::grasp::analytic::check_proposals`]): fingers closing from the full
    /// opening meet material on both sides within the friction cone, both finger lanes clear,
    /// the jaw covered, the palm clear. A proposal that passes is tried as proposed.
    Antipodal,
    /// As `antipodal`, and a proposal that passes is moved to its contacts' midpoint, its axis
    /// squared to the contact walls and its opening set to the contacts' distance (the
    /// proposal chooses where and which way; the depth, how wide).
    Refine,
    /// As `refine`, but the proposals the check refuses are not dropped: they follow the
    /// refined ones, as proposed and in their order (the planner's contact check still applies).
    /// Where the depth test finds nothing (flat or thin objects the analytic source cannot
    /// grasp either) the proposals are tried as they are.
    #[serde(rename = "refine-first")]
    RefineFirst,
    /// As `refine-first`, but the proposals that pass are tried in the order of the analytic
    /// source's quality where they settled (safe grasps first; its stability term prefers
    /// centres near the object's centroid), the proposal's rank breaking ties: the network
    /// chooses where to look, the depth which of those places first.
    #[serde(rename = "refine-ranked")]
    RefineRanked,
}

impl ProposalCheck {
    /// The word the option and the config spell.
    pub fn word(self) -> &'static str {
        match self {
            ProposalCheck::Contacts => "contacts",
            ProposalCheck::Antipodal => "antipodal",
            ProposalCheck::Refine => "refine",
            ProposalCheck::RefineFirst => "refine-first",
            ProposalCheck::RefineRanked => "refine-ranked",
        }
    }
}

/// Opening axes the robot's analytic source tries per centre: every 5° (the labeller's 12, every
/// 15°, leave a box up to 7.5° off its short axis, which widens a 20 cm wide cereal box's
/// cross-section by ~2.6 cm: more than the 85 mm stroke has to spare over its 6 cm depth).
pub const ROBOT_NUM_ANGLES: usize = 36;

/// Antipodal grasps from the crop's depth image ([`analytic_grasps`]). The search is a pure
/// function of the query, so the source remembers its last [`ANALYTIC_CACHE_SIZE`] answers and
/// gives them again for a query equal in every byte (crop, intrinsics, gripper, `k`): on a
/// cluttered table the robot looks at every object before each attempt, and the ones nothing
/// touched look the same as before.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticSource {
    /// Search parameters (`num_grasps` is replaced by the `k` asked for; default: the
    /// labeller's, with [`ROBOT_NUM_ANGLES`] axes).
    pub params: AnalyticParams,
    answers: Answers,
}

/// How many answers an [`AnalyticSource`] remembers.
pub const ANALYTIC_CACHE_SIZE: usize = 16;

/// Queries and their answers, most recent last.
#[derive(Debug, Clone, Default)]
struct Answers(Vec<Answer>);

#[derive(Debug, Clone)]
struct Answer {
    crop: ObjectCrop,
    intrinsics: Intrinsics,
    gripper: GraspSpec,
    params: AnalyticParams,
    grasps: Vec<DecodedGrasp>,
}

impl PartialEq for Answers {
    /// What a source remembers never makes it another source.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Default for AnalyticSource {
    fn default() -> Self {
        Self {
            params: AnalyticParams {
                num_angles: ROBOT_NUM_ANGLES,
                ..AnalyticParams::default()
            },
            answers: Answers::default(),
        }
    }
}

impl AnalyticSource {
    /// With the default parameters.
    pub fn new() -> Self {
        Self::default()
    }
}

impl GraspSource for AnalyticSource {
    fn name(&self) -> &str {
        "analytic"
    }

    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        if k == 0 {
            return Ok(Vec::new());
        }
        let params = AnalyticParams {
            num_grasps: k,
            ..self.params
        };
        let known = self.answers.0.iter().position(|a| {
            a.crop == *query.crop
                && a.intrinsics == *query.intrinsics
                && a.gripper == *query.gripper
                && a.params == params
        });
        if let Some(i) = known {
            let answer = self.answers.0.remove(i);
            let grasps = answer.grasps.clone();
            self.answers.0.push(answer);
            return Ok(grasps);
        }
        let grasps = analytic_grasps(query.crop, query.intrinsics, query.gripper, &params)?;
        if self.answers.0.len() >= ANALYTIC_CACHE_SIZE {
            self.answers.0.remove(0);
        }
        self.answers.0.push(Answer {
            crop: query.crop.clone(),
            intrinsics: *query.intrinsics,
            gripper: *query.gripper,
            params,
            grasps: grasps.clone(),
        });
        Ok(grasps)
    }
}

/// Proposals given beforehand, the same for every crop: the first `k` of them, in order. A
/// stand-in for a learnt source in tests and benchmarks (what the robot's checks do with a
/// proposal), and a way to replay grasps recorded elsewhere.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FixedSource(pub Vec<DecodedGrasp>);

impl GraspSource for FixedSource {
    fn name(&self) -> &str {
        "fixed"
    }

    fn grasps(
        &mut self,
        _query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        Ok(self.0.iter().copied().take(k).collect())
    }
}

/// The random baseline: each grasp is centred on a uniformly drawn object pixel of the crop (a
/// pixel at least [`RandomSource::min_height_m`] nearer than the table), with a uniform angle
/// and a uniform opening in (0, stroke]; qualities are uniform and sorted. Seeded: the same seed
/// and the same queries give the same grasps.
#[derive(Debug, Clone)]
pub struct RandomSource {
    rng: ChaCha8Rng,
    /// A crop pixel is on an object when it is this much nearer than the table (m; default
    /// 0.005, as segmentation).
    pub min_height_m: f32,
}

impl RandomSource {
    /// A random source seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            min_height_m: 0.005,
        }
    }
}

pub(crate) fn check_crop(crop: &ObjectCrop) -> Result<(), SourceError> {
    let n = crop.size_px as usize;
    if crop.depth_m.len() != n * n {
        return Err(SourceError::BadCrop(format!(
            "depth has {} values for {n}×{n} px",
            crop.depth_m.len()
        )));
    }
    if !(crop.table_depth_m.is_finite() && crop.table_depth_m > 0.0) {
        return Err(SourceError::BadCrop(format!(
            "table depth {}",
            crop.table_depth_m
        )));
    }
    let s = crop.window.image_px_per_map_px;
    if !(s.is_finite() && s > 0.0) {
        return Err(SourceError::BadCrop(format!("scale {s}")));
    }
    Ok(())
}

impl GraspSource for RandomSource {
    fn name(&self) -> &str {
        "random"
    }

    fn state(&self) -> Option<serde_json::Value> {
        Some(serde_json::json!({ "word_pos": self.rng.get_word_pos().to_string() }))
    }

    fn restore(&mut self, state: &serde_json::Value) -> Result<(), SourceError> {
        let pos = state["word_pos"]
            .as_str()
            .and_then(|s| s.parse::<u128>().ok())
            .ok_or_else(|| SourceError::State(format!("not a random source's state: {state}")))?;
        self.rng.set_word_pos(pos);
        Ok(())
    }

    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        let crop = query.crop;
        check_crop(crop)?;
        let limit = crop.table_depth_m - self.min_height_m;
        let object: Vec<usize> = crop
            .depth_m
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_finite() && **d > 0.0 && **d < limit)
            .map(|(i, _)| i)
            .collect();
        if object.is_empty() || k == 0 {
            return Ok(Vec::new());
        }
        let n = crop.size_px as usize;
        let stroke = query.gripper.max_opening_m;
        let mut out: Vec<DecodedGrasp> = (0..k)
            .map(|_| {
                let i = object[self.rng.random_range(0..object.len())];
                let px_per_m = query.crop_px_per_m(crop.depth_m[i]);
                let angle = self
                    .rng
                    .random_range(-std::f32::consts::FRAC_PI_2..std::f32::consts::FRAC_PI_2);
                let opening_m = stroke * (1.0 - self.rng.random::<f32>());
                let quality = 1.0 - self.rng.random::<f32>();
                DecodedGrasp {
                    center_px: [(i % n) as f32, (i / n) as f32],
                    angle,
                    width_px: opening_m * px_per_m,
                    jaw_px: query.gripper.finger_width_m * px_per_m,
                    quality,
                }
            })
            .collect();
        // Best first; a stable sort keeps the draw order among equal qualities.
        out.sort_by(|a, b| b.quality.total_cmp(&a.quality));
        Ok(out)
    }
}

/// Seed tag of the random grasp source.
const TAG_RANDOM_SOURCE: u64 = 0x5133_0002;

/// A grasp source name that is not built in (nor `network`, the bridge's).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown grasp source `{0}` (known: analytic, random, network)")]
pub struct UnknownSource(pub String);

/// A built-in grasp source by name: `analytic` or `random` (seeded from the run's seed).
/// `network` is `lgdm_pybridge::ae::robot::NetworkSource` (feature `ae`).
pub fn builtin_source(name: &str, seed: u64) -> Result<Box<dyn GraspSource>, UnknownSource> {
    match name {
        "analytic" => Ok(Box::new(AnalyticSource::new())),
        "random" => Ok(Box::new(RandomSource::new(derive_seed(
            seed,
            TAG_RANDOM_SOURCE,
            0,
            0,
        )))),
        other => Err(UnknownSource(other.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lgdm_pointcloud::grasp::decode::InputCrop;

    /// A 96 px crop of a table 0.5 m away with a 2 cm tall box of `side` px in the middle.
    fn crop(side: usize) -> ObjectCrop {
        let n = 96;
        let (lo, hi) = (48 - side / 2, 48 + side / 2);
        ObjectCrop {
            size_px: n as u32,
            rgb: vec![[90; 3]; n * n],
            depth_m: (0..n * n)
                .map(|i| {
                    let inside = (lo..hi).contains(&(i % n)) && (lo..hi).contains(&(i / n));
                    if inside { 0.48 } else { 0.5 }
                })
                .collect(),
            window: InputCrop::IDENTITY,
            table_depth_m: 0.5,
        }
    }

    #[test]
    fn a_remembered_answer_is_the_searchs_answer_and_other_queries_are_searched() {
        let intrinsics = Intrinsics::centered(96, 96, 200.0);
        let gripper = GraspSpec::default();
        let ask = |source: &mut AnalyticSource, crop: &ObjectCrop, k: usize| {
            let query = GraspQuery {
                crop,
                intrinsics: &intrinsics,
                gripper: &gripper,
                decode: &Default::default(),
            };
            source.grasps(&query, k).unwrap()
        };
        let (small, large) = (crop(16), crop(24));
        let mut source = AnalyticSource::new();
        let first = ask(&mut source, &small, 3);
        assert!(!first.is_empty());
        assert_eq!(source.answers.0.len(), 1);
        assert_eq!(ask(&mut source, &small, 3), first);
        assert_eq!(
            source.answers.0.len(),
            1,
            "the same query is answered again"
        );
        // Another crop, another k: searched, each equal to a fresh source's answer.
        let other = ask(&mut source, &large, 3);
        assert_ne!(other, first);
        assert_eq!(other, ask(&mut AnalyticSource::new(), &large, 3));
        assert_eq!(
            ask(&mut source, &small, 1),
            ask(&mut AnalyticSource::new(), &small, 1)
        );
        assert_eq!(source.answers.0.len(), 3);
        // Bounded: the oldest answers go.
        for side in 10..10 + ANALYTIC_CACHE_SIZE {
            ask(&mut source, &crop(2 * side), 1);
        }
        assert_eq!(source.answers.0.len(), ANALYTIC_CACHE_SIZE);
    }
}
