//! Grasp decoding: the grasp network's four pixel-wise maps (quality, cos 2θ, sin 2θ, width)
//! become ranked grasp rectangles ([`decode_grasps`]) and then 3-D grasp poses in the camera's
//! optical frame ([`grasp_pose`]). The inverse, rectangles → label maps ([`grasp_maps`]), gives
//! the training targets and lets tests check the round trip.
//!
//! Every convention is the one of `python/train_ae/src/train_ae/grasp.py` (`grasp_maps`,
//! `decode_grasps`), which trains the network, so that the robot decodes what was learnt:
//!
//! - Pixel (row r, column c) has its centre at (x = c, y = r), as in [`crate::render`].
//! - The grasp angle θ (radians) is the direction of the opening axis (a rectangle's first edge,
//!   corner 0 → corner 1) counter-clockwise *as seen on screen* from +x:
//!   θ = atan2(−dy, dx), wrapped to [−π/2, π/2) ([`grasp_angle`], [`wrap_angle`]). Note that
//!   [`GraspRectangle::angle`] and [`GraspRectangle::from_center`] turn from image x towards
//!   image y (clockwise on screen), i.e. they use −θ.
//! - Maps hold cos 2θ and sin 2θ (a parallel-jaw grasp is symmetric under θ → θ + π) and
//!   `width_px / WIDTH_SCALE_PX` clipped to [0, 1], with [`WIDTH_SCALE_PX`] = 150 pixels at the
//!   network input resolution.
//! - Label maps (GG-CNN style) mark quality 1, the angle and the width at the pixels whose
//!   centres lie inside the central third of each rectangle's opening axis (full jaw extent);
//!   later rectangles overwrite earlier ones; elsewhere every map is 0.
//! - Decoding smooths quality, cos 2θ and sin 2θ with a Gaussian of σ = 2 px (the trigonometric
//!   maps, never the wrapped angle, so that θ ≈ +90° and θ ≈ −90° average to ±90°, not 0°) and
//!   width with σ = 1 px; keeps the pixels that are the maximum of the smoothed quality within
//!   a square window of radius `min_distance_px` (Chebyshev distance, as `max_pool2d`) and
//!   reach the threshold; takes them best first (ties by row, then column), a flat top (equal
//!   maxima within the window) counting once at its mean position and the other maxima within
//!   the window of an accepted one being dropped; and reads θ = ½·atan2(sin, cos),
//!   opening = width · [`WIDTH_SCALE_PX`] at the peak.
//! - **The jaw is the gripper's finger width**: every decoded rectangle's jaw is
//!   `jaw_side_fraction` × the map side, the finger width in the object-centred crop
//!   ([`crate::crop`]: 0.02 m / 0.22 m, ≈ 10 px at 112 px) — the jaw every label of
//!   `lgdm gen-dataset` has. `jaw_side_fraction: None` gives Cornell's jaw = opening / 2, for
//!   whole-frame data labelled that way.
//!
//! The maps are at the network input resolution; [`InputCrop`] says where they sit in the
//! camera image (train_ae's `data.py` crops a square and resizes it), and [`grasp_pose`] places
//! a grasp with the median valid depth around its centre and the pinhole [`Intrinsics`].
//!
//! ```
//! use lgdm_pointcloud::grasp::GraspRectangle;
//! use lgdm_pointcloud::grasp::decode::{
//!     GraspDecodeParams, InputCrop, decode_grasps, grasp_maps, grasp_pose,
//! };
//! use lgdm_pointcloud::render::Intrinsics;
//!
//! // A 45 px grasp at θ = 30° (counter-clockwise on screen; `from_center` takes −θ).
//! let truth = GraspRectangle::from_center([60.0, 50.0], -30f32.to_radians(), 45.0, 20.0);
//! let maps = grasp_maps(&[truth], 112, 112).unwrap();
//! let params = GraspDecodeParams::default();
//! let best = decode_grasps(maps.view(), &params).unwrap()[0];
//! assert!((best.angle - 30f32.to_radians()).abs() < 0.01);
//! assert!((best.width_px - 45.0).abs() < 1.0);
//!
//! // The maps are the whole 112×112 image of a camera looking at a plane 0.5 m away.
//! let intrinsics = Intrinsics::centered(112, 112, 100.0);
//! let depth_m = vec![0.5; 112 * 112];
//! let pose = grasp_pose(&best, &depth_m, &intrinsics, &InputCrop::IDENTITY, &params).unwrap();
//! assert!((pose.position_m[2] - 0.5).abs() < 1e-6);
//! assert!((pose.opening_m - 45.0 * 0.5 / 100.0).abs() < 0.005);
//! ```

use std::f32::consts::{FRAC_PI_2, PI};

use serde::{Deserialize, Serialize};

use super::label::GraspRectangle;
use crate::math::{Pose, cross, dot, median, norm, normalize, pose_from_columns, scale, sub};
use crate::render::Intrinsics;

/// Opening width (pixels at the network input resolution) that maps to 1.0 in the width map
/// (`WIDTH_SCALE_PX` of train_ae's `grasp.py`).
pub const WIDTH_SCALE_PX: f32 = 150.0;

/// Label maps mark only this central fraction of each rectangle's opening axis (GG-CNN;
/// `LABEL_CENTRE_FRACTION` of train_ae's `grasp.py`).
pub const LABEL_CENTRE_FRACTION: f32 = 1.0 / 3.0;

/// Cornell's jaw: half the opening (`JAW_FRACTION` of train_ae's `grasp.py`).
pub const CORNELL_JAW_FRACTION: f32 = 0.5;

/// The default finger width over the default crop side (0.02 m / 0.22 m).
pub const DEFAULT_JAW_SIDE_FRACTION: f32 =
    super::label::DEFAULT_FINGER_WIDTH_M / crate::crop::DEFAULT_CROP_SIDE_M;

/// Largest accepted smoothing σ, pixels (the kernel has `2·⌊4σ + ½⌋ + 1` taps).
pub const MAX_SIGMA_PX: f32 = 64.0;

/// How maps become grasps and grasps become poses. Defaults are train_ae's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GraspDecodeParams {
    /// Most grasps returned, best first (default: 1, as `decode_grasps` in train_ae).
    pub num_grasps: usize,
    /// Quality threshold: peaks of the smoothed quality map below it are not grasps
    /// (default: 0.2).
    pub quality_threshold: f32,
    /// Peak window radius, pixels: a peak must be the maximum of the smoothed quality within
    /// this Chebyshev distance, and maxima within it of an accepted peak are dropped
    /// (default: 20).
    pub min_distance_px: usize,
    /// Gaussian σ smoothing the quality, cos 2θ and sin 2θ maps, pixels; 0 disables it
    /// (default: 2).
    pub quality_sigma_px: f32,
    /// Gaussian σ smoothing the width map, pixels; 0 disables it (default: 1).
    pub width_sigma_px: f32,
    /// Jaw extent of a decoded rectangle as a fraction of the map side (default: 0.02 / 0.22,
    /// the finger width in the default object-centred crop); `None`: half the opening
    /// (Cornell's convention).
    pub jaw_side_fraction: Option<f32>,
    /// Half-side of the square window of the depth image whose median valid depth places a
    /// grasp, pixels (default: 2, a 5×5 window).
    pub depth_radius_px: usize,
}

impl Default for GraspDecodeParams {
    fn default() -> Self {
        Self {
            num_grasps: 1,
            quality_threshold: 0.2,
            min_distance_px: 20,
            quality_sigma_px: 2.0,
            width_sigma_px: 1.0,
            jaw_side_fraction: Some(DEFAULT_JAW_SIDE_FRACTION),
            depth_radius_px: 2,
        }
    }
}

impl GraspDecodeParams {
    /// Checks the parameters; the error names the first bad field.
    pub fn validate(&self) -> Result<(), GraspDecodeError> {
        let bad = |field: &'static str, reason: &'static str| {
            Err(GraspDecodeError::InvalidParam { field, reason })
        };
        if self.num_grasps == 0 {
            return bad("num_grasps", "must be at least 1");
        }
        if !self.quality_threshold.is_finite() {
            return bad("quality_threshold", "must be finite");
        }
        let sigma_ok = |s: f32| s.is_finite() && (0.0..=MAX_SIGMA_PX).contains(&s);
        if !sigma_ok(self.quality_sigma_px) {
            return bad("quality_sigma_px", "must be in [0, 64]");
        }
        if !sigma_ok(self.width_sigma_px) {
            return bad("width_sigma_px", "must be in [0, 64]");
        }
        if self
            .jaw_side_fraction
            .is_some_and(|f| !(f.is_finite() && f > 0.0 && f <= 1.0))
        {
            return bad("jaw_side_fraction", "must be in (0, 1]");
        }
        Ok(())
    }
}

/// What went wrong while encoding, decoding or placing grasps.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraspDecodeError {
    /// A [`GraspDecodeParams`] field is out of range.
    #[error("invalid grasp decoding parameter `{field}`: {reason}")]
    InvalidParam {
        /// The field.
        field: &'static str,
        /// What it must be.
        reason: &'static str,
    },
    /// The maps have no pixel.
    #[error("grasp maps are empty ({rows}×{cols} pixels)")]
    EmptyMaps {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
    },
    /// A map's length is not `rows × cols`.
    #[error("grasp map `{map}` has {len} values, expected {rows}×{cols}")]
    MapSize {
        /// Which map (`quality`, `cos2t`, `sin2t`, `width`).
        map: &'static str,
        /// Its length.
        len: usize,
        /// Rows it should have.
        rows: usize,
        /// Columns it should have.
        cols: usize,
    },
    /// A map holds NaN or an infinity.
    #[error("grasp map `{map}` has the non-finite value {value} at row {row}, column {col}")]
    NonFinite {
        /// Which map.
        map: &'static str,
        /// Row of the first bad value.
        row: usize,
        /// Column of the first bad value.
        col: usize,
        /// The value.
        value: f32,
    },
    /// A rectangle to rasterise has a non-finite corner.
    #[error("grasp rectangle {index} has a non-finite corner")]
    InvalidRectangle {
        /// Index in the input slice.
        index: usize,
    },
    /// A grasp to place has a non-finite field.
    #[error("grasp has a non-finite `{field}`")]
    InvalidGrasp {
        /// The field.
        field: &'static str,
    },
    /// An [`InputCrop`] field is non-finite or its scale not positive.
    #[error("invalid input crop `{field}`: {value}")]
    InvalidCrop {
        /// The field.
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
    /// The depth image does not have the intrinsics' size.
    #[error("depth image has {len} values, the intrinsics say {width}×{height}")]
    DepthSize {
        /// Its length.
        len: usize,
        /// Intrinsics width.
        width: u32,
        /// Intrinsics height.
        height: u32,
    },
    /// The grasp centre falls outside the depth image.
    #[error("grasp centre ({x_px}, {y_px}) px lies outside the {width}×{height} depth image")]
    OutsideImage {
        /// Centre x in the depth image, pixels.
        x_px: f32,
        /// Centre y in the depth image, pixels.
        y_px: f32,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
    },
    /// No valid (finite, positive) depth near the grasp centre.
    #[error("no valid depth within {radius_px} px of ({x_px}, {y_px}) in the depth image")]
    NoDepth {
        /// Centre x in the depth image, pixels.
        x_px: f32,
        /// Centre y in the depth image, pixels.
        y_px: f32,
        /// Window half-side searched.
        radius_px: usize,
    },
}

/// The four grasp maps of one image, row-major `rows × cols` each (owned).
#[derive(Debug, Clone, PartialEq)]
pub struct GraspMaps {
    /// Rows (image height), pixels.
    pub rows: usize,
    /// Columns (image width), pixels.
    pub cols: usize,
    /// Grasp quality per pixel.
    pub quality: Vec<f32>,
    /// cos 2θ per pixel.
    pub cos2t: Vec<f32>,
    /// sin 2θ per pixel.
    pub sin2t: Vec<f32>,
    /// Opening width / [`WIDTH_SCALE_PX`] per pixel.
    pub width: Vec<f32>,
}

impl GraspMaps {
    /// All-zero maps.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        let n = rows.saturating_mul(cols);
        Self {
            rows,
            cols,
            quality: vec![0.0; n],
            cos2t: vec![0.0; n],
            sin2t: vec![0.0; n],
            width: vec![0.0; n],
        }
    }

    /// Borrowed view for [`decode_grasps`].
    pub fn view(&self) -> GraspMapsView<'_> {
        GraspMapsView {
            rows: self.rows,
            cols: self.cols,
            quality: &self.quality,
            cos2t: &self.cos2t,
            sin2t: &self.sin2t,
            width: &self.width,
        }
    }
}

/// The four grasp maps of one image, borrowed (e.g. straight from the network's output
/// arrays), row-major `rows × cols` each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspMapsView<'a> {
    /// Rows (image height), pixels.
    pub rows: usize,
    /// Columns (image width), pixels.
    pub cols: usize,
    /// Grasp quality per pixel.
    pub quality: &'a [f32],
    /// cos 2θ per pixel.
    pub cos2t: &'a [f32],
    /// sin 2θ per pixel.
    pub sin2t: &'a [f32],
    /// Opening width / [`WIDTH_SCALE_PX`] per pixel.
    pub width: &'a [f32],
}

impl GraspMapsView<'_> {
    /// Checks sizes and values: non-empty, every map `rows × cols`, all finite.
    pub fn validate(&self) -> Result<(), GraspDecodeError> {
        let (rows, cols) = (self.rows, self.cols);
        let n = match rows.checked_mul(cols) {
            Some(n) if n > 0 => n,
            _ => return Err(GraspDecodeError::EmptyMaps { rows, cols }),
        };
        for (map, data) in self.named() {
            if data.len() != n {
                return Err(GraspDecodeError::MapSize {
                    map,
                    len: data.len(),
                    rows,
                    cols,
                });
            }
        }
        for (map, data) in self.named() {
            if let Some(i) = data.iter().position(|v| !v.is_finite()) {
                return Err(GraspDecodeError::NonFinite {
                    map,
                    row: i / cols,
                    col: i % cols,
                    value: data[i],
                });
            }
        }
        Ok(())
    }

    fn named(&self) -> [(&'static str, &[f32]); 4] {
        [
            ("quality", self.quality),
            ("cos2t", self.cos2t),
            ("sin2t", self.sin2t),
            ("width", self.width),
        ]
    }
}

/// A grasp decoded from the maps, in map pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DecodedGrasp {
    /// Centre `[x, y]` (x = column, y = row), map pixels.
    pub center_px: [f32; 2],
    /// θ: opening-axis direction counter-clockwise on screen from +x, radians in
    /// [−π/2, π/2).
    pub angle: f32,
    /// Gripper opening (the first edge), map pixels.
    pub width_px: f32,
    /// Jaw extent (the second edge), map pixels.
    pub jaw_px: f32,
    /// Smoothed quality at the peak.
    pub quality: f32,
}

impl DecodedGrasp {
    /// The rectangle in the crate's Cornell convention (`corners[0] → corners[1]` along the
    /// opening axis), the same corners as train_ae's `GraspRectangle.corners()`.
    pub fn rectangle(&self) -> GraspRectangle {
        GraspRectangle::from_center(self.center_px, -self.angle, self.width_px, self.jaw_px)
    }
}

/// Wraps an angle to [−π/2, π/2): grasp angles are defined modulo π.
pub fn wrap_angle(angle: f32) -> f32 {
    let w = (angle + FRAC_PI_2).rem_euclid(PI) - FRAC_PI_2;
    // rem_euclid may round up to exactly π.
    if w >= FRAC_PI_2 { w - PI } else { w }
}

/// Absolute difference of two grasp angles modulo π, radians in [0, π/2].
pub fn angle_difference(a: f32, b: f32) -> f32 {
    wrap_angle(a - b).abs()
}

/// θ of a rectangle in train_ae's convention: the first edge's direction counter-clockwise on
/// screen, `atan2(−dy, dx)` wrapped to [−π/2, π/2) (the negated, wrapped
/// [`GraspRectangle::angle`]).
pub fn grasp_angle(rectangle: &GraspRectangle) -> f32 {
    let [p0, p1, ..] = rectangle.corners_px;
    wrap_angle((-(p1[1] - p0[1])).atan2(p1[0] - p0[0]))
}

/// Where the maps sit in the camera image: map pixel `(x, y)` is image pixel
/// `((x + ½)·s − ½ + x0, (y + ½)·s − ½ + y0)` with `s` = image pixels per map pixel. This
/// inverts the crop-and-resize of train_ae's `data.py` (`_transform_rect`, pixel-centre
/// aligned).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InputCrop {
    /// Column of the crop's left edge in the image, pixels.
    pub x0_px: f32,
    /// Row of the crop's top edge in the image, pixels.
    pub y0_px: f32,
    /// Image pixels per map pixel (crop side / network input side).
    pub image_px_per_map_px: f32,
}

impl Default for InputCrop {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl InputCrop {
    /// The maps are the camera image itself.
    pub const IDENTITY: InputCrop = InputCrop {
        x0_px: 0.0,
        y0_px: 0.0,
        image_px_per_map_px: 1.0,
    };

    /// A square of `side_px` image pixels with top-left corner `(x0_px, y0_px)`, resized to
    /// `input_size` map pixels.
    pub fn square(x0_px: u32, y0_px: u32, side_px: u32, input_size: u32) -> Self {
        Self {
            x0_px: x0_px as f32,
            y0_px: y0_px as f32,
            image_px_per_map_px: side_px as f32 / input_size as f32,
        }
    }

    /// train_ae's evaluation input (`GraspDataset.render` without augmentation): the centred
    /// square of the image's shorter side, resized to `input_size`.
    pub fn centered_square(image_width: u32, image_height: u32, input_size: u32) -> Self {
        let (w, h) = (image_width as f64, image_height as f64);
        let side = w.min(h);
        // Python: round(min(max(cx + 0.5 - side / 2, 0), w - side)), round half to even.
        let corner = |extent: f64| ((extent - side) / 2.0).clamp(0.0, extent - side);
        let x0 = corner(w).round_ties_even() as u32;
        let y0 = corner(h).round_ties_even() as u32;
        let side_px = (side as u32).min(image_width - x0).min(image_height - y0);
        Self::square(x0, y0, side_px, input_size)
    }

    /// Image pixel of map pixel `[x, y]`.
    pub fn image_from_map(&self, p: [f32; 2]) -> [f32; 2] {
        let s = self.image_px_per_map_px;
        [
            (p[0] + 0.5) * s - 0.5 + self.x0_px,
            (p[1] + 0.5) * s - 0.5 + self.y0_px,
        ]
    }

    fn validate(&self) -> Result<(), GraspDecodeError> {
        for (field, value) in [("x0_px", self.x0_px), ("y0_px", self.y0_px)] {
            if !value.is_finite() {
                return Err(GraspDecodeError::InvalidCrop { field, value });
            }
        }
        let s = self.image_px_per_map_px;
        if !(s.is_finite() && s > 0.0) {
            return Err(GraspDecodeError::InvalidCrop {
                field: "image_px_per_map_px",
                value: s,
            });
        }
        Ok(())
    }
}

/// A grasp placed in 3-D, in the camera's optical frame (x right, y down, z forward), metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspPose {
    /// Grasp centre in the camera frame: the centre pixel's ray at the median depth, metres.
    pub position_m: [f32; 3],
    /// Approach direction: unit vector along the camera ray through the centre, pointing away
    /// from the camera.
    pub approach: [f32; 3],
    /// Closing axis: unit vector along the opening axis θ, perpendicular to `approach`.
    pub closing_axis: [f32; 3],
    /// Opening between the jaws, metres: the rectangle's width unprojected at the grasp depth.
    pub opening_m: f32,
    /// Depth (optical z) used, metres: the median of the valid depths in the window.
    pub depth_m: f32,
    /// The grasp in map pixels it came from.
    pub grasp: DecodedGrasp,
}

impl GraspPose {
    /// The gripper frame in the camera frame: x = closing axis, y = approach × closing axis,
    /// z = approach, origin at the grasp centre.
    pub fn camera_from_grasp(&self) -> Pose {
        let x = self.closing_axis;
        let z = self.approach;
        let y = cross(z, x);
        pose_from_columns([x, y, z], self.position_m)
    }
}

/// Rasterises positive rectangles (map pixels) into training-target maps of `rows × cols`,
/// exactly as train_ae's `grasp_maps`: each rectangle, shrunk to the central third of its
/// opening axis (full jaw extent), marks quality 1, cos 2θ, sin 2θ and
/// `clip(width_px / WIDTH_SCALE_PX, 0, 1)` at the pixels whose centres lie inside it; later
/// rectangles overwrite earlier ones; elsewhere all maps are 0.
pub fn grasp_maps(
    rectangles: &[GraspRectangle],
    rows: usize,
    cols: usize,
) -> Result<GraspMaps, GraspDecodeError> {
    if rows.checked_mul(cols).is_none_or(|n| n == 0) {
        return Err(GraspDecodeError::EmptyMaps { rows, cols });
    }
    if let Some(index) = rectangles
        .iter()
        .position(|r| r.corners_px.iter().flatten().any(|v| !v.is_finite()))
    {
        return Err(GraspDecodeError::InvalidRectangle { index });
    }
    let mut maps = GraspMaps::zeros(rows, cols);
    for r in rectangles {
        // train_ae's GraspRectangle.from_corners, in f64.
        let p = r.corners_px.map(|[x, y]| [x as f64, y as f64]);
        let (dx, dy) = (p[1][0] - p[0][0], p[1][1] - p[0][1]);
        let cx = p.iter().map(|q| q[0]).sum::<f64>() / 4.0;
        let cy = p.iter().map(|q| q[1]).sum::<f64>() / 4.0;
        let theta = ((-dy).atan2(dx) + std::f64::consts::FRAC_PI_2)
            .rem_euclid(std::f64::consts::PI)
            - std::f64::consts::FRAC_PI_2;
        let width_px = dx.hypot(dy);
        let jaw_px = (p[2][0] - p[1][0]).hypot(p[2][1] - p[1][1]);
        // scaled_about_center(LABEL_CENTRE_FRACTION, 1).corners(), in f64 as train_ae.
        let half_w = width_px * (1.0 / 3.0) / 2.0;
        let (s, c) = theta.sin_cos();
        let u = [c * half_w, -s * half_w];
        let v = [s * jaw_px / 2.0, c * jaw_px / 2.0];
        let mut poly = [
            [cx - u[0] - v[0], cy - u[1] - v[1]],
            [cx + u[0] - v[0], cy + u[1] - v[1]],
            [cx + u[0] + v[0], cy + u[1] + v[1]],
            [cx - u[0] + v[0], cy - u[1] + v[1]],
        ];
        let area2: f64 = (0..4)
            .map(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % 4]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        if area2 < 0.0 {
            poly.reverse();
        }
        let (min_x, max_x, min_y, max_y) = poly.iter().fold(
            (f64::MAX, f64::MIN, f64::MAX, f64::MIN),
            |(a, b, c, d), q| (a.min(q[0]), b.max(q[0]), c.min(q[1]), d.max(q[1])),
        );
        let x0 = (min_x.floor() as i64).max(0);
        let x1 = (max_x.ceil() as i64).min(cols as i64 - 1);
        let y0 = (min_y.floor() as i64).max(0);
        let y1 = (max_y.ceil() as i64).min(rows as i64 - 1);
        let cos2 = (2.0 * theta).cos() as f32;
        let sin2 = (2.0 * theta).sin() as f32;
        let width = (width_px / WIDTH_SCALE_PX as f64).clamp(0.0, 1.0) as f32;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (xf, yf) = (x as f64, y as f64);
                let inside = (0..4).all(|i| {
                    let (a, b) = (poly[i], poly[(i + 1) % 4]);
                    (b[0] - a[0]) * (yf - a[1]) - (b[1] - a[1]) * (xf - a[0]) >= -1e-9
                });
                if inside {
                    let i = y as usize * cols + x as usize;
                    maps.quality[i] = 1.0;
                    maps.cos2t[i] = cos2;
                    maps.sin2t[i] = sin2;
                    maps.width[i] = width;
                }
            }
        }
    }
    Ok(maps)
}

/// Decodes one image's maps into at most `params.num_grasps` grasps, highest smoothed quality
/// first (ties by row, then column of the peak), as train_ae's `decode_grasps` (see the module
/// docs for the steps). No peak reaching the threshold gives an empty list.
pub fn decode_grasps(
    maps: GraspMapsView<'_>,
    params: &GraspDecodeParams,
) -> Result<Vec<DecodedGrasp>, GraspDecodeError> {
    params.validate()?;
    maps.validate()?;
    let (rows, cols) = (maps.rows, maps.cols);
    let quality_kernel = gaussian_kernel(params.quality_sigma_px);
    let q = smooth(maps.quality, rows, cols, &quality_kernel);
    let d = params.min_distance_px;
    let local_max = max_filter(&q, rows, cols, d);
    // Candidates: local maxima that reach the threshold, best first, ties by row then column
    // (row-major index order).
    let mut peaks: Vec<usize> = (0..q.len())
        .filter(|&i| q[i] >= local_max[i] && q[i] >= params.quality_threshold)
        .collect();
    if peaks.is_empty() {
        return Ok(Vec::new());
    }
    peaks.sort_by(|&a, &b| q[b].total_cmp(&q[a]).then(a.cmp(&b)));
    let c2 = smooth(maps.cos2t, rows, cols, &quality_kernel);
    let s2 = smooth(maps.sin2t, rows, cols, &quality_kernel);
    let wd = smooth(
        maps.width,
        rows,
        cols,
        &gaussian_kernel(params.width_sigma_px),
    );
    // Candidate index per pixel (u32::MAX: none) so that a window is scanned, not all peaks.
    const NONE: u32 = u32::MAX;
    let mut slot = vec![NONE; q.len()];
    for (k, &i) in peaks.iter().enumerate() {
        slot[i] = k as u32;
    }
    let mut taken = vec![false; peaks.len()];
    let mut out = Vec::new();
    for (k, &i) in peaks.iter().enumerate() {
        if taken[k] {
            continue;
        }
        let score = q[i];
        // numpy: float32 score minus a Python float, evaluated in float32.
        let floor = score - (1e-6 * (score.abs() as f64).max(1.0)) as f32;
        let (row, col) = (i / cols, i % cols);
        let (mut sum_r, mut sum_c, mut twins) = (0.0f64, 0.0f64, 0usize);
        for r in row.saturating_sub(d)..=(row.saturating_add(d)).min(rows - 1) {
            for c in col.saturating_sub(d)..=(col.saturating_add(d)).min(cols - 1) {
                let j = slot[r * cols + c];
                if j == NONE || taken[j as usize] {
                    continue;
                }
                taken[j as usize] = true;
                if q[r * cols + c] >= floor {
                    sum_r += r as f64;
                    sum_c += c as f64;
                    twins += 1;
                }
            }
        }
        // A flat top is one peak at its mean position; maps are read at the nearest pixel
        // (Python's round: half to even).
        let (cy, cx) = (sum_r / twins as f64, sum_c / twins as f64);
        let at = cy.round_ties_even() as usize * cols + cx.round_ties_even() as usize;
        let angle = wrap_angle((0.5 * (s2[at] as f64).atan2(c2[at] as f64)) as f32);
        let width_px = wd[at] * WIDTH_SCALE_PX;
        out.push(DecodedGrasp {
            center_px: [cx as f32, cy as f32],
            angle,
            width_px,
            jaw_px: match params.jaw_side_fraction {
                Some(f) => f * cols as f32,
                None => width_px * CORNELL_JAW_FRACTION,
            },
            quality: score,
        });
        if out.len() >= params.num_grasps {
            break;
        }
    }
    Ok(out)
}

/// Places a decoded grasp in 3-D. `depth_m` is the camera's depth image (optical z, metres,
/// row-major `intrinsics.width × intrinsics.height`; non-finite or non-positive = no data),
/// `crop` says where the maps sit in it. The depth is the median of the valid pixels in the
/// `(2·depth_radius_px + 1)²` window around the centre's nearest pixel; the position is the
/// centre's ray at that depth; the opening is the distance between the two jaw ends
/// unprojected at that depth (a fronto-parallel grasp).
pub fn grasp_pose(
    grasp: &DecodedGrasp,
    depth_m: &[f32],
    intrinsics: &Intrinsics,
    crop: &InputCrop,
    params: &GraspDecodeParams,
) -> Result<GraspPose, GraspDecodeError> {
    params.validate()?;
    crop.validate()?;
    let k = intrinsics;
    if !(k.fx.is_finite() && k.fx > 0.0 && k.fy.is_finite() && k.fy > 0.0) {
        return Err(GraspDecodeError::InvalidIntrinsics {
            reason: "focal lengths must be positive and finite",
        });
    }
    if !(k.cx.is_finite() && k.cy.is_finite()) {
        return Err(GraspDecodeError::InvalidIntrinsics {
            reason: "principal point must be finite",
        });
    }
    let (w, h) = (k.width as usize, k.height as usize);
    if w.checked_mul(h) != Some(depth_m.len()) || depth_m.is_empty() {
        return Err(GraspDecodeError::DepthSize {
            len: depth_m.len(),
            width: k.width,
            height: k.height,
        });
    }
    for (field, value) in [
        ("center_px", grasp.center_px[0]),
        ("center_px", grasp.center_px[1]),
        ("angle", grasp.angle),
        ("width_px", grasp.width_px),
    ] {
        if !value.is_finite() {
            return Err(GraspDecodeError::InvalidGrasp { field });
        }
    }
    let [u, v] = crop.image_from_map(grasp.center_px);
    let (ur, vr) = (u.round(), v.round());
    if !(ur >= 0.0 && vr >= 0.0 && ur < k.width as f32 && vr < k.height as f32) {
        return Err(GraspDecodeError::OutsideImage {
            x_px: u,
            y_px: v,
            width: k.width,
            height: k.height,
        });
    }
    let (col, row) = (ur as usize, vr as usize);
    let rad = params.depth_radius_px;
    let mut window: Vec<f32> = Vec::new();
    for r in row.saturating_sub(rad)..=row.saturating_add(rad).min(h - 1) {
        for c in col.saturating_sub(rad)..=col.saturating_add(rad).min(w - 1) {
            let z = depth_m[r * w + c];
            if z.is_finite() && z > 0.0 {
                window.push(z);
            }
        }
    }
    let Some(z) = median(&mut window) else {
        return Err(GraspDecodeError::NoDepth {
            x_px: u,
            y_px: v,
            radius_px: rad,
        });
    };
    let position_m = k.unproject(u, v, z);
    let approach = normalize(position_m);
    // Opening axis on screen (y down): (cos θ, −sin θ), in image pixels.
    let (s, c) = grasp.angle.sin_cos();
    let half = grasp.width_px * crop.image_px_per_map_px / 2.0;
    let end_a = k.unproject(u - c * half, v + s * half, z);
    let end_b = k.unproject(u + c * half, v - s * half, z);
    let opening_m = norm(sub(end_b, end_a));
    // Direction from a one-pixel step, so that it exists for zero-width grasps too.
    let along = sub(k.unproject(u + c, v - s, z), position_m);
    let closing_axis = normalize(sub(along, scale(approach, dot(along, approach))));
    Ok(GraspPose {
        position_m,
        approach,
        closing_axis,
        opening_m,
        depth_m: z,
        grasp: *grasp,
    })
}

/// train_ae's `gaussian_smooth` kernel: radius `max(⌊4σ + ½⌋, 1)`, normalised; `None` for σ = 0.
fn gaussian_kernel(sigma: f32) -> Option<Vec<f32>> {
    if sigma <= 0.0 {
        return None;
    }
    let radius = ((4.0 * sigma + 0.5) as i64).max(1);
    let k: Vec<f32> = (-radius..=radius)
        .map(|i| (-0.5 * (i as f32 / sigma).powi(2)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    Some(k.into_iter().map(|v| v / sum).collect())
}

/// Separable convolution with replicated edges, along rows first, then columns.
fn smooth(src: &[f32], rows: usize, cols: usize, kernel: &Option<Vec<f32>>) -> Vec<f32> {
    let Some(k) = kernel else {
        return src.to_vec();
    };
    let r = k.len() / 2;
    let mut tmp = vec![0.0f32; src.len()];
    for y in 0..rows {
        let line = &src[y * cols..(y + 1) * cols];
        for x in 0..cols {
            tmp[y * cols + x] = k
                .iter()
                .enumerate()
                .map(|(j, w)| w * line[(x + j).saturating_sub(r).min(cols - 1)])
                .sum();
        }
    }
    let mut out = vec![0.0f32; src.len()];
    for y in 0..rows {
        for x in 0..cols {
            out[y * cols + x] = k
                .iter()
                .enumerate()
                .map(|(j, w)| w * tmp[(y + j).saturating_sub(r).min(rows - 1) * cols + x])
                .sum();
        }
    }
    out
}

/// Maximum over the square window of radius `d` (clipped at the borders), separably.
fn max_filter(src: &[f32], rows: usize, cols: usize, d: usize) -> Vec<f32> {
    let mut tmp = vec![0.0f32; src.len()];
    for y in 0..rows {
        let line = &src[y * cols..(y + 1) * cols];
        for x in 0..cols {
            let (a, b) = (x.saturating_sub(d), x.saturating_add(d).min(cols - 1));
            tmp[y * cols + x] = line[a..=b].iter().copied().fold(f32::MIN, f32::max);
        }
    }
    let mut out = vec![0.0f32; src.len()];
    for y in 0..rows {
        let (a, b) = (y.saturating_sub(d), y.saturating_add(d).min(rows - 1));
        for x in 0..cols {
            out[y * cols + x] = (a..=b).map(|r| tmp[r * cols + x]).fold(f32::MIN, f32::max);
        }
    }
    out
}
