//! Recording of grasp rounds for Foxglove: one MCAP file per round (`/tf` of every body, a
//! scene of the meshes and shapes, the camera images with their calibration, the chosen grasp as
//! a marker, attempt events) and a PNG storyboard per round (the crop with the chosen grasp
//! drawn, the overview before and after the attempt, the target basket after it, and a caption
//! of the outcome).
//!
//! **Same seed, same bytes.** Every time stamp (MCAP `log_time` and `publish_time`, and each
//! message's `timestamp`) is sim time — the world's step count × dt — never the wall clock.
//! Channels are added in a fixed order, entities and frames are listed in spawn order, chunks
//! are zstd-compressed on the calling thread at zstd's default level; so the same round gives
//! the same bytes. Recording only reads the world: a run's `results.json` is the same with and
//! without it.
//!
//! **Cost.** Off by default. When on, a [`StepObserver`] samples the body poses every
//! 1/[`RecordConfig::tf_rate_hz`] s of sim time; each camera look is also published, and each
//! attempt renders two more frames (overview and basket after it) for the storyboard.
//!
//! | topic | schema | content |
//! |---|---|---|
//! | `/tf` | `foxglove.FrameTransforms` | `world` → `object/<name>`, `arm/link_1`…`arm/link_6`,
//! `gripper/palm`, `gripper/finger_l` / `finger_r` at [`RecordConfig::tf_rate_hz`]; `world` →
//! `camera/<name>` (optical frame: x right, y down, z forward) at each look | | `/scene` |
//! `foxglove.SceneUpdate` | one entity per body, `frame_locked`, in its tf frame: object colliders
//! (triangles in the meshes' colours), link capsules (cylinders and spheres), palm and finger
//! boxes; the scenery (table, baskets, pedestal) as boxes in `world`; sent when a body appears,
//! deletions when an object goes | | `/grasp` | `foxglove.SceneUpdate` | entity `grasp` in `world`:
//! the two pads at the planned tool centre (yawed, open to the predicted opening), the opening
//! line, the approach arrow, a label; metadata rank, quality, opening, yaw, outcome; yellow when
//! planned, then green (placed), orange (grasped, not placed) or red (failed) | |
//! `/camera/{overview,closeup,basket}/rgb` | `foxglove.RawImage` | `rgb8` | |
//! `/camera/{overview,closeup,basket}/depth` | `foxglove.RawImage` | `32FC1`, optical z in metres,
//! 0 where nothing was hit | | `/camera/{overview,closeup,basket}/calibration` |
//! `foxglove.CameraCalibration` | pinhole (`plumb_bob`, no distortion) | | `/events` |
//! `foxglove.Log` | round start and end, attempt start and end with the success flags and the
//! failure reason, each arm contact avoided (info: `arm contact avoided: link 5 touches
//! basket 0`) or made (warning: `arm contact: …`); recognitions and the teacher's lessons (pick-and-place) | | `/labels` |
//! `foxglove.SceneUpdate` | pick-and-place: entity `label/<object frame>`, `frame_locked` in the
//! object's frame, a billboard text above it (true instance, the robot's first guess and
//! confidence, the teacher's part), green when the robot knew it, amber when it did not know, red
//! when it was wrong; metadata with the same fields; deleted when the object goes |
//!
//! The file also holds an MCAP metadata record `lgdm.round` (round, scenario, grasp source,
//! seed, objects).
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::math::translation;
//! use lgdm_sim::run::record::{RecordConfig, Recorder};
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let recorder = Recorder::start(&mut world, &RecordConfig::default(), 0, Default::default()).unwrap();
//! let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [200, 40, 40]);
//! let top_z = world.config().table.top_z_m();
//! world.spawn_object("cube", &cube, &translation([0.05, -0.52, top_z + 0.05])).unwrap();
//! world.settle(); // every 8th step (30 Hz) lands on /tf
//! let round = recorder.finish(&mut world, "settled").unwrap();
//! assert!(round.mcap.starts_with(b"\x89MCAP0\r\n"));
//! assert_eq!(round.file_stem(), "round-0000");
//! ```
//!
//! A run records its rounds through [`RoundRecorder`], the runner's observer
//! ([`crate::run::observe`]); `lgdm sim grasp --record` writes them to
//! `RUN_DIR/rounds/round-NNNN.{mcap,png}`.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::sync::{Arc, Mutex, MutexGuard};

use foxglove::messages::{
    CameraCalibration, FrameTransforms, Log, RawImage, SceneEntity, SceneEntityDeletion,
    SceneUpdate,
};
use lgdm_pointcloud::dataset::{
    foxglove_pose, foxglove_schema, foxglove_timestamp, foxglove_writer,
};
use lgdm_pointcloud::grasp::cornell::draw_rectangles;
use lgdm_pointcloud::image::RgbImage;
use lgdm_pointcloud::render::Camera;
use prost::Message as _;
use rapier3d::prelude::{ColliderHandle, RigidBodyHandle};
use serde::{Deserialize, Serialize};

use crate::grasping::attempt::{Cell, Execution};
use crate::perception::camera::{CameraConfig, OverviewCamera, SceneFrame, render_world};
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::rapier_to_isometry;
use crate::physics::world::{StepObserver, World};
use crate::recognition::recognizer::RecognitionRecord;
use crate::robot::Robot;
use crate::run::captions::{
    ObjectLabel, attempt_caption, recognition_caption, recognition_label, round_summary,
};
use crate::run::observe::{GraspShown, ObserverError, RecordCamera, RoundInfo, RunObserver};
use crate::run::results::{AttemptRecord, RoundRecord};
use crate::tasks::packing::{BasketChoice, basket_name};
use crate::tasks::scenario::PlacedObject;

mod messages;
mod storyboard;

use messages::*;

pub use messages::WORLD_FRAME;
pub use storyboard::outcome_text;
use storyboard::*;

/// The `/tf` topic.
pub const TOPIC_TF: &str = "/tf";
/// The `/scene` topic.
pub const TOPIC_SCENE: &str = "/scene";
/// The `/grasp` topic.
pub const TOPIC_GRASP: &str = "/grasp";
/// The `/events` topic.
pub const TOPIC_EVENTS: &str = "/events";
/// The `/labels` topic.
pub const TOPIC_LABELS: &str = "/labels";

/// What to record. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordConfig {
    /// Rate of `/tf` in sim time (Hz; default 30: rounded to every 8th step at 240 Hz).
    pub tf_rate_hz: f64,
    /// Record only the first this many rounds (default `None`: every round).
    pub first_rounds: Option<usize>,
}

impl Default for RecordConfig {
    fn default() -> Self {
        Self {
            tf_rate_hz: 30.0,
            first_rounds: None,
        }
    }
}

impl RecordConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RecordError> {
        if !(self.tf_rate_hz.is_finite() && self.tf_rate_hz > 0.0) {
            return Err(RecordError::InvalidConfig {
                field: "tf_rate_hz",
                reason: format!("{} must be positive and finite", self.tf_rate_hz),
            });
        }
        Ok(())
    }

    /// Whether round `round` is recorded.
    pub fn records_round(&self, round: usize) -> bool {
        self.first_rounds.is_none_or(|n| round < n)
    }
}

/// Errors of the recorder.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RecordError {
    /// A bad [`RecordConfig`] field.
    #[error("record config: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The MCAP writer failed.
    #[error("writing the MCAP recording: {0}")]
    Mcap(String),
    /// A recording could not be written out.
    #[error("writing {path}: {reason}")]
    Write {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
}

/// One recorded round: the MCAP file's bytes and the storyboard.
#[derive(Debug, Clone, PartialEq)]
pub struct RoundRecording {
    /// Round number.
    pub round: usize,
    /// The MCAP file.
    pub mcap: Vec<u8>,
    /// The storyboard: one row per attempt.
    pub storyboard: RgbImage,
}

impl RoundRecording {
    /// `round-0003`: the files are `<stem>.mcap` and `<stem>.png`.
    pub fn file_stem(&self) -> String {
        format!("round-{:04}", self.round)
    }
}

/// Where recorded rounds go (a run directory, or memory).
pub trait RoundSink {
    /// Stores one round.
    fn write_round(&mut self, round: RoundRecording) -> Result<(), RecordError>;
}

impl RoundSink for Vec<RoundRecording> {
    fn write_round(&mut self, round: RoundRecording) -> Result<(), RecordError> {
        self.push(round);
        Ok(())
    }
}

/// A camera 0.8 m above basket `index`'s floor looking down (224 px, 40°: the whole basket), or
/// `None` when the world has no such basket.
pub fn basket_camera(world: &World, index: usize) -> Option<Camera> {
    let b = world.config().baskets.get(index)?;
    let [x, y, z] = b.floor_center_m;
    Some(
        OverviewCamera {
            eye_m: [x, y, z + 0.8],
            target_m: [x, y, z],
            ..OverviewCamera::default()
        }
        .camera(),
    )
}

/// Channel ids, added in this order.
#[derive(Debug, Clone, Copy)]
struct Channels {
    tf: u16,
    scene: u16,
    grasp: u16,
    events: u16,
    labels: u16,
    /// Per camera: rgb, depth, calibration.
    cameras: [[u16; 3]; 3],
}

/// A robot body and its frame.
#[derive(Debug, Clone)]
struct BodyFrame {
    body: RigidBodyHandle,
    frame: String,
}

/// A live object and its frame.
#[derive(Debug, Clone)]
struct ObjectFrame {
    handle: ObjectHandle,
    frame: String,
}

struct Recording {
    writer: Option<mcap::Writer<Cursor<Vec<u8>>>>,
    channels: Channels,
    sequences: BTreeMap<u16, u32>,
    error: Option<String>,
    tf_every_steps: u64,
    round: usize,
    bodies: Vec<BodyFrame>,
    objects: Vec<ObjectFrame>,
    /// Object frames with a label on `/labels`.
    labelled: Vec<String>,
    scenery: Vec<ColliderHandle>,
    /// The latest overview frame (the storyboard's "before").
    overview: Option<SceneFrame>,
    /// The attempt in progress: its panels so far.
    pending: Option<StoryRow>,
    rows: Vec<StoryRow>,
}

impl std::fmt::Debug for Recording {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recording")
            .field("round", &self.round)
            .field("bodies", &self.bodies.len())
            .field("objects", &self.objects.len())
            .field("rows", &self.rows.len())
            .finish_non_exhaustive()
    }
}

/// Records one round (see the module docs). Cheap to clone: the clones share the recording;
/// one of them sits in the world as its [`StepObserver`] until [`Recorder::finish`].
#[derive(Debug, Clone)]
pub struct Recorder {
    shared: Arc<Mutex<Recording>>,
}

/// The world's step observer: samples the poses.
#[derive(Debug)]
struct TfSampler(Arc<Mutex<Recording>>);

impl StepObserver for TfSampler {
    fn after_step(&mut self, world: &World) {
        let mut rec = lock(&self.0);
        if world.steps().is_multiple_of(rec.tf_every_steps) {
            rec.sample(world);
        }
    }
}

fn lock(shared: &Mutex<Recording>) -> MutexGuard<'_, Recording> {
    // A panic while recording leaves nothing inconsistent that matters: keep going.
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

/// Sim time of the world now (ns).
fn now_ns(world: &World) -> u64 {
    (world.time_s() * 1e9).round() as u64
}

impl Recorder {
    /// Starts recording round `round` of `world`: opens the MCAP (schemas, channels, a metadata
    /// record `lgdm.round` with `metadata`), installs the pose sampler as the world's
    /// [`StepObserver`] and publishes the scene as it is.
    pub fn start(
        world: &mut World,
        config: &RecordConfig,
        round: usize,
        metadata: BTreeMap<String, String>,
    ) -> Result<Self, RecordError> {
        config.validate()?;
        let mcap_err = |e: mcap::McapError| RecordError::Mcap(e.to_string());
        let library = concat!("lgdm-sim/", env!("CARGO_PKG_VERSION"));
        let mut writer = foxglove_writer(Cursor::new(Vec::new()), library).map_err(mcap_err)?;
        let mut schema = |(name, encoding, data): (String, String, Vec<u8>)| {
            writer.add_schema(&name, &encoding, &data)
        };
        let tf_schema = schema(foxglove_schema::<FrameTransforms>()).map_err(mcap_err)?;
        let scene_schema = schema(foxglove_schema::<SceneUpdate>()).map_err(mcap_err)?;
        let image_schema = schema(foxglove_schema::<RawImage>()).map_err(mcap_err)?;
        let calib_schema = schema(foxglove_schema::<CameraCalibration>()).map_err(mcap_err)?;
        let log_schema = schema(foxglove_schema::<Log>()).map_err(mcap_err)?;
        let none = BTreeMap::new();
        let mut channel = |schema: u16, topic: &str| {
            writer
                .add_channel(schema, topic, "protobuf", &none)
                .map_err(mcap_err)
        };
        let tf = channel(tf_schema, TOPIC_TF)?;
        let scene = channel(scene_schema, TOPIC_SCENE)?;
        let grasp = channel(scene_schema, TOPIC_GRASP)?;
        let events = channel(log_schema, TOPIC_EVENTS)?;
        let labels = channel(scene_schema, TOPIC_LABELS)?;
        let mut cameras = [[0u16; 3]; 3];
        for camera in RecordCamera::ALL {
            let name = camera.name();
            cameras[camera.index()] = [
                channel(image_schema, &format!("/camera/{name}/rgb"))?,
                channel(image_schema, &format!("/camera/{name}/depth"))?,
                channel(calib_schema, &format!("/camera/{name}/calibration"))?,
            ];
        }
        let mut metadata = metadata;
        metadata.insert("round".into(), round.to_string());
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "lgdm.round".into(),
                metadata,
            })
            .map_err(mcap_err)?;
        let steps = (1.0 / (config.tf_rate_hz * f64::from(world.dt_s()))).round();
        let shared = Arc::new(Mutex::new(Recording {
            writer: Some(writer),
            channels: Channels {
                tf,
                scene,
                grasp,
                events,
                labels,
                cameras,
            },
            sequences: BTreeMap::new(),
            error: None,
            tf_every_steps: (steps as u64).max(1),
            round,
            bodies: Vec::new(),
            objects: Vec::new(),
            labelled: Vec::new(),
            scenery: Vec::new(),
            overview: None,
            pending: None,
            rows: Vec::new(),
        }));
        let recorder = Self { shared };
        recorder.log(world, LogLevel::Info, &format!("round {round} start"));
        lock(&recorder.shared).sample(world);
        world.set_step_observer(Some(Box::new(TfSampler(recorder.shared.clone()))));
        Ok(recorder)
    }

    /// Adds the robot's bodies (links, palm, fingers) to the scene and to `/tf`.
    pub fn add_robot(&self, world: &World, robot: &Robot) {
        let mut rec = lock(&self.shared);
        let (palm, fingers) = robot.gripper().bodies();
        let mut parts: Vec<(RigidBodyHandle, String, [f64; 4])> = robot
            .link_bodies()
            .iter()
            .enumerate()
            .map(|(i, b)| (*b, format!("arm/link_{}", i + 1), ARM_RGBA))
            .collect();
        parts.push((palm, "gripper/palm".into(), PALM_RGBA));
        parts.push((fingers[0], "gripper/finger_l".into(), FINGER_RGBA));
        parts.push((fingers[1], "gripper/finger_r".into(), FINGER_RGBA));
        let t = now_ns(world);
        let mut entities = Vec::new();
        for (body, frame, color) in parts {
            entities.push(body_entity(world, body, &frame, color, t));
            rec.bodies.push(BodyFrame { body, frame });
        }
        let update = SceneUpdate {
            deletions: Vec::new(),
            entities,
        };
        let ch = rec.channels.scene;
        rec.write(ch, t, &update.encode_to_vec());
        rec.sample(world);
    }

    /// Publishes a camera frame (rgb, depth, calibration, and the camera's pose on `/tf`). The
    /// latest overview frame is kept as the storyboard's "before" panel.
    pub fn camera_shot(&self, world: &World, camera: RecordCamera, shot: &SceneFrame) {
        let mut rec = lock(&self.shared);
        rec.publish_shot(world, camera, shot);
        if camera == RecordCamera::Overview {
            rec.overview = Some(shot.clone());
        }
    }

    /// An attempt begins: publishes the planned grasp on `/grasp` and a start event, and keeps
    /// the storyboard's first panels (the crop with the grasp rectangle, the overview with the
    /// grasp projected).
    pub fn grasp_planned(&self, world: &World, shown: &GraspShown<'_>) {
        let mut rec = lock(&self.shared);
        let t = now_ns(world);
        rec.publish_grasp(t, grasp_entity(shown, None, t));
        let g = &shown.plan.grasp;
        rec.log_at(
            t,
            LogLevel::Info,
            &format!(
                "attempt start: {} grasp rank {} quality {:.3} opening {:.1} mm yaw {:.1} deg at ({:.3}, {:.3}, {:.3}) m",
                shown.object.unwrap_or("unknown object"),
                shown.rank,
                g.quality,
                1000.0 * g.opening_m,
                g.yaw_rad.to_degrees(),
                shown.plan.tcp_m[0],
                shown.plan.tcp_m[1],
                shown.plan.tcp_m[2],
            ),
        );
        let mut row = StoryRow::default();
        if let Some((crop, rect)) = &shown.crop {
            let mut img = RgbImage::from_pixels(
                crop.size_px as usize,
                crop.size_px as usize,
                crop.rgb.clone(),
            );
            draw_rectangles(&mut img, &[*rect], &[]);
            row.panels.push(("crop + grasp".into(), img));
        }
        if let Some(overview) = &rec.overview {
            let mut img = frame_image(overview);
            if let Some(rect) = project_grasp(&overview.camera, shown) {
                draw_rectangles(&mut img, &[rect], &[]);
            }
            row.panels.push(("before".into(), img));
        }
        rec.pending = Some(row);
    }

    /// An attempt ended: publishes the frames taken after it (overview, basket), the grasp
    /// coloured by its outcome and an end event; the frames join the storyboard row.
    pub fn grasp_done(
        &self,
        world: &World,
        shown: &GraspShown<'_>,
        exec: &Execution,
        after: &[(RecordCamera, SceneFrame)],
    ) {
        let mut rec = lock(&self.shared);
        let t = now_ns(world);
        for (camera, shot) in after {
            rec.publish_shot(world, *camera, shot);
        }
        rec.publish_grasp(t, grasp_entity(shown, Some(exec), t));
        let level = if exec.placement_success {
            LogLevel::Info
        } else {
            LogLevel::Warning
        };
        rec.log_at(t, level, &format!("attempt end: {}", outcome_text(exec)));
        let m = &exec.measured;
        for contact in &m.avoided_contacts {
            rec.log_at(
                t,
                LogLevel::Info,
                &format!("arm contact avoided: {contact}"),
            );
        }
        for contact in &m.arm_contacts {
            rec.log_at(t, LogLevel::Warning, &format!("arm contact: {contact}"));
        }
        let row = rec.pending.get_or_insert_with(StoryRow::default);
        for (camera, shot) in after {
            row.panels
                .push((format!("{} after", camera.name()), frame_image(shot)));
        }
    }

    /// The attempt's record is complete: closes its storyboard row with `caption` (a row with
    /// only the overview when no grasp was tried).
    pub fn attempt_recorded(&self, caption: String) {
        let mut rec = lock(&self.shared);
        let mut row = rec.pending.take().unwrap_or_else(|| StoryRow {
            panels: rec
                .overview
                .as_ref()
                .map(|o| ("overview".to_string(), frame_image(o)))
                .into_iter()
                .collect(),
            caption: String::new(),
        });
        row.caption = caption;
        rec.rows.push(row);
    }

    /// Shows `label` above `object` on `/labels` (replacing its earlier label), in the object's
    /// frame so that it travels with it; nothing when the object is gone.
    pub fn label_object(&self, world: &World, object: ObjectHandle, label: &ObjectLabel) {
        let mut rec = lock(&self.shared);
        let t = now_ns(world);
        rec.sync_scene(world, t);
        let Some(frame) = rec
            .objects
            .iter()
            .find(|o| o.handle == object)
            .map(|o| o.frame.clone())
        else {
            return;
        };
        // Above the object's top, whichever way it stands.
        let top = world.object_collider_mesh(object).map_or(0.1, |m| {
            m.vertices
                .iter()
                .map(|v| f64::from(v[2]))
                .fold(0.0, f64::max)
        });
        let entity = label_entity(&frame, top + 0.06, label, t);
        if !rec.labelled.contains(&frame) {
            rec.labelled.push(frame);
        }
        let ch = rec.channels.labels;
        rec.write(
            ch,
            t,
            &SceneUpdate {
                deletions: Vec::new(),
                entities: vec![entity],
            }
            .encode_to_vec(),
        );
    }

    /// Publishes an event on `/events`.
    pub fn log(&self, world: &World, level: LogLevel, text: &str) {
        lock(&self.shared).log_at(now_ns(world), level, text);
    }

    /// Ends the round: samples the poses a last time, logs `summary` as the round's end event,
    /// removes the sampler from the world and closes the MCAP; composes the storyboard.
    pub fn finish(self, world: &mut World, summary: &str) -> Result<RoundRecording, RecordError> {
        world.set_step_observer(None);
        let mut rec = lock(&self.shared);
        rec.sample(world);
        let round = rec.round;
        rec.log_at(
            now_ns(world),
            LogLevel::Info,
            &format!("round {round} end: {summary}"),
        );
        if let Some(e) = rec.error.take() {
            return Err(RecordError::Mcap(e));
        }
        let mut writer = rec
            .writer
            .take()
            .ok_or_else(|| RecordError::Mcap("the recording was already finished".into()))?;
        writer
            .finish()
            .map_err(|e| RecordError::Mcap(e.to_string()))?;
        let mcap = writer.into_inner().into_inner();
        let storyboard = compose_storyboard(&format!("round {round}: {summary}"), &rec.rows);
        Ok(RoundRecording {
            round,
            mcap,
            storyboard,
        })
    }
}

/// Severity of an event (foxglove.Log levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogLevel {
    /// Normal progress.
    Info = 2,
    /// A failed attempt.
    Warning = 3,
}

impl Recording {
    fn write(&mut self, channel: u16, t_ns: u64, data: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let Some(writer) = self.writer.as_mut() else {
            return;
        };
        let seq = self.sequences.entry(channel).or_insert(0);
        *seq += 1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: *seq,
            log_time: t_ns,
            publish_time: t_ns,
        };
        if let Err(e) = writer.write_to_known_channel(&header, data) {
            self.error = Some(e.to_string());
        }
    }

    /// The chosen grasp on `/grasp` (one entity, replacing the last).
    fn publish_grasp(&mut self, t_ns: u64, entity: SceneEntity) {
        let ch = self.channels.grasp;
        self.write(
            ch,
            t_ns,
            &SceneUpdate {
                deletions: Vec::new(),
                entities: vec![entity],
            }
            .encode_to_vec(),
        );
    }

    fn log_at(&mut self, t_ns: u64, level: LogLevel, text: &str) {
        let msg = Log {
            timestamp: Some(foxglove_timestamp(t_ns)),
            level: level as i32,
            message: text.to_string(),
            name: "lgdm.sim".into(),
            file: String::new(),
            line: 0,
        };
        let ch = self.channels.events;
        self.write(ch, t_ns, &msg.encode_to_vec());
    }

    /// Publishes scene changes (objects spawned or removed, scenery changed) and every body's
    /// pose now.
    fn sample(&mut self, world: &World) {
        let t = now_ns(world);
        self.sync_scene(world, t);
        let mut transforms = Vec::with_capacity(self.objects.len() + self.bodies.len());
        for o in &self.objects {
            if let Ok(pose) = world.object_pose(o.handle) {
                transforms.push(frame_transform(&o.frame, &foxglove_pose(&pose), t));
            }
        }
        for b in &self.bodies {
            if let Some(body) = world.physics.bodies.get(b.body) {
                let pose = isometry_pose(&rapier_to_isometry(body.position()));
                transforms.push(frame_transform(&b.frame, &pose, t));
            }
        }
        let ch = self.channels.tf;
        self.write(ch, t, &FrameTransforms { transforms }.encode_to_vec());
    }

    fn sync_scene(&mut self, world: &World, t: u64) {
        let mut update = SceneUpdate::default();
        let scenery: Vec<ColliderHandle> = world
            .physics
            .colliders
            .iter()
            .filter(|(h, _)| world.is_scenery(*h))
            .map(|(h, _)| h)
            .collect();
        if scenery != self.scenery {
            update.entities.push(scenery_entity(world, &scenery, t));
            self.scenery = scenery;
        }
        let live: Vec<ObjectHandle> = world.objects().collect();
        let (kept, gone): (Vec<ObjectFrame>, Vec<ObjectFrame>) = std::mem::take(&mut self.objects)
            .into_iter()
            .partition(|o| live.contains(&o.handle));
        let mut labels_gone = SceneUpdate::default();
        for o in gone {
            if let Some(i) = self.labelled.iter().position(|f| *f == o.frame) {
                self.labelled.remove(i);
                labels_gone.deletions.push(SceneEntityDeletion {
                    timestamp: Some(foxglove_timestamp(t)),
                    r#type: 0,
                    id: label_id(&o.frame),
                });
            }
            update.deletions.push(SceneEntityDeletion {
                timestamp: Some(foxglove_timestamp(t)),
                r#type: 0,
                id: o.frame,
            });
        }
        if !labels_gone.deletions.is_empty() {
            let ch = self.channels.labels;
            self.write(ch, t, &labels_gone.encode_to_vec());
        }
        self.objects = kept;
        for h in live {
            if self.objects.iter().any(|o| o.handle == h) {
                continue;
            }
            // The collider, as the physics has it (and the cameras draw it by default).
            let (Ok(name), Ok(mesh)) = (world.object_name(h), world.object_collider_mesh(h)) else {
                continue;
            };
            let mut frame = format!("object/{name}");
            if self.objects.iter().any(|o| o.frame == frame) {
                frame = format!("object/{name}@{}", h.0);
            }
            update
                .entities
                .push(object_entity(&frame, name, h, mesh, t));
            self.objects.push(ObjectFrame { handle: h, frame });
        }
        if !(update.entities.is_empty() && update.deletions.is_empty()) {
            let ch = self.channels.scene;
            self.write(ch, t, &update.encode_to_vec());
        }
    }

    fn publish_shot(&mut self, world: &World, camera: RecordCamera, shot: &SceneFrame) {
        let t = now_ns(world);
        let frame_id = format!("camera/{}", camera.name());
        let tf = FrameTransforms {
            transforms: vec![frame_transform(
                &frame_id,
                &foxglove_pose(&shot.camera.world_from_camera),
                t,
            )],
        };
        let ch = self.channels.tf;
        self.write(ch, t, &tf.encode_to_vec());
        let f = &shot.frame;
        let [rgb_ch, depth_ch, calib_ch] = self.channels.cameras[camera.index()];
        let rgb = RawImage {
            timestamp: Some(foxglove_timestamp(t)),
            frame_id: frame_id.clone(),
            width: f.width,
            height: f.height,
            encoding: "rgb8".into(),
            step: 3 * f.width,
            data: f.rgb.iter().flatten().copied().collect::<Vec<u8>>().into(),
        };
        self.write(rgb_ch, t, &rgb.encode_to_vec());
        let depth = RawImage {
            timestamp: Some(foxglove_timestamp(t)),
            frame_id: frame_id.clone(),
            width: f.width,
            height: f.height,
            encoding: "32FC1".into(),
            step: 4 * f.width,
            data: f
                .depth_m
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect::<Vec<u8>>()
                .into(),
        };
        self.write(depth_ch, t, &depth.encode_to_vec());
        let k = shot.camera.intrinsics;
        let (fx, fy, cx, cy) = (
            f64::from(k.fx),
            f64::from(k.fy),
            f64::from(k.cx),
            f64::from(k.cy),
        );
        let calib = CameraCalibration {
            timestamp: Some(foxglove_timestamp(t)),
            frame_id,
            width: k.width,
            height: k.height,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: vec![fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: vec![fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        };
        self.write(calib_ch, t, &calib.encode_to_vec());
    }
}

/// Recording as a [`RunObserver`]: records the rounds `config` selects and hands each, when it
/// ends, to `sink` (a run directory writes `rounds/round-NNNN.{mcap,png}`).
pub struct RoundRecorder<'a> {
    config: &'a RecordConfig,
    sink: &'a mut dyn RoundSink,
    cameras: CameraConfig,
    current: Option<Recorder>,
}

impl std::fmt::Debug for RoundRecorder<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RoundRecorder")
            .field("config", self.config)
            .field("recording", &self.current.is_some())
            .finish_non_exhaustive()
    }
}

impl<'a> RoundRecorder<'a> {
    /// Records with `config` into `sink`; `cameras` renders the views after each attempt (the
    /// run's cameras). The config is checked here.
    pub fn new(
        config: &'a RecordConfig,
        sink: &'a mut dyn RoundSink,
        cameras: CameraConfig,
    ) -> Result<Self, RecordError> {
        config.validate()?;
        Ok(Self {
            config,
            sink,
            cameras,
            current: None,
        })
    }
}

impl RunObserver for RoundRecorder<'_> {
    fn round_started(
        &mut self,
        world: &mut World,
        round: &RoundInfo<'_>,
    ) -> Result<(), ObserverError> {
        self.current = None;
        if self.config.records_round(round.round) {
            let metadata = BTreeMap::from([
                ("scenario".to_string(), round.scenario.as_str().to_string()),
                ("grasp_source".to_string(), round.grasp_source.to_string()),
                ("seed".to_string(), round.seed.to_string()),
                ("objects".to_string(), round.objects.to_string()),
            ]);
            self.current = Some(Recorder::start(world, self.config, round.round, metadata)?);
        }
        Ok(())
    }

    fn table_set(&mut self, cell: &Cell, objects: &[PlacedObject]) {
        if let Some(r) = &self.current {
            r.add_robot(&cell.world, &cell.robot);
            let names: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
            r.log(
                &cell.world,
                LogLevel::Info,
                &format!("table set: {}", names.join(", ")),
            );
        }
    }

    fn camera_shot(&mut self, world: &World, camera: RecordCamera, shot: &SceneFrame) {
        if let Some(r) = &self.current {
            r.camera_shot(world, camera, shot);
        }
    }

    fn recognised(&mut self, world: &World, object: ObjectHandle, record: &RecognitionRecord) {
        if let Some(r) = &self.current {
            r.log(world, LogLevel::Info, &recognition_caption(record));
            r.label_object(world, object, &recognition_label(record));
        }
    }

    fn basket_chosen(&mut self, world: &World, c: &BasketChoice) {
        if let Some(r) = &self.current {
            r.log(
                world,
                LogLevel::Info,
                &format!(
                    "packing as {} ({}): {} basket",
                    c.packed_as.as_deref().unwrap_or("nothing recognised"),
                    c.decided_by.as_str(),
                    basket_name(c.basket)
                ),
            );
        }
    }

    fn grasp_planned(&mut self, world: &World, grasp: &GraspShown<'_>) {
        if let Some(r) = &self.current {
            r.grasp_planned(world, grasp);
        }
    }

    fn grasp_done(
        &mut self,
        cell: &Cell,
        grasp: &GraspShown<'_>,
        execution: &Execution,
        basket: usize,
    ) -> Result<(), ObserverError> {
        let Some(r) = &self.current else {
            return Ok(());
        };
        // The outcome as the cameras see it, before the table is reset.
        let mut after = vec![(
            RecordCamera::Overview,
            self.cameras.render_overview(&cell.world)?,
        )];
        if let Some(camera) = basket_camera(&cell.world, basket) {
            let shot = render_world(&cell.world, &camera, self.cameras.draw)?;
            after.push((RecordCamera::Basket, shot));
        }
        r.grasp_done(&cell.world, grasp, execution, &after);
        Ok(())
    }

    fn attempt_recorded(&mut self, attempt: &AttemptRecord) {
        if let Some(r) = &self.current {
            r.attempt_recorded(attempt_caption(attempt));
        }
    }

    fn round_ended(&mut self, world: &mut World, round: &RoundRecord) -> Result<(), ObserverError> {
        if let Some(recorder) = self.current.take() {
            let recording = recorder.finish(world, &round_summary(round))?;
            self.sink.write_round(recording)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_validation_and_round_selection() {
        let c = RecordConfig::default();
        c.validate().unwrap();
        assert!(c.records_round(499));
        let c = RecordConfig {
            first_rounds: Some(2),
            ..RecordConfig::default()
        };
        assert!(c.records_round(1) && !c.records_round(2));
        let c = RecordConfig {
            tf_rate_hz: 0.0,
            ..RecordConfig::default()
        };
        assert!(matches!(
            c.validate(),
            Err(RecordError::InvalidConfig {
                field: "tf_rate_hz",
                ..
            })
        ));
    }

    #[test]
    fn storyboard_has_a_row_per_attempt() {
        let rows = vec![
            StoryRow {
                panels: vec![
                    ("a".into(), RgbImage::new(20, 30, [255, 0, 0])),
                    ("b".into(), RgbImage::new(10, 10, [0, 255, 0])),
                ],
                caption: "attempt 0".into(),
            },
            StoryRow {
                panels: Vec::new(),
                caption: "attempt 1: no grasp found".into(),
            },
        ];
        let img = compose_storyboard("round 0", &rows);
        assert!(img.width >= 240);
        // Title, then row 0 (caption, labels, 30 px panels), then row 1 (no panels).
        assert_eq!(img.height, 12 + GAP + (24 + 30 + GAP) + (24 + GAP));
        assert_eq!(img.get(GAP, 12 + GAP + 24), [255, 0, 0]);
    }
}
