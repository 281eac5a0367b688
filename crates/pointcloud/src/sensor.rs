//! A depth sensor model: what a real active-stereo RGB-D camera (a RealSense D4xx, a Kinect)
//! does to the renderer's perfect depth, applied to a rendered [`RgbdFrame`] in place.
//!
//! In order, from the clean depth:
//! 1. **Missing pixels** (depth 0, the renderer's "nothing seen", which segmentation, the crop
//!    and the grasp decoders already skip):
//!    - *stereo shadow*: pixels the second imager, `baseline_m` to the right, cannot see behind
//!      a nearer surface (the band on the left of every object in a RealSense image);
//!    - *steep surfaces*: incidence above `max_incidence_deg` (normals from the clean depth);
//!    - *depth edges*: pixels next to a depth jump of more than `edge_jump_m` are lost with
//!      probability `edge_dropout`;
//!    - *dark surfaces*: pixels darker than `dark_luminance` are lost with probability
//!      `dark_dropout` (little infrared comes back).
//! 2. **Axial noise**: Gaussian, σ(z, θ) = `axial_base_m` + `axial_quadratic_per_m` ·
//!    (z − `axial_reference_m`)² + `axial_angular_m` / √z · θ² / (π/2 − θ)², the Kinect model of
//!    Nguyen, Izadi and Lovell (3DIMPVT 2012): 1.2 mm at 0.4–0.5 m, 2.2 mm at the overview
//!    camera's 1.115 m, growing towards grazing incidence.
//! 3. **Quantisation** to `quantum_m` (1 mm, the RealSense z16 unit).
//!
//! Colour and labels are left alone (labels are ground truth for bookkeeping). The draws depend
//! only on the seed given to [`DepthNoise::apply`]: one stream per image row, so rows run in
//! parallel and the bytes do not depend on the thread count. [`DepthNoise::frame_seed`] makes a
//! frame's seed from the model's `seed`, a caller's salt (the world's step) and the clean
//! depth, so two different frames never share their noise.
//!
//! ```
//! use lgdm_pointcloud::math::{Pose, look_at};
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::render::{render, Camera, Intrinsics, RenderItem};
//! use lgdm_pointcloud::sensor::DepthNoise;
//! let camera = Camera::new(Intrinsics::kinect_qvga(), look_at([0.0, 0.0, 0.5], [0.0; 3], [0.0, 1.0, 0.0]));
//! let table = Mesh::cuboid([0.0, 0.0, -0.01], [2.0, 2.0, 0.02], [150, 118, 84]);
//! let cube = Mesh::cuboid([0.0, 0.0, 0.05], [0.1; 3], [200, 40, 40]);
//! let items = [
//!     RenderItem { mesh: &table, world_from_object: Pose::identity(), label: 1 },
//!     RenderItem { mesh: &cube, world_from_object: Pose::identity(), label: 2 },
//! ];
//! let mut frame = render(&camera, &items);
//! let noise = DepthNoise::default();
//! noise.validate().unwrap();
//! let seed = noise.frame_seed(0, &frame);
//! noise.apply(&mut frame, &camera.intrinsics, seed);
//! // Quantised to millimetres, and a stereo shadow left of the cube.
//! let centre = 120 * 320 + 160;
//! assert!((frame.depth_m[centre] * 1000.0 - (frame.depth_m[centre] * 1000.0).round()).abs() < 1e-3);
//! assert!(frame.depth_m.iter().filter(|&&d| d == 0.0).count() > 100);
//! ```

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::math::{cross, derive_seed, dot, norm, sub};
use crate::render::{Intrinsics, RgbdFrame};

/// Seed tag of a frame's noise (see [`derive_seed`]).
const TAG_FRAME: u64 = 0x5E45_0001;

/// The depth sensor model. Defaults: a RealSense D435-class camera (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthNoise {
    /// Apply the model (default: true); false leaves frames as rendered.
    pub enabled: bool,
    /// Base seed of the noise (default: 0).
    pub seed: u64,
    /// Axial noise at `axial_reference_m`, facing the camera (m; default 0.0012).
    pub axial_base_m: f32,
    /// Growth of the axial noise with the squared distance from `axial_reference_m`
    /// (1/m; default 0.0019).
    pub axial_quadratic_per_m: f32,
    /// Distance of the least axial noise (m; default 0.4).
    pub axial_reference_m: f32,
    /// Angular term of the axial noise (m^1.5; default 0.0001).
    pub axial_angular_m: f32,
    /// Depth quantum (m; default 0.001; 0 leaves depth continuous).
    pub quantum_m: f32,
    /// Baseline to the second imager, to the right in the image (m; default 0.05; 0: no stereo
    /// shadow).
    pub baseline_m: f32,
    /// Pixels seen at a larger incidence are missing (degrees; default 80; 90: none).
    pub max_incidence_deg: f32,
    /// A depth step larger than this between 4-neighbours is a depth edge (m; default 0.01).
    pub edge_jump_m: f32,
    /// Probability that a pixel at a depth edge is missing (default: 0.3).
    pub edge_dropout: f32,
    /// Pixels with a luminance (0–1, Rec. 709) below this are dark (default: 0.06).
    pub dark_luminance: f32,
    /// Probability that a dark pixel is missing (default: 0.3).
    pub dark_dropout: f32,
}

impl Default for DepthNoise {
    fn default() -> Self {
        Self {
            enabled: true,
            seed: 0,
            axial_base_m: 0.0012,
            axial_quadratic_per_m: 0.0019,
            axial_reference_m: 0.4,
            axial_angular_m: 0.0001,
            quantum_m: 0.001,
            baseline_m: 0.05,
            max_incidence_deg: 80.0,
            edge_jump_m: 0.01,
            edge_dropout: 0.3,
            dark_luminance: 0.06,
            dark_dropout: 0.3,
        }
    }
}

/// A bad [`DepthNoise`] field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("depth noise: {field}: {reason}")]
pub struct DepthNoiseError {
    /// The field, e.g. `axial_base_m`.
    pub field: &'static str,
    /// What is wrong.
    pub reason: String,
}

impl DepthNoise {
    /// The model switched off: frames stay as rendered.
    pub fn off() -> Self {
        Self {
            enabled: false,
            ..Self::default()
        }
    }

    /// Checks every field (also when disabled, so a config file cannot hide a typo); the error
    /// names the first bad one.
    pub fn validate(&self) -> Result<(), DepthNoiseError> {
        let ranges: [(&'static str, f32, f32, f32); 11] = [
            ("axial_base_m", self.axial_base_m, 0.0, 0.05),
            (
                "axial_quadratic_per_m",
                self.axial_quadratic_per_m,
                0.0,
                0.1,
            ),
            ("axial_reference_m", self.axial_reference_m, 0.0, 10.0),
            ("axial_angular_m", self.axial_angular_m, 0.0, 0.01),
            ("quantum_m", self.quantum_m, 0.0, 0.05),
            ("baseline_m", self.baseline_m, 0.0, 0.5),
            ("max_incidence_deg", self.max_incidence_deg, 1.0, 90.0),
            ("edge_jump_m", self.edge_jump_m, 1e-4, 1.0),
            ("edge_dropout", self.edge_dropout, 0.0, 1.0),
            ("dark_luminance", self.dark_luminance, 0.0, 1.0),
            ("dark_dropout", self.dark_dropout, 0.0, 1.0),
        ];
        for (field, value, lo, hi) in ranges {
            if !(value.is_finite() && value >= lo && value <= hi) {
                return Err(DepthNoiseError {
                    field,
                    reason: format!("{value} must be in [{lo}, {hi}]"),
                });
            }
        }
        Ok(())
    }

    /// The seed of one frame's noise: the model's `seed`, the caller's `salt` (e.g. the
    /// simulation step) and a checksum of the clean depth.
    pub fn frame_seed(&self, salt: u64, frame: &RgbdFrame) -> u64 {
        let mut h = crc32fast::Hasher::new();
        for d in &frame.depth_m {
            h.update(&d.to_bits().to_le_bytes());
        }
        derive_seed(self.seed, TAG_FRAME, salt, u64::from(h.finalize()))
    }

    /// Applies the model to `frame` with the draws of [`DepthNoise::frame_seed`] for `salt`
    /// (the robot's cameras pass the simulation step): what every camera of a run does with a
    /// clean frame. A no-op when disabled.
    pub fn sense(&self, frame: &mut RgbdFrame, intrinsics: &Intrinsics, salt: u64) {
        if self.enabled {
            let seed = self.frame_seed(salt, frame);
            self.apply(frame, intrinsics, seed);
        }
    }

    /// Axial standard deviation (m) at depth `z_m` and incidence `theta_rad`.
    pub fn axial_sigma_m(&self, z_m: f32, theta_rad: f32) -> f32 {
        let dz = z_m - self.axial_reference_m;
        let theta = theta_rad.clamp(0.0, 1.5);
        let angular = self.axial_angular_m / z_m.max(1e-3).sqrt() * theta * theta
            / (std::f32::consts::FRAC_PI_2 - theta).powi(2);
        self.axial_base_m + self.axial_quadratic_per_m * dz * dz + angular
    }

    /// Applies the model to `frame` (taken by a camera with `intrinsics`) with the draws of
    /// `seed`; a no-op when disabled or when the buffers do not match the intrinsics.
    pub fn apply(&self, frame: &mut RgbdFrame, intrinsics: &Intrinsics, seed: u64) {
        let (w, h) = (frame.width as usize, frame.height as usize);
        if !self.enabled
            || w == 0
            || h == 0
            || frame.depth_m.len() != w * h
            || frame.rgb.len() != w * h
            || intrinsics.width != frame.width
            || intrinsics.height != frame.height
        {
            return;
        }
        let clean = &frame.depth_m;
        let valid = |i: usize| clean[i].is_finite() && clean[i] > 0.0;
        let shadow = self.stereo_shadow(clean, intrinsics, w, h);
        let cos_max = self.max_incidence_deg.to_radians().cos();
        let rgb = &frame.rgb;
        // Written row by row in place: one allocation, no concatenation of rayon's pieces.
        let mut noisy = vec![0.0f32; w * h];
        noisy.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, TAG_FRAME, y as u64, 0));
            let shadow = &shadow;
            let mut pixel = |x: usize| -> f32 {
                // Three draws per pixel whatever happens to it, so one pixel's fate never
                // shifts another's.
                let (p_edge, p_dark): (f32, f32) = (rng.random(), rng.random());
                let n: f32 = rng.sample(StandardNormal);
                let i = y * w + x;
                if !valid(i) || shadow[i] {
                    return 0.0;
                }
                let z = clean[i];
                let near = |j: usize| valid(j) && (clean[j] - z).abs() <= self.edge_jump_m;
                let neighbours = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < w).then(|| i + 1),
                    (y > 0).then(|| i - w),
                    (y + 1 < h).then(|| i + w),
                ];
                let at_edge = neighbours.iter().any(|j| j.is_some_and(|j| !near(j)));
                if at_edge && p_edge < self.edge_dropout {
                    return 0.0;
                }
                let [r, g, b] = rgb[i].map(f32::from);
                let luminance = (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0;
                if luminance < self.dark_luminance && p_dark < self.dark_dropout {
                    return 0.0;
                }
                let point =
                    |j: usize| intrinsics.unproject((j % w) as f32, (j / w) as f32, clean[j]);
                // Tangents from the neighbours on the same surface (central where both are).
                let tangent = |a: Option<usize>, b: Option<usize>| {
                    let a = a.filter(|&j| near(j)).unwrap_or(i);
                    let b = b.filter(|&j| near(j)).unwrap_or(i);
                    (a != b).then(|| sub(point(b), point(a)))
                };
                let mut theta = 0.0;
                if let (Some(tx), Some(ty)) = (
                    tangent(neighbours[0], neighbours[1]),
                    tangent(neighbours[2], neighbours[3]),
                ) {
                    let normal = cross(tx, ty);
                    let p = point(i);
                    let denom = norm(normal) * norm(p);
                    if denom > 0.0 {
                        let cos = (dot(normal, p) / denom).abs().min(1.0);
                        if cos < cos_max {
                            return 0.0;
                        }
                        theta = cos.acos();
                    }
                }
                let mut d = z + self.axial_sigma_m(z, theta) * n;
                if self.quantum_m > 0.0 {
                    d = (d / self.quantum_m).round() * self.quantum_m;
                }
                d.max(self.quantum_m.max(1e-4))
            };
            for (x, out) in row.iter_mut().enumerate() {
                *out = pixel(x);
            }
        });
        frame.depth_m = noisy;
    }

    /// Pixels the second imager cannot see: scanning each row from the right, a pixel whose
    /// column in the second image is not left of every column seen to its right is hidden by a
    /// nearer surface.
    fn stereo_shadow(&self, depth: &[f32], k: &Intrinsics, w: usize, h: usize) -> Vec<bool> {
        let mut shadow = vec![false; w * h];
        if self.baseline_m <= 0.0 {
            return shadow;
        }
        let fb = k.fx * self.baseline_m;
        shadow.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let mut min_right = f32::INFINITY;
            for x in (0..w).rev() {
                let z = depth[y * w + x];
                if !(z.is_finite() && z > 0.0) {
                    continue;
                }
                let u_right = x as f32 - fb / z;
                if u_right >= min_right {
                    row[x] = true;
                } else {
                    min_right = u_right;
                }
            }
        });
        shadow
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Pose, look_at};
    use crate::mesh::Mesh;
    use crate::render::{Camera, RenderItem, render};

    /// A table 0.5 m (or `height_m`) below a top-down camera, with a 0.1 m cube of `rgb`.
    fn scene(height_m: f32, rgb: [u8; 3]) -> (Camera, RgbdFrame) {
        let camera = Camera::new(
            Intrinsics::kinect_qvga(),
            look_at([0.0, 0.0, height_m], [0.0; 3], [0.0, 1.0, 0.0]),
        );
        let table = Mesh::cuboid([0.0, 0.0, -0.01], [4.0, 4.0, 0.02], [150, 118, 84]);
        let cube = Mesh::cuboid([0.0, 0.0, 0.05], [0.1; 3], rgb);
        let frame = render(
            &camera,
            &[
                RenderItem {
                    mesh: &table,
                    world_from_object: Pose::identity(),
                    label: 1,
                },
                RenderItem {
                    mesh: &cube,
                    world_from_object: Pose::identity(),
                    label: 2,
                },
            ],
        );
        (camera, frame)
    }

    fn noisy(noise: &DepthNoise, height_m: f32, rgb: [u8; 3], seed: u64) -> (RgbdFrame, RgbdFrame) {
        let (camera, clean) = scene(height_m, rgb);
        let mut frame = clean.clone();
        noise.apply(&mut frame, &camera.intrinsics, seed);
        (clean, frame)
    }

    /// The table's residuals: their standard deviation is the model's σ at that distance.
    fn table_sigma(noise: &DepthNoise, height_m: f32) -> f64 {
        let (clean, frame) = noisy(noise, height_m, [200, 40, 40], 3);
        let r: Vec<f64> = clean
            .depth_m
            .iter()
            .zip(&frame.depth_m)
            .zip(&clean.label)
            .filter(|((c, n), l)| **l == 1 && **c > 0.0 && **n > 0.0)
            .map(|((c, n), _)| f64::from(n - c))
            .collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
    }

    #[test]
    fn axial_noise_follows_the_model_and_grows_with_distance() {
        let noise = DepthNoise {
            quantum_m: 0.0,
            ..DepthNoise::default()
        };
        let near = table_sigma(&noise, 0.5);
        let far = table_sigma(&noise, 1.2);
        // The table is seen at up to ~30° off-axis: a little above the on-axis σ.
        let at = |z: f32| f64::from(noise.axial_sigma_m(z, 0.0));
        assert!(near > 0.95 * at(0.5) && near < 1.25 * at(0.5), "{near}");
        assert!(far > 0.95 * at(1.2) && far < 1.25 * at(1.2), "{far}");
        assert!(far > 1.5 * near, "{far} vs {near}");
        // σ(0.5 m) about 1.2 mm: the published RealSense/Kinect figure of 1–2 mm.
        assert!((0.001..0.002).contains(&at(0.5)));
    }

    #[test]
    fn depth_is_quantised() {
        let (_, frame) = noisy(&DepthNoise::default(), 0.5, [200, 40, 40], 1);
        for &d in frame.depth_m.iter().filter(|&&d| d > 0.0) {
            let mm = d * 1000.0;
            assert!((mm - mm.round()).abs() < 1e-3, "{d}");
        }
    }

    #[test]
    fn stereo_shadow_lies_left_of_the_object_and_scales_with_the_baseline() {
        let only_shadow = DepthNoise {
            edge_dropout: 0.0,
            dark_dropout: 0.0,
            ..DepthNoise::default()
        };
        let (camera, clean) = scene(0.5, [200, 40, 40]);
        let count = |noise: &DepthNoise| {
            let mut f = clean.clone();
            noise.apply(&mut f, &camera.intrinsics, 0);
            let row = 120 * 320;
            let lost: Vec<usize> = (0..320)
                .filter(|&x| clean.depth_m[row + x] > 0.0 && f.depth_m[row + x] == 0.0)
                .collect();
            lost
        };
        let lost = count(&only_shadow);
        // The cube's top spans columns ~124–195; the shadow sits just left of it, its
        // width f·b·(1/z_top − 1/z_table) = 287.5·0.05·(1/0.4 − 1/0.5) ≈ 7 px.
        let cube_left = (0..320).find(|&x| clean.label[120 * 320 + x] == 2).unwrap();
        assert!((6..=9).contains(&lost.len()), "{lost:?}");
        assert!(
            lost.iter().all(|&x| x < cube_left && x + 12 > cube_left),
            "{lost:?}"
        );
        let wider = count(&DepthNoise {
            baseline_m: 0.1,
            ..only_shadow.clone()
        });
        assert!(wider.len() >= 2 * lost.len() - 1, "{wider:?}");
        assert!(
            count(&DepthNoise {
                baseline_m: 0.0,
                ..only_shadow
            })
            .is_empty()
        );
    }

    #[test]
    fn dark_surfaces_and_edges_lose_pixels() {
        let base = DepthNoise {
            baseline_m: 0.0,
            edge_dropout: 0.0,
            dark_dropout: 0.0,
            ..DepthNoise::default()
        };
        let lost_on_cube = |noise: &DepthNoise, rgb: [u8; 3]| {
            let (clean, f) = noisy(noise, 0.5, rgb, 9);
            (0..clean.depth_m.len())
                .filter(|&i| clean.label[i] == 2 && f.depth_m[i] == 0.0)
                .count()
        };
        assert_eq!(lost_on_cube(&base, [5, 5, 5]), 0);
        let dark = DepthNoise {
            dark_dropout: 0.5,
            ..base.clone()
        };
        let (_, clean) = scene(0.5, [5, 5, 5]);
        let cube_px = clean.label.iter().filter(|&&l| l == 2).count();
        let lost = lost_on_cube(&dark, [5, 5, 5]) as f64 / cube_px as f64;
        assert!((0.4..0.6).contains(&lost), "{lost}");
        // A bright cube keeps its pixels.
        assert_eq!(lost_on_cube(&dark, [200, 200, 200]), 0);
        let edges = DepthNoise {
            edge_dropout: 1.0,
            ..base
        };
        let (clean, f) = noisy(&edges, 0.5, [200, 40, 40], 9);
        // Every cube-top pixel on the top's border is lost, no pixel inside it.
        let w = 320;
        let top = |i: usize| clean.label[i] == 2 && (clean.depth_m[i] - 0.4).abs() < 1e-3;
        let mut border = 0;
        for i in (w..clean.depth_m.len() - w).filter(|&i| top(i)) {
            let inner = top(i - 1) && top(i + 1) && top(i - w) && top(i + w);
            if inner {
                assert!(f.depth_m[i] > 0.0);
            } else {
                border += 1;
                assert_eq!(f.depth_m[i], 0.0);
            }
        }
        assert!(border > 100, "{border}");
    }

    #[test]
    fn steep_surfaces_are_missing() {
        // With a 20° limit the table at the image's corners (seen ~35° off-axis) is lost.
        let steep = DepthNoise {
            max_incidence_deg: 20.0,
            baseline_m: 0.0,
            edge_dropout: 0.0,
            dark_dropout: 0.0,
            ..DepthNoise::default()
        };
        let (clean, f) = noisy(&steep, 0.5, [200, 40, 40], 0);
        let corner = 3 * 320 + 3;
        assert!(clean.depth_m[corner] > 0.0 && f.depth_m[corner] == 0.0);
        assert!(f.depth_m[120 * 320 + 160] > 0.0);
    }

    #[test]
    fn same_seed_same_bytes_and_seeds_differ() {
        let noise = DepthNoise::default();
        let (_, a) = noisy(&noise, 0.5, [200, 40, 40], 11);
        let (_, b) = noisy(&noise, 0.5, [200, 40, 40], 11);
        let (_, c) = noisy(&noise, 0.5, [200, 40, 40], 12);
        assert_eq!(a.depth_m, b.depth_m);
        assert_ne!(a.depth_m, c.depth_m);
        let (_, clean) = scene(0.5, [200, 40, 40]);
        assert_eq!(noise.frame_seed(1, &clean), noise.frame_seed(1, &clean));
        assert_ne!(noise.frame_seed(1, &clean), noise.frame_seed(2, &clean));
        // Colour and labels are untouched; off leaves depth alone.
        assert_eq!(a.rgb, clean.rgb);
        assert_eq!(a.label, clean.label);
        let (clean, off) = noisy(&DepthNoise::off(), 0.5, [200, 40, 40], 11);
        assert_eq!(off, clean);
    }

    #[test]
    fn validation_names_the_field() {
        DepthNoise::default().validate().unwrap();
        for (noise, field) in [
            (
                DepthNoise {
                    axial_base_m: -0.001,
                    ..DepthNoise::default()
                },
                "axial_base_m",
            ),
            (
                DepthNoise {
                    quantum_m: 1.0,
                    ..DepthNoise::default()
                },
                "quantum_m",
            ),
            (
                DepthNoise {
                    edge_dropout: f32::NAN,
                    ..DepthNoise::default()
                },
                "edge_dropout",
            ),
            (
                DepthNoise {
                    baseline_m: 3.0,
                    enabled: false,
                    ..DepthNoise::default()
                },
                "baseline_m",
            ),
        ] {
            let e = noise.validate().unwrap_err();
            assert_eq!(e.field, field, "{e}");
            assert!(e.to_string().contains(field));
        }
    }
}
