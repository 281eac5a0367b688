//! The grasp network's input: an **object-centred crop of fixed metric size** — a square of
//! [`CropSpec::side_m`] of table (measured on the table plane at the crop centre) around one
//! segmented object, resampled to [`CropSpec::size_px`] pixels (`docs/DESIGN.md` §5).
//!
//! One function, [`object_crop`], makes it for every user: the grasp images of
//! `lgdm gen-dataset` (so training and evaluation read it from disk), the autoencoder's
//! recognition views (`--encoder ae`) and the robot's camera. The network then always sees the
//! same pixels per metre, whatever camera took the frame.
//!
//! The default, 0.22 m at 224 px (≈ 1 mm per pixel; 2 mm at the `cpu` network's 112 px), was
//! chosen from the procedural objects: the widest round object (a bowl, up to 0.18 m) fits with
//! a margin for the centroid's offset, while a 5 mm rim is 5 px wide in the crop and 2.5 px at
//! the `cpu` input, and a finger (0.02 m) 20 px / 10 px. Long objects (books, boxes, up to
//! 0.28 m) stick out; their grasps lie across the short side, near the centre.
//!
//! Resampling is bilinear at pixel centres (map pixel `(x, y)` ↔ image point
//! `((x + ½)·s − ½ + x0, (y + ½)·s − ½ + y0)`, the [`InputCrop`] convention); depth averages
//! only valid neighbours (0 where none is valid); the frame's edge is replicated outside it.
//!
//! ```
//! use lgdm_pointcloud::crop::{CropSpec, crop_largest_object};
//! use lgdm_pointcloud::grasp::cornell::table_mesh;
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
//! let spec = CropSpec::default();
//! let found = crop_largest_object(&frame, &camera.intrinsics, &SegmentParams::default(), &spec).unwrap();
//! assert_eq!(found.crop.depth_m.len(), 224 * 224);
//! // 0.22 m at 0.5 m with a 575 px focal length is 253 image pixels.
//! assert!((found.crop.window.image_px_per_map_px * 224.0 - 253.0).abs() < 1.0);
//! ```

use serde::{Deserialize, Serialize};

use crate::grasp::decode::InputCrop;
use crate::render::{Intrinsics, RgbdFrame};
use crate::segment::{ObjectSegment, Plane, SegmentError, SegmentParams, segment_objects};

/// Default side of the crop, metres of table.
pub const DEFAULT_CROP_SIDE_M: f32 = 0.22;

/// Default side of the crop, pixels.
pub const DEFAULT_CROP_PX: u32 = 224;

/// Size of the object-centred crop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CropSpec {
    /// Side of the square, metres of table at the crop centre (default: 0.22).
    pub side_m: f32,
    /// Side of the resampled crop, pixels (default: 224).
    pub size_px: u32,
}

impl Default for CropSpec {
    fn default() -> Self {
        Self {
            side_m: DEFAULT_CROP_SIDE_M,
            size_px: DEFAULT_CROP_PX,
        }
    }
}

impl CropSpec {
    /// Checks the spec, naming the first bad field.
    pub fn validate(&self) -> Result<(), CropError> {
        if !(self.side_m.is_finite() && self.side_m >= 0.02 && self.side_m <= 2.0) {
            return Err(CropError::Param {
                field: "side_m",
                reason: "must be in [0.02, 2] metres",
            });
        }
        if !(8..=1024).contains(&self.size_px) {
            return Err(CropError::Param {
                field: "size_px",
                reason: "must be in 8..=1024",
            });
        }
        Ok(())
    }

    /// Metres of table per crop pixel.
    pub fn metres_per_px(&self) -> f32 {
        self.side_m / self.size_px as f32
    }

    /// A length on the table as a fraction of the crop side: the jaw of a grasp rectangle is
    /// `side_fraction(finger_width_m)` × the side of the image or map, in pixels.
    pub fn side_fraction(&self, length_m: f32) -> f32 {
        length_m / self.side_m
    }
}

/// Why a crop could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CropError {
    /// A crop parameter is out of range.
    #[error("crop parameter {field}: {reason}")]
    Param {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: &'static str,
    },
    /// The frame could not be segmented.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// The crop centre's ray does not meet the table in front of the camera.
    #[error("the ray through pixel ({x}, {y}) does not meet the table plane")]
    OffTable {
        /// Column.
        x: f32,
        /// Row.
        y: f32,
    },
}

/// An object-centred crop.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectCrop {
    /// Side, pixels.
    pub size_px: u32,
    /// Row-major colours.
    pub rgb: Vec<[u8; 3]>,
    /// Row-major optical depth, metres (0: no data).
    pub depth_m: Vec<f32>,
    /// Where the crop sits in the frame (crop pixel → frame pixel).
    pub window: InputCrop,
    /// Optical depth of the table at the crop centre, metres.
    pub table_depth_m: f32,
}

impl ObjectCrop {
    /// Frame pixel of crop pixel `p`.
    pub fn frame_from_crop(&self, p: [f32; 2]) -> [f32; 2] {
        self.window.image_from_map(p)
    }

    /// Crop pixel of frame pixel `p`.
    pub fn crop_from_frame(&self, p: [f32; 2]) -> [f32; 2] {
        let s = self.window.image_px_per_map_px;
        [
            (p[0] + 0.5 - self.window.x0_px) / s - 0.5,
            (p[1] + 0.5 - self.window.y0_px) / s - 0.5,
        ]
    }

    /// Crop pixels per frame pixel.
    pub fn scale(&self) -> f32 {
        1.0 / self.window.image_px_per_map_px
    }

    /// Fills the depth's holes (0: a camera's missing pixels, [`crate::sensor`]): each run of
    /// missing pixels along a row between two valid pixels takes the farther of their depths,
    /// as a missing pixel next to an object is most often the surface behind it (a stereo
    /// shadow on the table, an edge's lost pixels); columns then do the same; what neither
    /// reaches (a run open at the crop's edge) takes the table's depth at the crop centre, never
    /// the nearer surface, which would widen the object. Deterministic; returns the pixels
    /// filled (0 for a crop without holes).
    pub fn fill_depth_holes(&mut self) -> usize {
        let n = self.size_px as usize;
        if self.depth_m.len() != n * n || n == 0 {
            return 0;
        }
        let mut filled = fill_runs(&mut self.depth_m, n, 1, n, n);
        if self.depth_m.iter().any(|&d| !valid_depth(d)) {
            filled += fill_runs(&mut self.depth_m, n, n, 1, n);
        }
        if valid_depth(self.table_depth_m) {
            for d in self.depth_m.iter_mut().filter(|d| !valid_depth(**d)) {
                *d = self.table_depth_m;
                filled += 1;
            }
        }
        filled
    }
}

fn valid_depth(d: f32) -> bool {
    d.is_finite() && d > 0.0
}

/// Fills each run of invalid depths between two valid ones along `lines` lines of `len` pixels
/// (pixel k of line l at `l * line_stride + k * step`) with the farther of the two; returns the
/// count.
fn fill_runs(
    depth: &mut [f32],
    lines: usize,
    step: usize,
    line_stride: usize,
    len: usize,
) -> usize {
    let mut filled = 0;
    for l in 0..lines {
        let at = |k: usize| l * line_stride + k * step;
        let mut k = 0;
        while k < len {
            if valid_depth(depth[at(k)]) {
                k += 1;
                continue;
            }
            let start = k;
            while k < len && !valid_depth(depth[at(k)]) {
                k += 1;
            }
            if start == 0 || k == len {
                continue;
            }
            let fill = depth[at(start - 1)].max(depth[at(k)]);
            for j in start..k {
                depth[at(j)] = fill;
            }
            filled += k - start;
        }
    }
    filled
}

/// Cuts the crop of `spec` centred on frame pixel `centre_px`; its side in frame pixels is
/// `side_m` at the depth where the centre's ray meets `table`.
pub fn object_crop(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    table: &Plane,
    centre_px: [f32; 2],
    spec: &CropSpec,
) -> Result<ObjectCrop, CropError> {
    spec.validate()?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    if frame.width != intrinsics.width
        || frame.height != intrinsics.height
        || frame.depth_m.len() != w * h
        || frame.rgb.len() != w * h
        || w == 0
        || h == 0
    {
        return Err(SegmentError::Size {
            width: intrinsics.width,
            height: intrinsics.height,
        }
        .into());
    }
    let [cx, cy] = centre_px;
    let off_table = CropError::OffTable { x: cx, y: cy };
    if !(cx.is_finite() && cy.is_finite()) {
        return Err(off_table);
    }
    let z = table.depth_at(intrinsics, cx, cy).ok_or(off_table)?;
    let side_px = spec.side_m * intrinsics.fx / z;
    let s = side_px / spec.size_px as f32;
    let window = InputCrop {
        x0_px: cx - side_px / 2.0 + 0.5,
        y0_px: cy - side_px / 2.0 + 0.5,
        image_px_per_map_px: s,
    };
    let n = spec.size_px as usize;
    let mut rgb = Vec::with_capacity(n * n);
    let mut depth = Vec::with_capacity(n * n);
    for y in 0..n {
        for x in 0..n {
            let [u, v] = window.image_from_map([x as f32, y as f32]);
            let u = u.clamp(0.0, (w - 1) as f32);
            let v = v.clamp(0.0, (h - 1) as f32);
            let (x0, y0) = (u.floor() as usize, v.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (tx, ty) = (u - x0 as f32, v - y0 as f32);
            let taps = [
                (y0 * w + x0, (1.0 - tx) * (1.0 - ty)),
                (y0 * w + x1, tx * (1.0 - ty)),
                (y1 * w + x0, (1.0 - tx) * ty),
                (y1 * w + x1, tx * ty),
            ];
            let mut c = [0.0f32; 3];
            let (mut dz, mut wz) = (0.0f32, 0.0f32);
            for (i, wt) in taps {
                for (k, ck) in c.iter_mut().enumerate() {
                    *ck += wt * frame.rgb[i][k] as f32;
                }
                let d = frame.depth_m[i];
                if d.is_finite() && d > 0.0 {
                    dz += wt * d;
                    wz += wt;
                }
            }
            rgb.push(c.map(|v| v.round().clamp(0.0, 255.0) as u8));
            depth.push(if wz > 1e-6 { dz / wz } else { 0.0 });
        }
    }
    Ok(ObjectCrop {
        size_px: spec.size_px,
        rgb,
        depth_m: depth,
        window,
        table_depth_m: z,
    })
}

/// A crop around the largest object of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundObject {
    /// The crop (centred on the frame's centre when no object was found).
    pub crop: ObjectCrop,
    /// The table plane.
    pub table: Plane,
    /// The object, `None` when the table is empty.
    pub object: Option<ObjectSegment>,
}

/// Segments the frame ([`segment_objects`]) and crops around the centroid of its largest
/// object — or around the frame's centre when no object stands on the table.
pub fn crop_largest_object(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    params: &SegmentParams,
    spec: &CropSpec,
) -> Result<FoundObject, CropError> {
    let seg = segment_objects(frame, intrinsics, params)?;
    let object = seg.objects.into_iter().next();
    let centre = object
        .as_ref()
        .map(|o| o.centroid_px)
        .unwrap_or([intrinsics.cx, intrinsics.cy]);
    let crop = object_crop(frame, intrinsics, &seg.table, centre, spec)?;
    Ok(FoundObject {
        crop,
        table: seg.table,
        object,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grasp::cornell::table_mesh;
    use crate::math::{Pose, look_at, translation};
    use crate::objects::procedural_object;
    use crate::render::{Camera, RenderItem, render};

    fn frame_at(height_m: f32, at: [f32; 3], k: Intrinsics) -> (Camera, RgbdFrame) {
        let camera = Camera::new(k, look_at([0.0, 0.0, height_m], [0.0; 3], [0.0, 1.0, 0.0]));
        let (table, bowl) = (table_mesh(), procedural_object("bowl", 0, 2).unwrap());
        let frame = render(
            &camera,
            &[
                RenderItem {
                    mesh: &table,
                    world_from_object: Pose::identity(),
                    label: 1,
                },
                RenderItem {
                    mesh: &bowl,
                    world_from_object: translation(at),
                    label: 2,
                },
            ],
        );
        (camera, frame)
    }

    /// Two cameras of different resolutions and focal lengths give crops of the same metric
    /// scale: the object covers about the same number of crop pixels. (The scale is the
    /// table's: from another height, perspective makes the object's top larger or smaller —
    /// 16 % more pixels for a 6 cm bowl at 0.5 m than at 1.1 m — so the robot renders its
    /// crops from the training camera's height.)
    #[test]
    fn holes_take_the_farther_surface() {
        let mut crop = ObjectCrop {
            size_px: 5,
            rgb: vec![[0; 3]; 25],
            depth_m: vec![0.5; 25],
            window: InputCrop {
                x0_px: 0.0,
                y0_px: 0.0,
                image_px_per_map_px: 1.0,
            },
            table_depth_m: 0.5,
        };
        assert_eq!(crop.fill_depth_holes(), 0);
        // An object top at 0.4 m in the left columns, a 2-px hole beside it, table beyond.
        for y in 0..5 {
            crop.depth_m[y * 5] = 0.4;
            crop.depth_m[y * 5 + 1] = 0.0;
            crop.depth_m[y * 5 + 2] = 0.0;
        }
        let copy = crop.clone();
        assert_eq!(crop.fill_depth_holes(), 10);
        for y in 0..5 {
            assert_eq!(&crop.depth_m[y * 5..y * 5 + 5], &[0.4, 0.5, 0.5, 0.5, 0.5]);
        }
        let mut again = copy;
        again.fill_depth_holes();
        assert_eq!(again, crop);
        // A whole missing row is filled from its column.
        crop.depth_m[10..15].fill(0.0);
        assert_eq!(crop.fill_depth_holes(), 5);
        assert_eq!(&crop.depth_m[10..15], &[0.4, 0.5, 0.5, 0.5, 0.5]);
        // A run open at the crop's edge never takes the nearer surface: the table's depth.
        crop.depth_m[0] = 0.0;
        crop.depth_m[5] = 0.0;
        crop.depth_m[1] = 0.4;
        crop.depth_m[6] = 0.4;
        crop.table_depth_m = 0.55;
        assert_eq!(crop.fill_depth_holes(), 2);
        assert_eq!((crop.depth_m[0], crop.depth_m[5]), (0.55, 0.55));
        let mut empty = ObjectCrop {
            depth_m: vec![0.0; 25],
            table_depth_m: 0.0,
            ..crop
        };
        assert_eq!(empty.fill_depth_holes(), 0);
    }

    #[test]
    fn crops_have_a_fixed_metric_scale() {
        let spec = CropSpec::default();
        let params = SegmentParams::default();
        let object_px = |height, k| {
            let (c, f) = frame_at(height, [0.03, -0.02, 0.0], k);
            let found = crop_largest_object(&f, &c.intrinsics, &params, &spec).unwrap();
            let table = found.crop.table_depth_m;
            found
                .crop
                .depth_m
                .iter()
                .filter(|&&d| d > 0.0 && d < table - 0.005)
                .count() as f32
        };
        let near = object_px(0.5, Intrinsics::kinect_vga());
        let sharp = object_px(0.5, Intrinsics::centered(1024, 1024, 1400.0));
        assert!(near > 2000.0, "{near}");
        assert!((near / sharp - 1.0).abs() < 0.03, "{near} vs {sharp}");
        let far = object_px(1.1, Intrinsics::centered(1024, 1024, 1400.0));
        assert!((near / far - 1.0).abs() < 0.25, "{near} vs {far}");
    }

    /// The crop is centred on the object, wherever it stands in the frame.
    #[test]
    fn the_object_is_at_the_crop_centre() {
        let spec = CropSpec::default();
        let (c, f) = frame_at(0.5, [0.08, 0.05, 0.0], Intrinsics::kinect_vga());
        let found =
            crop_largest_object(&f, &c.intrinsics, &SegmentParams::default(), &spec).unwrap();
        let o = found.object.unwrap();
        let centre = found.crop.crop_from_frame(o.centroid_px);
        assert!((centre[0] - 111.5).abs() < 1e-3 && (centre[1] - 111.5).abs() < 1e-3);
        let back = found.crop.frame_from_crop(centre);
        assert!((back[0] - o.centroid_px[0]).abs() < 1e-3);
        // Crop pixels around the centre are the object (above the table).
        let table = found.crop.table_depth_m;
        let d = found.crop.depth_m[112 * 224 + 112];
        assert!(d > 0.0 && d < table - 0.005, "{d} vs table {table}");
    }

    #[test]
    fn bad_specs_and_centres_are_errors() {
        let (c, f) = frame_at(0.5, [0.0; 3], Intrinsics::kinect_vga());
        let seg = segment_objects(&f, &c.intrinsics, &SegmentParams::default()).unwrap();
        let bad = CropSpec {
            side_m: f32::NAN,
            ..CropSpec::default()
        };
        assert!(matches!(
            object_crop(&f, &c.intrinsics, &seg.table, [10.0, 10.0], &bad),
            Err(CropError::Param {
                field: "side_m",
                ..
            })
        ));
        assert!(matches!(
            object_crop(
                &f,
                &c.intrinsics,
                &seg.table,
                [f32::NAN, 1.0],
                &CropSpec::default()
            ),
            Err(CropError::OffTable { .. })
        ));
    }
}
