//! How the robot asks a grasp source: [`ranked_grasps`] (the source's best grasps for the full
//! stroke, then for each narrower fallback opening) and [`checked_grasps`] (the proposals checked
//! against the close-up's depth first, as the run's [`ProposalCheck`] says). The robot's and
//! `lgdm sim grasp-data`'s one way to ask a source.

use lgdm_pointcloud::grasp::GraspSpec;
use lgdm_pointcloud::grasp::analytic::{CheckedProposal, check_proposals_scored};
use lgdm_pointcloud::grasp::decode::{DecodedGrasp, GraspDecodeParams};

use crate::grasping::source::{
    AnalyticSource, GraspQuery, GraspSource, ProposalCheck, SourceError,
};
use crate::perception::ObjectView;

/// The grippers a source is asked with, in turn, until it finds a grasp: the full stroke, then
/// each narrower opening of `fallback_openings_m` (wider ones are skipped).
fn stroke_then_fallbacks<'a>(
    gripper: &'a GraspSpec,
    fallback_openings_m: &'a [f32],
) -> impl Iterator<Item = GraspSpec> + 'a {
    let narrower = fallback_openings_m
        .iter()
        .copied()
        .filter(|w| *w < gripper.max_opening_m);
    std::iter::once(gripper.max_opening_m)
        .chain(narrower)
        .map(|max_opening_m| GraspSpec {
            max_opening_m,
            ..*gripper
        })
}

/// The query of `view`'s close-up for `gripper`.
fn query<'a>(
    view: &'a ObjectView,
    gripper: &'a GraspSpec,
    decode: &'a GraspDecodeParams,
) -> GraspQuery<'a> {
    GraspQuery {
        crop: &view.crop,
        intrinsics: &view.shot.camera.intrinsics,
        gripper,
        decode,
    }
}

/// `source`'s `k` best grasps on `view` for `gripper`, maps decoded with `decode` (the run's
/// `[attempt.decode]`); when it finds none for the full stroke, it is asked again for each
/// narrower opening of `fallback_openings_m` in turn (an attempt opens the fingers to the
/// grasp's width plus a margin, not to the stroke). The robot's and `lgdm sim grasp-data`'s one
/// way to ask a source.
pub fn ranked_grasps(
    source: &mut dyn GraspSource,
    view: &ObjectView,
    gripper: &GraspSpec,
    k: usize,
    fallback_openings_m: &[f32],
    decode: &GraspDecodeParams,
) -> Result<Vec<DecodedGrasp>, SourceError> {
    let mut grasps = Vec::new();
    for spec in stroke_then_fallbacks(gripper, fallback_openings_m) {
        grasps = source.grasps(&query(view, &spec, decode), k)?;
        if !grasps.is_empty() {
            break;
        }
    }
    Ok(grasps)
}

/// Proposals a source is asked for, per grasp wanted, when they are checked before planning
/// ([`checked_grasps`]): room for the check to refuse some.
pub const CHECK_POOL: usize = 4;

/// What [`checked_grasps`] found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckedGrasps {
    /// At most `k` grasps that passed, best first (refined ones as refined).
    pub grasps: Vec<DecodedGrasp>,
    /// Proposals the check looked at.
    pub checked: usize,
    /// Of those, refused.
    pub refused: usize,
}

/// How many times [`CHECK_POOL`] proposals per grasp wanted the source is asked for when the check
/// refused all of the first ones and
/// [`crate::grasping::attempt::AttemptConfig::widen_when_refused`] is set.
pub const WIDEN_POOL: usize = 4;

/// [`ranked_grasps`] with each proposal checked against the close-up's depth as `check` says
/// ([`ProposalCheck`]): the source is asked for `k ×` [`CHECK_POOL`] proposals, they are checked
/// in rank order ([`check_proposals_scored`] with the analytic source's parameters) and the
/// first `k` that pass are kept, in their order (`refine-ranked`: in the order of their
/// analytic quality) and, with `refine-first` and `refine-ranked`, followed by the refused ones
/// as proposed. With `widen` (the run's `widen_when_refused`), when every proposal is refused
/// the source is asked once more for [`WIDEN_POOL`] times as many, decoded with half the
/// quality threshold and half the peak distance, and those are checked before the refused
/// ones are kept. When none is kept for the full stroke, the source is asked again for each of
/// `fallback_openings_m` as [`ranked_grasps`] does. `contacts` is [`ranked_grasps`] itself
/// (nothing checked).
#[allow(clippy::too_many_arguments)]
pub fn checked_grasps(
    source: &mut dyn GraspSource,
    view: &ObjectView,
    gripper: &GraspSpec,
    k: usize,
    fallback_openings_m: &[f32],
    decode: &GraspDecodeParams,
    check: ProposalCheck,
    widen: bool,
) -> Result<CheckedGrasps, SourceError> {
    let refine = match check {
        ProposalCheck::Contacts => {
            let grasps = ranked_grasps(source, view, gripper, k, fallback_openings_m, decode)?;
            return Ok(CheckedGrasps {
                grasps,
                ..CheckedGrasps::default()
            });
        }
        ProposalCheck::Antipodal => false,
        ProposalCheck::Refine | ProposalCheck::RefineFirst | ProposalCheck::RefineRanked => true,
    };
    let keep_refused = matches!(
        check,
        ProposalCheck::RefineFirst | ProposalCheck::RefineRanked
    );
    let params = AnalyticSource::new().params;
    let wide = GraspDecodeParams {
        quality_threshold: decode.quality_threshold / 2.0,
        min_distance_px: decode.min_distance_px / 2,
        ..*decode
    };
    let mut out = CheckedGrasps::default();
    for spec in stroke_then_fallbacks(gripper, fallback_openings_m) {
        let pool = k.saturating_mul(CHECK_POOL);
        // Checks `proposals`, counting what it looked at and refused.
        let mut check_all = |proposals: &[DecodedGrasp]| {
            let passed = check_proposals_scored(
                &view.crop,
                &view.shot.camera.intrinsics,
                &spec,
                &params,
                proposals,
                refine,
            )?;
            out.checked += passed.len();
            out.refused += passed.iter().filter(|g| g.is_none()).count();
            Ok::<_, SourceError>(passed)
        };
        let proposals = source.grasps(&query(view, &spec, decode), pool)?;
        let mut passed = check_all(&proposals)?;
        if widen && !proposals.is_empty() && passed.iter().all(Option::is_none) {
            let more =
                source.grasps(&query(view, &spec, &wide), pool.saturating_mul(WIDEN_POOL))?;
            passed = check_all(&more)?.into_iter().chain(passed).collect();
        }
        let mut kept: Vec<(usize, CheckedProposal)> = passed
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.map(|c| (i, c)))
            .collect();
        if check == ProposalCheck::RefineRanked {
            // Best analytic quality first; the proposal's rank breaks ties.
            kept.sort_by(|(i, a), (j, b)| {
                b.analytic_quality
                    .total_cmp(&a.analytic_quality)
                    .then(i.cmp(j))
            });
        }
        let refused = proposals
            .iter()
            .zip(passed.iter().skip(passed.len() - proposals.len()))
            .filter(|(_, g)| keep_refused && g.is_none())
            .map(|(p, _)| *p);
        out.grasps = kept
            .into_iter()
            .map(|(_, c)| c.grasp)
            .chain(refused)
            .take(k)
            .collect();
        if !out.grasps.is_empty() {
            break;
        }
    }
    Ok(out)
}
