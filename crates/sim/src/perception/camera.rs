//! The robot's cameras: RGB-D frames of the physics world drawn by the pointcloud crate's
//! z-buffer renderer ([`lgdm_pointcloud::render::render`]) from the bodies' current poses — the
//! same renderer that draws the datasets — with every camera constant in one config,
//! [`CameraConfig`].
//!
//! Two cameras, both top-down:
//! - the **overview** camera, the reference sim's fixed camera (1.115 m above the table top at
//!   (0.05, −0.52), 224×224, vertical field of view 40°, image right = world +x, image down =
//!   world −y): it finds the objects on the table;
//! - a **close-up** camera, placed for each object 0.5 m above its point on the table with the
//!   dataset's grasp-camera intrinsics ([`Intrinsics::kinect_vga`]). The grasp network is fed
//!   the object-centred crop ([`lgdm_pointcloud::crop`], 0.22 m at 224 px) of this frame, so it
//!   sees exactly the pixels per metre *and* the perspective of its training images
//!   (`grasp::cornell::grasp_scene` renders them from 0.5 m). The reference camera's 224 px
//!   over 0.81 m of table (3.6 mm/px) would give a crop of ~61 px upsampled 3.7×, too coarse
//!   for rims and handles, and its 1.115 m height scales the tops of objects differently.
//!
//! What is drawn: the table (in the dataset's table colour), the baskets and the objects — by
//! default their colliders in the meshes' colours ([`ObjectDrawing`]), so the camera sees what
//! the fingers will meet (`mesh` draws the visual meshes). Every
//! overview and close-up frame then goes through a depth sensor model
//! ([`lgdm_pointcloud::sensor::DepthNoise`], `[cameras.noise]`, on by default): axial noise
//! growing with distance, 1 mm quantisation, stereo shadows and missing pixels at edges and on
//! dark or steep surfaces, seeded by the world's step and the frame. The
//! arm and gripper are not drawn: frames are taken with the arm parked away from the table.
//! Labels: [`LABEL_SCENERY`] for table and baskets, [`LABEL_FIRST_OBJECT`] + k for the k-th
//! live object ([`SceneFrame::object_at_label`]); labels are ground truth for bookkeeping
//! (which object an attempt aimed at), never for perception.
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::math::translation;
//! use lgdm_sim::perception::camera::CameraConfig;
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let top_z = world.config().table.top_z_m();
//! let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [200, 40, 40]);
//! let h = world.spawn_object("cube", &cube, &translation([0.05, -0.52, top_z])).unwrap();
//! let cameras = CameraConfig::default();
//! let shot = cameras.render_overview(&world).unwrap();
//! // The cube sits at the camera's target: the image centre sees its top, 1.115 − 0.05 m away
//! // (give or take the sensor's σ ≈ 2 mm there and its 1 mm quantum).
//! let centre = 112 * 224 + 112;
//! assert!((shot.frame.depth_m[centre] - 1.065).abs() < 0.012);
//! assert_eq!(shot.object_at_label(shot.frame.label[centre]), Some(h));
//! ```

use lgdm_pointcloud::crop::CropSpec;
use lgdm_pointcloud::math::{Pose, look_at};
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, RgbdFrame, render};
use lgdm_pointcloud::segment::SegmentParams;
use lgdm_pointcloud::sensor::DepthNoise;
use serde::{Deserialize, Serialize};

use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;

/// Label of the scenery (table, baskets) in rendered frames.
pub const LABEL_SCENERY: u8 = 1;

/// Label of the first live object; the k-th live object (spawn order) has this + k.
pub const LABEL_FIRST_OBJECT: u8 = 2;

/// Most objects a frame can label apart.
pub const MAX_LABELLED_OBJECTS: usize = (u8::MAX - LABEL_FIRST_OBJECT) as usize + 1;

/// Colour of the table: the dataset's table (`grasp::cornell::table_mesh`), so the grasp
/// network sees the table it was trained on.
pub const TABLE_RGB: [u8; 3] = [150, 118, 84];

/// Colour of the baskets.
pub const BASKET_RGB: [u8; 3] = [90, 90, 100];

/// The fixed overview camera. Defaults: the reference sim's camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OverviewCamera {
    /// Camera position (m; default (0.05, −0.52, 1.9): 1.115 m above the table top at
    /// z = 0.785, the reference `Camera((0.05, −0.52, 1.9), …)`).
    pub eye_m: [f32; 3],
    /// Point looked at (m; default (0.05, −0.52, 0.785), on the table top).
    pub target_m: [f32; 3],
    /// World direction that appears up in the image (default (0, 1, 0): image right = world
    /// +x, image down = world −y, as the reference's `computeViewMatrix(up = [0, 1, 0])`).
    pub up: [f32; 3],
    /// Image width (px; default 224).
    pub width_px: u32,
    /// Image height (px; default 224).
    pub height_px: u32,
    /// Vertical field of view (degrees; default 40).
    pub vertical_fov_deg: f32,
}

impl Default for OverviewCamera {
    fn default() -> Self {
        Self {
            eye_m: [0.05, -0.52, 1.9],
            target_m: [0.05, -0.52, 0.785],
            up: [0.0, 1.0, 0.0],
            width_px: 224,
            height_px: 224,
            vertical_fov_deg: 40.0,
        }
    }
}

impl OverviewCamera {
    /// Square-pixel intrinsics from the vertical field of view, principal point at the centre.
    pub fn intrinsics(&self) -> Intrinsics {
        let half = (0.5 * self.vertical_fov_deg).to_radians();
        let focal_px = 0.5 * self.height_px as f32 / half.tan();
        Intrinsics::centered(self.width_px, self.height_px, focal_px)
    }

    /// The camera (intrinsics and `world_from_camera`).
    pub fn camera(&self) -> Camera {
        Camera::new(
            self.intrinsics(),
            look_at(self.eye_m, self.target_m, self.up),
        )
    }
}

/// The virtual close-up camera rendered per object. Defaults: the dataset's grasp camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloseupCamera {
    /// Height above the table top (m; default 0.5, the dataset's `GraspSpec::camera_height_m`).
    pub height_above_table_m: f32,
    /// Intrinsics (default [`Intrinsics::kinect_vga`], 640×480, focal 575 px: the dataset's
    /// grasp images; the 0.22 m crop is then 253 px of the frame, resampled to 224).
    pub intrinsics: Intrinsics,
    /// World direction that appears up in the image (default (0, 1, 0), as the dataset's).
    pub up: [f32; 3],
}

impl Default for CloseupCamera {
    fn default() -> Self {
        Self {
            height_above_table_m: 0.5,
            intrinsics: Intrinsics::kinect_vga(),
            up: [0.0, 1.0, 0.0],
        }
    }
}

impl CloseupCamera {
    /// The camera looking straight down at `table_point_m` (a point on the table top) from
    /// `height_above_table_m` above it.
    pub fn camera_at(&self, table_point_m: [f32; 3]) -> Camera {
        let [x, y, z] = table_point_m;
        Camera::new(
            self.intrinsics,
            look_at([x, y, z + self.height_above_table_m], [x, y, z], self.up),
        )
    }
}

/// What the cameras draw for an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectDrawing {
    /// The object's mesh, as the dataset draws it: the camera sees the designed shape, as a
    /// real camera sees the real object, which the physics' collider only approximates (a
    /// decomposition fills a vase's neck, a single hull a glass).
    Mesh,
    /// The object's collider — every convex part, each triangle in the colour of the nearest
    /// mesh triangle (default): the camera sees exactly the shape the fingers meet. Drawing the
    /// mesh costs the procedural vases, mugs and teapots what their decomposition does not
    /// have (`docs/DESIGN.md` §7).
    #[default]
    Collider,
}

/// Every camera and perception constant of the robot, once. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// The fixed overview camera (default: the reference sim's).
    pub overview: OverviewCamera,
    /// The per-object close-up camera (default: the dataset's grasp camera, 0.5 m up).
    pub closeup: CloseupCamera,
    /// The object-centred crop fed to grasp sources (default 0.22 m at 224 px, the dataset's).
    pub crop: CropSpec,
    /// Table-plane fit and object segmentation (default: the dataset's).
    pub segment: SegmentParams,
    /// What is drawn for an object (default `collider`, the shape the physics simulates; `mesh`
    /// draws the object's visual mesh, as a real camera would see it).
    pub draw: ObjectDrawing,
    /// The depth sensor model applied to every overview and close-up frame (`[cameras.noise]`;
    /// default: on, a RealSense D435-class camera, [`DepthNoise`]).
    pub noise: DepthNoise,
}

/// Errors of the cameras.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// A bad [`CameraConfig`] field.
    #[error("camera config: {field}: {reason}")]
    InvalidConfig {
        /// The field, e.g. `overview.vertical_fov_deg`.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// More live objects than a frame's labels can tell apart.
    #[error("{objects} objects in the scene; a frame labels at most {MAX_LABELLED_OBJECTS}")]
    TooManyObjects {
        /// Live objects.
        objects: usize,
    },
    /// A world query failed.
    #[error(transparent)]
    World(#[from] WorldError),
}

impl CameraConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), CameraError> {
        let bad =
            |field: &'static str, reason: String| Err(CameraError::InvalidConfig { field, reason });
        let o = &self.overview;
        if !(o.vertical_fov_deg.is_finite()
            && o.vertical_fov_deg > 1.0
            && o.vertical_fov_deg < 170.0)
        {
            return bad(
                "overview.vertical_fov_deg",
                format!("{} must be in (1, 170) degrees", o.vertical_fov_deg),
            );
        }
        if !(8..=4096).contains(&o.width_px) || !(8..=4096).contains(&o.height_px) {
            return bad(
                "overview.width_px",
                format!("{}×{} must be in 8..=4096 px", o.width_px, o.height_px),
            );
        }
        let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        if !finite(&o.eye_m) || !finite(&o.target_m) || !finite(&o.up) {
            return bad("overview.eye_m", "eye, target and up must be finite".into());
        }
        let d = [
            o.target_m[0] - o.eye_m[0],
            o.target_m[1] - o.eye_m[1],
            o.target_m[2] - o.eye_m[2],
        ];
        if d.iter().map(|c| c * c).sum::<f32>() < 1e-6 {
            return bad("overview.target_m", "coincides with eye_m".into());
        }
        let c = &self.closeup;
        if !(c.height_above_table_m.is_finite()
            && c.height_above_table_m > 0.05
            && c.height_above_table_m < 5.0)
        {
            return bad(
                "closeup.height_above_table_m",
                format!("{} must be in (0.05, 5) m", c.height_above_table_m),
            );
        }
        let k = &c.intrinsics;
        let usable = k.fx.is_finite()
            && k.fx > 0.0
            && k.fy.is_finite()
            && k.fy > 0.0
            && k.cx.is_finite()
            && k.cy.is_finite()
            && (8..=4096).contains(&k.width)
            && (8..=4096).contains(&k.height);
        if !usable {
            return bad(
                "closeup.intrinsics",
                "focal lengths must be positive, the principal point finite and the size 8..=4096 px"
                    .into(),
            );
        }
        if !finite(&c.up) {
            return bad("closeup.up", "must be finite".into());
        }
        self.crop
            .validate()
            .or_else(|e| bad("crop", e.to_string()))?;
        self.segment
            .validate()
            .or_else(|e| bad("segment", e.to_string()))?;
        self.noise
            .validate()
            .or_else(|e| bad("noise", e.to_string()))?;
        Ok(())
    }

    /// Renders the overview camera's frame of `world` now, through the sensor model.
    pub fn render_overview(&self, world: &World) -> Result<SceneFrame, CameraError> {
        let shot = render_world(world, &self.overview.camera(), self.draw)?;
        Ok(self.sense(world, shot))
    }

    /// Renders the close-up frame looking down at `table_point_m`, through the sensor model.
    pub fn render_closeup(
        &self,
        world: &World,
        table_point_m: [f32; 3],
    ) -> Result<SceneFrame, CameraError> {
        let shot = render_world(world, &self.closeup.camera_at(table_point_m), self.draw)?;
        Ok(self.sense(world, shot))
    }

    /// Applies the sensor model to a frame of `world`: the draws depend on the model's seed,
    /// the world's step and the clean depth, so a run's frames are the same bytes every time.
    fn sense(&self, world: &World, mut shot: SceneFrame) -> SceneFrame {
        self.noise
            .sense(&mut shot.frame, &shot.camera.intrinsics, world.steps());
        shot
    }
}

/// A rendered frame of the world and what its labels mean.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFrame {
    /// The camera that took it.
    pub camera: Camera,
    /// Depth (optical z, m), colour and label buffers.
    pub frame: RgbdFrame,
    /// The live objects in label order: label [`LABEL_FIRST_OBJECT`] + k is `objects[k]`.
    pub objects: Vec<ObjectHandle>,
}

impl SceneFrame {
    /// The object drawn with `label`, if it is an object's label.
    pub fn object_at_label(&self, label: u8) -> Option<ObjectHandle> {
        let k = label.checked_sub(LABEL_FIRST_OBJECT)? as usize;
        self.objects.get(k).copied()
    }

    /// The object most of `pixels` (row-major indices) show, if any (ties: the earlier one).
    pub fn majority_object(&self, pixels: &[u32]) -> Option<ObjectHandle> {
        let mut counts = vec![0usize; self.objects.len()];
        for &i in pixels {
            if let Some(k) = self
                .frame
                .label
                .get(i as usize)
                .and_then(|l| l.checked_sub(LABEL_FIRST_OBJECT))
                .map(usize::from)
                .filter(|&k| k < counts.len())
            {
                counts[k] += 1;
            }
        }
        let (best, n) = counts
            .iter()
            .enumerate()
            .fold((0, 0), |acc, (k, &n)| if n > acc.1 { (k, n) } else { acc });
        (n > 0).then(|| self.objects[best])
    }
}

/// The scenery's meshes (table top, basket floors and walls) in the world frame.
pub fn scenery_meshes(world: &World) -> Vec<Mesh> {
    let config = world.config();
    let t = &config.table;
    let mut out = vec![Mesh::cuboid(t.center_m, t.size_m, TABLE_RGB)];
    for b in &config.baskets {
        let [x, y, z] = b.floor_center_m;
        let th = b.wall_thickness_m;
        let [ix, iy] = b.inner_size_m;
        let (ox, oy) = (ix + 2.0 * th, iy + 2.0 * th);
        let h = b.wall_height_m;
        let wall_z = z + 0.5 * h;
        out.push(Mesh::cuboid([x, y, z - 0.5 * th], [ox, oy, th], BASKET_RGB));
        for (c, s) in [
            ([x + 0.5 * (ix + th), y, wall_z], [th, oy, h]),
            ([x - 0.5 * (ix + th), y, wall_z], [th, oy, h]),
            ([x, y + 0.5 * (iy + th), wall_z], [ox, th, h]),
            ([x, y - 0.5 * (iy + th), wall_z], [ox, th, h]),
        ] {
            out.push(Mesh::cuboid(c, s, BASKET_RGB));
        }
    }
    out
}

/// Renders the scenery and every live object of `world` at its current pose, each object drawn
/// as `draw` says.
pub fn render_world(
    world: &World,
    camera: &Camera,
    draw: ObjectDrawing,
) -> Result<SceneFrame, CameraError> {
    let objects: Vec<ObjectHandle> = world.objects().collect();
    if objects.len() > MAX_LABELLED_OBJECTS {
        return Err(CameraError::TooManyObjects {
            objects: objects.len(),
        });
    }
    let scenery = scenery_meshes(world);
    let mut items: Vec<RenderItem<'_>> = scenery
        .iter()
        .map(|mesh| RenderItem {
            mesh,
            world_from_object: Pose::identity(),
            label: LABEL_SCENERY,
        })
        .collect();
    for (k, &h) in objects.iter().enumerate() {
        let mesh = match draw {
            ObjectDrawing::Mesh => world.object_mesh(h)?,
            ObjectDrawing::Collider => world.object_collider_mesh(h)?,
        };
        items.push(RenderItem {
            mesh,
            world_from_object: world.object_pose(h)?,
            label: LABEL_FIRST_OBJECT + k as u8,
        });
    }
    let frame = render(camera, &items);
    Ok(SceneFrame {
        camera: *camera,
        frame,
        objects,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;

    /// The default overview camera is the reference's: 1.115 m above this world's table top,
    /// looking at the drop region's centre, 0.81 m of table across the image.
    #[test]
    fn default_overview_matches_the_world() {
        let world = World::new(WorldConfig::default()).unwrap();
        let top = world.config().table.top_z_m();
        let o = OverviewCamera::default();
        assert!((o.eye_m[2] - top - 1.115).abs() < 1e-5);
        assert!((o.target_m[2] - top).abs() < 1e-6);
        let k = o.intrinsics();
        let span_m = 224.0 * 1.115 / k.fy;
        assert!((span_m - 0.812).abs() < 0.002, "{span_m}");
        // Image right = world +x, image down = world −y.
        let cam = o.camera();
        let r = cam.world_from_camera.rotation.matrix();
        assert!((r[(0, 0)] - 1.0).abs() < 1e-6 && (r[(1, 1)] + 1.0).abs() < 1e-6);
        CameraConfig::default().validate().unwrap();
    }

    /// The robot's frames go through the sensor model by default: the same world gives the same
    /// bytes, another step other noise, and `enabled = false` the renderer's depth.
    #[test]
    fn frames_are_noisy_by_default_and_deterministic() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let top = world.config().table.top_z_m();
        let cube = Mesh::cuboid([0.0, 0.0, 0.05], [0.06, 0.06, 0.1], [200, 40, 40]);
        world
            .spawn_object(
                "cube",
                &cube,
                &lgdm_pointcloud::math::translation([0.05, -0.52, top]),
            )
            .unwrap();
        let point = [0.05, -0.52, top];
        let on = CameraConfig::default();
        let off = CameraConfig {
            noise: DepthNoise::off(),
            ..CameraConfig::default()
        };
        let a = on.render_closeup(&world, point).unwrap();
        let b = on.render_closeup(&world, point).unwrap();
        let clean = off.render_closeup(&world, point).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.frame.label, clean.frame.label);
        let (mut lost, mut moved, mut worst) = (0, 0, 0.0f32);
        for (n, c) in a.frame.depth_m.iter().zip(&clean.frame.depth_m) {
            if *c > 0.0 && *n == 0.0 {
                lost += 1;
            } else if *c > 0.0 {
                moved += usize::from(n != c);
                worst = worst.max((n - c).abs());
            }
        }
        // The cube's stereo shadow alone is ~7 px × ~120 rows at 0.5 m.
        assert!(lost > 500, "{lost}");
        assert!(moved > a.frame.depth_m.len() / 2, "{moved}");
        // σ ≈ 1.2 mm: nothing moves by a centimetre.
        assert!(worst < 0.01, "{worst}");
        world.step();
        let c = on.render_closeup(&world, point).unwrap();
        assert_ne!(c.frame.depth_m, a.frame.depth_m);
        let overview = on.render_overview(&world).unwrap();
        let overview_clean = off.render_overview(&world).unwrap();
        assert_ne!(overview.frame.depth_m, overview_clean.frame.depth_m);
    }

    #[test]
    fn validation_names_the_field() {
        let mut c = CameraConfig::default();
        c.overview.vertical_fov_deg = f32::NAN;
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("overview.vertical_fov_deg")
        );
        let mut c = CameraConfig::default();
        c.closeup.height_above_table_m = 0.0;
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("closeup.height_above_table_m")
        );
        let mut c = CameraConfig::default();
        c.crop.size_px = 3;
        assert!(c.validate().unwrap_err().to_string().contains("crop"));
        let mut c = CameraConfig::default();
        c.noise.axial_base_m = -1.0;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("noise") && e.contains("axial_base_m"), "{e}");
    }
}
