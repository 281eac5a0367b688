//! The augmentations that distinguish the dataset's collections, each parameterised and seeded.
//!
//! Scene augmentations (translation, rotation, scale) change where and how the object stands on
//! the turntable before rendering, so the camera really sees a different view; cloud
//! augmentations (noise, voxel down-sampling, occlusion, dropout, outliers) act on each view's
//! back-projected cloud.
//!
//! ```
//! use lgdm_pointcloud::augment::Augmentation;
//! use lgdm_pointcloud::PointCloud;
//! use rand::SeedableRng;
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
//! let cloud = PointCloud::new((0..1000).map(|i| [i as f32 * 1e-4, 0.0, 1.0]).collect(), None);
//! let out = Augmentation::Dropout { rate: 0.5 }.apply_to_cloud(&cloud, &mut rng);
//! assert!(out.len() > 400 && out.len() < 600);
//! ```

use rand::{Rng, RngExt};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::cloud::{PointCloud, bounds};
use crate::math::{Pose, rotation_axis_angle};

/// One collection's augmentation. Lengths in metres, angles in radians.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Augmentation {
    /// Clean views.
    None,
    /// The object stands off the turntable's axis by a random offset up to `max_offset_m`
    /// (so it orbits as the table turns).
    Translation {
        /// Largest horizontal offset from the axis, metres.
        max_offset_m: f32,
    },
    /// The object is tilted about a random horizontal axis by up to `max_tilt_rad`.
    Rotation {
        /// Largest tilt, radians.
        max_tilt_rad: f32,
    },
    /// The object is scaled uniformly by a random factor in `[min, max]`.
    Scale {
        /// Smallest factor.
        min: f32,
        /// Largest factor.
        max: f32,
    },
    /// Isotropic Gaussian noise of standard deviation `sigma_m` on every coordinate.
    GaussianNoise {
        /// Standard deviation per coordinate, metres.
        sigma_m: f32,
    },
    /// Voxel-grid down-sampling: one point (the mean) per occupied voxel of edge `voxel_m`.
    VoxelDownsample {
        /// Voxel edge, metres.
        voxel_m: f32,
    },
    /// Gaussian noise, then voxel down-sampling.
    NoiseAndVoxel {
        /// Noise standard deviation, metres.
        sigma_m: f32,
        /// Voxel edge, metres.
        voxel_m: f32,
    },
    /// An occluder with a straight edge at a random image-plane angle hides `fraction` of the
    /// view's points from one side.
    Occlusion {
        /// Fraction of points removed, in `[0, 1)`.
        fraction: f32,
    },
    /// Each point is dropped independently with probability `rate`.
    Dropout {
        /// Drop probability, in `[0, 1)`.
        rate: f32,
    },
    /// `fraction × n` outlier points drawn uniformly in the view's bounding box grown by
    /// `margin_m`, coloured grey.
    Outliers {
        /// Outliers added per existing point.
        fraction: f32,
        /// Margin around the bounding box, metres.
        margin_m: f32,
    },
}

impl Augmentation {
    /// Short machine-readable name of the kind (`gaussian_noise`).
    pub fn kind(&self) -> &'static str {
        match self {
            Augmentation::None => "none",
            Augmentation::Translation { .. } => "translation",
            Augmentation::Rotation { .. } => "rotation",
            Augmentation::Scale { .. } => "scale",
            Augmentation::GaussianNoise { .. } => "gaussian_noise",
            Augmentation::VoxelDownsample { .. } => "voxel_downsample",
            Augmentation::NoiseAndVoxel { .. } => "noise_and_voxel",
            Augmentation::Occlusion { .. } => "occlusion",
            Augmentation::Dropout { .. } => "dropout",
            Augmentation::Outliers { .. } => "outliers",
        }
    }

    /// Human-readable description with parameters (`gaussian_noise(sigma=4mm)`).
    pub fn describe(&self) -> String {
        let mm = |m: f32| format!("{}mm", (m * 1000.0 * 10.0).round() / 10.0);
        match *self {
            Augmentation::None => "none".into(),
            Augmentation::Translation { max_offset_m } => {
                format!("translation(max_offset={})", mm(max_offset_m))
            }
            Augmentation::Rotation { max_tilt_rad } => {
                format!("rotation(max_tilt={:.0}deg)", max_tilt_rad.to_degrees())
            }
            Augmentation::Scale { min, max } => format!("scale({min}..{max})"),
            Augmentation::GaussianNoise { sigma_m } => {
                format!("gaussian_noise(sigma={})", mm(sigma_m))
            }
            Augmentation::VoxelDownsample { voxel_m } => {
                format!("voxel_downsample(voxel={})", mm(voxel_m))
            }
            Augmentation::NoiseAndVoxel { sigma_m, voxel_m } => {
                format!(
                    "noise_and_voxel(sigma={}, voxel={})",
                    mm(sigma_m),
                    mm(voxel_m)
                )
            }
            Augmentation::Occlusion { fraction } => format!("occlusion(fraction={fraction})"),
            Augmentation::Dropout { rate } => format!("dropout(rate={rate})"),
            Augmentation::Outliers { fraction, margin_m } => {
                format!("outliers(fraction={fraction}, margin={})", mm(margin_m))
            }
        }
    }

    /// Checks the parameters; returns the name of the first bad field.
    pub fn validate(&self) -> Result<(), &'static str> {
        let ok = |v: f32, lo: f32, hi: f32| v.is_finite() && v >= lo && v <= hi;
        let bad = match *self {
            Augmentation::None => None,
            Augmentation::Translation { max_offset_m } => {
                (!ok(max_offset_m, 0.0, 0.5)).then_some("max_offset_m")
            }
            Augmentation::Rotation { max_tilt_rad } => {
                (!ok(max_tilt_rad, 0.0, 1.2)).then_some("max_tilt_rad")
            }
            Augmentation::Scale { min, max } => {
                (!(ok(min, 0.1, 10.0) && ok(max, 0.1, 10.0) && min <= max)).then_some("min/max")
            }
            Augmentation::GaussianNoise { sigma_m } => {
                (!ok(sigma_m, 0.0, 0.1)).then_some("sigma_m")
            }
            Augmentation::VoxelDownsample { voxel_m } => {
                (!ok(voxel_m, 1e-4, 0.2)).then_some("voxel_m")
            }
            Augmentation::NoiseAndVoxel { sigma_m, voxel_m } => {
                if !ok(sigma_m, 0.0, 0.1) {
                    Some("sigma_m")
                } else {
                    (!ok(voxel_m, 1e-4, 0.2)).then_some("voxel_m")
                }
            }
            Augmentation::Occlusion { fraction } => {
                (!ok(fraction, 0.0, 0.95)).then_some("fraction")
            }
            Augmentation::Dropout { rate } => (!ok(rate, 0.0, 0.95)).then_some("rate"),
            Augmentation::Outliers { fraction, margin_m } => {
                if !ok(fraction, 0.0, 1.0) {
                    Some("fraction")
                } else {
                    (!ok(margin_m, 0.0, 0.5)).then_some("margin_m")
                }
            }
        };
        bad.map_or(Ok(()), Err)
    }

    /// The per-sequence scene change: `turntable_from_object` placement (before the turntable
    /// rotation) and a uniform scale factor for the mesh. Identity for cloud augmentations.
    pub fn scene_placement<R: Rng + ?Sized>(&self, rng: &mut R) -> ScenePlacement {
        match *self {
            Augmentation::Translation { max_offset_m } => {
                let angle = rng.random_range(0.0..std::f32::consts::TAU);
                // Uniform over the disc.
                let r = max_offset_m * rng.random_range(0.0f32..1.0).sqrt();
                ScenePlacement {
                    offset_m: [r * angle.cos(), r * angle.sin()],
                    ..ScenePlacement::default()
                }
            }
            Augmentation::Rotation { max_tilt_rad } => {
                let axis_angle = rng.random_range(0.0..std::f32::consts::TAU);
                let tilt = rng.random_range(0.3 * max_tilt_rad..=max_tilt_rad);
                ScenePlacement {
                    tilt: rotation_axis_angle([axis_angle.cos(), axis_angle.sin(), 0.0], tilt),
                    ..ScenePlacement::default()
                }
            }
            Augmentation::Scale { min, max } => ScenePlacement {
                scale: if max > min {
                    rng.random_range(min..=max)
                } else {
                    min
                },
                ..ScenePlacement::default()
            },
            _ => ScenePlacement::default(),
        }
    }

    /// Applies the cloud-level part of the augmentation (identity for scene augmentations).
    pub fn apply_to_cloud<R: Rng + ?Sized>(&self, cloud: &PointCloud, rng: &mut R) -> PointCloud {
        match *self {
            Augmentation::GaussianNoise { sigma_m } => gaussian_noise(cloud, sigma_m, rng),
            Augmentation::VoxelDownsample { voxel_m } => voxel_downsample(cloud, voxel_m),
            Augmentation::NoiseAndVoxel { sigma_m, voxel_m } => {
                voxel_downsample(&gaussian_noise(cloud, sigma_m, rng), voxel_m)
            }
            Augmentation::Occlusion { fraction } => {
                let angle = rng.random_range(0.0..std::f32::consts::TAU);
                occlude(cloud, fraction, angle)
            }
            Augmentation::Dropout { rate } => dropout(cloud, rate, rng),
            Augmentation::Outliers { fraction, margin_m } => {
                add_outliers(cloud, fraction, margin_m, rng)
            }
            Augmentation::None
            | Augmentation::Translation { .. }
            | Augmentation::Rotation { .. }
            | Augmentation::Scale { .. } => cloud.clone(),
        }
    }
}

/// How a scene augmentation places the object on the turntable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScenePlacement {
    /// Horizontal offset from the turntable axis, metres.
    pub offset_m: [f32; 2],
    /// Tilt applied to the object (about its base), before re-resting it on the table.
    pub tilt: Pose,
    /// Uniform scale factor of the mesh.
    pub scale: f32,
}

impl Default for ScenePlacement {
    fn default() -> Self {
        Self {
            offset_m: [0.0; 2],
            tilt: Pose::identity(),
            scale: 1.0,
        }
    }
}

/// Adds isotropic Gaussian noise (σ per coordinate, metres).
pub fn gaussian_noise<R: Rng + ?Sized>(
    cloud: &PointCloud,
    sigma_m: f32,
    rng: &mut R,
) -> PointCloud {
    if sigma_m <= 0.0 {
        return cloud.clone();
    }
    let normal = Normal::new(0.0f32, sigma_m).expect("sigma validated finite and positive");
    let points = cloud
        .points
        .iter()
        .map(|p| {
            [
                p[0] + normal.sample(rng),
                p[1] + normal.sample(rng),
                p[2] + normal.sample(rng),
            ]
        })
        .collect();
    PointCloud::new(points, cloud.colors.clone())
}

/// Voxel-grid down-sampling: the mean point (and mean colour) of every occupied voxel of edge
/// `voxel_m`, in increasing voxel-key order (deterministic).
pub fn voxel_downsample(cloud: &PointCloud, voxel_m: f32) -> PointCloud {
    if cloud.is_empty() || voxel_m <= 0.0 {
        return cloud.clone();
    }
    let key = |p: &[f32; 3]| {
        [
            (p[0] / voxel_m).floor() as i32,
            (p[1] / voxel_m).floor() as i32,
            (p[2] / voxel_m).floor() as i32,
        ]
    };
    let mut order: Vec<([i32; 3], usize)> = cloud
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i))
        .collect();
    order.sort_unstable();
    let mut points = Vec::new();
    let mut colors = cloud.colors.as_ref().map(|_| Vec::new());
    let mut start = 0;
    while start < order.len() {
        let k = order[start].0;
        let mut end = start;
        let mut sum = [0f64; 3];
        let mut csum = [0u32; 3];
        while end < order.len() && order[end].0 == k {
            let i = order[end].1;
            for (s, &v) in sum.iter_mut().zip(&cloud.points[i]) {
                *s += f64::from(v);
            }
            if let Some(c) = &cloud.colors {
                for (s, &v) in csum.iter_mut().zip(&c[i]) {
                    *s += u32::from(v);
                }
            }
            end += 1;
        }
        let n = (end - start) as f64;
        points.push([
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
        ]);
        if let Some(out) = colors.as_mut() {
            let n = (end - start) as u32;
            out.push([
                (csum[0] / n) as u8,
                (csum[1] / n) as u8,
                (csum[2] / n) as u8,
            ]);
        }
        start = end;
    }
    PointCloud::new(points, colors)
}

/// Removes the `fraction` of points lying furthest along the image-plane direction
/// `(cos angle, sin angle)` (a straight-edged occluder entering from that side).
pub fn occlude(cloud: &PointCloud, fraction: f32, angle: f32) -> PointCloud {
    let n = cloud.len();
    let remove = ((fraction.clamp(0.0, 1.0) * n as f32).round() as usize).min(n);
    if remove == 0 {
        return cloud.clone();
    }
    let (s, c) = angle.sin_cos();
    let mut proj: Vec<(f32, usize)> = cloud
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let z = p[2].max(1e-6);
            (c * p[0] / z + s * p[1] / z, i)
        })
        .collect();
    proj.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut keep: Vec<usize> = proj[..n - remove].iter().map(|&(_, i)| i).collect();
    keep.sort_unstable();
    cloud.select(&keep)
}

/// Drops each point with probability `rate`.
pub fn dropout<R: Rng + ?Sized>(cloud: &PointCloud, rate: f32, rng: &mut R) -> PointCloud {
    let keep: Vec<usize> = (0..cloud.len())
        .filter(|_| rng.random::<f32>() >= rate)
        .collect();
    cloud.select(&keep)
}

/// Adds `round(fraction × n)` points uniformly distributed in the bounding box grown by
/// `margin_m`, coloured mid-grey.
pub fn add_outliers<R: Rng + ?Sized>(
    cloud: &PointCloud,
    fraction: f32,
    margin_m: f32,
    rng: &mut R,
) -> PointCloud {
    let Some((lo, hi)) = bounds(&cloud.points) else {
        return cloud.clone();
    };
    let count = (fraction * cloud.len() as f32).round() as usize;
    let mut out = cloud.clone();
    for _ in 0..count {
        let mut p = [0.0f32; 3];
        for d in 0..3 {
            let (a, b) = (lo[d] - margin_m, hi[d] + margin_m);
            p[d] = if b > a { rng.random_range(a..b) } else { a };
        }
        out.points.push(p);
        if let Some(c) = out.colors.as_mut() {
            c.push([128, 128, 128]);
        }
    }
    out
}

/// Uniform random subsample to at most `max_points`, keeping the original order.
pub fn subsample<R: Rng + ?Sized>(
    cloud: &PointCloud,
    max_points: usize,
    rng: &mut R,
) -> PointCloud {
    let n = cloud.len();
    if n <= max_points {
        return cloud.clone();
    }
    let mut idx: Vec<usize> = (0..n).collect();
    for i in 0..max_points {
        let j = rng.random_range(i..n);
        idx.swap(i, j);
    }
    idx.truncate(max_points);
    idx.sort_unstable();
    cloud.select(&idx)
}
