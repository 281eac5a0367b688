//! Grasp labelling: antipodal parallel-jaw grasp rectangles computed from the object's
//! geometry.
//!
//! For a top-down RGB-D image of an object on a table, candidates are sampled as (pixel on the
//! object, opening angle every 15°). Each is tested on the mesh itself: the grasp centre lies
//! below the visible top surface at one of four depths up to `finger_length_m` (the deepest
//! that passes is kept); rays cast from both fingers' open positions
//! towards the centre along the horizontal opening axis find the contacts; the contact normals
//! must lie inside the friction cone (half-angle `atan(friction)`) around the closing
//! direction; the opening plus clearance must fit the gripper; and nothing may stick out
//! beyond a contact into the lane a finger sweeps while closing (checked at several heights
//! and across the finger's width). Accepted candidates become positive rectangles, rejected
//! ones negative rectangles, each in the Cornell convention: corners `p0 → p1` along the
//! opening axis (length = opening + clearance on both sides, in pixels), `p1 → p2` across the
//! jaw (finger width).
//!
//! ```
//! use lgdm_pointcloud::grasp::GraspRectangle;
//! let r = GraspRectangle::from_center([100.0, 80.0], 0.0, 40.0, 20.0);
//! assert!((r.width_px() - 40.0).abs() < 1e-4 && (r.height_px() - 20.0).abs() < 1e-4);
//! assert!((r.center()[0] - 100.0).abs() < 1e-4);
//! ```

use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use crate::math::{add, cross, dot, normalize, scale, sub, transform_point};
use crate::mesh::Mesh;
use crate::render::{Camera, RgbdFrame};

/// Width of a finger pad of the default gripper, metres.
pub const DEFAULT_FINGER_WIDTH_M: f32 = 0.02;

/// Gripper and sampling parameters of the grasp labels. Lengths in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GraspSpec {
    /// Largest opening of the parallel-jaw gripper (default: 0.085, a Robotiq 2F-85).
    pub max_opening_m: f32,
    /// Width of a finger pad across the opening axis (default: 0.02).
    pub finger_width_m: f32,
    /// How far the fingers can reach below the top of the object at the grasp centre; grasps
    /// are tried at 1/6, 1/3, 2/3 and all of it (default: 0.045).
    pub finger_length_m: f32,
    /// Free space needed beyond each contact for the finger to close (default: 0.004).
    pub clearance_m: f32,
    /// Coulomb friction coefficient of the friction cone (default: 0.5, half-angle ≈ 26.6°).
    pub friction: f32,
    /// Candidate centre pixels sampled per image, each tried at 12 angles (default: 150).
    pub candidates_per_image: usize,
    /// Most positive rectangles kept per image (default: 30).
    pub max_positives: usize,
    /// Most negative (rejected) rectangles kept per image (default: 15).
    pub max_negatives: usize,
    /// Height of the top-down grasp camera above the table, metres (default: 0.5).
    pub camera_height_m: f32,
}

impl Default for GraspSpec {
    fn default() -> Self {
        Self {
            max_opening_m: 0.085,
            finger_width_m: DEFAULT_FINGER_WIDTH_M,
            finger_length_m: 0.045,
            clearance_m: 0.004,
            friction: 0.5,
            candidates_per_image: 150,
            max_positives: 30,
            max_negatives: 15,
            camera_height_m: 0.5,
        }
    }
}

impl GraspSpec {
    /// Checks the parameters, describing the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        if !pos(self.max_opening_m) || self.max_opening_m > 0.5 {
            return Err("max_opening_m must be in (0, 0.5]".into());
        }
        if !pos(self.finger_width_m) || !pos(self.finger_length_m) || !pos(self.clearance_m) {
            return Err("finger_width_m, finger_length_m and clearance_m must be positive".into());
        }
        if !pos(self.friction) {
            return Err("friction must be positive".into());
        }
        if !(self.camera_height_m.is_finite()
            && self.camera_height_m > 0.2
            && self.camera_height_m < 3.0)
        {
            return Err("camera_height_m must be in (0.2, 3)".into());
        }
        if self.candidates_per_image == 0 {
            return Err("candidates_per_image must be at least 1".into());
        }
        Ok(())
    }
}

/// A grasp rectangle in pixel coordinates (Cornell convention: `corners[0] → corners[1]` is
/// the opening axis, `corners[1] → corners[2]` the jaw).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspRectangle {
    /// Corners `[x, y]` in pixels.
    pub corners_px: [[f32; 2]; 4],
}

impl GraspRectangle {
    /// A rectangle centred at `center_px`, opening axis at `angle_rad` (image x towards image
    /// y), `width_px` along the opening axis and `height_px` across it.
    pub fn from_center(center_px: [f32; 2], angle_rad: f32, width_px: f32, height_px: f32) -> Self {
        let (s, c) = angle_rad.sin_cos();
        let a = [c * width_px / 2.0, s * width_px / 2.0];
        let b = [-s * height_px / 2.0, c * height_px / 2.0];
        let [x, y] = center_px;
        GraspRectangle {
            corners_px: [
                [x - a[0] - b[0], y - a[1] - b[1]],
                [x + a[0] - b[0], y + a[1] - b[1]],
                [x + a[0] + b[0], y + a[1] + b[1]],
                [x - a[0] + b[0], y - a[1] + b[1]],
            ],
        }
    }

    /// Centre in pixels.
    pub fn center(&self) -> [f32; 2] {
        let c = &self.corners_px;
        [(c[0][0] + c[2][0]) / 2.0, (c[0][1] + c[2][1]) / 2.0]
    }

    /// Angle of the opening axis (`corners[0] → corners[1]`), radians in `(-π, π]`.
    pub fn angle(&self) -> f32 {
        let c = &self.corners_px;
        (c[1][1] - c[0][1]).atan2(c[1][0] - c[0][0])
    }

    /// Length along the opening axis, pixels.
    pub fn width_px(&self) -> f32 {
        let c = &self.corners_px;
        (c[1][0] - c[0][0]).hypot(c[1][1] - c[0][1])
    }

    /// Length across the opening axis (the jaw), pixels.
    pub fn height_px(&self) -> f32 {
        let c = &self.corners_px;
        (c[2][0] - c[1][0]).hypot(c[2][1] - c[1][1])
    }
}

/// Why a candidate was rejected (or that it was accepted).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum GraspVerdict {
    /// A stable antipodal grasp.
    Accepted,
    /// A finger ray met no surface at the grasp height.
    NoContact,
    /// The object is wider than the gripper opens (or a finger would start inside it).
    TooWide {
        /// Opening needed, metres (∞ when a finger starts inside the object).
        opening_m: f32,
    },
    /// A contact normal lies outside the friction cone.
    OutsideFrictionCone {
        /// Largest angle between a contact normal and its closing direction, radians.
        angle_rad: f32,
    },
    /// Part of the object protrudes into a finger's closing lane.
    Collision,
}

/// One evaluated candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspCandidate {
    /// The rectangle in the image.
    pub rectangle: GraspRectangle,
    /// The verdict.
    pub verdict: GraspVerdict,
    /// Grasp centre in the world, metres.
    pub center_m: [f32; 3],
    /// Opening between the contacts, metres (0 when there are none).
    pub opening_m: f32,
}

/// Evaluates one candidate: `center_top_m` is the visible top-surface point (world) under the
/// candidate pixel, `axis` the horizontal opening direction (world, unit). Tries the grasp
/// heights from deepest to shallowest and returns the first accepted one, else the verdict at
/// the middle depth. Returns the verdict, the opening (metres) and the grasp centre (world).
pub fn evaluate_grasp(
    mesh_world: &Mesh,
    center_top_m: [f32; 3],
    axis: [f32; 3],
    spec: &GraspSpec,
) -> (GraspVerdict, f32, [f32; 3]) {
    let mut middle = None;
    for (i, f) in [1.0f32, 2.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0]
        .into_iter()
        .enumerate()
    {
        let z_g = (center_top_m[2] - f * spec.finger_length_m).max(0.008);
        let r = evaluate_grasp_at(mesh_world, center_top_m, axis, z_g, spec);
        if r.0 == GraspVerdict::Accepted {
            return r;
        }
        if i == 1 {
            middle = Some(r);
        }
    }
    middle.expect("four depths tried")
}

/// Evaluates one candidate at grasp height `z_g` (world, metres).
pub fn evaluate_grasp_at(
    mesh_world: &Mesh,
    center_top_m: [f32; 3],
    axis: [f32; 3],
    z_g: f32,
    spec: &GraspSpec,
) -> (GraspVerdict, f32, [f32; 3]) {
    let up = [0.0, 0.0, 1.0];
    let a = normalize([axis[0], axis[1], 0.0]);
    let lateral = cross(up, a);
    let c = [center_top_m[0], center_top_m[1], z_g];
    let r_open = spec.max_opening_m / 2.0;
    let cone = spec.friction.atan();
    // Contacts: rays from each finger's open position towards the centre.
    let mut s_contact = [0.0f32; 2];
    let mut worst_angle = 0.0f32;
    for (k, side) in [1.0f32, -1.0].into_iter().enumerate() {
        let start = add(c, scale(a, side * r_open));
        let dir = scale(a, -side);
        // Cast beyond the centre so that a start inside the object shows as an exit face.
        let Some(hit) = mesh_world.raycast(start, dir, 1.0) else {
            return (GraspVerdict::NoContact, 0.0, c);
        };
        if dot(hit.normal, dir) > 0.0 {
            // The ray left the solid: the finger would start inside the object.
            return (
                GraspVerdict::TooWide {
                    opening_m: f32::INFINITY,
                },
                0.0,
                c,
            );
        }
        if hit.t > 2.0 * r_open {
            return (GraspVerdict::NoContact, 0.0, c);
        }
        // Signed position of the contact along the axis, measured from the centre.
        s_contact[k] = side * (r_open - hit.t);
        let angle = dot(hit.normal, scale(dir, -1.0)).clamp(-1.0, 1.0).acos();
        worst_angle = worst_angle.max(angle);
    }
    let opening = s_contact[0] - s_contact[1];
    if opening <= 0.0 {
        return (GraspVerdict::NoContact, 0.0, c);
    }
    if opening + 2.0 * spec.clearance_m > spec.max_opening_m {
        return (GraspVerdict::TooWide { opening_m: opening }, opening, c);
    }
    if worst_angle > cone {
        return (
            GraspVerdict::OutsideFrictionCone {
                angle_rad: worst_angle,
            },
            opening,
            c,
        );
    }
    // Finger lanes: from the open position (plus the finger's own clearance) to the contact, at
    // several heights from the grasp height up to above the object, across the finger width.
    let top = mesh_world.bounds().map_or(z_g, |(_, hi)| hi[2]) + 0.01;
    let tolerance = 0.002;
    let heights = {
        let n = (((top - z_g) / 0.01).ceil() as usize).clamp(1, 40);
        (0..=n).map(move |i| z_g + (top - z_g) * i as f32 / n as f32)
    };
    for h in heights {
        for l in [-0.5f32, 0.0, 0.5] {
            let base = add(
                add(c, scale(lateral, l * spec.finger_width_m)),
                [0.0, 0.0, h - z_g],
            );
            for (k, side) in [1.0f32, -1.0].into_iter().enumerate() {
                let reach = r_open + spec.clearance_m;
                let start = add(base, scale(a, side * reach));
                let dir = scale(a, -side);
                if let Some(hit) = mesh_world.raycast(start, dir, 1.0) {
                    if dot(hit.normal, dir) > 0.0 {
                        return (GraspVerdict::Collision, opening, c);
                    }
                    let s_hit = side * (reach - hit.t);
                    if side * (s_hit - s_contact[k]) > tolerance {
                        return (GraspVerdict::Collision, opening, c);
                    }
                }
            }
        }
    }
    let mid = (s_contact[0] + s_contact[1]) / 2.0;
    (GraspVerdict::Accepted, opening, add(c, scale(a, mid)))
}

/// Angle between the opening angles tried at one pixel.
const ANGLE_STEP: f32 = std::f32::consts::PI / 12.0;

/// Samples and evaluates grasp candidates for a rendered top-down frame of `mesh_world` (the
/// object mesh already placed in the world). Returns accepted and rejected candidates,
/// thinned so that no two kept rectangles of the same kind are near duplicates (centres within
/// 6 px and angles within 15°), at most `max_positives` / `max_negatives` of each.
pub fn synthesize_grasps<R: Rng + ?Sized>(
    mesh_world: &Mesh,
    frame: &RgbdFrame,
    camera: &Camera,
    object_label: u8,
    spec: &GraspSpec,
    rng: &mut R,
) -> Vec<GraspCandidate> {
    let object_pixels: Vec<usize> = (0..frame.label.len())
        .filter(|&i| frame.label[i] == object_label && frame.depth_m[i] > 0.0)
        .collect();
    let mut kept: Vec<GraspCandidate> = Vec::new();
    if object_pixels.is_empty() {
        return kept;
    }
    let k = camera.intrinsics;
    let world_from_camera = camera.world_from_camera;
    let camera_from_world = world_from_camera.inverse();
    let w = frame.width as usize;
    let (mut positives, mut negatives) = (0usize, 0usize);
    'pixels: for _ in 0..spec.candidates_per_image {
        if positives >= spec.max_positives && negatives >= spec.max_negatives {
            break;
        }
        let i = object_pixels[rng.random_range(0..object_pixels.len())];
        let (u, v) = ((i % w) as f32, (i / w) as f32);
        let z = frame.depth_m[i];
        let top = transform_point(&world_from_camera, k.unproject(u, v, z));
        let phase = rng.random_range(0.0..ANGLE_STEP);
        for step in 0..12 {
            let angle = phase + step as f32 * ANGLE_STEP;
            // Opening axis: the image direction at `angle`, as a horizontal world direction.
            let (s, cs) = angle.sin_cos();
            let p2 = transform_point(
                &world_from_camera,
                k.unproject(u + 10.0 * cs, v + 10.0 * s, z),
            );
            let axis = normalize(sub(p2, top));
            let (verdict, opening, center) = evaluate_grasp(mesh_world, top, axis, spec);
            if verdict == GraspVerdict::NoContact {
                continue;
            }
            let accepted = verdict == GraspVerdict::Accepted;
            if (accepted && positives >= spec.max_positives)
                || (!accepted && negatives >= spec.max_negatives)
            {
                continue;
            }
            // Rectangle: project the grasp centre at the top-surface height.
            let centre_top = [center[0], center[1], top[2]];
            let Some(centre_px) = k.project(transform_point(&camera_from_world, centre_top)) else {
                continue 'pixels;
            };
            let depth_here = transform_point(&camera_from_world, centre_top)[2].max(0.05);
            let metres_to_px = k.fx / depth_here;
            let opening_m = if opening > 0.0 && opening.is_finite() {
                opening
            } else {
                spec.max_opening_m
            };
            let width_px = (opening_m + 2.0 * spec.clearance_m) * metres_to_px;
            let height_px = spec.finger_width_m * metres_to_px;
            let rectangle = GraspRectangle::from_center(centre_px, angle, width_px, height_px);
            let duplicate = kept.iter().any(|g| {
                (g.verdict == GraspVerdict::Accepted) == accepted && {
                    let d = g.rectangle.center();
                    let da =
                        (g.rectangle.angle() - rectangle.angle()).rem_euclid(std::f32::consts::PI);
                    let da = da.min(std::f32::consts::PI - da);
                    (d[0] - centre_px[0]).hypot(d[1] - centre_px[1]) < 6.0
                        && da < 15f32.to_radians()
                }
            });
            if duplicate {
                continue;
            }
            if accepted {
                positives += 1;
            } else {
                negatives += 1;
            }
            kept.push(GraspCandidate {
                rectangle,
                verdict,
                center_m: center,
                opening_m: opening,
            });
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangle_geometry() {
        let r = GraspRectangle::from_center([50.0, 40.0], 0.5, 30.0, 10.0);
        assert!((r.angle() - 0.5).abs() < 1e-5);
        assert!((r.width_px() - 30.0).abs() < 1e-4);
        assert!((r.height_px() - 10.0).abs() < 1e-4);
        let c = r.center();
        assert!((c[0] - 50.0).abs() < 1e-4 && (c[1] - 40.0).abs() < 1e-4);
    }

    #[test]
    fn box_grasps_across_the_narrow_side_only() {
        // A 4 cm × 12 cm × 10 cm box: graspable across x (4 cm), too wide across y (12 cm).
        let mesh = Mesh::cuboid([0.0, 0.0, 0.05], [0.04, 0.12, 0.1], [100, 100, 100]);
        let spec = GraspSpec::default();
        let top = [0.0, 0.0, 0.1];
        let (v, opening, _) = evaluate_grasp(&mesh, top, [1.0, 0.0, 0.0], &spec);
        assert_eq!(v, GraspVerdict::Accepted);
        assert!((opening - 0.04).abs() < 1e-4);
        let (v, _, _) = evaluate_grasp(&mesh, top, [0.0, 1.0, 0.0], &spec);
        assert!(matches!(v, GraspVerdict::TooWide { .. }), "{v:?}");
        // 45°: the contacts are on faces whose normals are 45° off the closing direction.
        let d = std::f32::consts::FRAC_1_SQRT_2;
        let (v, _, _) = evaluate_grasp(&mesh, top, [d, d, 0.0], &spec);
        assert!(
            matches!(v, GraspVerdict::OutsideFrictionCone { .. }),
            "{v:?}"
        );
    }

    #[test]
    fn protrusion_in_the_finger_lane_is_a_collision() {
        // A narrow post with a wide plate above the grasp height (6 cm) on one side.
        let mut mesh = Mesh::cuboid([0.0, 0.0, 0.05], [0.03, 0.03, 0.1], [1, 1, 1]);
        mesh.append(&Mesh::cuboid(
            [0.02, 0.0, 0.095],
            [0.04, 0.03, 0.01],
            [1, 1, 1],
        ));
        let spec = GraspSpec::default();
        let (v, _, _) = evaluate_grasp_at(&mesh, [0.0, 0.0, 0.1], [1.0, 0.0, 0.0], 0.06, &spec);
        assert_eq!(v, GraspVerdict::Collision);
        // Across the other axis the plate is not in the way.
        let (v, _, _) = evaluate_grasp_at(&mesh, [0.0, 0.0, 0.1], [0.0, 1.0, 0.0], 0.06, &spec);
        assert_eq!(v, GraspVerdict::Accepted);
    }
}
