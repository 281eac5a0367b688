//! Projection of a view's point cloud to a square depth or RGB-D image (224×224 for the
//! autoencoder), and entropy-based best-view selection.
//!
//! The cloud is re-projected through the camera that saw it (perspective, optical frame), the
//! projected points' bounding square (plus a margin) is mapped onto the image, and each point
//! is splatted as a small square with a z-buffer (nearest wins). Empty pixels have depth 0.
//!
//! [`ProjectionParams`] are bounded ([`ProjectionParams::validate`], checked by
//! [`project_to_image`] before anything is allocated): `size` in `1..=`[`MAX_IMAGE_SIZE`]
//! (4096: 64 MiB of depth), `splat_px` in `0..=`[`MAX_SPLAT_PX`] (64), `margin` in `[0, 0.5]`.
//! The work is then at most `points × min(splat_px, size)²` pixel writes.
//!
//! ```
//! use lgdm_pointcloud::projection::{project_to_image, best_view, ProjectionParams};
//! use lgdm_pointcloud::PointCloud;
//! let cloud = PointCloud::new((0..400).map(|i| [(i % 20) as f32 * 0.005, (i / 20) as f32 * 0.005, 0.8]).collect(), None);
//! let img = project_to_image(&cloud, &ProjectionParams::default()).unwrap();
//! assert_eq!(img.depth_m.len(), 224 * 224);
//! assert_eq!(best_view(&[cloud.clone(), cloud]), Some(0));
//! ```

use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;

/// The largest image side in pixels: 4096 (16.8 M pixels, 64 MiB of depth plus 48 MiB of
/// colour), 18 times the autoencoder's 224.
pub const MAX_IMAGE_SIZE: usize = 4096;

/// The largest splat side in pixels: 64. The automatic splat is at most 9; a larger square only
/// blurs the silhouette while each point costs `splat_px²` pixel writes.
pub const MAX_SPLAT_PX: usize = 64;

/// How a cloud becomes an image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProjectionParams {
    /// Image side in pixels, `1..=`[`MAX_IMAGE_SIZE`] (default: 224).
    pub size: usize,
    /// Margin around the object as a fraction of the side, in `[0, 0.5]`; values above 0.45
    /// act as 0.45 (default: 0.08).
    pub margin: f32,
    /// Splat side in pixels, `0..=`[`MAX_SPLAT_PX`]; 0 chooses it from the point density
    /// (default: 0).
    pub splat_px: usize,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        Self {
            size: 224,
            margin: 0.08,
            splat_px: 0,
        }
    }
}

impl ProjectionParams {
    /// Checks every field against its documented range; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ProjectionError> {
        let bad = |field: &'static str, reason: String| {
            Err(ProjectionError::InvalidParam { field, reason })
        };
        if !(1..=MAX_IMAGE_SIZE).contains(&self.size) {
            return bad(
                "size",
                format!("must be in 1..={MAX_IMAGE_SIZE} (got {})", self.size),
            );
        }
        if self.splat_px > MAX_SPLAT_PX {
            return bad(
                "splat_px",
                format!("must be in 0..={MAX_SPLAT_PX} (got {})", self.splat_px),
            );
        }
        if !(0.0..=0.5).contains(&self.margin) {
            return bad(
                "margin",
                format!("must be in [0, 0.5] (got {})", self.margin),
            );
        }
        Ok(())
    }
}

/// A square projected image.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectedImage {
    /// Side in pixels.
    pub size: usize,
    /// Depth (optical z, metres) per pixel, row-major; 0 where empty.
    pub depth_m: Vec<f32>,
    /// Colour per pixel when the cloud has colours (black where empty).
    pub rgb: Option<Vec<[u8; 3]>>,
}

impl ProjectedImage {
    /// Depth normalised to `[0, 1]` over the object's own range, near = 1, empty = 0: a
    /// single-channel image for networks.
    pub fn normalized_depth(&self) -> Vec<f32> {
        let valid = self.depth_m.iter().copied().filter(|&d| d > 0.0);
        let (lo, hi) = valid.fold((f32::MAX, f32::MIN), |(a, b), d| (a.min(d), b.max(d)));
        let span = (hi - lo).max(1e-6);
        self.depth_m
            .iter()
            .map(|&d| {
                if d > 0.0 {
                    1.0 - 0.9 * (d - lo) / span
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// Why a cloud could not be projected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProjectionError {
    /// No point in front of the camera.
    #[error("no point of the cloud lies in front of the camera")]
    Empty,
    /// A parameter is outside its documented range ([`ProjectionParams::validate`]).
    #[error("projection parameter `{field}` {reason}")]
    InvalidParam {
        /// The field of [`ProjectionParams`] (`size`, `splat_px`, `margin`).
        field: &'static str,
        /// The range and the value given.
        reason: String,
    },
}

/// Projects a cloud (optical frame, metres) to a square depth / RGB-D image. `params` are
/// validated first ([`ProjectionParams::validate`]).
pub fn project_to_image(
    cloud: &PointCloud,
    params: &ProjectionParams,
) -> Result<ProjectedImage, ProjectionError> {
    params.validate()?;
    let size = params.size;
    let front: Vec<usize> = (0..cloud.len())
        .filter(|&i| cloud.points[i][2] > 1e-3 && cloud.points[i].iter().all(|v| v.is_finite()))
        .collect();
    if front.is_empty() {
        return Err(ProjectionError::Empty);
    }
    let uv: Vec<[f32; 2]> = front
        .iter()
        .map(|&i| {
            let p = cloud.points[i];
            [p[0] / p[2], p[1] / p[2]]
        })
        .collect();
    let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
    for q in &uv {
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
    let side = extent / (1.0 - 2.0 * params.margin.clamp(0.0, 0.45));
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let scale = size as f32 / side;
    let splat = if params.splat_px > 0 {
        params.splat_px
    } else {
        // Enough to close the gaps between neighbouring points of an object covering about
        // half of the image.
        ((0.5 * (size * size) as f32 / front.len() as f32)
            .sqrt()
            .ceil() as usize)
            .clamp(1, 9)
    };
    let mut depth = vec![0.0f32; size * size];
    let mut rgb = cloud.colors.as_ref().map(|_| vec![[0u8; 3]; size * size]);
    for (j, &i) in front.iter().enumerate() {
        let x = ((uv[j][0] - centre[0]) * scale + size as f32 / 2.0).floor() as i64;
        let y = ((uv[j][1] - centre[1]) * scale + size as f32 / 2.0).floor() as i64;
        let z = cloud.points[i][2];
        // The splat square, clipped to the image (rows, then columns, as unclipped).
        let r0 = -((splat as i64 - 1) / 2);
        let span = |c: i64| {
            let lo = c.saturating_add(r0);
            (lo.max(0), lo.saturating_add(splat as i64).min(size as i64))
        };
        let ((x0, x1), (y0, y1)) = (span(x), span(y));
        for py in y0..y1 {
            for px in x0..x1 {
                let o = py as usize * size + px as usize;
                if depth[o] == 0.0 || z < depth[o] {
                    depth[o] = z;
                    if let (Some(img), Some(c)) = (rgb.as_mut(), cloud.colors.as_ref()) {
                        img[o] = c[i];
                    }
                }
            }
        }
    }
    Ok(ProjectedImage {
        size,
        depth_m: depth,
        rgb,
    })
}

/// Grid side of [`view_entropy`].
pub const ENTROPY_GRID: usize = 32;

/// Viewpoint entropy of a view: the Shannon entropy (nats) of the distribution of its points
/// over a 32×32 grid on the image plane, spanning the view's own projected bounding square
/// (scaled by its size relative to the largest side) — larger, more evenly covered silhouettes
/// score higher. 0 for an empty cloud.
pub fn view_entropy(cloud: &PointCloud) -> f32 {
    let uv: Vec<[f32; 2]> = cloud
        .points
        .iter()
        .filter(|p| p[2] > 1e-3)
        .map(|p| [p[0] / p[2], p[1] / p[2]])
        .collect();
    if uv.is_empty() {
        return 0.0;
    }
    let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
    for q in &uv {
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let side = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
    let n = ENTROPY_GRID;
    let mut hist = vec![0u32; n * n];
    for q in &uv {
        let x = (((q[0] - lo[0]) / side * n as f32) as usize).min(n - 1);
        let y = (((q[1] - lo[1]) / side * n as f32) as usize).min(n - 1);
        hist[y * n + x] += 1;
    }
    let total = uv.len() as f64;
    -hist
        .iter()
        .filter(|&&c| c > 0)
        .map(|&c| {
            let p = f64::from(c) / total;
            p * p.ln()
        })
        .sum::<f64>() as f32
}

/// Index of the view with the highest [`view_entropy`] (the first on ties), `None` when
/// `views` is empty.
pub fn best_view(views: &[PointCloud]) -> Option<usize> {
    let mut best: Option<(usize, f32)> = None;
    for (i, v) in views.iter().enumerate() {
        let e = view_entropy(v);
        if best.is_none_or(|(_, b)| e > b) {
            best = Some((i, e));
        }
    }
    best.map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud() -> PointCloud {
        PointCloud::new(
            (0..100)
                .map(|i| [(i % 10) as f32 * 0.01, (i / 10) as f32 * 0.01, 0.8])
                .collect(),
            None,
        )
    }

    #[test]
    fn parameters_out_of_range_are_named_before_any_allocation() {
        let cases = [
            (
                "size",
                ProjectionParams {
                    size: 0,
                    ..Default::default()
                },
            ),
            (
                "size",
                ProjectionParams {
                    size: 100_000,
                    ..Default::default()
                },
            ),
            (
                "size",
                ProjectionParams {
                    size: usize::MAX,
                    ..Default::default()
                },
            ),
            (
                "splat_px",
                ProjectionParams {
                    splat_px: 1_000_000,
                    ..Default::default()
                },
            ),
            (
                "splat_px",
                ProjectionParams {
                    splat_px: MAX_SPLAT_PX + 1,
                    ..Default::default()
                },
            ),
            (
                "margin",
                ProjectionParams {
                    margin: f32::NAN,
                    ..Default::default()
                },
            ),
            (
                "margin",
                ProjectionParams {
                    margin: -0.1,
                    ..Default::default()
                },
            ),
            (
                "margin",
                ProjectionParams {
                    margin: 0.51,
                    ..Default::default()
                },
            ),
        ];
        for (name, params) in cases {
            match project_to_image(&cloud(), &params) {
                Err(ProjectionError::InvalidParam { field, reason }) => {
                    assert_eq!(field, name, "{reason}");
                    let msg = ProjectionError::InvalidParam { field, reason }.to_string();
                    assert!(msg.contains(&format!("`{name}`")), "{msg}");
                }
                other => panic!("{params:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn the_largest_parameters_work() {
        let params = ProjectionParams {
            size: 64,
            splat_px: MAX_SPLAT_PX,
            margin: 0.49,
        };
        let img = project_to_image(&cloud(), &params).unwrap();
        // A 64-pixel splat on a 64-pixel image covers it.
        assert!(img.depth_m.iter().all(|&d| d == 0.8));
        let big = ProjectionParams {
            size: MAX_IMAGE_SIZE,
            splat_px: 1,
            margin: 0.0,
        };
        assert_eq!(
            project_to_image(&cloud(), &big).unwrap().depth_m.len(),
            4096 * 4096
        );
    }
}
