//! [`PointCloud`]: the partial view of one object, points in metres in the camera's optical
//! frame (x right, y down, z forward), with optional per-point colours.
//!
//! ```
//! use lgdm_pointcloud::PointCloud;
//! let cloud = PointCloud::new(vec![[0.0, 0.0, 1.0], [0.1, 0.0, 1.0]], None);
//! assert_eq!(cloud.len(), 2);
//! assert!((cloud.centroid().unwrap()[0] - 0.05).abs() < 1e-6);
//! ```

use serde::{Deserialize, Serialize};

/// One view of an object: points in metres (camera optical frame), optional RGB colours.
///
/// When `colors` is `Some`, it has exactly one entry per point.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PointCloud {
    /// Points in metres, camera optical frame (x right, y down, z forward).
    pub points: Vec<[f32; 3]>,
    /// Per-point colour (8-bit sRGB), same length as `points` when present.
    pub colors: Option<Vec<[u8; 3]>>,
}

impl PointCloud {
    /// A cloud from points and optional colours (the caller keeps the lengths equal).
    pub fn new(points: Vec<[f32; 3]>, colors: Option<Vec<[u8; 3]>>) -> Self {
        debug_assert!(colors.as_ref().is_none_or(|c| c.len() == points.len()));
        Self { points, colors }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Mean of the points, `None` for an empty cloud.
    pub fn centroid(&self) -> Option<[f32; 3]> {
        centroid(&self.points)
    }

    /// Axis-aligned bounds `(min, max)`, `None` for an empty cloud.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        bounds(&self.points)
    }

    /// Keeps the points at the given (increasing) indices, with their colours.
    pub fn select(&self, indices: &[usize]) -> PointCloud {
        PointCloud {
            points: indices.iter().map(|&i| self.points[i]).collect(),
            colors: self
                .colors
                .as_ref()
                .map(|c| indices.iter().map(|&i| c[i]).collect()),
        }
    }

    /// Whether every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.points.iter().all(|p| p.iter().all(|v| v.is_finite()))
    }
}

/// Mean of `points` (accumulated in f64), `None` when empty.
pub fn centroid(points: &[[f32; 3]]) -> Option<[f32; 3]> {
    if points.is_empty() {
        return None;
    }
    let mut s = [0f64; 3];
    for p in points {
        for k in 0..3 {
            s[k] += f64::from(p[k]);
        }
    }
    let n = points.len() as f64;
    Some([(s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32])
}

/// Axis-aligned bounds `(min, max)` of `points`, `None` when empty.
pub fn bounds(points: &[[f32; 3]]) -> Option<([f32; 3], [f32; 3])> {
    let first = *points.first()?;
    let mut lo = first;
    let mut hi = first;
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    Some((lo, hi))
}
