//! The analytic grasp source: antipodal parallel-jaw grasps computed from the depth image of an
//! object-centred crop ([`crate::crop`]) — what a robot sees, no mesh and no labels — returned
//! as [`DecodedGrasp`]s in the grasp network's conventions, so that the robot places either
//! source's grasps with [`super::decode::grasp_pose`] and the crop's `window`.
//!
//! The algorithm mirrors the geometric labeller ([`super::label`]) on a height map:
//!
//! 1. **Points and table.** Every crop pixel with depth becomes a 3-D point on its camera ray
//!    (the crop's `window` and the frame's [`Intrinsics`], so perspective is exact whatever the
//!    camera). At a depth jump, where resampling mixes foreground and background, a pixel in
//!    the nearer part of the jump keeps its depth (it may be a steep surface seen edge-on) and
//!    the others join the farther surface, so that no point floats in between. The table is
//!    a seeded RANSAC plane through the crop's table point (`table_depth_m` on the centre ray)
//!    and two points no more than 4 cm in front of it, refined by least squares: a tilted
//!    camera still gives true heights.
//! 2. **Height map.** The points are splatted, each over its pixel's footprint, into an
//!    orthographic height map on the table (cells of [`AnalyticParams::cell_m`], highest
//!    point per cell). A hole among known cells takes the lowest of its neighbours; the rest
//!    of what no point reached (the table hidden behind the object) is free table. Cells
//!    outside the crop and around an object cut off by the crop's edge are unknown: no
//!    contact or finger lane may rest on them. Under the visible surface everything is solid
//!    (a 2.5-D world).
//! 3. **Candidates.** Centres on the object nearest the crop centre (cells at least
//!    [`AnalyticParams::min_height_m`] above the table, one every
//!    [`AnalyticParams::grid_step_m`]) × [`AnalyticParams::num_angles`] opening axes, each tried
//!    at the labeller's grasp heights below the top at the centre ([`GRASP_DEPTH_FRACTIONS`] of
//!    `finger_length_m`, never below [`AnalyticParams::min_grasp_height_m`]). At a height
//!    `z_g`: fingers coming in from the full opening meet the outermost material taller than
//!    `z_g` on each side (the contacts); the opening plus both clearances must fit
//!    `max_opening_m`; the height map's 3-D normals at the contacts must lie inside the
//!    friction cone (`atan(friction)`) around the closing axis; in both finger lanes, at
//!    [`AnalyticParams::jaw_samples`] offsets across the finger width, out to the full opening
//!    plus clearance and at least a finger thickness beyond the contact, material may stick
//!    out at most [`AnalyticParams::lane_tolerance_m`] beyond the contact (the labeller's
//!    test, measured to a fraction of a cell); the palm (`finger_length_m` above `z_g`) must
//!    clear everything between the fingers; and the slice must reach the contact over most
//!    of the jaw ([`AnalyticParams::min_jaw_coverage`]). A candidate that passes at some height
//!    is moved to the midpoint of its contacts, its axis turned square to the contact walls
//!    (their slope across the jaw), and must pass there again.
//! 4. **Ranking.** *Safe* grasps — lanes within [`AnalyticParams::safe_lane_tolerance_m`],
//!    the opening [`AnalyticParams::opening_margin_m`] short of the gripper's, normals within
//!    [`AnalyticParams::safe_cone_fraction`] of the cone — come first with quality in
//!    [0.5, 1]; the others follow in (0, 0.5). Within a tier, quality combines normal
//!    alignment, jaw coverage, stability (a Gaussian of the centre's distance to the object's
//!    centroid), depth support (the share of grasp heights that pass) and lane clearance.
//!    Near-duplicates (centres within [`AnalyticParams::suppress_radius_m`] and axes within
//!    [`AnalyticParams::suppress_angle_rad`] of a better grasp) are dropped; ties are broken
//!    by position and angle, so the same input gives the same grasps, bit for bit.
//!
//! What it cannot see: undercuts and overhangs (the wall of a glass below its flared rim, the
//! narrowing under an apple's equator, a handle's hole) are filled in the height map, so a
//! contact below the visible edge is taken to be on a vertical wall; thin rims are measured
//! at the height map's resolution (a cell, about a millimetre); and of an object taller than
//! the crop shows (a standing cereal box's top fills it) only the part in view is grasped.
//!
//! ```
//! use lgdm_pointcloud::crop::{CropSpec, crop_largest_object};
//! use lgdm_pointcloud::grasp::analytic::{AnalyticParams, analytic_grasps};
//! use lgdm_pointcloud::grasp::cornell::table_mesh;
//! use lgdm_pointcloud::grasp::GraspSpec;
//! use lgdm_pointcloud::math::{Pose, look_at};
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};
//! use lgdm_pointcloud::segment::SegmentParams;
//!
//! let camera = Camera::new(Intrinsics::kinect_vga(), look_at([0.0, 0.0, 0.5], [0.0; 3], [0.0, 1.0, 0.0]));
//! let (table, can) = (table_mesh(), procedural_object("can", 0, 1).unwrap());
//! let frame = render(&camera, &[
//!     RenderItem { mesh: &table, world_from_object: Pose::identity(), label: 1 },
//!     RenderItem { mesh: &can, world_from_object: Pose::identity(), label: 2 },
//! ]);
//! let found = crop_largest_object(&frame, &camera.intrinsics, &SegmentParams::default(), &CropSpec::default()).unwrap();
//! let grasps = analytic_grasps(&found.crop, &camera.intrinsics, &GraspSpec::default(), &AnalyticParams::default()).unwrap();
//! // A can (6.4–8 cm across) is grasped across its body, near its centre.
//! let best = grasps[0];
//! assert!((best.center_px[0] - 111.5).abs() < 15.0 && (best.center_px[1] - 111.5).abs() < 15.0);
//! assert!(best.quality > 0.0 && best.quality <= 1.0);
//! ```

use std::collections::HashSet;
use std::f32::consts::PI;

use nalgebra::{Matrix3, SymmetricEigen};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::decode::{DecodedGrasp, wrap_angle};
use super::label::GraspSpec;
use crate::crop::ObjectCrop;
use crate::math::{add, cross, dot, median, norm, normalize, scale, splitmix64, sub};
use crate::render::Intrinsics;

/// Grasp heights tried below the top at the grasp centre, as fractions of `finger_length_m`
/// (the labeller's, [`super::label::evaluate_grasp`]).
pub const GRASP_DEPTH_FRACTIONS: [f32; 4] = [1.0, 2.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];

/// Largest height map side, cells.
const MAX_CELLS: usize = 2048;

/// RANSAC hypotheses of the table fit.
const TABLE_HYPOTHESES: usize = 128;

/// An unknown height-map cell with at least this many known neighbours (of 8) is a sampling
/// gap and takes their lowest height.
const HOLE_NEIGHBOURS: usize = 5;

/// The slice reaches a contact in a row across the jaw when its outermost material there is
/// within this distance inside the contact, metres.
const COVERAGE_BAND_M: f32 = 0.003;

/// At a depth jump, pixels within this share of the jump from the nearer surface keep their
/// depth; the others join the farther surface.
const NEAR_SHARE: f32 = 0.35;

/// Components of fewer cells are fragments, not the object.
const MIN_OBJECT_CELLS: usize = 50;

/// Cells within this many cells of an object cut off by the crop's edge are unknown.
const CUT_RADIUS: usize = 2;

/// Table hypotheses are drawn from points at most this much nearer than the crop's table
/// point, metres.
const POOL_DEPTH_M: f32 = 0.04;

/// Fewest inliers (of the coarse grid) a table plane needs; fewer: the plane facing the
/// camera through the crop's table point.
const MIN_TABLE_INLIERS: usize = 30;

/// Seed of the table fit's samples (fixed: same crop, same plane).
const TABLE_SEED: u64 = 0x7AB1_E5EE_D000_0001;

/// How analytic grasps are searched and ranked. Lengths in metres, angles in radians.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalyticParams {
    /// Most grasps returned, best first (default: 10).
    pub num_grasps: usize,
    /// Spacing of the candidate centres on the object (default: 0.004).
    pub grid_step_m: f32,
    /// Opening axes tried per centre, evenly over 180° (default: 12, every 15°).
    pub num_angles: usize,
    /// A height-map cell belongs to an object when it is this far above the table (default:
    /// 0.005, as segmentation).
    pub min_height_m: f32,
    /// Grasp heights are never lower than this above the table (default: 0.008, as the
    /// labeller).
    pub min_grasp_height_m: f32,
    /// Side of a height-map cell (default: 0.001, about a crop pixel at the default crop).
    pub cell_m: f32,
    /// Thickness of a finger along the closing axis: its lane reaches at least this far beyond
    /// the contact plus clearance (default: 0.01).
    pub finger_thickness_m: f32,
    /// Material in a finger lane up to this far beyond the contact is tolerated (default:
    /// 0.002, as the labeller).
    pub lane_tolerance_m: f32,
    /// Grasps whose lanes hold at most this much (and whose opening keeps
    /// `opening_margin_m` to spare) are *safe* and rank before all others (default: 0.001).
    pub safe_lane_tolerance_m: f32,
    /// Lanes and coverage are sampled at this many offsets across the finger width
    /// (default: 5).
    pub jaw_samples: usize,
    /// The slice must reach the contact in at least this share of the offsets across the
    /// finger width (default: 0.6).
    pub min_jaw_coverage: f32,
    /// A safe grasp's opening plus both clearances fits the gripper with this much to spare,
    /// for the height map's resolution (default: 0.002).
    pub opening_margin_m: f32,
    /// A safe grasp's contact normals lie within this fraction of the friction cone's
    /// half-angle (default: 0.9).
    pub safe_cone_fraction: f32,
    /// The contact normals must lie within this fraction of the friction cone's half-angle
    /// `atan(friction)` (default: 1.0).
    pub friction_cone_fraction: f32,
    /// Width of the Gaussian that scores a centre's distance to the object's centroid
    /// (default: 0.03).
    pub stability_scale_m: f32,
    /// A grasp whose centre lies within this distance of a better one … (default: 0.006)
    pub suppress_radius_m: f32,
    /// … and whose axis is within this angle of it is a near-duplicate and dropped
    /// (default: 15° = 0.2618).
    pub suppress_angle_rad: f32,
    /// Points within this distance of a table-plane hypothesis are its inliers (default:
    /// 0.003).
    pub table_inlier_m: f32,
    /// Depths spanning more than this around a pixel (its 3×3 neighbourhood) mark a depth
    /// jump, where resampling mixes surfaces (default: 0.01).
    pub depth_jump_m: f32,
}

impl Default for AnalyticParams {
    fn default() -> Self {
        Self {
            num_grasps: 10,
            grid_step_m: 0.004,
            num_angles: 12,
            min_height_m: 0.005,
            min_grasp_height_m: 0.008,
            cell_m: 0.001,
            finger_thickness_m: 0.01,
            lane_tolerance_m: 0.002,
            safe_lane_tolerance_m: 0.001,
            jaw_samples: 5,
            min_jaw_coverage: 0.6,
            opening_margin_m: 0.002,
            safe_cone_fraction: 0.9,
            friction_cone_fraction: 1.0,
            stability_scale_m: 0.03,
            suppress_radius_m: 0.006,
            suppress_angle_rad: 15f32.to_radians(),
            table_inlier_m: 0.003,
            depth_jump_m: 0.01,
        }
    }
}

impl AnalyticParams {
    /// Checks the parameters; the error names the first bad field.
    pub fn validate(&self) -> Result<(), AnalyticError> {
        let bad = |field: &'static str, reason: &'static str| {
            Err(AnalyticError::InvalidParam { field, reason })
        };
        let in_range = |v: f32, lo: f32, hi: f32| v.is_finite() && v >= lo && v <= hi;
        if self.num_grasps == 0 {
            return bad("num_grasps", "must be at least 1");
        }
        if !in_range(self.cell_m, 0.0002, 0.01) {
            return bad("cell_m", "must be in [0.0002, 0.01]");
        }
        if !in_range(self.grid_step_m, self.cell_m, 0.05) {
            return bad("grid_step_m", "must be in [cell_m, 0.05]");
        }
        if !(1..=180).contains(&self.num_angles) {
            return bad("num_angles", "must be in 1..=180");
        }
        if !in_range(self.min_height_m, 0.0, 0.1) {
            return bad("min_height_m", "must be in [0, 0.1]");
        }
        if !in_range(self.min_grasp_height_m, 0.0, 0.2) {
            return bad("min_grasp_height_m", "must be in [0, 0.2]");
        }
        if !in_range(self.finger_thickness_m, 0.0, 0.05) {
            return bad("finger_thickness_m", "must be in [0, 0.05]");
        }
        if !in_range(self.lane_tolerance_m, 0.0, 0.01) {
            return bad("lane_tolerance_m", "must be in [0, 0.01]");
        }
        if !in_range(self.safe_lane_tolerance_m, 0.0, self.lane_tolerance_m) {
            return bad("safe_lane_tolerance_m", "must be in [0, lane_tolerance_m]");
        }
        if !(1..=33).contains(&self.jaw_samples) {
            return bad("jaw_samples", "must be in 1..=33");
        }
        if !in_range(self.min_jaw_coverage, 0.0, 1.0) {
            return bad("min_jaw_coverage", "must be in [0, 1]");
        }
        if !in_range(self.opening_margin_m, 0.0, 0.05) {
            return bad("opening_margin_m", "must be in [0, 0.05]");
        }
        if !in_range(self.safe_cone_fraction, 0.0, 1.0) {
            return bad("safe_cone_fraction", "must be in [0, 1]");
        }
        if !(self.friction_cone_fraction.is_finite()
            && self.friction_cone_fraction > 0.0
            && self.friction_cone_fraction <= 1.0)
        {
            return bad("friction_cone_fraction", "must be in (0, 1]");
        }
        if !(self.stability_scale_m.is_finite() && self.stability_scale_m > 0.0) {
            return bad("stability_scale_m", "must be positive and finite");
        }
        if !in_range(self.suppress_radius_m, 0.0, 1.0) {
            return bad("suppress_radius_m", "must be in [0, 1]");
        }
        if !in_range(self.suppress_angle_rad, 0.0, PI / 2.0) {
            return bad("suppress_angle_rad", "must be in [0, π/2]");
        }
        if !in_range(self.table_inlier_m, 0.0001, 0.05) {
            return bad("table_inlier_m", "must be in [0.0001, 0.05]");
        }
        if !(self.depth_jump_m.is_finite() && self.depth_jump_m > 0.0) {
            return bad("depth_jump_m", "must be positive and finite");
        }
        Ok(())
    }
}

/// Why analytic grasps could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalyticError {
    /// An [`AnalyticParams`] field is out of range.
    #[error("invalid analytic grasp parameter `{field}`: {reason}")]
    InvalidParam {
        /// The field.
        field: &'static str,
        /// What it must be.
        reason: &'static str,
    },
    /// The gripper ([`GraspSpec`]) is invalid.
    #[error("invalid gripper: {0}")]
    InvalidGripper(String),
    /// A crop buffer does not hold `size_px × size_px` values.
    #[error("crop `{buffer}` has {len} values, expected {size_px}×{size_px}")]
    CropSize {
        /// Which buffer (`depth_m`, `rgb`).
        buffer: &'static str,
        /// Its length.
        len: usize,
        /// The crop's side, pixels.
        size_px: u32,
    },
    /// A crop field is not finite or out of range.
    #[error("invalid crop `{field}`: {value}")]
    InvalidCrop {
        /// The field (`table_depth_m`, `window.x0_px`, …).
        field: &'static str,
        /// Its value.
        value: f32,
    },
    /// The intrinsics are not a usable pinhole camera.
    #[error("invalid intrinsics: {reason}")]
    InvalidIntrinsics {
        /// What is wrong.
        reason: &'static str,
    },
}

/// One analytic grasp with what the search measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AnalyticGrasp {
    /// The grasp in crop pixels, in the network's conventions.
    pub grasp: DecodedGrasp,
    /// Distance between the contacts, metres.
    pub opening_m: f32,
    /// Height of the top surface at the grasp centre above the table, metres.
    pub top_height_m: f32,
    /// Height of the grasp (finger tips) above the table, metres: the deepest safe height
    /// that passed, else the deepest that passed.
    pub grasp_height_m: f32,
    /// Largest angle between a contact normal and the closing axis, radians.
    pub contact_angle_rad: f32,
    /// Share of the finger width over which the slice reaches the contact, in [0, 1].
    pub jaw_coverage: f32,
    /// Share of the grasp heights tried that passed, in (0, 1].
    pub depth_support: f32,
    /// Distance of the grasp centre to the object's centroid on the table, metres.
    pub centroid_distance_m: f32,
    /// Within the safe lane tolerance, opening margin and cone (quality ≥ 0.5).
    pub safe: bool,
}

/// Analytic grasps for one object-centred crop ([`crate::crop::object_crop`]), best first, at
/// most `params.num_grasps`, in crop pixels (place them with [`super::decode::grasp_pose`] and
/// the crop's `window`). `intrinsics` are those of the frame the crop was cut from: with the
/// `window` they give every crop pixel's ray, so that heights and widths are metric whatever
/// the camera's pose. Grasps of quality ≥ 0.5 are *safe* (see the module docs). A crop with
/// no object on the table gives no grasp; bad parameters or buffers are an error.
pub fn analytic_grasps(
    crop: &ObjectCrop,
    intrinsics: &Intrinsics,
    gripper: &GraspSpec,
    params: &AnalyticParams,
) -> Result<Vec<DecodedGrasp>, AnalyticError> {
    Ok(analytic_grasps_detailed(crop, intrinsics, gripper, params)?
        .into_iter()
        .map(|g| g.grasp)
        .collect())
}

/// [`analytic_grasps`] with the measurements of each grasp.
pub fn analytic_grasps_detailed(
    crop: &ObjectCrop,
    intrinsics: &Intrinsics,
    gripper: &GraspSpec,
    params: &AnalyticParams,
) -> Result<Vec<AnalyticGrasp>, AnalyticError> {
    params.validate()?;
    gripper.validate().map_err(AnalyticError::InvalidGripper)?;
    let camera = CropCamera::new(crop, intrinsics)?;
    let n = crop.size_px as usize;
    let points = crop_points(crop, &camera, params);
    if points.iter().filter(|p| p.is_some()).count() < 3 {
        return Ok(Vec::new());
    }
    let anchor = scale(camera.ray([(n as f32 - 1.0) / 2.0; 2]), crop.table_depth_m);
    let table = fit_table(&points, n, anchor, params);
    let map = HeightMap::build(&points, &table, crop, &camera, params);
    let Some(object) = map.object_nearest_origin(params.min_height_m) else {
        return Ok(Vec::new());
    };
    let search = Search {
        map: &map,
        gripper,
        params,
        centroid: object.centroid,
    };
    let candidates = search.run(&object.cells);
    let jaw_px = gripper.finger_width_m * intrinsics.fx
        / (crop.window.image_px_per_map_px * crop.table_depth_m);
    let mut out = Vec::new();
    for c in candidates {
        if out.len() >= params.num_grasps {
            break;
        }
        if let Some(g) = to_crop(&c, &table, &camera, gripper, jaw_px) {
            out.push(g);
        }
    }
    Ok(out)
}

/// Turns of a proposal's axis tried when refining it ([`check_proposals`]), degrees; the
/// unturned axis first.
pub const REFINE_TURNS_DEG: [f32; 5] = [0.0, -10.0, 10.0, -20.0, 20.0];

/// Shifts of a proposal's centre across its axis tried when refining it, metres; unshifted
/// first.
pub const REFINE_SHIFTS_M: [f32; 5] = [0.0, -0.003, 0.003, -0.006, 0.006];

/// Another source's grasps (a network's proposals, in crop pixels) checked against the crop's
/// depth with the analytic search's own test, each at its own centre and axis: the height map,
/// table and object of [`analytic_grasps_detailed`], then, for a proposal, its centre (the
/// median depth of the 5×5 pixels around it, on its ray, as [`super::decode::grasp_pose`]
/// places it) and axis on the table, evaluated at the grasp heights below the top there
/// (fingers closing from the full opening onto the outermost material, the friction cone at
/// both contacts, both finger lanes clear, the jaw covered, the palm clear).
///
/// `refine = false` (*antipodal*): a proposal that passes is returned unchanged, one that
/// fails is `None`. `refine = true`: the proposal's neighbourhood — its centre shifted up to
/// 6 mm across its axis ([`REFINE_SHIFTS_M`]), its axis turned up to 20°
/// ([`REFINE_TURNS_DEG`]) — is searched as the analytic source searches its grid: each
/// (centre, axis) that passes is moved to the midpoint of its contacts with its axis square to
/// the contact walls and must pass again there; the best of them by the analytic quality
/// replaces the proposal, with its opening the contacts' distance plus both clearances and
/// the proposal's quality (its rank). `None` when nothing in the neighbourhood passes. One
/// entry per proposal, in order.
pub fn check_proposals(
    crop: &ObjectCrop,
    intrinsics: &Intrinsics,
    gripper: &GraspSpec,
    params: &AnalyticParams,
    proposals: &[DecodedGrasp],
    refine: bool,
) -> Result<Vec<Option<DecodedGrasp>>, AnalyticError> {
    Ok(
        check_proposals_scored(crop, intrinsics, gripper, params, proposals, refine)?
            .into_iter()
            .map(|o| o.map(|c| c.grasp))
            .collect(),
    )
}

/// A proposal that passed [`check_proposals_scored`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckedProposal {
    /// The grasp as [`check_proposals`] returns it (the proposal's quality kept).
    pub grasp: DecodedGrasp,
    /// The analytic source's quality where it passed (the refined place, or the proposal's own
    /// centre and axis without `refine`): safe grasps in [0.5, 1], the others below, as the
    /// analytic source ranks its own.
    pub analytic_quality: f32,
}

/// [`check_proposals`] with the analytic quality of each proposal that passed.
pub fn check_proposals_scored(
    crop: &ObjectCrop,
    intrinsics: &Intrinsics,
    gripper: &GraspSpec,
    params: &AnalyticParams,
    proposals: &[DecodedGrasp],
    refine: bool,
) -> Result<Vec<Option<CheckedProposal>>, AnalyticError> {
    params.validate()?;
    gripper.validate().map_err(AnalyticError::InvalidGripper)?;
    let camera = CropCamera::new(crop, intrinsics)?;
    let n = crop.size_px as usize;
    let points = crop_points(crop, &camera, params);
    if proposals.is_empty() || points.iter().filter(|p| p.is_some()).count() < 3 {
        return Ok(vec![None; proposals.len()]);
    }
    let anchor = scale(camera.ray([(n as f32 - 1.0) / 2.0; 2]), crop.table_depth_m);
    let table = fit_table(&points, n, anchor, params);
    let map = HeightMap::build(&points, &table, crop, &camera, params);
    let Some(object) = map.object_nearest_origin(params.min_height_m) else {
        return Ok(vec![None; proposals.len()]);
    };
    let search = Search {
        map: &map,
        gripper,
        params,
        centroid: object.centroid,
    };
    let jaw_px = gripper.finger_width_m * intrinsics.fx
        / (crop.window.image_px_per_map_px * crop.table_depth_m);
    Ok(proposals
        .iter()
        .map(|g| {
            let (c, angle) = on_table(g, crop, &camera, &table)?;
            let top = map.top(c);
            if !refine {
                return search.evaluate(c, angle, top).map(|eval| {
                    let distance = (c[0] - object.centroid[0]).hypot(c[1] - object.centroid[1]);
                    CheckedProposal {
                        grasp: *g,
                        analytic_quality: search.quality(&eval, distance),
                    }
                });
            }
            // The neighbourhood: shifted across the axis, turned about the centre; the best
            // candidate that settles there.
            let across = [-angle.sin(), angle.cos()];
            let settled = REFINE_TURNS_DEG
                .iter()
                .flat_map(|turn| REFINE_SHIFTS_M.iter().map(move |shift| (turn, shift)))
                .filter_map(|(turn, shift)| {
                    let p = [c[0] + across[0] * shift, c[1] + across[1] * shift];
                    let a = (angle + turn.to_radians()).rem_euclid(PI);
                    let moved = search.moved(p, a, map.top(p))?;
                    search.settle(&moved)
                })
                .fold(None::<Candidate>, |best, x| match best {
                    Some(b) if b.quality >= x.quality => Some(b),
                    _ => Some(x),
                })?;
            let out = to_crop(&settled, &table, &camera, gripper, jaw_px)?;
            Some(CheckedProposal {
                grasp: DecodedGrasp {
                    quality: g.quality,
                    ..out.grasp
                },
                analytic_quality: settled.quality,
            })
        })
        .collect())
}

/// A crop-pixel grasp's centre and axis angle (in [0, π)) on the table: the centre on its
/// ray at the median depth of the 5×5 pixels around it; the axis through a second point 8 px
/// along it, on that ray at the centre's height. `None` when no depth is near the centre or a
/// value is not finite.
fn on_table(
    g: &DecodedGrasp,
    crop: &ObjectCrop,
    camera: &CropCamera,
    table: &Table,
) -> Option<([f32; 2], f32)> {
    let n = crop.size_px as i64;
    let [x, y] = g.center_px;
    if !(x.is_finite() && y.is_finite() && g.angle.is_finite()) {
        return None;
    }
    let (xr, yr) = (x.round() as i64, y.round() as i64);
    let mut depths: Vec<f32> = (yr - 2..=yr + 2)
        .flat_map(|yy| (xr - 2..=xr + 2).map(move |xx| (xx, yy)))
        .filter(|&(xx, yy)| xx >= 0 && yy >= 0 && xx < n && yy < n)
        .map(|(xx, yy)| crop.depth_m[(yy * n + xx) as usize])
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    let z = median(&mut depths)?;
    let centre = table.table_point(scale(camera.ray([x, y]), z));
    let step = 8.0;
    let other = [x + step * g.angle.cos(), y - step * g.angle.sin()];
    let ray = camera.ray(other);
    let along = dot(table.up, ray);
    if along.abs() < 1e-6 {
        return None;
    }
    let t = (centre[2] - table.offset_m) / along;
    let far = table.table_point(scale(ray, t));
    let angle = (far[1] - centre[1])
        .atan2(far[0] - centre[0])
        .rem_euclid(PI);
    (centre.iter().all(|v| v.is_finite()) && angle.is_finite())
        .then_some(([centre[0], centre[1]], angle))
}

/// Pinhole rays of crop pixels: crop pixel → frame pixel (the window) → ray.
struct CropCamera {
    k: Intrinsics,
    x0: f32,
    y0: f32,
    s: f32,
}

impl CropCamera {
    fn new(crop: &ObjectCrop, k: &Intrinsics) -> Result<Self, AnalyticError> {
        let n = crop.size_px as usize;
        if n == 0 || n.checked_mul(n) != Some(crop.depth_m.len()) {
            return Err(AnalyticError::CropSize {
                buffer: "depth_m",
                len: crop.depth_m.len(),
                size_px: crop.size_px,
            });
        }
        if crop.rgb.len() != n * n {
            return Err(AnalyticError::CropSize {
                buffer: "rgb",
                len: crop.rgb.len(),
                size_px: crop.size_px,
            });
        }
        let w = &crop.window;
        for (field, value) in [("window.x0_px", w.x0_px), ("window.y0_px", w.y0_px)] {
            if !value.is_finite() {
                return Err(AnalyticError::InvalidCrop { field, value });
            }
        }
        if !(w.image_px_per_map_px.is_finite() && w.image_px_per_map_px > 0.0) {
            return Err(AnalyticError::InvalidCrop {
                field: "window.image_px_per_map_px",
                value: w.image_px_per_map_px,
            });
        }
        if !(crop.table_depth_m.is_finite() && crop.table_depth_m > 0.0) {
            return Err(AnalyticError::InvalidCrop {
                field: "table_depth_m",
                value: crop.table_depth_m,
            });
        }
        if !(k.fx.is_finite() && k.fx > 0.0 && k.fy.is_finite() && k.fy > 0.0) {
            return Err(AnalyticError::InvalidIntrinsics {
                reason: "focal lengths must be positive and finite",
            });
        }
        if !(k.cx.is_finite() && k.cy.is_finite()) {
            return Err(AnalyticError::InvalidIntrinsics {
                reason: "principal point must be finite",
            });
        }
        Ok(Self {
            k: *k,
            x0: w.x0_px,
            y0: w.y0_px,
            s: w.image_px_per_map_px,
        })
    }

    /// Ray (optical z = 1) through crop pixel `p`.
    fn ray(&self, p: [f32; 2]) -> [f32; 3] {
        let u = (p[0] + 0.5) * self.s - 0.5 + self.x0;
        let v = (p[1] + 0.5) * self.s - 0.5 + self.y0;
        [
            (u - self.k.cx) / self.k.fx,
            (v - self.k.cy) / self.k.fy,
            1.0,
        ]
    }

    /// Crop pixel of a camera-frame point (`None` behind the camera).
    fn project(&self, p: [f32; 3]) -> Option<[f32; 2]> {
        if p[2] <= 1e-6 {
            return None;
        }
        let u = self.k.fx * p[0] / p[2] + self.k.cx;
        let v = self.k.fy * p[1] / p[2] + self.k.cy;
        Some([
            (u + 0.5 - self.x0) / self.s - 0.5,
            (v + 0.5 - self.y0) / self.s - 0.5,
        ])
    }
}

/// Camera-frame points of the crop pixels (row-major; `None`: no data).
fn crop_points(
    crop: &ObjectCrop,
    camera: &CropCamera,
    params: &AnalyticParams,
) -> Vec<Option<[f32; 3]>> {
    let n = crop.size_px as usize;
    let d = &crop.depth_m;
    let ok = |z: f32| z.is_finite() && z > 0.0;
    let jump = params.depth_jump_m;
    let mut out = vec![None; n * n];
    for y in 0..n {
        for x in 0..n {
            let z = d[y * n + x];
            if !ok(z) {
                continue;
            }
            let (mut lo, mut hi) = (z, z);
            for yy in y.saturating_sub(1)..=(y + 1).min(n - 1) {
                for xx in x.saturating_sub(1)..=(x + 1).min(n - 1) {
                    let q = d[yy * n + xx];
                    if ok(q) {
                        lo = lo.min(q);
                        hi = hi.max(q);
                    }
                }
            }
            // At a depth jump (the neighbours' depths span more than `depth_jump_m`),
            // resampling mixes the two surfaces. A pixel in the nearer part of the span keeps
            // its depth (it may be a steep surface seen edge-on, such as a sphere's rim); the
            // others are snapped to the farther surface, so that no point floats in between.
            let range = hi - lo;
            let z = if range > jump && z - lo > NEAR_SHARE * range {
                hi
            } else {
                z
            };
            out[y * n + x] = Some(scale(camera.ray([x as f32, y as f32]), z));
        }
    }
    out
}

/// The table plane and a frame on it: `height(p) = up · p + offset_m` (camera frame), axes
/// `ex` (the camera's x on the table) and `ey = up × ex`, origin on the crop centre's ray.
#[derive(Debug, Clone, Copy)]
struct Table {
    up: [f32; 3],
    offset_m: f32,
    ex: [f32; 3],
    ey: [f32; 3],
    origin: [f32; 3],
}

impl Table {
    fn from_plane(up: [f32; 3], offset_m: f32, anchor: [f32; 3]) -> Self {
        let ex = normalize(sub([1.0, 0.0, 0.0], scale(up, up[0])));
        let ey = cross(up, ex);
        // The anchor's foot on the plane.
        let origin = sub(anchor, scale(up, dot(up, anchor) + offset_m));
        Self {
            up,
            offset_m,
            ex,
            ey,
            origin,
        }
    }

    /// `[x, y, height]` on the table of a camera-frame point.
    fn table_point(&self, p: [f32; 3]) -> [f32; 3] {
        let r = sub(p, self.origin);
        [
            dot(r, self.ex),
            dot(r, self.ey),
            dot(self.up, p) + self.offset_m,
        ]
    }

    /// Camera-frame point of table coordinates `[x, y, height]`.
    fn camera_point(&self, t: [f32; 3]) -> [f32; 3] {
        add(
            add(self.origin, scale(self.ex, t[0])),
            add(scale(self.ey, t[1]), scale(self.up, t[2])),
        )
    }
}

/// Seeded RANSAC plane through the anchor (the crop's table point) and two sampled points,
/// facing the camera, refined by least squares on its inliers. Falls back to the plane
/// through the anchor facing the camera's axis.
fn fit_table(
    points: &[Option<[f32; 3]>],
    n: usize,
    anchor: [f32; 3],
    params: &AnalyticParams,
) -> Table {
    let fallback = Table::from_plane([0.0, 0.0, -1.0], anchor[2], anchor);
    let coarse: Vec<[f32; 3]> = (0..n)
        .step_by(4)
        .flat_map(|y| (0..n).step_by(4).map(move |x| y * n + x))
        .filter_map(|i| points[i])
        .collect();
    if coarse.len() < 3 {
        return fallback;
    }
    // Hypotheses: the anchor and two points that may be table (no nearer than
    // POOL_DEPTH_M in front of the anchor's depth: tall objects are not sampled).
    let pool: Vec<[f32; 3]> = coarse
        .iter()
        .copied()
        .filter(|p| p[2] > anchor[2] - POOL_DEPTH_M)
        .collect();
    if pool.len() < 2 {
        return fallback;
    }
    let towards_camera = normalize(scale(anchor, -1.0));
    let mut state = TABLE_SEED;
    let mut next = |len: usize| {
        state = splitmix64(state);
        (state % len as u64) as usize
    };
    let mut best: Option<([f32; 3], f32, usize)> = None;
    for _ in 0..TABLE_HYPOTHESES {
        let (a, b) = (pool[next(pool.len())], pool[next(pool.len())]);
        let normal = cross(sub(a, anchor), sub(b, anchor));
        if norm(normal) < 1e-8 {
            continue;
        }
        let mut up = normalize(normal);
        if dot(up, towards_camera) < 0.0 {
            up = scale(up, -1.0);
        }
        if dot(up, towards_camera) < 0.5 {
            continue;
        }
        let offset = -dot(up, anchor);
        let inliers = coarse
            .iter()
            .filter(|&&p| (dot(up, p) + offset).abs() < params.table_inlier_m)
            .count();
        if best.is_none_or(|(_, _, k)| inliers > k) {
            best = Some((up, offset, inliers));
        }
    }
    let Some((mut up, mut offset, inliers)) = best else {
        return fallback;
    };
    if inliers < MIN_TABLE_INLIERS {
        return fallback;
    }
    // Least squares on the inliers of all points, twice.
    for _ in 0..2 {
        let mut sum = [0.0f64; 3];
        let mut count = 0usize;
        let inlier = |p: &[f32; 3]| (dot(up, *p) + offset).abs() < params.table_inlier_m;
        for p in points.iter().flatten().filter(|p| inlier(p)) {
            for k in 0..3 {
                sum[k] += p[k] as f64;
            }
            count += 1;
        }
        if count < 3 {
            break;
        }
        let c = sum.map(|v| v / count as f64);
        let mut m = Matrix3::<f64>::zeros();
        for p in points.iter().flatten().filter(|p| inlier(p)) {
            let d = [p[0] as f64 - c[0], p[1] as f64 - c[1], p[2] as f64 - c[2]];
            for i in 0..3 {
                for j in 0..3 {
                    m[(i, j)] += d[i] * d[j];
                }
            }
        }
        let eig = SymmetricEigen::new(m);
        let k = (0..3)
            .min_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]))
            .unwrap_or(0);
        let v = eig.eigenvectors.column(k);
        let mut u = normalize([v[0] as f32, v[1] as f32, v[2] as f32]);
        if dot(u, towards_camera) < 0.0 {
            u = scale(u, -1.0);
        }
        if dot(u, towards_camera) < 0.5 {
            break;
        }
        up = u;
        offset = -(u[0] * c[0] as f32 + u[1] * c[1] as f32 + u[2] * c[2] as f32);
    }
    Table::from_plane(up, offset, anchor)
}

/// Orthographic height map over the table: cell `(i, j)` covers
/// `x ∈ [x0 + i·cell, x0 + (i+1)·cell)`, `y` likewise; heights in metres above the table.
struct HeightMap {
    nx: usize,
    ny: usize,
    cell: f32,
    x0: f32,
    y0: f32,
    h: Vec<f32>,
    /// `h`, but +∞ (unknown counts as tall) outside the crop and around an object the
    /// crop's edge cuts off.
    h_seen: Vec<f32>,
    /// ∂h/∂x and ∂h/∂y (Sobel), metres per metre.
    gx: Vec<f32>,
    gy: Vec<f32>,
}

/// The object's cells and centroid.
struct Object {
    cells: Vec<usize>,
    centroid: [f32; 2],
}

impl HeightMap {
    fn build(
        points: &[Option<[f32; 3]>],
        table: &Table,
        crop: &ObjectCrop,
        camera: &CropCamera,
        params: &AnalyticParams,
    ) -> Self {
        // The crop's side on the table at its centre, and a margin for what sticks out.
        let side = crop.size_px as f32 * camera.s * crop.table_depth_m / camera.k.fx;
        let half = 0.6 * side;
        let cell = params.cell_m;
        let cells = ((2.0 * half / cell).ceil() as usize).clamp(8, MAX_CELLS);
        let (nx, ny) = (cells, cells);
        let (x0, y0) = (-(cells as f32) * cell / 2.0, -(cells as f32) * cell / 2.0);
        let mut h = vec![f32::NEG_INFINITY; nx * ny];
        // Each point covers its pixel's footprint (a square of the pixel's size at its
        // depth), so that silhouettes keep their full extent.
        let px_per_depth = camera.s / camera.k.fx;
        let n = crop.size_px as usize;
        let mut cut = vec![false; nx * ny];
        for (index, p) in points.iter().enumerate() {
            let Some(p) = p else {
                continue;
            };
            let t = table.table_point(*p);
            let (px, py) = (index % n, index / n);
            let border = px == 0 || py == 0 || px == n - 1 || py == n - 1;
            let is_cut = border && t[2] >= params.min_height_m;
            let r = 0.5 * p[2] * px_per_depth;
            let cell_of = |v: f32, v0: f32, n: usize| {
                ((v - v0) / cell).floor().clamp(-1.0, n as f32) as isize
            };
            let (i0, i1) = (cell_of(t[0] - r, x0, nx), cell_of(t[0] + r, x0, nx));
            let (j0, j1) = (cell_of(t[1] - r, y0, ny), cell_of(t[1] + r, y0, ny));
            for j in j0.max(0)..=j1.min(ny as isize - 1) {
                for i in i0.max(0)..=i1.min(nx as isize - 1) {
                    let k = j as usize * nx + i as usize;
                    h[k] = h[k].max(t[2]);
                    cut[k] |= is_cut;
                }
            }
        }
        // Unknown cells: a hole among known cells (sampling gaps) takes the lowest of its
        // known neighbours; the rest (the table hidden behind the object, dropped depth
        // jumps, beyond the crop) is taken to be free table.
        let known = h.clone();
        let mut assumed_free = vec![false; h.len()];
        for j in 0..ny {
            for i in 0..nx {
                let k = j * nx + i;
                if known[k] > f32::NEG_INFINITY {
                    continue;
                }
                let (mut lo, mut count) = (f32::INFINITY, 0);
                for jj in j.saturating_sub(1)..=(j + 1).min(ny - 1) {
                    for ii in i.saturating_sub(1)..=(i + 1).min(nx - 1) {
                        let v = known[jj * nx + ii];
                        if v > f32::NEG_INFINITY {
                            lo = lo.min(v);
                            count += 1;
                        }
                    }
                }
                if count >= HOLE_NEIGHBOURS {
                    h[k] = lo;
                } else {
                    h[k] = 0.0;
                    assumed_free[k] = true;
                }
            }
        }
        let (mut gx, mut gy) = (vec![0.0f32; h.len()], vec![0.0f32; h.len()]);
        let at = |i: isize, j: isize| {
            let i = i.clamp(0, nx as isize - 1) as usize;
            let j = j.clamp(0, ny as isize - 1) as usize;
            h[j * nx + i]
        };
        let norm_factor = 1.0 / (8.0 * cell);
        for j in 0..ny as isize {
            for i in 0..nx as isize {
                let dx = (at(i + 1, j - 1) + 2.0 * at(i + 1, j) + at(i + 1, j + 1))
                    - (at(i - 1, j - 1) + 2.0 * at(i - 1, j) + at(i - 1, j + 1));
                let dy = (at(i - 1, j + 1) + 2.0 * at(i, j + 1) + at(i + 1, j + 1))
                    - (at(i - 1, j - 1) + 2.0 * at(i, j - 1) + at(i + 1, j - 1));
                let k = j as usize * nx + i as usize;
                gx[k] = dx * norm_factor;
                gy[k] = dy * norm_factor;
            }
        }
        // Unknown (+∞) in `h_seen`: cells taken to be free table whose foot lies outside the
        // crop, and the cells of an object cut off by the crop's edge (and their
        // neighbours), so that no contact or lane rests on what the crop did not see.
        let size = crop.size_px as f32;
        let inside = |q: [f32; 3]| {
            camera
                .project(table.camera_point(q))
                .is_some_and(|[x, y]| x >= -0.5 && y >= -0.5 && x < size - 0.5 && y < size - 0.5)
        };
        let mut h_seen = h.clone();
        for j in 0..ny {
            for i in 0..nx {
                let k = j * nx + i;
                let near_cut =
                    (j.saturating_sub(CUT_RADIUS)..=(j + CUT_RADIUS).min(ny - 1)).any(|jj| {
                        (i.saturating_sub(CUT_RADIUS)..=(i + CUT_RADIUS).min(nx - 1))
                            .any(|ii| cut[jj * nx + ii])
                    });
                let x = x0 + (i as f32 + 0.5) * cell;
                let y = y0 + (j as f32 + 0.5) * cell;
                if near_cut || (assumed_free[k] && !inside([x, y, 0.0])) {
                    h_seen[k] = f32::INFINITY;
                }
            }
        }
        Self {
            nx,
            ny,
            cell,
            x0,
            y0,
            h,
            h_seen,
            gx,
            gy,
        }
    }

    /// Centre of cell `k` on the table.
    fn cell_centre(&self, k: usize) -> [f32; 2] {
        let (i, j) = (k % self.nx, k / self.nx);
        [
            self.x0 + (i as f32 + 0.5) * self.cell,
            self.y0 + (j as f32 + 0.5) * self.cell,
        ]
    }

    /// Bilinear sample of `field` at table point `p`; outside the map: `outside`.
    #[inline(always)]
    fn sample(&self, field: &[f32], p: [f32; 2], outside: f32) -> f32 {
        let fx = (p[0] - self.x0) / self.cell - 0.5;
        let fy = (p[1] - self.y0) / self.cell - 0.5;
        self.sample_at(field, fx, fy, outside)
    }

    /// [`HeightMap::sample`] at map coordinates (`fx`, `fy`), in cells from the first cell's
    /// centre.
    #[inline(always)]
    fn sample_at(&self, field: &[f32], fx: f32, fy: f32, outside: f32) -> f32 {
        // Truncation is the floor for the non-negative (and `floor` is a libm call where SSE4.1
        // is not enabled: a fifth of the search's time); NaN and negatives are outside.
        if !(fx >= 0.0 && fy >= 0.0) {
            return outside;
        }
        let (ix, iy) = ((fx as i32) as f32, (fy as i32) as f32);
        if !(ix + 1.0 < self.nx as f32 && iy + 1.0 < self.ny as f32) {
            return outside;
        }
        let (tx, ty) = (fx - ix, fy - iy);
        let k = iy as usize * self.nx + ix as usize;
        let (a, b) = (field[k], field[k + 1]);
        let (c, d) = (field[k + self.nx], field[k + self.nx + 1]);
        (a * (1.0 - tx) + b * tx) * (1.0 - ty) + (c * (1.0 - tx) + d * tx) * ty
    }

    /// Height at `p`, +∞ where the crop did not see it.
    #[inline(always)]
    fn height_seen(&self, p: [f32; 2]) -> f32 {
        let v = self.sample(&self.h_seen, p, f32::INFINITY);
        if v.is_finite() { v } else { f32::INFINITY }
    }

    /// Median height over the 5×5 cells around the one holding `p`: the top at a grasp
    /// centre, as [`super::decode::grasp_pose`] takes the median depth of a 5×5 window.
    fn top(&self, p: [f32; 2]) -> f32 {
        let i = ((p[0] - self.x0) / self.cell).floor() as isize;
        let j = ((p[1] - self.y0) / self.cell).floor() as isize;
        let mut v = [0.0f32; 25];
        let mut m = 0;
        for jj in j - 2..=j + 2 {
            for ii in i - 2..=i + 2 {
                if ii >= 0 && jj >= 0 && (ii as usize) < self.nx && (jj as usize) < self.ny {
                    v[m] = self.h[jj as usize * self.nx + ii as usize];
                    m += 1;
                }
            }
        }
        median(&mut v[..m]).unwrap_or(0.0)
    }

    /// The 8-connected component of cells at least `min_height` tall (and at least
    /// [`MIN_OBJECT_CELLS`] of them) nearest the origin (the crop centre's ray); ties by size,
    /// then by first cell.
    fn object_nearest_origin(&self, min_height: f32) -> Option<Object> {
        let tall: Vec<bool> = self.h.iter().map(|&v| v >= min_height).collect();
        let mut label = vec![u32::MAX; self.h.len()];
        let mut best: Option<(f32, usize, Vec<usize>)> = None;
        let mut stack = Vec::new();
        for start in 0..self.h.len() {
            if !tall[start] || label[start] != u32::MAX {
                continue;
            }
            let id = start as u32;
            let mut cells = Vec::new();
            label[start] = id;
            stack.push(start);
            while let Some(k) = stack.pop() {
                cells.push(k);
                let (i, j) = (k % self.nx, k / self.nx);
                for jj in j.saturating_sub(1)..=(j + 1).min(self.ny - 1) {
                    for ii in i.saturating_sub(1)..=(i + 1).min(self.nx - 1) {
                        let q = jj * self.nx + ii;
                        if tall[q] && label[q] == u32::MAX {
                            label[q] = id;
                            stack.push(q);
                        }
                    }
                }
            }
            if cells.len() < MIN_OBJECT_CELLS {
                continue;
            }
            let dist = cells
                .iter()
                .map(|&k| {
                    let c = self.cell_centre(k);
                    c[0].hypot(c[1])
                })
                .fold(f32::INFINITY, f32::min);
            let better = match &best {
                None => true,
                Some((d, len, _)) => dist < *d || (dist == *d && cells.len() > *len),
            };
            if better {
                best = Some((dist, cells.len(), cells));
            }
        }
        let (_, _, mut cells) = best?;
        cells.sort_unstable();
        let mut c = [0.0f64; 2];
        for &k in &cells {
            let p = self.cell_centre(k);
            c[0] += p[0] as f64;
            c[1] += p[1] as f64;
        }
        let len = cells.len() as f64;
        Some(Object {
            centroid: [(c[0] / len) as f32, (c[1] / len) as f32],
            cells,
        })
    }
}

/// A grasp found on the height map (table coordinates).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    centre: [f32; 2],
    /// Axis angle on the table, radians in [0, π).
    angle: f32,
    axis: [f32; 2],
    eval: Evaluation,
    quality: f32,
    centroid_distance: f32,
}

/// What one (centre, axis) gave over the grasp heights.
#[derive(Debug, Clone, Copy)]
struct Evaluation {
    top: f32,
    /// The deepest passing height.
    z_g: f32,
    s_plus: f32,
    s_minus: f32,
    /// Outward in-plane normal directions at the + and − contacts.
    normals: [[f32; 2]; 2],
    worst_angle: f32,
    coverage: f32,
    /// Largest lane incursion, metres.
    incursion: f32,
    /// Slope of the contact walls across the jaw.
    wall_slope: Option<f32>,
    /// Within the safe lane tolerance and opening margin.
    safe: bool,
    passing: usize,
    tried: usize,
}

/// Contacts and friction at one grasp height, before the lanes are checked.
#[derive(Debug, Clone, Copy)]
struct Slice {
    z_g: f32,
    s_plus: f32,
    s_minus: f32,
    normals: [[f32; 2]; 2],
    worst_angle: f32,
}

/// A (centre, axis) moved to its contacts' midpoint ([`Search::moved`]).
#[derive(Debug, Clone, Copy)]
struct Moved {
    centre: [f32; 2],
    /// The axis it was found with.
    angle: f32,
    /// The axis turned to the walls.
    refined: f32,
}

/// The height profiles along the closing axis at the lanes across the jaw
/// ([`AnalyticParams::jaw_samples`] offsets over the finger width), each made on first use: a
/// slice that fails at one lane leaves the others unread.
struct LaneRows<'a> {
    search: &'a Search<'a>,
    c: [f32; 2],
    axis: [f32; 2],
    rows: Vec<Option<Vec<f32>>>,
}

impl LaneRows<'_> {
    /// Lane `r`'s profile ([`Search::profile`]).
    fn get(&mut self, r: usize) -> &[f32] {
        let jaw = self.rows.len();
        let (search, c, axis) = (self.search, self.c, self.axis);
        self.rows[r].get_or_insert_with(|| {
            let l = if jaw == 1 {
                0.0
            } else {
                search.gripper.finger_width_m * (r as f32 / (jaw - 1) as f32 - 0.5)
            };
            let mut row = Vec::new();
            search.profile(c, axis, l, &mut row);
            row
        })
    }
}

struct Search<'a> {
    map: &'a HeightMap,
    gripper: &'a GraspSpec,
    params: &'a AnalyticParams,
    centroid: [f32; 2],
}

impl Search<'_> {
    fn run(&self, object_cells: &[usize]) -> Vec<Candidate> {
        let map = self.map;
        let p = self.params;
        let step = ((p.grid_step_m / map.cell).round() as usize).max(1);
        let centres: Vec<usize> = object_cells
            .iter()
            .copied()
            .filter(|&k| (k % map.nx).is_multiple_of(step) && (k / map.nx).is_multiple_of(step))
            .collect();
        // 1. Every (centre, axis) on the grid, in parallel: moved to the contacts' midpoint,
        //    the axis aligned with the contact normals.
        let moved: Vec<Vec<Option<Moved>>> = centres
            .par_iter()
            .map(|&k| {
                let c = map.cell_centre(k);
                let top = map.top(c);
                (0..p.num_angles)
                    .map(|a| self.moved(c, a as f32 * PI / p.num_angles as f32, top))
                    .collect()
            })
            .collect();
        // 2. In grid order (so the result never depends on the threads): a (midpoint cell,
        //    degree) already taken by an earlier centre is not evaluated again.
        let mut seen: HashSet<(i32, i32, i32)> = HashSet::new();
        let unique: Vec<Moved> = moved
            .into_iter()
            .flatten()
            .flatten()
            .filter(|m| {
                seen.insert((
                    (m.centre[0] / map.cell).round() as i32,
                    (m.centre[1] / map.cell).round() as i32,
                    m.refined.to_degrees().round() as i32,
                ))
            })
            .collect();
        // 3. Each moved centre evaluated again, in parallel, kept in grid order.
        let mut found: Vec<Candidate> = unique.par_iter().filter_map(|m| self.settle(m)).collect();
        // Best first; ties by position, then angle.
        found.sort_by(|a, b| {
            b.quality
                .total_cmp(&a.quality)
                .then(a.centre[1].total_cmp(&b.centre[1]))
                .then(a.centre[0].total_cmp(&b.centre[0]))
                .then(a.angle.total_cmp(&b.angle))
        });
        let mut kept: Vec<Candidate> = Vec::new();
        for c in found {
            if kept.len() >= p.num_grasps {
                break;
            }
            let duplicate = kept.iter().any(|g| {
                let d = (g.centre[0] - c.centre[0]).hypot(g.centre[1] - c.centre[1]);
                d < p.suppress_radius_m
                    && angle_between(g.angle, c.angle) <= p.suppress_angle_rad + 1e-4
            });
            if !duplicate {
                kept.push(c);
            }
        }
        kept
    }

    /// The first evaluation of (centre `c`, axis `angle`), moved to its contacts' midpoint with
    /// the axis turned to the walls' slope (else the contact normals).
    fn moved(&self, c: [f32; 2], angle: f32, top: f32) -> Option<Moved> {
        let first = self.evaluate(c, angle, top)?;
        let axis = unit(angle);
        let mid = (first.s_plus + first.s_minus) / 2.0;
        let centre = [c[0] + axis[0] * mid, c[1] + axis[1] * mid];
        // The walls' slope across the jaw; without it, the contact normals.
        let refined = match first.wall_slope {
            Some(slope) => (angle - slope.atan()).rem_euclid(PI),
            None => {
                let [n_plus, n_minus] = first.normals;
                let ideal = [n_plus[0] - n_minus[0], n_plus[1] - n_minus[1]];
                ideal[1].atan2(ideal[0]).rem_euclid(PI)
            }
        };
        Some(Moved {
            centre,
            angle,
            refined,
        })
    }

    /// A moved centre evaluated with the refined axis, else the original one: a candidate when
    /// its contacts stay centred (within 1.5 cells).
    fn settle(&self, m: &Moved) -> Option<Candidate> {
        let map = self.map;
        let top_m = map.top(m.centre);
        let mut tries = vec![m.refined];
        if angle_between(m.refined, m.angle) > 1e-3 {
            tries.push(m.angle);
        }
        for angle in tries {
            let Some(eval) = self.evaluate(m.centre, angle, top_m) else {
                continue;
            };
            let shift = (eval.s_plus + eval.s_minus) / 2.0;
            if shift.abs() > 1.5 * map.cell {
                continue;
            }
            let centroid_distance =
                (m.centre[0] - self.centroid[0]).hypot(m.centre[1] - self.centroid[1]);
            return Some(Candidate {
                centre: m.centre,
                angle,
                axis: unit(angle),
                eval,
                quality: self.quality(&eval, centroid_distance),
                centroid_distance,
            });
        }
        None
    }

    fn quality(&self, e: &Evaluation, centroid_distance: f32) -> f32 {
        let p = self.params;
        let cone = self.gripper.friction.atan() * p.friction_cone_fraction;
        let align = (1.0 - e.worst_angle / cone).clamp(0.0, 1.0);
        let stability = (-0.5 * (centroid_distance / p.stability_scale_m).powi(2)).exp();
        let support = e.passing as f32 / e.tried.max(1) as f32;
        let clearance = if p.lane_tolerance_m > 0.0 {
            (1.0 - e.incursion.max(0.0) / p.lane_tolerance_m).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let raw =
            0.3 * align + 0.15 * e.coverage + 0.25 * stability + 0.15 * support + 0.15 * clearance;
        // Safe grasps in [0.5, 1], the others in [0.01, 0.5).
        if e.safe {
            (0.5 + 0.5 * raw).clamp(0.5, 1.0)
        } else {
            (0.01 + 0.489 * raw).clamp(0.01, 0.499)
        }
    }

    /// Samples per half profile: the labeller's lane (full opening plus clearance) and a
    /// finger thickness more.
    fn half_len(&self) -> usize {
        let g = self.gripper;
        let reach = g.max_opening_m / 2.0 + g.clearance_m + self.params.finger_thickness_m;
        (reach / self.map.cell).ceil() as usize + 1
    }

    /// The height profile along `axis` through `c` shifted `lateral_m` across it:
    /// `out[k]` at `s = (k − half)·cell`; unseen cells are infinitely tall.
    fn profile(&self, c: [f32; 2], axis: [f32; 2], lateral_m: f32, out: &mut Vec<f32>) {
        let map = self.map;
        let half = self.half_len();
        let base = [c[0] - axis[1] * lateral_m, c[1] + axis[0] * lateral_m];
        let n = 2 * half + 1;
        // The map coordinates of every sample first, in a loop the compiler vectorises (the
        // same operations in the same order as `HeightMap::sample`: the same bits), then the
        // lookups.
        out.clear();
        out.resize(2 * n, 0.0);
        let (fx, fy) = out.split_at_mut(n);
        for (k, (fx, fy)) in fx.iter_mut().zip(fy.iter_mut()).enumerate() {
            let s = (k as f32 - half as f32) * map.cell;
            *fx = (base[0] + axis[0] * s - map.x0) / map.cell - 0.5;
            *fy = (base[1] + axis[1] * s - map.y0) / map.cell - 0.5;
        }
        for k in 0..n {
            let v = map.sample_at(&map.h_seen, out[k], out[n + k], f32::INFINITY);
            out[k] = if v.is_finite() { v } else { f32::INFINITY };
        }
        out.truncate(n);
    }

    /// Evaluates (centre, axis angle) at every grasp height below `top`; `None` when none
    /// passes.
    fn evaluate(&self, c: [f32; 2], angle: f32, top: f32) -> Option<Evaluation> {
        let g = self.gripper;
        let p = self.params;
        if top < p.min_height_m {
            return None;
        }
        let axis = unit(angle);
        let mut heights = [0.0f32; GRASP_DEPTH_FRACTIONS.len()];
        let mut tried = 0;
        for f in GRASP_DEPTH_FRACTIONS {
            let z = (top - f * g.finger_length_m).max(p.min_grasp_height_m);
            if z < top && (tried == 0 || heights[tried - 1] != z) {
                heights[tried] = z;
                tried += 1;
            }
        }
        if tried == 0 {
            return None;
        }
        // A finger starting inside the object at every height: done.
        let r_open = (g.max_opening_m / 2.0 / self.map.cell).floor() * self.map.cell;
        let open_height = self
            .map
            .height_seen([c[0] + axis[0] * r_open, c[1] + axis[1] * r_open])
            .max(
                self.map
                    .height_seen([c[0] - axis[0] * r_open, c[1] - axis[1] * r_open]),
            );
        if open_height > heights[tried - 1] {
            return None;
        }
        // The centre line first: contacts, opening and friction at each height.
        let mut centre_row = Vec::new();
        self.profile(c, axis, 0.0, &mut centre_row);
        let mut slices = [None; GRASP_DEPTH_FRACTIONS.len()];
        let mut any = false;
        for (slot, &z_g) in slices.iter_mut().zip(&heights[..tried]) {
            *slot = self.slice(c, axis, &centre_row, z_g);
            any |= slot.is_some();
        }
        if !any {
            return None;
        }
        // Then the lanes across the jaw, each profiled when a slice first needs it.
        let mut rows = LaneRows {
            search: self,
            c,
            axis,
            rows: vec![None; p.jaw_samples],
        };
        let jaw = p.jaw_samples;
        if jaw > 1 && jaw % 2 == 1 {
            rows.rows[jaw / 2] = Some(centre_row);
        }
        // The deepest safe height, else the deepest that passes.
        let safe_cone = g.friction.atan() * p.safe_cone_fraction;
        let mut best: Option<Evaluation> = None;
        let mut passing = 0;
        for slice in slices[..tried].iter().flatten() {
            let Some(lanes) = self.lanes(&mut rows, slice) else {
                continue;
            };
            passing += 1;
            let safe = lanes.incursion <= p.safe_lane_tolerance_m
                && slice.worst_angle <= safe_cone
                && slice.s_plus - slice.s_minus + 2.0 * g.clearance_m + p.opening_margin_m
                    <= g.max_opening_m;
            if best.is_none_or(|b| safe && !b.safe) {
                best = Some(Evaluation {
                    top,
                    z_g: slice.z_g,
                    s_plus: slice.s_plus,
                    s_minus: slice.s_minus,
                    normals: slice.normals,
                    worst_angle: slice.worst_angle,
                    coverage: lanes.coverage,
                    incursion: lanes.incursion,
                    wall_slope: lanes.wall_slope,
                    safe,
                    passing: 0,
                    tried,
                });
            }
        }
        best.map(|e| Evaluation { passing, ..e })
    }

    /// Contacts at grasp height `z_g` on the centre line — fingers coming in from the full
    /// opening meet the outermost material taller than `z_g` (the scan goes on past the centre,
    /// as the labeller's rays do) — the opening, and the friction cone at the contacts.
    fn slice(&self, c: [f32; 2], axis: [f32; 2], row: &[f32], z_g: f32) -> Option<Slice> {
        let map = self.map;
        let g = self.gripper;
        let cell = map.cell;
        let half = self.half_len() as isize;
        let k_open = ((g.max_opening_m / 2.0 / cell).floor() as isize).min(half - 1);
        let mut s_contact = [0.0f32; 2];
        for (side, sign) in [1isize, -1].into_iter().enumerate() {
            let at = |t: isize| (half + sign * t) as usize;
            if row[at(k_open)] > z_g {
                // A finger would start inside the object.
                return None;
            }
            let hit = (1 - k_open..k_open).rev().find(|&t| row[at(t)] > z_g)?;
            if !row[at(hit)].is_finite() {
                // The contact would rest on what the crop did not see.
                return None;
            }
            // Step `hit` is taller than z_g, the next one out is not: interpolate the crossing.
            let (hi, lo) = (row[at(hit)], row[at(hit + 1)]);
            let frac = if hi.is_finite() {
                ((hi - z_g) / (hi - lo)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            s_contact[side] = sign as f32 * (hit as f32 + frac) * cell;
        }
        let (s_plus, s_minus) = (s_contact[0], s_contact[1]);
        let opening = s_plus - s_minus;
        if opening <= 0.0 || opening + 2.0 * g.clearance_m > g.max_opening_m {
            return None;
        }
        // Friction cone: the height map's 3-D normal against the closing axis.
        let cone = g.friction.atan() * self.params.friction_cone_fraction;
        let mut worst = 0.0f32;
        let mut normals = [[0.0f32; 2]; 2];
        for (k, (s, sign)) in [(s_plus, 1.0f32), (s_minus, -1.0)].into_iter().enumerate() {
            let q = [c[0] + axis[0] * s, c[1] + axis[1] * s];
            let gx = map.sample(&map.gx, q, 0.0);
            let gy = map.sample(&map.gy, q, 0.0);
            let n3 = normalize([-gx, -gy, 1.0]);
            let cos = (n3[0] * axis[0] + n3[1] * axis[1]) * sign;
            worst = worst.max(cos.clamp(-1.0, 1.0).acos());
            let planar = gx.hypot(gy);
            normals[k] = if planar > 0.0 {
                [-gx / planar, -gy / planar]
            } else {
                [axis[0] * sign, axis[1] * sign]
            };
        }
        if worst > cone {
            return None;
        }
        Some(Slice {
            z_g,
            s_plus,
            s_minus,
            normals,
            worst_angle: worst,
        })
    }

    /// Finger lanes and palm across the jaw for one slice. In each row across the jaw and on
    /// each side, the outermost material taller than `z_g` between the contact and the lane's
    /// end (the full opening plus clearance, and at least a finger thickness beyond the
    /// contact plus clearance) may stick out at most `lane_tolerance_m` beyond the contact
    /// (the labeller's test, to sub-cell precision); nothing between the fingers may reach
    /// the palm (`z_g + finger_length_m`); and the slice must reach the contact (within
    /// [`COVERAGE_BAND_M`]) in at least `min_jaw_coverage` of the rows.
    fn lanes(&self, rows: &mut LaneRows<'_>, slice: &Slice) -> Option<Lanes> {
        let g = self.gripper;
        let p = self.params;
        let cell = self.map.cell;
        let half = self.half_len();
        let z_g = slice.z_g;
        let palm = z_g + g.finger_length_m;
        let r_open = g.max_opening_m / 2.0;
        let index = |s: f32| (half as f32 + s / cell).round() as usize;
        let mut covered = 0usize;
        let mut incursion = f32::NEG_INFINITY;
        // Least-squares sums of the crossings' positions against the offset across the jaw,
        // per side: the walls' slope relative to the axis.
        let mut fit = [[0.0f32; 5]; 2];
        let jaw = rows.rows.len();
        for r in 0..jaw {
            let h = rows.get(r);
            let lateral = if jaw == 1 {
                0.0
            } else {
                g.finger_width_m * (r as f32 / (jaw - 1) as f32 - 0.5)
            };
            let mut reaches = true;
            for (side, (s, sign)) in [(slice.s_plus, 1.0f32), (slice.s_minus, -1.0)]
                .into_iter()
                .enumerate()
            {
                let limit = (r_open + g.clearance_m)
                    .max(s.abs() + g.clearance_m + p.finger_thickness_m)
                    .min((half - 1) as f32 * cell);
                let k_to = (limit / cell).floor() as isize;
                let at = |t: isize| h[(half as isize + sign as isize * t) as usize];
                if at(k_to) > z_g {
                    return None;
                }
                // The outermost crossing of z_g, scanning in from the lane's end.
                let k_stop = ((s.abs() - COVERAGE_BAND_M) / cell).floor() as isize;
                let outer = (k_stop.max(1 - k_to)..k_to).rev().find(|&t| at(t) > z_g);
                match outer {
                    Some(t) => {
                        let (hi, lo) = (at(t), at(t + 1));
                        if !hi.is_finite() {
                            return None;
                        }
                        let frac = ((hi - z_g) / (hi - lo)).clamp(0.0, 1.0);
                        let excess = (t as f32 + frac) * cell - s.abs();
                        if excess > p.lane_tolerance_m {
                            return None;
                        }
                        incursion = incursion.max(excess);
                        let position = sign * (t as f32 + frac) * cell;
                        let f = &mut fit[side];
                        f[0] += 1.0;
                        f[1] += lateral;
                        f[2] += position;
                        f[3] += lateral * lateral;
                        f[4] += lateral * position;
                    }
                    None => reaches = false,
                }
            }
            // The palm clears everything between the fingers.
            let (a, b) = (
                index(slice.s_minus - g.clearance_m),
                index(slice.s_plus + g.clearance_m),
            );
            if h[a.min(b)..=b.max(a).min(h.len() - 1)]
                .iter()
                .any(|&v| v > palm)
            {
                return None;
            }
            if reaches {
                covered += 1;
            }
        }
        let coverage = covered as f32 / jaw as f32;
        let slopes: Vec<f32> = fit
            .iter()
            .filter(|f| f[0] >= 2.0)
            .filter_map(|f| {
                let den = f[0] * f[3] - f[1] * f[1];
                (den.abs() > 1e-12).then(|| (f[0] * f[4] - f[1] * f[2]) / den)
            })
            .collect();
        let wall_slope =
            (!slopes.is_empty()).then(|| slopes.iter().sum::<f32>() / slopes.len() as f32);
        (coverage + 1e-6 >= p.min_jaw_coverage).then_some(Lanes {
            coverage,
            incursion: incursion.max(-COVERAGE_BAND_M),
            wall_slope,
        })
    }
}

/// What the lanes of one slice measured.
#[derive(Debug, Clone, Copy)]
struct Lanes {
    /// Share of the rows across the jaw in which the slice reaches the contact.
    coverage: f32,
    /// Largest distance by which material sticks out beyond a contact (negative: recedes),
    /// metres.
    incursion: f32,
    /// Mean slope of the contact walls across the jaw (d position / d offset); the axis is
    /// perpendicular to them when 0.
    wall_slope: Option<f32>,
}

/// Unit vector at `angle` on the table.
fn unit(angle: f32) -> [f32; 2] {
    [angle.cos(), angle.sin()]
}

/// Difference of two axis angles modulo π, radians in [0, π/2].
fn angle_between(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d)
}

/// The candidate as a grasp in crop pixels.
fn to_crop(
    c: &Candidate,
    table: &Table,
    camera: &CropCamera,
    gripper: &GraspSpec,
    jaw_px: f32,
) -> Option<AnalyticGrasp> {
    let e = &c.eval;
    let centre = table.camera_point([c.centre[0], c.centre[1], e.top]);
    let half = 0.01;
    let a = table.camera_point([
        c.centre[0] - c.axis[0] * half,
        c.centre[1] - c.axis[1] * half,
        e.top,
    ]);
    let b = table.camera_point([
        c.centre[0] + c.axis[0] * half,
        c.centre[1] + c.axis[1] * half,
        e.top,
    ]);
    let (pc, pa, pb) = (
        camera.project(centre)?,
        camera.project(a)?,
        camera.project(b)?,
    );
    let (dx, dy) = (pb[0] - pa[0], pb[1] - pa[1]);
    let px_per_m = dx.hypot(dy) / (2.0 * half);
    let opening = e.s_plus - e.s_minus;
    let grasp = DecodedGrasp {
        center_px: pc,
        angle: wrap_angle((-dy).atan2(dx)),
        width_px: (opening + 2.0 * gripper.clearance_m) * px_per_m,
        jaw_px,
        quality: c.quality,
    };
    let finite = grasp.center_px.iter().all(|v| v.is_finite())
        && grasp.angle.is_finite()
        && grasp.width_px.is_finite();
    finite.then_some(AnalyticGrasp {
        grasp,
        opening_m: opening,
        top_height_m: e.top,
        grasp_height_m: e.z_g,
        contact_angle_rad: e.worst_angle,
        jaw_coverage: e.coverage,
        depth_support: e.passing as f32 / e.tried.max(1) as f32,
        centroid_distance_m: c.centroid_distance,
        safe: e.safe,
    })
}
