//! Perception on one RGB-D frame of objects on a table: the table plane (a seeded RANSAC fit to
//! the depth image, refined by least squares), the pixels standing above it, and their
//! connected components — one [`ObjectSegment`] (pixel mask, box, centroid, points) per object.
//!
//! The grasp images of `lgdm gen-dataset`, the autoencoder's recognition views and the robot's
//! camera all find objects this way, without labels; [`crate::crop`] then cuts the
//! object-centred input of the grasp network around a segment (`docs/DESIGN.md` §5).
//!
//! ```
//! use lgdm_pointcloud::math::look_at;
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};
//! use lgdm_pointcloud::segment::{SegmentParams, segment_objects};
//! use lgdm_pointcloud::grasp::cornell::table_mesh;
//! use lgdm_pointcloud::math::Pose;
//!
//! let camera = Camera::new(Intrinsics::kinect_qvga(), look_at([0.0, 0.0, 0.6], [0.0; 3], [0.0, 1.0, 0.0]));
//! let (table, mug) = (table_mesh(), procedural_object("mug", 0, 1).unwrap());
//! let frame = render(&camera, &[
//!     RenderItem { mesh: &table, world_from_object: Pose::identity(), label: 1 },
//!     RenderItem { mesh: &mug, world_from_object: Pose::identity(), label: 2 },
//! ]);
//! let scene = segment_objects(&frame, &camera.intrinsics, &SegmentParams::default()).unwrap();
//! assert_eq!(scene.objects.len(), 1);
//! // The camera is 0.6 m above the table; the point 0.6 m down its axis lies on it.
//! assert!((scene.table.offset_m - 0.6).abs() < 1e-3);
//! assert!(scene.table.distance_m([0.0, 0.0, 0.6]) < 1e-3);
//! ```

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;
use crate::math::{cross, dot, norm, scale, sub};
use crate::render::{Intrinsics, RgbdFrame};

/// How objects are found. Lengths in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentParams {
    /// A pixel belongs to an object when its point is at least this far above the table plane
    /// (default: 0.005).
    pub min_height_m: f32,
    /// Points within this distance of a plane hypothesis are its inliers (default: 0.004).
    pub plane_inlier_m: f32,
    /// The plane is fitted to every `plane_step_px`-th pixel in both directions (default: 4).
    pub plane_step_px: usize,
    /// RANSAC hypotheses (default: 200).
    pub plane_iterations: usize,
    /// Components with fewer pixels are noise, not objects (default: 50).
    pub min_pixels: usize,
    /// Split touching objects (default: true; [`SegmentParams::whole_components`] does not, as
    /// the dataset's grasp images were cut): two neighbouring pixels belong to one object
    /// unless both their depths differ by more than `edge_depth_m` and their colours by more
    /// than `edge_colour` — the edge where one object meets another of another colour and
    /// height. A single object's own steps (a mug's rim over its inside) share its colour.
    pub split_edges: bool,
    /// Depth step of an edge between touching objects (m; default 0.01).
    pub edge_depth_m: f32,
    /// Colour difference of an edge between touching objects: the sum of the absolute RGB
    /// differences (0–765; default 60).
    pub edge_colour: u32,
}

impl Default for SegmentParams {
    fn default() -> Self {
        Self {
            min_height_m: 0.005,
            plane_inlier_m: 0.004,
            plane_step_px: 4,
            plane_iterations: 200,
            min_pixels: 50,
            split_edges: true,
            edge_depth_m: 0.01,
            edge_colour: 60,
        }
    }
}

impl SegmentParams {
    /// The defaults without splitting touching objects: connected components only, as the
    /// dataset's grasp images (`gen-dataset`'s Cornell export) and the autoencoder's views are
    /// cut, so their bytes do not change.
    pub fn whole_components() -> Self {
        Self {
            split_edges: false,
            ..Self::default()
        }
    }
}

/// Why a frame could not be segmented.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SegmentError {
    /// The frame's buffers do not match its size or the intrinsics.
    #[error("frame buffers do not match {width}×{height} pixels")]
    Size {
        /// Expected width.
        width: u32,
        /// Expected height.
        height: u32,
    },
    /// A parameter is out of range.
    #[error("segmentation parameter {field}: {reason}")]
    Param {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: &'static str,
    },
    /// Too few valid depth pixels, or no plane supported by a fifth of them.
    #[error("no table plane found ({valid} valid depth samples, best plane has {inliers} inliers)")]
    NoTable {
        /// Valid depth samples on the fitting grid.
        valid: usize,
        /// Inliers of the best hypothesis.
        inliers: usize,
    },
}

/// A plane in the camera's optical frame: points `p` with `normal · p + offset_m = 0`; the
/// normal is a unit vector pointing towards the camera, so [`Plane::height_m`] is positive above
/// the table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    /// Unit normal, towards the camera (optical frame).
    pub normal: [f32; 3],
    /// Offset, metres (the camera's height above the plane).
    pub offset_m: f32,
}

impl Plane {
    /// Signed height of `p` above the plane, metres.
    pub fn height_m(&self, p: [f32; 3]) -> f32 {
        dot(self.normal, p) + self.offset_m
    }

    /// Distance from `p` to the plane, metres.
    pub fn distance_m(&self, p: [f32; 3]) -> f32 {
        self.height_m(p).abs()
    }

    /// Optical depth (z) where the ray through pixel `(u, v)` meets the plane; `None` when the
    /// ray is parallel to it or meets it behind the camera.
    pub fn depth_at(&self, intrinsics: &Intrinsics, u: f32, v: f32) -> Option<f32> {
        let ray = intrinsics.unproject(u, v, 1.0);
        let denom = dot(self.normal, ray);
        if denom.abs() < 1e-9 {
            return None;
        }
        let z = -self.offset_m / denom;
        (z.is_finite() && z > 0.0).then_some(z)
    }
}

/// One object found in a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSegment {
    /// Row-major indices of its pixels, ascending.
    pub pixels: Vec<u32>,
    /// Bounding box `[x_min, y_min, x_max, y_max]`, pixels (inclusive).
    pub bbox_px: [u32; 4],
    /// Mean pixel position `[x, y]`.
    pub centroid_px: [f32; 2],
    /// Its points in the optical frame, with the frame's colours, in pixel order.
    pub points: PointCloud,
    /// Height of its highest point above the table, metres.
    pub top_height_m: f32,
}

/// The table and the objects on it.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// The table plane.
    pub table: Plane,
    /// Objects, largest first (ties: first pixel first).
    pub objects: Vec<ObjectSegment>,
}

impl SegmentParams {
    /// Checks the parameters, naming the first bad field.
    pub fn validate(&self) -> Result<(), SegmentError> {
        let bad = |field, reason| Err(SegmentError::Param { field, reason });
        if !(self.min_height_m.is_finite() && self.min_height_m > 0.0) {
            return bad("min_height_m", "must be positive");
        }
        if !(self.plane_inlier_m.is_finite() && self.plane_inlier_m > 0.0) {
            return bad("plane_inlier_m", "must be positive");
        }
        if !(1..=64).contains(&self.plane_step_px) {
            return bad("plane_step_px", "must be in 1..=64");
        }
        if !(1..=100_000).contains(&self.plane_iterations) {
            return bad("plane_iterations", "must be in 1..=100000");
        }
        if !(self.edge_depth_m.is_finite() && self.edge_depth_m > 0.0) {
            return bad("edge_depth_m", "must be positive");
        }
        if self.edge_colour > 765 {
            return bad("edge_colour", "must be in 0..=765");
        }
        Ok(())
    }
}

fn check_frame(frame: &RgbdFrame, k: &Intrinsics) -> Result<usize, SegmentError> {
    let n = frame.width as usize * frame.height as usize;
    if frame.width != k.width
        || frame.height != k.height
        || frame.depth_m.len() != n
        || frame.rgb.len() != n
    {
        return Err(SegmentError::Size {
            width: k.width,
            height: k.height,
        });
    }
    Ok(n)
}

fn valid_depth(z: f32) -> bool {
    z.is_finite() && z > 0.0
}

/// Fits the table plane to the frame's depth (see the module docs). Deterministic: the RANSAC
/// draws come from a fixed seed.
pub fn fit_table_plane(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    params: &SegmentParams,
) -> Result<Plane, SegmentError> {
    params.validate()?;
    check_frame(frame, intrinsics)?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let step = params.plane_step_px;
    let mut pts = Vec::new();
    for y in (0..h).step_by(step) {
        for x in (0..w).step_by(step) {
            let z = frame.depth_m[y * w + x];
            if valid_depth(z) {
                pts.push(intrinsics.unproject(x as f32, y as f32, z));
            }
        }
    }
    let no_table = |inliers| SegmentError::NoTable {
        valid: pts.len(),
        inliers,
    };
    if pts.len() < 3 {
        return Err(no_table(0));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0x7AB1E);
    let mut best: Option<(usize, Plane)> = None;
    for _ in 0..params.plane_iterations {
        let a = pts[rng.random_range(0..pts.len())];
        let b = pts[rng.random_range(0..pts.len())];
        let c = pts[rng.random_range(0..pts.len())];
        let n = cross(sub(b, a), sub(c, a));
        let len = norm(n);
        if len < 1e-9 {
            continue;
        }
        let plane = oriented(scale(n, 1.0 / len), a);
        let inliers = pts
            .iter()
            .filter(|&&p| plane.distance_m(p) < params.plane_inlier_m)
            .count();
        // Ties keep the lower plane (further from the camera): the table is under the objects.
        let better = match &best {
            None => true,
            Some((k, p)) => inliers > *k || (inliers == *k && plane.offset_m > p.offset_m),
        };
        if better {
            best = Some((inliers, plane));
        }
    }
    let Some((inliers, plane)) = best else {
        return Err(no_table(0));
    };
    if inliers < 3 || inliers * 5 < pts.len() {
        return Err(no_table(inliers));
    }
    // Least-squares refinement on the inliers (smallest principal axis).
    let inl: Vec<[f32; 3]> = pts
        .iter()
        .copied()
        .filter(|&p| plane.distance_m(p) < params.plane_inlier_m)
        .collect();
    let m = inl.len() as f64;
    let mean = inl.iter().fold(Vector3::<f64>::zeros(), |s, p| {
        s + Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    }) / m;
    let mut cov = Matrix3::<f64>::zeros();
    for p in &inl {
        let d = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) - mean;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov / m);
    let i = eig.eigenvalues.imin();
    let n = eig.eigenvectors.column(i);
    let refined = oriented(
        [n[0] as f32, n[1] as f32, n[2] as f32],
        [mean[0] as f32, mean[1] as f32, mean[2] as f32],
    );
    Ok(refined)
}

/// The plane through `p` with unit normal `n`, the normal turned towards the camera (origin).
fn oriented(n: [f32; 3], p: [f32; 3]) -> Plane {
    let offset = -dot(n, p);
    if offset < 0.0 {
        Plane {
            normal: scale(n, -1.0),
            offset_m: -offset,
        }
    } else {
        Plane {
            normal: n,
            offset_m: offset,
        }
    }
}

/// The table plane and the objects standing on it: pixels whose point is at least
/// `min_height_m` above the plane, grouped into 8-connected components of at least
/// `min_pixels` pixels.
pub fn segment_objects(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    params: &SegmentParams,
) -> Result<Segmentation, SegmentError> {
    let table = fit_table_plane(frame, intrinsics, params)?;
    let objects = objects_above(frame, intrinsics, &table, params)?;
    Ok(Segmentation { table, objects })
}

/// The objects above a known table plane (see [`segment_objects`]).
pub fn objects_above(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    table: &Plane,
    params: &SegmentParams,
) -> Result<Vec<ObjectSegment>, SegmentError> {
    params.validate()?;
    let n = check_frame(frame, intrinsics)?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let point = |i: usize| intrinsics.unproject((i % w) as f32, (i / w) as f32, frame.depth_m[i]);
    let above: Vec<bool> = (0..n)
        .map(|i| valid_depth(frame.depth_m[i]) && table.height_m(point(i)) >= params.min_height_m)
        .collect();
    // Whether neighbours `i` and `j` (both above the table) are one object.
    let joined = |i: usize, j: usize| {
        if !params.split_edges {
            return true;
        }
        let step = (frame.depth_m[i] - frame.depth_m[j]).abs();
        let [a, b] = [frame.rgb[i], frame.rgb[j]];
        let colour: u32 = (0..3).map(|k| u32::from(a[k].abs_diff(b[k]))).sum();
        !(step > params.edge_depth_m && colour > params.edge_colour)
    };
    let mut seen = vec![false; n];
    let mut objects = Vec::new();
    let mut stack = Vec::new();
    for start in 0..n {
        if !above[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut pixels = Vec::new();
        while let Some(i) = stack.pop() {
            pixels.push(i as u32);
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if above[j] && !seen[j] && joined(i, j) {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if pixels.len() < params.min_pixels {
            continue;
        }
        pixels.sort_unstable();
        let mut bbox = [u32::MAX, u32::MAX, 0, 0];
        let (mut sx, mut sy) = (0.0f64, 0.0f64);
        let mut points = Vec::with_capacity(pixels.len());
        let mut colors = Vec::with_capacity(pixels.len());
        let mut top = f32::MIN;
        for &p in &pixels {
            let (x, y) = (p % w as u32, p / w as u32);
            bbox = [
                bbox[0].min(x),
                bbox[1].min(y),
                bbox[2].max(x),
                bbox[3].max(y),
            ];
            sx += x as f64;
            sy += y as f64;
            let q = point(p as usize);
            top = top.max(table.height_m(q));
            points.push(q);
            colors.push(frame.rgb[p as usize]);
        }
        let m = pixels.len() as f64;
        objects.push(ObjectSegment {
            bbox_px: bbox,
            centroid_px: [(sx / m) as f32, (sy / m) as f32],
            points: PointCloud::new(points, Some(colors)),
            top_height_m: top,
            pixels,
        });
    }
    objects.sort_by(|a, b| {
        b.pixels
            .len()
            .cmp(&a.pixels.len())
            .then(a.pixels[0].cmp(&b.pixels[0]))
    });
    Ok(objects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grasp::cornell::table_mesh;
    use crate::math::{Pose, look_at, translation};
    use crate::objects::procedural_object;
    use crate::render::{Camera, RenderItem, render};

    fn scene(objects: &[(&str, [f32; 3])], eye: [f32; 3]) -> (Camera, RgbdFrame) {
        let camera = Camera::new(
            Intrinsics::kinect_qvga(),
            look_at(eye, [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        );
        let table = table_mesh();
        let meshes: Vec<_> = objects
            .iter()
            .map(|(c, _)| procedural_object(c, 0, 3).unwrap())
            .collect();
        let mut items = vec![RenderItem {
            mesh: &table,
            world_from_object: Pose::identity(),
            label: 1,
        }];
        for (m, (_, at)) in meshes.iter().zip(objects) {
            items.push(RenderItem {
                mesh: m,
                world_from_object: translation(*at),
                label: 2,
            });
        }
        let frame = render(&camera, &items);
        (camera, frame)
    }

    #[test]
    fn finds_the_table_under_a_tilted_camera() {
        // 30° elevation, 0.75 m away, as the dataset's turntable camera.
        let eye = [0.0, -0.65, 0.375];
        let (camera, frame) = scene(&[("bowl", [0.0; 3])], eye);
        let plane = fit_table_plane(&frame, &camera.intrinsics, &SegmentParams::default()).unwrap();
        // The camera is 0.375 m above the table.
        assert!((plane.offset_m - 0.375).abs() < 1e-3, "{plane:?}");
    }

    #[test]
    fn separate_objects_are_separate_segments_largest_first() {
        let (camera, frame) = scene(
            &[("mug", [-0.12, 0.0, 0.0]), ("bowl", [0.1, 0.0, 0.0])],
            [0.0, 0.0, 0.6],
        );
        let seg = segment_objects(&frame, &camera.intrinsics, &SegmentParams::default()).unwrap();
        assert_eq!(seg.objects.len(), 2);
        assert!(seg.objects[0].pixels.len() >= seg.objects[1].pixels.len());
        // The bowl (x > 0) is on the image's right: camera up is world +y, so x is image x.
        let cx = camera.intrinsics.cx;
        assert!(seg.objects.iter().any(|o| o.centroid_px[0] > cx));
        assert!(seg.objects.iter().any(|o| o.centroid_px[0] < cx));
        for o in &seg.objects {
            assert!(
                o.top_height_m > 0.03 && o.top_height_m < 0.2,
                "{}",
                o.top_height_m
            );
            assert_eq!(o.points.len(), o.pixels.len());
        }
    }

    /// Two boxes pushed together (a red 10 cm one and a blue 6 cm one, touching along x = 0)
    /// and a two-step object of one colour, seen from 0.6 m straight above.
    fn touching_boxes() -> (Camera, RgbdFrame) {
        let camera = Camera::new(
            Intrinsics::kinect_qvga(),
            look_at([0.0, 0.0, 0.6], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        );
        let table = table_mesh();
        let red = crate::mesh::Mesh::cuboid([-0.03, 0.0, 0.05], [0.06, 0.06, 0.1], [200, 30, 30]);
        let blue = crate::mesh::Mesh::cuboid([0.03, 0.0, 0.03], [0.06, 0.06, 0.06], [30, 60, 200]);
        // One green object with a step: a 4 cm base and a narrower 8 cm tower in it.
        let mut stepped =
            crate::mesh::Mesh::cuboid([0.0, -0.12, 0.02], [0.08, 0.06, 0.04], [40, 160, 40]);
        stepped.append(&crate::mesh::Mesh::cuboid(
            [0.0, -0.12, 0.04],
            [0.03, 0.03, 0.08],
            [40, 160, 40],
        ));
        let items = [
            RenderItem {
                mesh: &table,
                world_from_object: Pose::identity(),
                label: 1,
            },
            RenderItem {
                mesh: &red,
                world_from_object: Pose::identity(),
                label: 2,
            },
            RenderItem {
                mesh: &blue,
                world_from_object: Pose::identity(),
                label: 3,
            },
            RenderItem {
                mesh: &stepped,
                world_from_object: Pose::identity(),
                label: 4,
            },
        ];
        let frame = render(&camera, &items);
        (camera, frame)
    }

    #[test]
    fn touching_objects_of_other_colours_and_heights_are_split_on_request() {
        let (camera, frame) = touching_boxes();
        let plain = segment_objects(
            &frame,
            &camera.intrinsics,
            &SegmentParams::whole_components(),
        )
        .unwrap();
        assert_eq!(
            plain.objects.len(),
            2,
            "the touching boxes are one component"
        );
        let split = SegmentParams {
            split_edges: true,
            ..SegmentParams::default()
        };
        let seg = segment_objects(&frame, &camera.intrinsics, &split).unwrap();
        assert_eq!(
            seg.objects.len(),
            3,
            "the boxes apart, the stepped object whole"
        );
        let mut tops: Vec<f32> = seg.objects.iter().map(|o| o.top_height_m).collect();
        tops.sort_by(f32::total_cmp);
        for (top, want) in tops.iter().zip([0.06, 0.08, 0.1]) {
            assert!((top - want).abs() < 0.01, "{tops:?}");
        }
        // Each segment holds one object: one dominant colour channel (shading darkens the
        // sides, it does not change the hue).
        let hue = |c: &[u8; 3]| (0..3).max_by_key(|&k| c[k]).unwrap();
        for o in &seg.objects {
            let colours = o.points.colors.as_ref().unwrap();
            let first = hue(&colours[0]);
            assert!(
                colours.iter().all(|c| hue(c) == first),
                "a segment mixes objects"
            );
        }
    }

    #[test]
    fn an_empty_table_has_no_objects_and_a_blank_frame_no_table() {
        let (camera, frame) = scene(&[], [0.0, 0.0, 0.6]);
        let seg = segment_objects(&frame, &camera.intrinsics, &SegmentParams::default()).unwrap();
        assert!(seg.objects.is_empty());
        let blank = RgbdFrame {
            depth_m: vec![0.0; frame.depth_m.len()],
            ..frame.clone()
        };
        assert!(matches!(
            segment_objects(&blank, &camera.intrinsics, &SegmentParams::default()),
            Err(SegmentError::NoTable { .. })
        ));
        let short = RgbdFrame {
            depth_m: vec![0.5; 3],
            ..frame
        };
        assert!(matches!(
            segment_objects(&short, &camera.intrinsics, &SegmentParams::default()),
            Err(SegmentError::Size { .. })
        ));
    }
}
