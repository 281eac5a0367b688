//! Rim proposals: grasps that straddle the wall of an open object — one finger in the opening,
//! one outside — proposed from the crop's depth alone, for `lgdm sim grasp-data` (issue 44, item
//! 3). The analytic source closes its fingers from the full opening onto the outermost material,
//! so on a mug, a glass or a bowl it proposes grasps across the whole body and never one on the
//! rim; the network learns only the grasps its data label, so without rim proposals a set holds
//! no rim positives for it to learn.
//!
//! A crop pixel is a **rim pixel across a direction u** when it is on the object at least
//! [`RimSource::min_height_m`] above the table and, within [`RimSource::reach_m`] along +u and
//! along −u, the depth falls away by at least [`RimSource::drop_m`] on both sides — a ridge a few
//! millimetres thick, the top of its wall (nothing within twice the reach stands above it) — with
//! nothing but the object within twice the reach on one side (the opening) and the table within
//! it on the other. A wall standing alone on the table has table on both sides and is an ordinary
//! grasp; a step on a closed object has object on both; the edge of a closed object's top falls
//! onto the table on one side and not at all on the other. The crop has no object mask, so in
//! clutter the edge of a taller object standing over a lower neighbour passes too: those few
//! proposals are labelled by physics like the rest (measured in `docs/guide/grasp-network.md`).
//!
//! The grasp is centred on the pixel with its opening axis along u and [`RimSource::opening_m`]
//! of opening, so that the fingers come down on either side of the wall. Pixels are visited on a
//! grid of [`RimSource::stride_px`], each with [`RimSource::angles`] directions; the best
//! direction of a pixel is the one across which the wall is thinnest (the falls nearest on both
//! sides: across the wall, not along it), it scores the smaller of its two drops, and the
//! proposals are the best pixels at least [`RimSource::suppress_m`] apart. Nothing is checked
//! beyond that: whether a rim grasp holds is what the physics labels. Deterministic: the same
//! crop gives the same grasps.
//!
//! ```
//! use lgdm_pointcloud::crop::{CropSpec, crop_largest_object};
//! use lgdm_pointcloud::grasp::GraspSpec;
//! use lgdm_pointcloud::grasp::cornell::table_mesh;
//! use lgdm_pointcloud::math::{Pose, look_at};
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};
//! use lgdm_pointcloud::segment::SegmentParams;
//! use lgdm_sim::grasping::rim::RimSource;
//! use lgdm_sim::grasping::source::{GraspQuery, GraspSource};
//!
//! let camera = Camera::new(Intrinsics::kinect_vga(), look_at([0.0, 0.0, 0.5], [0.0; 3], [0.0, 1.0, 0.0]));
//! let table = table_mesh();
//! let shot = |name: &str| {
//!     let object = procedural_object(name, 0, 1).unwrap();
//!     let frame = render(&camera, &[
//!         RenderItem { mesh: &table, world_from_object: Pose::identity(), label: 1 },
//!         RenderItem { mesh: &object, world_from_object: Pose::identity(), label: 2 },
//!     ]);
//!     crop_largest_object(&frame, &camera.intrinsics, &SegmentParams::default(), &CropSpec::default())
//!         .unwrap()
//!         .crop
//! };
//! let (gripper, decode) = (GraspSpec::default(), Default::default());
//! let mut rims = |name: &str| {
//!     let crop = shot(name);
//!     let query = GraspQuery { crop: &crop, intrinsics: &camera.intrinsics, gripper: &gripper, decode: &decode };
//!     RimSource::default().grasps(&query, 4).unwrap()
//! };
//! assert!(!rims("glass").is_empty()); // an open glass has a rim
//! assert!(rims("can").is_empty()); // a closed can has none
//! ```

use lgdm_pointcloud::grasp::decode::{DecodedGrasp, wrap_angle};
use serde::{Deserialize, Serialize};

use super::source::{GraspQuery, GraspSource, SourceError, check_crop};

/// Proposes grasps across the rims of open objects (see the module docs). Lengths in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RimSource {
    /// A rim pixel is at least this high above the table (default 0.02).
    pub min_height_m: f32,
    /// The depth falls away by at least this much on both sides of a rim (default 0.015).
    pub drop_m: f32,
    /// How far from the pixel the fall is looked for on each side (default 0.012: a wall up to
    /// about 2 cm thick).
    pub reach_m: f32,
    /// The grasp's opening: the fingers come down this far apart, astride the wall (default
    /// 0.04).
    pub opening_m: f32,
    /// Directions tried per pixel, over half a turn (default 16).
    pub angles: usize,
    /// Pixels visited every this many crop pixels in each direction (default 2).
    pub stride_px: usize,
    /// Proposals at least this far apart (default 0.02).
    pub suppress_m: f32,
}

impl Default for RimSource {
    fn default() -> Self {
        Self {
            min_height_m: 0.02,
            drop_m: 0.015,
            reach_m: 0.012,
            opening_m: 0.04,
            angles: 16,
            stride_px: 2,
            suppress_m: 0.02,
        }
    }
}

/// How far a pixel within twice the reach of a rim pixel may stand above it (the sensor's noise
/// at the close-up's distance is 1–2 mm).
const RISE_TOLERANCE_M: f32 = 0.005;

/// A rim pixel's best direction: the smaller of its two drops, the pixel, the angle.
#[derive(Debug, Clone, Copy)]
struct Ridge {
    drop_m: f32,
    x: usize,
    y: usize,
    angle: f32,
}

impl RimSource {
    /// The rim pixels of `query`'s crop, each with its best direction, best first (ties by
    /// position, so the order is the same for the same crop).
    fn ridges(&self, query: &GraspQuery<'_>) -> Vec<Ridge> {
        let crop = query.crop;
        let n = crop.size_px as usize;
        let depth = |x: isize, y: isize| -> Option<f32> {
            if x < 0 || y < 0 || x >= n as isize || y >= n as isize {
                return None;
            }
            let d = crop.depth_m[y as usize * n + x as usize];
            (d.is_finite() && d > 0.0).then_some(d)
        };
        let on_object = |d: f32| d < crop.table_depth_m - 0.005;
        let directions: Vec<(f32, [f32; 2])> = (0..self.angles.max(1))
            .map(|a| {
                let angle = -std::f32::consts::FRAC_PI_2
                    + std::f32::consts::PI * a as f32 / self.angles.max(1) as f32;
                // Screen direction of the opening axis (θ counter-clockwise from +x, y down).
                (angle, [angle.cos(), -angle.sin()])
            })
            .collect();
        let mut ridges = Vec::new();
        let stride = self.stride_px.max(1);
        for y in (0..n).step_by(stride) {
            for x in (0..n).step_by(stride) {
                let Some(d) = depth(x as isize, y as isize) else {
                    continue;
                };
                if crop.table_depth_m - d < self.min_height_m {
                    continue;
                }
                let reach_px = self.reach_m * query.crop_px_per_m(d);
                let steps = reach_px.ceil().max(1.0) as usize;
                let mut best: Option<(usize, Ridge)> = None;
                for &(angle, u) in &directions {
                    // Per side: the largest fall within reach, and whether every pixel within
                    // twice the reach is on the object (inside an opening: the edge of a closed
                    // object's top, blurred by the crop's resampling, has object pixels a few
                    // millimetres high just before the table) or one is not (the table, or
                    // nothing seen: outside).
                    // Also the first step at which the fall reaches `drop_m`: the wall's
                    // half-thickness along u.
                    let side = |sign: f32| -> Option<(f32, bool, usize)> {
                        let (mut fall, mut inside, mut first) = (0.0f32, true, usize::MAX);
                        for s in 1..=2 * steps {
                            let r = reach_px * s as f32 / steps as f32 * sign;
                            let q = depth(
                                (x as f32 + r * u[0]).round() as isize,
                                (y as f32 + r * u[1]).round() as isize,
                            );
                            if let Some(dq) = q
                                && s <= steps
                            {
                                fall = fall.max(dq - d);
                                if fall >= self.drop_m {
                                    first = first.min(s);
                                }
                            }
                            inside &= q.is_some_and(on_object);
                            // A rim is the top of its wall: nothing on either side stands above
                            // it (a pixel blurred between the table and an object's top is not).
                            if q.is_some_and(|dq| d - dq > RISE_TOLERANCE_M) {
                                return None;
                            }
                        }
                        Some((fall, inside, first))
                    };
                    let (Some((fall_a, inside_a, first_a)), Some((fall_b, inside_b, first_b))) =
                        (side(1.0), side(-1.0))
                    else {
                        continue;
                    };
                    let drop_m = fall_a.min(fall_b);
                    if drop_m < self.drop_m || inside_a == inside_b {
                        continue;
                    }
                    // Across the wall, not along it: the direction in which it is thinnest,
                    // then the deepest.
                    let thickness = first_a + first_b;
                    if best.is_none_or(|(t, b)| (thickness, -drop_m) < (t, -b.drop_m)) {
                        best = Some((
                            thickness,
                            Ridge {
                                drop_m,
                                x,
                                y,
                                angle,
                            },
                        ));
                    }
                }
                ridges.extend(best.map(|(_, r)| r));
            }
        }
        ridges.sort_by(|a, b| {
            b.drop_m
                .total_cmp(&a.drop_m)
                .then(a.y.cmp(&b.y))
                .then(a.x.cmp(&b.x))
        });
        ridges
    }
}

impl GraspSource for RimSource {
    fn name(&self) -> &str {
        "rim"
    }

    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        let crop = query.crop;
        check_crop(crop)?;
        let n = crop.size_px as usize;
        let mut out: Vec<DecodedGrasp> = Vec::new();
        if k == 0 {
            return Ok(out);
        }
        for r in self.ridges(query) {
            let px_per_m = query.crop_px_per_m(crop.depth_m[r.y * n + r.x]);
            let centre = [r.x as f32, r.y as f32];
            let apart = self.suppress_m * px_per_m;
            if out.iter().any(|g| {
                let (dx, dy) = (g.center_px[0] - centre[0], g.center_px[1] - centre[1]);
                dx * dx + dy * dy < apart * apart
            }) {
                continue;
            }
            out.push(DecodedGrasp {
                center_px: centre,
                angle: wrap_angle(r.angle),
                width_px: self.opening_m.min(query.gripper.max_opening_m) * px_per_m,
                jaw_px: query.gripper.finger_width_m * px_per_m,
                // In (0.5, 1]: deeper openings first.
                quality: 0.5 + 0.5 * (r.drop_m / (r.drop_m + self.drop_m)),
            });
            if out.len() == k {
                break;
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lgdm_pointcloud::crop::{CropSpec, ObjectCrop, crop_largest_object};
    use lgdm_pointcloud::grasp::GraspSpec;
    use lgdm_pointcloud::grasp::cornell::table_mesh;
    use lgdm_pointcloud::math::{Pose, look_at};
    use lgdm_pointcloud::objects::procedural_object;
    use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};
    use lgdm_pointcloud::segment::SegmentParams;

    fn camera() -> Camera {
        Camera::new(
            Intrinsics::kinect_vga(),
            look_at([0.0, 0.0, 0.5], [0.0; 3], [0.0, 1.0, 0.0]),
        )
    }

    fn crop_of(name: &str, instance: u64) -> ObjectCrop {
        let table = table_mesh();
        let object = procedural_object(name, 0, instance).unwrap();
        let frame = render(
            &camera(),
            &[
                RenderItem {
                    mesh: &table,
                    world_from_object: Pose::identity(),
                    label: 1,
                },
                RenderItem {
                    mesh: &object,
                    world_from_object: Pose::identity(),
                    label: 2,
                },
            ],
        );
        crop_largest_object(
            &frame,
            &camera().intrinsics,
            &SegmentParams::default(),
            &CropSpec::default(),
        )
        .unwrap()
        .crop
    }

    fn rims(crop: &ObjectCrop, k: usize) -> Vec<DecodedGrasp> {
        let (gripper, decode) = (GraspSpec::default(), Default::default());
        let intrinsics = camera().intrinsics;
        let query = GraspQuery {
            crop,
            intrinsics: &intrinsics,
            gripper: &gripper,
            decode: &decode,
        };
        RimSource::default().grasps(&query, k).unwrap()
    }

    /// The object's centre and outer radius in crop pixels (from its pixels above the table).
    fn disc(crop: &ObjectCrop) -> ([f32; 2], f32) {
        let n = crop.size_px as usize;
        let pixels: Vec<[f32; 2]> = (0..n * n)
            .filter(|&i| {
                let d = crop.depth_m[i];
                d > 0.0 && d < crop.table_depth_m - 0.005
            })
            .map(|i| [(i % n) as f32, (i / n) as f32])
            .collect();
        let c = pixels
            .iter()
            .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
        let c = [c[0] / pixels.len() as f32, c[1] / pixels.len() as f32];
        // Robust to a handle: in a filled disc of radius r, 90 % of the pixels lie within
        // r·√0.9 of the centre.
        let mut d: Vec<f32> = pixels
            .iter()
            .map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt())
            .collect();
        d.sort_by(f32::total_cmp);
        (c, d[d.len() * 9 / 10] / 0.9f32.sqrt())
    }

    #[test]
    fn open_objects_are_grasped_on_the_rim_across_the_wall() {
        for (name, instance) in [("glass", 1), ("mug", 1), ("bowl", 1), ("glass", 3)] {
            let crop = crop_of(name, instance);
            let grasps = rims(&crop, 6);
            assert!(grasps.len() >= 3, "{name} {instance}: {grasps:?}");
            let (c, r) = disc(&crop);
            for g in &grasps {
                let (dx, dy) = (g.center_px[0] - c[0], g.center_px[1] - c[1]);
                let dist = (dx * dx + dy * dy).sqrt();
                // On the wall: near the outer edge (a bowl's rim is its widest circle; a mug's
                // handle is outside the disc of its body, so it is not counted here).
                assert!(
                    dist > 0.6 * r && dist <= r + 2.0,
                    "{name} {instance}: centre at {dist:.1} px of a {r:.1} px disc: {g:?}"
                );
                // The opening axis crosses the wall: radial within 25°.
                let radial = (-dy).atan2(dx);
                let off = wrap_angle(g.angle - radial).abs();
                assert!(
                    off < 25f32.to_radians() || dist > 0.95 * r,
                    "{name} {instance}: axis {:.0}° off radial at {dist:.1} px of {r:.1} from {c:?}: {g:?}",
                    off.to_degrees()
                );
                assert!(g.quality > 0.5 && g.quality <= 1.0);
            }
            // Spread around the rim, not all in one place.
            let far = grasps.iter().any(|g| {
                let (a, b) = (g.center_px, grasps[0].center_px);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() > r
            });
            assert!(far, "{name} {instance}: {grasps:?}");
            // Same crop, same grasps.
            assert_eq!(rims(&crop, 6), grasps);
        }
    }

    #[test]
    fn closed_objects_have_no_rim() {
        for (name, instance) in [("can", 1), ("apple", 1), ("book", 1), ("cereal_box", 2)] {
            let crop = crop_of(name, instance);
            assert_eq!(rims(&crop, 6), [], "{name} {instance}");
        }
    }

    #[test]
    fn nothing_asked_nothing_given_and_bad_crops_are_errors() {
        let crop = crop_of("glass", 1);
        assert_eq!(rims(&crop, 0), []);
        let mut bad = crop.clone();
        bad.depth_m.pop();
        let (gripper, decode) = (GraspSpec::default(), Default::default());
        let intrinsics = camera().intrinsics;
        let query = GraspQuery {
            crop: &bad,
            intrinsics: &intrinsics,
            gripper: &gripper,
            decode: &decode,
        };
        assert!(RimSource::default().grasps(&query, 3).is_err());
    }
}
