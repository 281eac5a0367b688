//! Perception: from the world's rendered frames to one object-centred crop per object, and from a
//! grasp in crop pixels back to a grasp in the world.
//!
//! 1. [`Perception::look`]: the overview frame ([`crate::perception::camera`]) is segmented with
//!    [`lgdm_pointcloud::segment::segment_objects`] (table-plane fit, pixels ≥ 5 mm above it,
//!    connected components): one [`ObjectSegment`] per object — the paper's contour boxes.
//! 2. [`Perception::close_up`]: for one segment, the close-up camera is placed 0.5 m above the
//!    point where the segment's centroid ray meets the table; its frame is segmented again and
//!    cropped ([`lgdm_pointcloud::crop::object_crop`], 0.22 m at 224 px) around the segment
//!    nearest the image centre — the grasp network's input, at its training scale.
//! 3. [`ObjectView::grasp_in_world`]: a grasp of the crop (the conventions of
//!    [`lgdm_pointcloud::grasp::decode`]) is placed in the close-up camera's optical frame with
//!    [`grasp_pose`] (the median depth around its centre) and moved to the world with the
//!    camera's `world_from_camera`: a top-down [`WorldGrasp`] (position, jaw yaw, opening).
//!
//! Only depth and colour are used. The renderer's label buffer is read for bookkeeping alone:
//! [`ObjectView::object`] names the object a view shows, so that results can say which object
//! an attempt aimed at.
//!
//! ```
//! use lgdm_pointcloud::math::translation;
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_sim::perception::camera::CameraConfig;
//! use lgdm_sim::perception::Perception;
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let top_z = world.config().table.top_z_m();
//! let can = procedural_object("can", 0, 1).unwrap();
//! let h = world.spawn_object("can", &can, &translation([0.1, -0.5, top_z])).unwrap();
//! let perception = Perception::new(CameraConfig::default()).unwrap();
//! let scene = perception.look(&world).unwrap();
//! assert_eq!(scene.segments.len(), 1);
//! let view = perception.close_up(&world, &scene, 0).unwrap();
//! assert_eq!(view.object, Some(h));
//! // The table point lies under the can's centre (within a few millimetres).
//! assert!((view.table_point_m[0] - 0.1).abs() < 0.01 && (view.table_point_m[1] + 0.5).abs() < 0.01);
//! assert_eq!(view.crop.size_px, 224);
//! ```

pub mod camera;

use lgdm_pointcloud::crop::{CropError, ObjectCrop, object_crop};
use lgdm_pointcloud::grasp::decode::{
    DecodedGrasp, GraspDecodeError, GraspDecodeParams, GraspPose, grasp_pose,
};
use lgdm_pointcloud::math::{rotate_vector, transform_point};
use lgdm_pointcloud::render::Camera;
use lgdm_pointcloud::segment::{ObjectSegment, Plane, SegmentError, segment_objects};
use serde::{Deserialize, Serialize};

use crate::perception::camera::{CameraConfig, CameraError, SceneFrame};
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;

/// Errors of perception.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PerceptionError {
    /// Rendering or a camera constant failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The frame could not be segmented (no table found).
    #[error("segmentation: {0}")]
    Segment(#[from] SegmentError),
    /// The crop could not be cut.
    #[error("crop: {0}")]
    Crop(#[from] CropError),
    /// A segment index beyond the scene's segments.
    #[error("segment {index} of a scene with {segments} segments")]
    NoSuchSegment {
        /// The index asked for.
        index: usize,
        /// Segments in the scene.
        segments: usize,
    },
    /// The segment's centroid ray does not meet the table.
    #[error("segment {index}: its centroid's ray does not meet the table plane")]
    OffTable {
        /// The segment.
        index: usize,
    },
    /// The close-up frame shows no object.
    #[error("the close-up at ({x_m:.3}, {y_m:.3}) shows no object")]
    NothingInCloseup {
        /// Table point x (m).
        x_m: f32,
        /// Table point y (m).
        y_m: f32,
    },
    /// A grasp could not be placed (no depth at its centre, outside the frame, …).
    #[error("grasp placement: {0}")]
    Grasp(#[from] GraspDecodeError),
}

/// The overview frame and the objects found in it.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneView {
    /// The overview frame.
    pub shot: SceneFrame,
    /// The table plane (overview camera's optical frame).
    pub table: Plane,
    /// One segment per object on the table, largest first.
    pub segments: Vec<ObjectSegment>,
}

/// One object seen close up: the crop a grasp source reads, and what maps its pixels back.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectView {
    /// The overview segment this view is of.
    pub segment: usize,
    /// The object the crop's segment shows (from the renderer's labels; bookkeeping only).
    pub object: Option<ObjectHandle>,
    /// Where the overview centroid's ray meets the table (world, m): the close-up looks here.
    pub table_point_m: [f32; 3],
    /// The close-up frame.
    pub shot: SceneFrame,
    /// The table plane in the close-up camera's optical frame.
    pub table: Plane,
    /// The object's segment in the close-up frame.
    pub closeup_segment: ObjectSegment,
    /// The object-centred crop (its `window` maps crop pixels to close-up pixels).
    pub crop: ObjectCrop,
}

/// A top-down grasp in the world.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorldGrasp {
    /// The grasp centre on the visible surface (m, world): the centre pixel's ray at the median
    /// depth around it.
    pub position_m: [f64; 3],
    /// Direction of the jaws' opening axis about world z (rad, in (−π, π]).
    pub yaw_rad: f64,
    /// Opening between the jaws the grasp asks for (m).
    pub opening_m: f64,
    /// The source's quality score.
    pub quality: f32,
}

/// The perception pipeline (stateless apart from its config).
#[derive(Debug, Clone, PartialEq)]
pub struct Perception {
    config: CameraConfig,
}

impl Perception {
    /// Validates the config.
    pub fn new(config: CameraConfig) -> Result<Self, PerceptionError> {
        config.validate()?;
        Ok(Self { config })
    }

    /// The config.
    pub fn config(&self) -> &CameraConfig {
        &self.config
    }

    /// Renders the overview frame and segments it.
    pub fn look(&self, world: &World) -> Result<SceneView, PerceptionError> {
        let shot = self.config.render_overview(world)?;
        self.segment_scene(shot)
    }

    /// Segments an overview frame ([`Perception::look`] without the rendering).
    pub fn segment_scene(&self, shot: SceneFrame) -> Result<SceneView, PerceptionError> {
        let seg = segment_objects(&shot.frame, &shot.camera.intrinsics, &self.config.segment)?;
        Ok(SceneView {
            shot,
            table: seg.table,
            segments: seg.objects,
        })
    }

    /// Where segment `index`'s centroid ray meets the table (world, m).
    pub fn table_point_m(
        &self,
        scene: &SceneView,
        index: usize,
    ) -> Result<[f32; 3], PerceptionError> {
        let seg = scene
            .segments
            .get(index)
            .ok_or(PerceptionError::NoSuchSegment {
                index,
                segments: scene.segments.len(),
            })?;
        let k = &scene.shot.camera.intrinsics;
        let [u, v] = seg.centroid_px;
        let z = scene
            .table
            .depth_at(k, u, v)
            .ok_or(PerceptionError::OffTable { index })?;
        Ok(transform_point(
            &scene.shot.camera.world_from_camera,
            k.unproject(u, v, z),
        ))
    }

    /// The close-up view of segment `index` of `scene`.
    pub fn close_up(
        &self,
        world: &World,
        scene: &SceneView,
        index: usize,
    ) -> Result<ObjectView, PerceptionError> {
        let table_point_m = self.table_point_m(scene, index)?;
        let shot = self.config.render_closeup(world, table_point_m)?;
        self.view_from(shot, index, table_point_m)
    }

    /// The close-up view from a close-up frame already rendered at `table_point_m`
    /// ([`Perception::close_up`] without the rendering).
    pub fn view_from(
        &self,
        shot: SceneFrame,
        index: usize,
        table_point_m: [f32; 3],
    ) -> Result<ObjectView, PerceptionError> {
        let k = shot.camera.intrinsics;
        let seg = segment_objects(&shot.frame, &k, &self.config.segment)?;
        // The segment under the image centre, else the one whose centroid is nearest to it.
        let (cx, cy) = (k.cx, k.cy);
        let centre = (cy.round() as u32) * k.width + cx.round() as u32;
        let pick = seg
            .objects
            .iter()
            .position(|o| o.pixels.binary_search(&centre).is_ok())
            .or_else(|| {
                seg.objects
                    .iter()
                    .enumerate()
                    .map(|(i, o)| {
                        let [x, y] = o.centroid_px;
                        (i, (x - cx).powi(2) + (y - cy).powi(2))
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
                    .map(|(i, _)| i)
            })
            .ok_or(PerceptionError::NothingInCloseup {
                x_m: table_point_m[0],
                y_m: table_point_m[1],
            })?;
        let closeup_segment = seg.objects[pick].clone();
        let mut crop = object_crop(
            &shot.frame,
            &k,
            &seg.table,
            closeup_segment.centroid_px,
            &self.config.crop,
        )?;
        // The sensor's missing pixels, filled as GR-ConvNet inpaints its input (a no-op on a
        // clean frame, whose crop has none).
        crop.fill_depth_holes();
        let object = shot.majority_object(&closeup_segment.pixels);
        Ok(ObjectView {
            segment: index,
            object,
            table_point_m,
            shot,
            table: seg.table,
            closeup_segment,
            crop,
        })
    }
}

impl ObjectView {
    /// The close-up camera.
    pub fn camera(&self) -> &Camera {
        &self.shot.camera
    }

    /// Places a crop grasp in the close-up camera's optical frame ([`grasp_pose`], median depth
    /// in a `params.depth_radius_px` window).
    pub fn grasp_in_camera(
        &self,
        grasp: &DecodedGrasp,
        params: &GraspDecodeParams,
    ) -> Result<GraspPose, PerceptionError> {
        Ok(grasp_pose(
            grasp,
            &self.shot.frame.depth_m,
            &self.shot.camera.intrinsics,
            &self.crop.window,
            params,
        )?)
    }

    /// A crop grasp as a top-down grasp in the world: the pose from
    /// [`ObjectView::grasp_in_camera`] moved by the camera's `world_from_camera`; the jaw yaw is
    /// the closing axis's direction in the world's xy plane.
    pub fn grasp_in_world(
        &self,
        grasp: &DecodedGrasp,
        params: &GraspDecodeParams,
    ) -> Result<WorldGrasp, PerceptionError> {
        let pose = self.grasp_in_camera(grasp, params)?;
        let world_from_camera = &self.shot.camera.world_from_camera;
        let p = transform_point(world_from_camera, pose.position_m);
        let axis = rotate_vector(world_from_camera, pose.closing_axis);
        Ok(WorldGrasp {
            position_m: p.map(f64::from),
            yaw_rad: f64::from(axis[1]).atan2(f64::from(axis[0])),
            opening_m: f64::from(pose.opening_m),
            quality: grasp.quality,
        })
    }

    /// Crop pixels per metre on the table plane at the crop centre.
    pub fn crop_px_per_m(&self) -> f32 {
        self.shot.camera.intrinsics.fx
            / (self.crop.table_depth_m * self.crop.window.image_px_per_map_px)
    }
}
