//! A pinhole RGB-D camera and a z-buffer rasteriser: depth in metres, RGB from per-triangle
//! colours with Lambert shading, a per-pixel label buffer, and back-projection of the labelled
//! object pixels to a point cloud in the camera's optical frame (table removed).
//!
//! Pixel centres sit at integer coordinates: pixel `(u, v)` sees the ray through
//! `((u - cx) / fx, (v - cy) / fy, 1)`.
//!
//! ```
//! use lgdm_pointcloud::math::{Pose, look_at};
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::render::{render, Camera, Intrinsics, RenderItem};
//! let camera = Camera::new(Intrinsics::kinect_qvga(), look_at([0.0, -0.8, 0.4], [0.0, 0.0, 0.05], [0.0, 0.0, 1.0]));
//! let mesh = Mesh::cuboid([0.0, 0.0, 0.05], [0.1, 0.1, 0.1], [200, 0, 0]);
//! let frame = render(&camera, &[RenderItem { mesh: &mesh, world_from_object: Pose::identity(), label: 2 }]);
//! let cloud = frame.backproject(&camera, 2);
//! assert!(cloud.len() > 100);
//! ```

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;
use crate::math::{Pose, cross, dot, normalize, rotate_vector, sub, transform_point};
use crate::mesh::Mesh;

/// Pinhole intrinsics (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
}

impl Intrinsics {
    /// A Kinect-like camera at 320×240 (horizontal field of view ≈ 58°).
    pub fn kinect_qvga() -> Self {
        Self::centered(320, 240, 287.5)
    }

    /// A Kinect-like camera at 640×480 (horizontal field of view ≈ 58°).
    pub fn kinect_vga() -> Self {
        Self::centered(640, 480, 575.0)
    }

    /// Square pixels, principal point at the image centre.
    pub fn centered(width: u32, height: u32, focal_px: f32) -> Self {
        Self {
            width,
            height,
            fx: focal_px,
            fy: focal_px,
            cx: (width as f32 - 1.0) / 2.0,
            cy: (height as f32 - 1.0) / 2.0,
        }
    }

    /// Projects a point in the optical frame to `(u, v)` pixels; `None` behind the camera.
    #[inline]
    pub fn project(&self, p: [f32; 3]) -> Option<[f32; 2]> {
        (p[2] > 1e-6).then(|| {
            [
                self.fx * p[0] / p[2] + self.cx,
                self.fy * p[1] / p[2] + self.cy,
            ]
        })
    }

    /// The optical-frame point at pixel `(u, v)` with depth `z` metres.
    #[inline]
    pub fn unproject(&self, u: f32, v: f32, z: f32) -> [f32; 3] {
        [(u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z]
    }
}

/// A camera: intrinsics and its pose `world_from_camera` (optical convention).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Pose of the camera in the world (optical frame: x right, y down, z forward).
    #[serde(with = "crate::math::pose_serde")]
    pub world_from_camera: Pose,
}

impl Camera {
    /// A camera from intrinsics and pose.
    pub fn new(intrinsics: Intrinsics, world_from_camera: Pose) -> Self {
        Self {
            intrinsics,
            world_from_camera,
        }
    }
}

/// One mesh placed in the scene.
#[derive(Debug, Clone, Copy)]
pub struct RenderItem<'a> {
    /// The mesh in its own frame.
    pub mesh: &'a Mesh,
    /// Where the mesh is in the world.
    pub world_from_object: Pose,
    /// Label written to the label buffer where this mesh is visible (0 is background).
    pub label: u8,
}

/// Label of background pixels.
pub const LABEL_BACKGROUND: u8 = 0;

/// A rendered RGB-D frame: row-major buffers of `width × height`.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Depth (optical z) in metres; 0 where nothing was hit.
    pub depth_m: Vec<f32>,
    /// Shaded colour per pixel.
    pub rgb: Vec<[u8; 3]>,
    /// Label of the visible surface per pixel ([`LABEL_BACKGROUND`] where nothing was hit).
    pub label: Vec<u8>,
}

/// Background colour of rendered images.
pub const BACKGROUND_RGB: [u8; 3] = [0, 0, 0];

/// Near clipping distance, metres: triangles with a vertex closer than this are skipped.
pub const NEAR_M: f32 = 0.02;

/// Renders the items with a z-buffer: depth is interpolated perspective-correctly, colour is
/// the triangle's colour shaded by a fixed light (Lambert, two-sided) plus ambient.
pub fn render(camera: &Camera, items: &[RenderItem<'_>]) -> RgbdFrame {
    let k = camera.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    let mut frame = RgbdFrame {
        width: k.width,
        height: k.height,
        depth_m: vec![0.0; w * h],
        rgb: vec![BACKGROUND_RGB; w * h],
        label: vec![LABEL_BACKGROUND; w * h],
    };
    let triangles = prepare_triangles(camera, items);
    // Bands of rows on rayon's threads. Each band draws, in order, every triangle's pixels
    // inside it, so each pixel meets the same triangles in the same order as in one pass: the
    // same frame.
    let band = RENDER_BAND_ROWS * w.max(1);
    let mut zbuf = vec![f32::INFINITY; w * h];
    frame
        .depth_m
        .par_chunks_mut(band)
        .zip(frame.rgb.par_chunks_mut(band))
        .zip(frame.label.par_chunks_mut(band))
        .zip(zbuf.par_chunks_mut(band))
        .enumerate()
        .for_each(|(b, (((depth_m, rgb), label), zbuf))| {
            let first_row = b * RENDER_BAND_ROWS;
            let last_row = first_row + depth_m.len() / w.max(1) - 1;
            for t in &triangles {
                let (min_y, max_y) = (t.min_y.max(first_row), t.max_y.min(last_row));
                let [s0, s1, s2] = t.screen;
                for y in min_y..=max_y {
                    let py = y as f32;
                    for x in t.min_x..=t.max_x {
                        let px = x as f32;
                        let w0 = ((s1[0] - px) * (s2[1] - py) - (s1[1] - py) * (s2[0] - px))
                            * t.inv_area;
                        let w1 = ((s2[0] - px) * (s0[1] - py) - (s2[1] - py) * (s0[0] - px))
                            * t.inv_area;
                        let w2 = 1.0 - w0 - w1;
                        if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                            continue;
                        }
                        let [iz0, iz1, iz2] = t.inv_depth;
                        let z = 1.0 / (w0 * iz0 + w1 * iz1 + w2 * iz2);
                        let i = (y - first_row) * w + x;
                        if z < zbuf[i] {
                            zbuf[i] = z;
                            depth_m[i] = z;
                            rgb[i] = t.color;
                            label[i] = t.label;
                        }
                    }
                }
            }
        });
    frame
}

/// Rows per band [`render`] draws on one thread.
const RENDER_BAND_ROWS: usize = 16;

/// A triangle ready to be drawn: its screen corners, the pixels its box covers (inclusive),
/// its shaded colour and label.
struct ScreenTriangle {
    screen: [[f32; 2]; 3],
    inv_depth: [f32; 3],
    inv_area: f32,
    min_x: usize,
    max_x: usize,
    min_y: usize,
    max_y: usize,
    color: [u8; 3],
    label: u8,
}

/// Every item's triangles in front of the near plane whose box covers a pixel, in drawing
/// order, each flat-shaded from its camera-frame normal.
fn prepare_triangles(camera: &Camera, items: &[RenderItem<'_>]) -> Vec<ScreenTriangle> {
    let k = camera.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    let camera_from_world = camera.world_from_camera.inverse();
    // Light: from above and slightly behind the camera (world frame), expressed in camera frame.
    let light_world = normalize([0.3, -0.6, 1.0]);
    let light = rotate_vector(&camera_from_world, light_world);
    let mut projected: Vec<([f32; 3], [f32; 2])> = Vec::new();
    let mut out = Vec::new();
    for item in items {
        let camera_from_object = camera_from_world * item.world_from_object;
        projected.clear();
        projected.extend(item.mesh.vertices.iter().map(|&v| {
            let p = transform_point(&camera_from_object, v);
            let uv = if p[2] > NEAR_M {
                [k.fx * p[0] / p[2] + k.cx, k.fy * p[1] / p[2] + k.cy]
            } else {
                [f32::NAN, f32::NAN]
            };
            (p, uv)
        }));
        for (ti, tri) in item.mesh.triangles.iter().enumerate() {
            let (p0, s0) = projected[tri[0] as usize];
            let (p1, s1) = projected[tri[1] as usize];
            let (p2, s2) = projected[tri[2] as usize];
            if p0[2] <= NEAR_M || p1[2] <= NEAR_M || p2[2] <= NEAR_M {
                continue;
            }
            let area = (s1[0] - s0[0]) * (s2[1] - s0[1]) - (s1[1] - s0[1]) * (s2[0] - s0[0]);
            if area.abs() < 1e-12 {
                continue;
            }
            let min_x = s0[0].min(s1[0]).min(s2[0]).ceil().max(0.0);
            let max_x = s0[0].max(s1[0]).max(s2[0]).floor().min(w as f32 - 1.0);
            let min_y = s0[1].min(s1[1]).min(s2[1]).ceil().max(0.0);
            let max_y = s0[1].max(s1[1]).max(s2[1]).floor().min(h as f32 - 1.0);
            if min_x > max_x || min_y > max_y {
                continue;
            }
            // Flat shading from the camera-frame normal, flipped towards the viewer.
            let mut n = normalize(cross(sub(p1, p0), sub(p2, p0)));
            let centre = [
                (p0[0] + p1[0] + p2[0]) / 3.0,
                (p0[1] + p1[1] + p2[1]) / 3.0,
                (p0[2] + p1[2] + p2[2]) / 3.0,
            ];
            if dot(n, centre) > 0.0 {
                n = [-n[0], -n[1], -n[2]];
            }
            let lambert = dot(n, light).max(0.0);
            let head = dot(n, normalize([-centre[0], -centre[1], -centre[2]])).max(0.0);
            let shade = 0.25 + 0.5 * lambert + 0.25 * head;
            let base = item.mesh.colors.get(ti).copied().unwrap_or([160, 160, 160]);
            out.push(ScreenTriangle {
                screen: [s0, s1, s2],
                inv_depth: [1.0 / p0[2], 1.0 / p1[2], 1.0 / p2[2]],
                inv_area: 1.0 / area,
                min_x: min_x as usize,
                max_x: max_x as usize,
                min_y: min_y as usize,
                max_y: max_y as usize,
                color: [
                    (f32::from(base[0]) * shade).min(255.0) as u8,
                    (f32::from(base[1]) * shade).min(255.0) as u8,
                    (f32::from(base[2]) * shade).min(255.0) as u8,
                ],
                label: item.label,
            });
        }
    }
    out
}

impl RgbdFrame {
    /// Back-projects the pixels carrying `label` to a cloud in the camera's optical frame
    /// (metres), row-major pixel order, with their colours.
    pub fn backproject(&self, camera: &Camera, label: u8) -> PointCloud {
        let k = camera.intrinsics;
        let mut points = Vec::new();
        let mut colors = Vec::new();
        for (i, (&l, &z)) in self.label.iter().zip(&self.depth_m).enumerate() {
            if l == label && z > 0.0 {
                let u = (i % self.width as usize) as f32;
                let v = (i / self.width as usize) as f32;
                points.push(k.unproject(u, v, z));
                colors.push(self.rgb[i]);
            }
        }
        PointCloud::new(points, Some(colors))
    }

    /// Number of pixels carrying `label`.
    pub fn count_label(&self, label: u8) -> usize {
        self.label.iter().filter(|&&l| l == label).count()
    }
}

/// Projects a cloud (optical frame) into a depth image with the given intrinsics, keeping the
/// nearest point per pixel (rounded to the nearest pixel centre); 0 where no point falls.
pub fn depth_from_cloud(cloud: &PointCloud, intrinsics: &Intrinsics) -> Vec<f32> {
    let (w, h) = (intrinsics.width as usize, intrinsics.height as usize);
    let mut depth = vec![0.0f32; w * h];
    for &p in &cloud.points {
        if let Some([u, v]) = intrinsics.project(p) {
            let (x, y) = (u.round(), v.round());
            if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
                let i = y as usize * w + x as usize;
                if depth[i] == 0.0 || p[2] < depth[i] {
                    depth[i] = p[2];
                }
            }
        }
    }
    depth
}

/// Label [`splat_cloud`] gives the pixels it draws.
pub const CLOUD_LABEL: u8 = 3;

/// Colour of splatted points of a cloud without colours.
pub const CLOUD_GREY: [u8; 3] = [128, 128, 128];

/// Draws a cloud (optical frame) into a frame taken with `intrinsics`: each point covers the
/// `(2r + 1)²` pixels around its projection where it is nearer than what is there (z-buffer),
/// with its colour (grey without colours) and [`CLOUD_LABEL`]. `radius_px` `None` chooses
/// `r` from the density: half the mean spacing of the points over their projected box,
/// rounded up, at most 4.
pub fn splat_cloud(
    frame: &mut RgbdFrame,
    intrinsics: &Intrinsics,
    cloud: &PointCloud,
    radius_px: Option<usize>,
) {
    let (w, h) = (frame.width as i64, frame.height as i64);
    let projected: Vec<(usize, [f32; 2])> = cloud
        .points
        .iter()
        .enumerate()
        .filter(|(_, p)| p.iter().all(|v| v.is_finite()))
        .filter_map(|(i, &p)| intrinsics.project(p).map(|uv| (i, uv)))
        .filter(|(_, [u, v])| u.is_finite() && v.is_finite())
        .collect();
    if projected.is_empty() {
        return;
    }
    let r = radius_px.unwrap_or_else(|| {
        let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
        for (_, [u, v]) in &projected {
            lo = [lo[0].min(*u), lo[1].min(*v)];
            hi = [hi[0].max(*u), hi[1].max(*v)];
        }
        let area = (hi[0] - lo[0] + 1.0) * (hi[1] - lo[1] + 1.0);
        let spacing = (area / projected.len() as f32).sqrt();
        ((spacing / 2.0).ceil() as usize).min(4)
    }) as i64;
    for (i, [u, v]) in projected {
        let z = cloud.points[i][2];
        let colour = cloud.colors.as_ref().map_or(CLOUD_GREY, |c| c[i]);
        let (x, y) = (u.round() as i64, v.round() as i64);
        for yy in (y - r).max(0)..=(y + r).min(h - 1) {
            for xx in (x - r).max(0)..=(x + r).min(w - 1) {
                let j = (yy * w + xx) as usize;
                let d = frame.depth_m[j];
                if d.is_nan() || d <= 0.0 || z < d {
                    frame.depth_m[j] = z;
                    frame.rgb[j] = colour;
                    frame.label[j] = CLOUD_LABEL;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn front_camera() -> Camera {
        // Camera at the origin looking along world +z... expressed with look_at: eye at origin,
        // target on +z, "up" = -y so that the optical frame equals the world frame.
        Camera::new(
            Intrinsics::kinect_qvga(),
            crate::math::look_at([0.0; 3], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]),
        )
    }

    #[test]
    fn optical_frame_equals_world_for_front_camera() {
        let c = front_camera();
        let p = transform_point(&c.world_from_camera, [0.1, 0.2, 0.3]);
        assert!(
            (p[0] - 0.1).abs() < 1e-6 && (p[1] - 0.2).abs() < 1e-6 && (p[2] - 0.3).abs() < 1e-6
        );
    }

    /// A fronto-parallel plane at z = 1 m renders depth exactly 1 m everywhere it covers.
    #[test]
    fn plane_depth_is_analytic() {
        let c = front_camera();
        let mut quad = Mesh::new();
        let (a, b, cc, d) = (
            [-0.3, -0.2, 1.0],
            [0.3, -0.2, 1.0],
            [0.3, 0.2, 1.0],
            [-0.3, 0.2, 1.0],
        );
        quad.push_triangle(a, b, cc, [255, 0, 0]);
        quad.push_triangle(a, cc, d, [255, 0, 0]);
        let f = render(
            &c,
            &[RenderItem {
                mesh: &quad,
                world_from_object: Pose::identity(),
                label: 1,
            }],
        );
        let k = c.intrinsics;
        // Pixel under the centre, and one near the plane's corner (0.25, 0.15).
        for (x, y) in [(0.0f32, 0.0f32), (0.25, 0.15), (-0.25, -0.15)] {
            let u = (k.fx * x + k.cx).round() as usize;
            let v = (k.fy * y + k.cy).round() as usize;
            let i = v * k.width as usize + u;
            assert_eq!(f.label[i], 1);
            assert!((f.depth_m[i] - 1.0).abs() < 1e-5, "depth {}", f.depth_m[i]);
        }
        // Outside the quad: background.
        let u = (k.fx * 0.35 + k.cx).round() as usize;
        assert_eq!(f.label[(k.cy.round() as usize) * k.width as usize + u], 0);
    }
}
