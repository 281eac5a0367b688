//! The physics world: a rapier3d scene with the reference tabletop (a fixed table whose top is
//! at z = 0.785 m, two fixed baskets beside it, a floor) and dynamic objects built from the
//! pointcloud crate's meshes.
//!
//! Z is up, gravity −9.81 m/s², one step is 1/240 s, and friction coefficients are combined by
//! multiplication as Bullet does (object μ 1.0 on the table's μ 0.5 gives 0.5). Every constant
//! sits in [`WorldConfig`], whose field docs give the defaults and why. Where the defaults
//! differ from rapier's, a contract test in `tests/grasp_physics.rs` fails without the change:
//! - contact softness 480 Hz between dynamic bodies (rapier: 30 Hz, fingers sink 2–4 cm into a
//!   small box) and 4 internal PGS iterations (rapier: 1, the grip creeps); contacts with fixed
//!   bodies keep rapier's 60 Hz (480 Hz there makes upright cylinders rock);
//! - contacts recomputed once a pair moved 1 mm (rapier: 5 cm, so a finger that passed a box's
//!   top edge during the descent keeps a stale contact and stops 1 cm short of the box);
//! - hull faces thinned to at most 12 vertices and settling with warm start 0.8 (an upright can
//!   whose hull base is a 32-gon otherwise rocks until it topples); grasping keeps warm start 1
//!   (at 0.8 a squeezed box creeps out ~3 mm/s);
//! - angular damping 0.5 /s on objects, standing in for the rolling friction rapier lacks.
//!
//! Objects are dynamic bodies with a convex-hull collider of their mesh vertices; the body frame
//! is the mesh frame, so [`World::object_pose`] (an `lgdm_pointcloud::math::Pose`) is exactly
//! what the pointcloud crate's renderer needs to draw the mesh. A mesh whose hull cannot be
//! built, or an object larger than the table, is a typed error naming the object.
//!
//! Here: the configuration ([`WorldConfig`] and its parts, validated by [`World::new`]) and the
//! errors, the [`World`] (scenery, objects, stepping, settling, drops in a [`DropRegion`]), and
//! the pose conversions at the boundary to rapier's math types. How collider shapes are built —
//! decompositions in [`crate::physics::shapes`], the thinning of big hull faces and the reduction of
//! dense meshes' hulls (a scan of millions of triangles) in [`crate::physics::hull`].
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::math::translation;
//! use lgdm_sim::physics::world::{World, WorldConfig};
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let top_z = world.config().table.top_z_m();
//! let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [200, 40, 40]);
//! let h = world.spawn_object("cube", &cube, &translation([0.0, -0.6, top_z + 0.01])).unwrap();
//! let report = world.settle();
//! assert!(report.settled);
//! let z = world.object_pose(h).unwrap().translation.z;
//! assert!((z - top_z).abs() < 2e-3); // resting on the table top
//! ```

use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::mesh::Mesh;
use nalgebra::{Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion};
use rand::RngExt;
use rapier3d::prelude::{
    CoefficientCombineRule, ColliderBuilder, ColliderHandle, FrictionModel, Group,
    InteractionGroups, InteractionTestMode, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
    SharedShape, SpringCoefficients,
};
use serde::{Deserialize, Serialize};

use crate::physics::hull::thinned_hull;

/// rapier's glam-based math types, used only at this boundary.
pub(crate) type RVec = rapier3d::math::Vector;
pub(crate) type RQuat = rapier3d::math::Rotation;
pub(crate) type RPose = rapier3d::math::Pose;

// Conversions at that boundary: lgdm poses (f32, rotation matrix) and the arm's f64
// isometries to and from rapier's poses.

/// An lgdm pose (rotation matrix, f32) as a rapier pose; `None` if not finite.
pub(crate) fn pose_to_rapier(pose: &Pose) -> Option<RPose> {
    let t = pose.translation.vector;
    let m = pose.rotation.matrix();
    if !(t.iter().all(|v| v.is_finite()) && m.iter().all(|v| v.is_finite())) {
        return None;
    }
    let q = UnitQuaternion::from_rotation_matrix(&pose.rotation);
    Some(RPose::from_parts(
        RVec::new(t.x, t.y, t.z),
        RQuat::from_xyzw(q.i, q.j, q.k, q.w).normalize(),
    ))
}

/// A rapier pose as an lgdm pose (rotation matrix, f32).
pub(crate) fn rapier_to_pose(pose: &RPose) -> Pose {
    let q = pose.rotation;
    let t = pose.translation;
    let rotation = UnitQuaternion::new_normalize(Quaternion::new(q.w, q.x, q.y, q.z));
    Pose::from_parts(
        Translation3::new(t.x, t.y, t.z),
        rotation.to_rotation_matrix(),
    )
}

/// An f64 isometry (the arm's frames) as a rapier pose; `None` if not finite.
pub(crate) fn isometry_to_rapier(pose: &Isometry3<f64>) -> Option<RPose> {
    let t = pose.translation.vector;
    let q = pose.rotation;
    let all = [t.x, t.y, t.z, q.i, q.j, q.k, q.w];
    if !all.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(RPose::from_parts(
        RVec::new(t.x as f32, t.y as f32, t.z as f32),
        RQuat::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
    ))
}

/// A rapier pose as an f64 isometry.
pub(crate) fn rapier_to_isometry(pose: &RPose) -> Isometry3<f64> {
    let q = pose.rotation;
    let t = pose.translation;
    Isometry3::from_parts(
        Translation3::new(f64::from(t.x), f64::from(t.y), f64::from(t.z)),
        UnitQuaternion::new_normalize(Quaternion::new(
            f64::from(q.w),
            f64::from(q.x),
            f64::from(q.y),
            f64::from(q.z),
        )),
    )
}

/// Collision group of fixed scenery: table, baskets, floor, arm pedestal.
pub(crate) const GROUP_STATIC: Group = Group::GROUP_1;
/// Collision group of the dynamic objects.
pub(crate) const GROUP_OBJECT: Group = Group::GROUP_2;
/// Collision group of the gripper (palm and fingers).
pub(crate) const GROUP_GRIPPER: Group = Group::GROUP_3;
/// Collision group of the arm's links.
pub(crate) const GROUP_ARM: Group = Group::GROUP_4;

/// Scenery collides with objects and the gripper.
pub(crate) fn static_groups() -> InteractionGroups {
    InteractionGroups::new(
        GROUP_STATIC,
        GROUP_OBJECT | GROUP_GRIPPER,
        InteractionTestMode::And,
    )
}

/// Objects collide with everything.
pub(crate) fn object_groups() -> InteractionGroups {
    InteractionGroups::new(
        GROUP_OBJECT,
        GROUP_STATIC | GROUP_OBJECT | GROUP_GRIPPER | GROUP_ARM,
        InteractionTestMode::And,
    )
}

/// Which contact-friction model rapier solves (serde mirror of rapier's `FrictionModel`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionKind {
    /// One friction row per group of 4 contacts plus a twist row (rapier's default, faster).
    Simplified,
    /// One Coulomb friction row per contact point.
    Coulomb,
}

/// The fixed table: a box whose top face is the grasping surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TableConfig {
    /// Centre of the table-top box (m; default (0, −0.65, 0.76): the reference `table.urdf`
    /// placement).
    pub center_m: [f32; 3],
    /// Size of the table-top box along x, y, z (m; default 1.0 × 0.65 × 0.05, so the top is at
    /// z = 0.76 + 0.025 = 0.785 m, the reference `Z_TABLE_TOP`).
    pub size_m: [f32; 3],
    /// Friction coefficient of the table (default 0.5: pybullet's default for a URDF link without
    /// a `<contact>` block; unverified in the reference).
    pub friction: f32,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            center_m: [0.0, -0.65, 0.76],
            size_m: [1.0, 0.65, 0.05],
            friction: 0.5,
        }
    }
}

impl TableConfig {
    /// Height of the table top (m).
    pub fn top_z_m(&self) -> f32 {
        self.center_m[2] + 0.5 * self.size_m[2]
    }
}

/// A fixed basket (tray): an open box of thin walls on its floor plate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BasketConfig {
    /// Centre of the basket's floor top face (m; default (0.7, 0, 0.685), the reference
    /// target tray; the second default basket mirrors it to (−0.7, 0, 0.685)).
    pub floor_center_m: [f32; 3],
    /// Inner size along x and y (m; default 0.42 × 0.42: pybullet's `traybox.urdf` scaled by
    /// 0.7 as in the reference, approximately).
    pub inner_size_m: [f32; 2],
    /// Height of the walls above the floor (m; default 0.1).
    pub wall_height_m: f32,
    /// Thickness of the walls and the floor plate (m; default 0.01).
    pub wall_thickness_m: f32,
    /// Friction coefficient (default 0.5, as the table).
    pub friction: f32,
}

impl Default for BasketConfig {
    fn default() -> Self {
        Self {
            floor_center_m: [0.7, 0.0, 0.685],
            inner_size_m: [0.42, 0.42],
            wall_height_m: 0.1,
            wall_thickness_m: 0.01,
            friction: 0.5,
        }
    }
}

impl BasketConfig {
    /// The same basket mirrored across the plane x = 0.
    pub fn mirrored_x(&self) -> Self {
        let [x, y, z] = self.floor_center_m;
        Self {
            floor_center_m: [-x, y, z],
            ..self.clone()
        }
    }

    /// The inside of the basket as an axis-aligned box `(min, max)` (m): from the floor top to
    /// the wall tops, between the walls. A placement succeeds when the object's centre is here.
    pub fn inner_bounds_m(&self) -> ([f32; 3], [f32; 3]) {
        let [x, y, z] = self.floor_center_m;
        let [hx, hy] = [0.5 * self.inner_size_m[0], 0.5 * self.inner_size_m[1]];
        (
            [x - hx, y - hy, z],
            [x + hx, y + hy, z + self.wall_height_m],
        )
    }
}

/// Material and mass rules for dynamic objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectMaterial {
    /// Density of the convex hull (kg/m³; default 400: hulls fill hollow objects — a mug's hull
    /// is ~0.5 l — so a solid-material density would make household objects far too heavy;
    /// 400 gives a mug ~200 g, a 5 cm cube 50 g).
    pub density_kg_m3: f32,
    /// The mass is clamped up to this (kg; default 0.05).
    pub min_mass_kg: f32,
    /// The mass is clamped down to this (kg; default 0.5: the grip holds 2·μ·F = 80 N, and a
    /// cereal-box hull at 400 kg/m³ would weigh 1.4 kg).
    pub max_mass_kg: f32,
    /// Friction coefficient (default 1.0, the reference objects' `lateralFriction`).
    pub friction: f32,
    /// Restitution (default 0; the reference's 0.01 is negligible).
    pub restitution: f32,
    /// Angular velocity damping (1/s; default 0.5): a stand-in for the reference's rolling and
    /// spinning friction (0.002 / 0.001), which rapier lacks — without it a lying bottle rolls
    /// across the table for seconds.
    pub angular_damping: f32,
}

impl Default for ObjectMaterial {
    fn default() -> Self {
        Self {
            density_kg_m3: 400.0,
            min_mass_kg: 0.05,
            max_mass_kg: 0.5,
            friction: 1.0,
            restitution: 0.0,
            angular_damping: 0.5,
        }
    }
}

impl ObjectMaterial {
    /// This material with an object's own mass and friction where it has them (an imported
    /// mesh's `objects.toml`): the mass replaces the density rule and its clamp.
    pub fn with_physics(&self, physics: &lgdm_pointcloud::sidecar::ObjectPhysics) -> Self {
        let mut m = self.clone();
        if let Some(kg) = physics.mass_kg {
            m.min_mass_kg = kg;
            m.max_mass_kg = kg;
        }
        if let Some(mu) = physics.friction {
            m.friction = mu;
        }
        m
    }

    /// Checks every field; the error names the first bad one (prefixed with `prefix`).
    fn validate(&self, prefix: &str) -> Result<(), WorldError> {
        positive(&format!("{prefix}density_kg_m3"), self.density_kg_m3)?;
        positive(&format!("{prefix}min_mass_kg"), self.min_mass_kg)?;
        positive(&format!("{prefix}max_mass_kg"), self.max_mass_kg)?;
        if self.min_mass_kg > self.max_mass_kg {
            return Err(WorldError::InvalidConfig {
                field: format!("{prefix}min_mass_kg"),
                reason: format!(
                    "{} is above max_mass_kg {}",
                    self.min_mass_kg, self.max_mass_kg
                ),
            });
        }
        non_negative(&format!("{prefix}friction"), self.friction)?;
        non_negative(&format!("{prefix}restitution"), self.restitution)?;
        non_negative(&format!("{prefix}angular_damping"), self.angular_damping)?;
        Ok(())
    }
}

/// When [`World::settle`] calls the scene at rest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SettleConfig {
    /// Every object's linear speed below this (m/s; default 0.005), or asleep.
    pub max_linear_speed_m_s: f32,
    /// Every object's angular speed below this (rad/s; default 0.05), or asleep.
    pub max_angular_speed_rad_s: f32,
    /// For this many consecutive steps (default 12 = 0.05 s).
    pub quiet_steps: u32,
    /// Give up after this many steps (default 1000, the reference `wait_until_all_still` cap).
    pub max_steps: u32,
    /// Warm-start coefficient while settling (default 0.8). Fully warm-started contacts keep
    /// some tall round objects (bottles, vases) wobbling on their rim for seconds; 0.8 lets all
    /// 100 test drops of the procedural library come to rest. Settling is scene preparation, so
    /// the softer solver is used only there; the world's own coefficient is restored after.
    pub warmstart_coefficient: f32,
}

impl Default for SettleConfig {
    fn default() -> Self {
        Self {
            max_linear_speed_m_s: 0.005,
            max_angular_speed_rad_s: 0.05,
            quiet_steps: 12,
            max_steps: 1000,
            warmstart_coefficient: 0.8,
        }
    }
}

/// Every constant of the physics world. Defaults are stated per field; `WorldConfig::default()`
/// is the reference tabletop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorldConfig {
    /// Gravity along world z (m/s²; default −9.81; the reference uses −10).
    pub gravity_z_m_s2: f32,
    /// Time step (s; default 1/240, pybullet's step).
    pub dt_s: f32,
    /// rapier solver iterations (substeps) per step (default 4, rapier's default).
    pub solver_iterations: u32,
    /// Internal PGS iterations per solver iteration (default 4; rapier's default of 1 lets a
    /// squeezed box creep 6–20 mm/s out of the grip).
    pub internal_pgs_iterations: u32,
    /// Natural frequency of contact constraints between two dynamic bodies (Hz; default 480;
    /// rapier's 30 Hz lets 40 N fingers sink 2–4 cm into a 5 cm box, 480 Hz ~0.3 mm).
    pub contact_frequency_hz: f32,
    /// Damping ratio of contact constraints (default 10, rapier's default).
    pub contact_damping_ratio: f32,
    /// Natural frequency of contacts against fixed or kinematic bodies (Hz; default 480; rapier's
    /// default is 60).
    pub static_contact_frequency_hz: f32,
    /// Friction model (default `simplified`, rapier's default).
    pub friction_model: FrictionKind,
    /// Fraction of the previous step's contact and joint impulses the solver starts from
    /// (default 1, rapier's default: static friction in a grip needs it — at 0.8 a squeezed
    /// box creeps ~3 mm/s, at 0 it slides out; see [`SettleConfig::warmstart_coefficient`]).
    pub warmstart_coefficient: f32,
    /// Warm-start joint impulses from the previous step (default true: the stiff finger motors
    /// converge better; rapier's default is false).
    pub warmstart_joints: bool,
    /// Let rapier reuse a pair's contact points while the pair moved less than
    /// `contact_recycle_distance_m` since its last full update (default true, as rapier).
    pub contact_recycling: bool,
    /// How far a pair may move before its contacts are recomputed (m; default 0.001). rapier's
    /// default, 0.05, keeps stale contact anchors over centimetres: a finger that passed beside
    /// a box's top edge during the descent then stops 1 cm short of the box when it closes.
    pub contact_recycle_distance_m: f32,
    /// Bodies closer than this get predictive (speculative) contacts (m; default 0.002; rapier's
    /// default is 0.02). With 2 cm every convex part of a decomposed bowl or mug within 2 cm of
    /// the table gets a speculative contact, and rapier keeps such a body wobbling at 0.5–3 rad/s
    /// for ever; at 5 mm a teapot still wobbles, at 2 mm every library object rests as its
    /// single hull does. Faster bodies then overlap by a few millimetres for a step (an object
    /// released 3 cm above the basket floor lands at 0.8 m/s, 3.2 mm per step) and are pushed
    /// back out: every fixed plate is thicker than that.
    pub prediction_distance_m: f32,
    /// Let bodies at rest fall asleep (default true; a touch or a joint wakes them).
    pub allow_sleep: bool,
    /// The table.
    pub table: TableConfig,
    /// The baskets (default two: the reference target tray at (0.7, 0, 0.685) and its mirror at
    /// (−0.7, 0, 0.685)).
    pub baskets: Vec<BasketConfig>,
    /// A fixed floor plane at z = 0 (default true) so an object knocked off the table comes to
    /// rest instead of falling forever.
    pub floor: bool,
    /// Material of spawned objects.
    pub object: ObjectMaterial,
    /// A flat hull face with more vertices keeps only this many of them, chosen by
    /// farthest-point sampling (default 12). With warm-started contacts rapier rocks an upright
    /// cylinder whose base is a 32-gon until it topples (the four contact points it keeps of a
    /// many-sided face change every step); 8–12-gon bases rest. Only the big flat faces (the
    /// base and top of a can, the sides of a box never) lose vertices, so the hull's width
    /// elsewhere is kept.
    pub max_face_vertices: u32,
    /// When the scene counts as settled.
    pub settle: SettleConfig,
}

impl Default for WorldConfig {
    fn default() -> Self {
        let basket = BasketConfig::default();
        Self {
            gravity_z_m_s2: -9.81,
            dt_s: 1.0 / 240.0,
            solver_iterations: 4,
            internal_pgs_iterations: 4,
            contact_frequency_hz: 480.0,
            contact_damping_ratio: 10.0,
            static_contact_frequency_hz: 60.0,
            friction_model: FrictionKind::Simplified,
            warmstart_coefficient: 1.0,
            warmstart_joints: true,
            contact_recycling: true,
            contact_recycle_distance_m: 0.001,
            prediction_distance_m: 0.002,
            allow_sleep: true,
            table: TableConfig::default(),
            baskets: vec![basket.clone(), basket.mirrored_x()],
            floor: true,
            object: ObjectMaterial::default(),
            max_face_vertices: 12,
            settle: SettleConfig::default(),
        }
    }
}

fn finite(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} is not finite"),
        })
    }
}

fn positive(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} must be positive and finite"),
        })
    }
}

fn non_negative(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} must be non-negative and finite"),
        })
    }
}

fn at_least_one(field: &str, value: u32) -> Result<(), WorldError> {
    if value >= 1 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: "must be at least 1".into(),
        })
    }
}

impl WorldConfig {
    /// Checks every field; the error names the first bad one (e.g. `table.size_m[2]`).
    pub fn validate(&self) -> Result<(), WorldError> {
        finite("gravity_z_m_s2", self.gravity_z_m_s2)?;
        non_negative(
            "contact_recycle_distance_m",
            self.contact_recycle_distance_m,
        )?;
        positive("prediction_distance_m", self.prediction_distance_m)?;
        positive("dt_s", self.dt_s)?;
        if self.dt_s > 0.05 {
            return Err(WorldError::InvalidConfig {
                field: "dt_s".into(),
                reason: format!("{} s is longer than 0.05 s", self.dt_s),
            });
        }
        at_least_one("solver_iterations", self.solver_iterations)?;
        at_least_one("internal_pgs_iterations", self.internal_pgs_iterations)?;
        positive("contact_frequency_hz", self.contact_frequency_hz)?;
        non_negative("contact_damping_ratio", self.contact_damping_ratio)?;
        positive(
            "static_contact_frequency_hz",
            self.static_contact_frequency_hz,
        )?;
        for (i, v) in self.table.center_m.iter().enumerate() {
            finite(&format!("table.center_m[{i}]"), *v)?;
        }
        for (i, v) in self.table.size_m.iter().enumerate() {
            positive(&format!("table.size_m[{i}]"), *v)?;
        }
        non_negative("table.friction", self.table.friction)?;
        for (b, basket) in self.baskets.iter().enumerate() {
            for (i, v) in basket.floor_center_m.iter().enumerate() {
                finite(&format!("baskets[{b}].floor_center_m[{i}]"), *v)?;
            }
            for (i, v) in basket.inner_size_m.iter().enumerate() {
                positive(&format!("baskets[{b}].inner_size_m[{i}]"), *v)?;
            }
            positive(&format!("baskets[{b}].wall_height_m"), basket.wall_height_m)?;
            positive(
                &format!("baskets[{b}].wall_thickness_m"),
                basket.wall_thickness_m,
            )?;
            non_negative(&format!("baskets[{b}].friction"), basket.friction)?;
        }
        self.object.validate("object.")?;
        positive(
            "settle.max_linear_speed_m_s",
            self.settle.max_linear_speed_m_s,
        )?;
        positive(
            "settle.max_angular_speed_rad_s",
            self.settle.max_angular_speed_rad_s,
        )?;
        at_least_one("settle.quiet_steps", self.settle.quiet_steps)?;
        if self.max_face_vertices < 3 {
            return Err(WorldError::InvalidConfig {
                field: "max_face_vertices".into(),
                reason: format!("{} is below 3", self.max_face_vertices),
            });
        }
        at_least_one("settle.max_steps", self.settle.max_steps)?;
        for (field, value) in [
            ("warmstart_coefficient", self.warmstart_coefficient),
            (
                "settle.warmstart_coefficient",
                self.settle.warmstart_coefficient,
            ),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(WorldError::InvalidConfig {
                    field: field.into(),
                    reason: format!("{value} is outside [0, 1]"),
                });
            }
        }
        Ok(())
    }
}

/// Why a convex hull could not be built.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HullProblem {
    /// The mesh has fewer than 4 vertices.
    TooFewVertices(usize),
    /// A vertex is NaN or infinite.
    NonFiniteVertex(usize),
    /// The vertices are (nearly) coplanar or collinear: the hull has no volume.
    Flat,
    /// The hull algorithm failed on these vertices.
    Failed,
}

impl std::fmt::Display for HullProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewVertices(n) => write!(f, "{n} vertices, at least 4 needed"),
            Self::NonFiniteVertex(i) => write!(f, "vertex {i} is not finite"),
            Self::Flat => write!(f, "the vertices are flat (no volume)"),
            Self::Failed => write!(f, "the convex-hull algorithm failed"),
        }
    }
}

/// Errors of the physics world.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldError {
    /// A bad [`WorldConfig`] (or gripper/robot config) field.
    #[error("config: {field}: {reason}")]
    InvalidConfig {
        /// The field, e.g. `table.size_m[2]`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The object's convex hull cannot be built.
    #[error("object `{object}`: cannot build its convex hull: {problem}")]
    Hull {
        /// The object's name.
        object: String,
        /// Why.
        problem: HullProblem,
    },
    /// The object does not fit on the table.
    #[error(
        "object `{object}` is {extent_m} m across, larger than the table's smaller side {limit_m} m"
    )]
    ObjectTooLarge {
        /// The object's name.
        object: String,
        /// The object's largest bounding-box extent (m).
        extent_m: f32,
        /// The table's smaller horizontal side (m).
        limit_m: f32,
    },
    /// A pose with a NaN or infinite component.
    #[error("{what}: pose is not finite")]
    NonFinitePose {
        /// What the pose was for.
        what: String,
    },
    /// A handle that names no (or a removed) object.
    #[error("no object with handle {0:?}")]
    UnknownObject(ObjectHandle),
    /// A body's state became NaN or infinite during the simulation.
    #[error("object `{object}` has a non-finite pose or velocity after step {step}")]
    NonFiniteState {
        /// The object's name.
        object: String,
        /// The step count when found.
        step: u64,
    },
}

/// A dynamic object in the [`World`] (an index; stays valid until the object is removed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ObjectHandle(pub u32);

#[derive(Debug, Clone)]
struct ObjectEntry {
    name: String,
    mesh: Mesh,
    body: RigidBodyHandle,
    collider: ColliderHandle,
    /// The collider drawn as triangles in the mesh's colours, built on first use.
    drawn_collider: std::sync::OnceLock<Mesh>,
}

/// Where and how [`World::drop_object`] drops an object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DropRegion {
    /// Centre of the region on the table (m; default (0.05, −0.52), the reference camera's
    /// target).
    pub center_xy_m: [f32; 2],
    /// Half extents of the region (m; default ±0.10, the reference isolated scenario).
    pub half_extents_m: [f32; 2],
    /// Height of the object's lowest point above the table top when released (m; default 0.01).
    pub drop_height_m: f32,
    /// Tumble: a uniformly random orientation instead of upright with a random yaw (default
    /// false). The object then comes to rest on whichever face it falls on.
    pub tumble: bool,
}

impl DropRegion {
    /// A random pose for `mesh` in the region (uniform x, y; upright with a uniform yaw, or a
    /// uniform orientation when `tumble`), its lowest point `drop_height_m` above a table top
    /// at `table_top_z_m`. The draws are the same whatever calls it.
    pub fn sample_pose<R: rand::Rng + ?Sized>(
        &self,
        mesh: &Mesh,
        table_top_z_m: f32,
        rng: &mut R,
    ) -> Pose {
        let [hx, hy] = self.half_extents_m.map(f32::abs);
        let x = self.center_xy_m[0] + hx * rng.random_range(-1.0_f32..=1.0);
        let y = self.center_xy_m[1] + hy * rng.random_range(-1.0_f32..=1.0);
        let rotation = if self.tumble {
            uniform_rotation(rng)
        } else {
            let yaw = rng.random_range(0.0_f32..std::f32::consts::TAU);
            UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), yaw).to_rotation_matrix()
        };
        let lowest = mesh
            .vertices
            .iter()
            .map(|v| (rotation * nalgebra::Vector3::from(*v)).z)
            .fold(f32::INFINITY, f32::min);
        let lowest = if lowest.is_finite() { lowest } else { 0.0 };
        let z = table_top_z_m + self.drop_height_m - lowest;
        Pose::from_parts(Translation3::new(x, y, z), rotation)
    }
}

/// A uniformly random rotation (Shoemake's method).
pub(crate) fn uniform_rotation<R: rand::Rng + ?Sized>(rng: &mut R) -> Rotation3<f32> {
    let (u1, u2, u3) = (
        rng.random_range(0.0_f32..1.0),
        rng.random_range(0.0_f32..std::f32::consts::TAU),
        rng.random_range(0.0_f32..std::f32::consts::TAU),
    );
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    UnitQuaternion::from_quaternion(Quaternion::new(
        b * u3.cos(),
        a * u2.sin(),
        a * u2.cos(),
        b * u3.sin(),
    ))
    .to_rotation_matrix()
}

impl Default for DropRegion {
    fn default() -> Self {
        Self {
            center_xy_m: [0.05, -0.52],
            half_extents_m: [0.1, 0.1],
            drop_height_m: 0.01,
            tumble: false,
        }
    }
}

/// The result of [`World::settle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettleReport {
    /// Steps taken.
    pub steps: u32,
    /// Whether every object came to rest before the step cap.
    pub settled: bool,
}

/// The physics world: rapier's state plus the scenery and the objects.
pub struct World {
    config: WorldConfig,
    pub(crate) physics: PhysicsWorld,
    objects: Vec<Option<ObjectEntry>>,
    scenery: Vec<ColliderHandle>,
    steps: u64,
    observer: Option<Box<dyn StepObserver>>,
}

/// Called after every physics step with the world's new state, read-only — e.g. the recorder
/// of [`crate::run::record`] sampling body poses. Set with [`World::set_step_observer`]; none by
/// default, and then a step costs nothing extra.
pub trait StepObserver: Send + Sync {
    /// Called after [`World::step`] (the step count already advanced).
    fn after_step(&mut self, world: &World);
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("config", &self.config)
            .field("objects", &self.objects.iter().flatten().count())
            .field("steps", &self.steps)
            .finish_non_exhaustive()
    }
}

impl World {
    /// Validates the config and builds the scenery (table, baskets, floor).
    pub fn new(config: WorldConfig) -> Result<Self, WorldError> {
        config.validate()?;
        let mut physics = PhysicsWorld::new();
        physics.gravity = RVec::new(0.0, 0.0, config.gravity_z_m_s2);
        let p = &mut physics.integration_parameters;
        p.dt = config.dt_s;
        p.num_solver_iterations = config.solver_iterations as usize;
        p.num_internal_pgs_iterations = config.internal_pgs_iterations as usize;
        p.contact_softness =
            SpringCoefficients::new(config.contact_frequency_hz, config.contact_damping_ratio);
        p.static_contact_softness = SpringCoefficients::new(
            config.static_contact_frequency_hz,
            config.contact_damping_ratio,
        );
        p.friction_model = match config.friction_model {
            FrictionKind::Simplified => FrictionModel::Simplified,
            FrictionKind::Coulomb => FrictionModel::Coulomb,
        };
        p.warmstart_joints = config.warmstart_joints;
        p.warmstart_coefficient = config.warmstart_coefficient;
        p.contact_recycling = config.contact_recycling;
        p.normalized_contact_recycle_distance = config.contact_recycle_distance_m;
        p.normalized_prediction_distance = config.prediction_distance_m;
        let mut world = Self {
            config,
            physics,
            objects: Vec::new(),
            scenery: Vec::new(),
            steps: 0,
            observer: None,
        };
        world.build_scenery();
        Ok(world)
    }

    fn build_scenery(&mut self) {
        let table = self.config.table.clone();
        let [cx, cy, cz] = table.center_m;
        let [sx, sy, sz] = table.size_m;
        self.add_fixed_box([cx, cy, cz], [sx / 2.0, sy / 2.0, sz / 2.0], table.friction);
        for basket in self.config.baskets.clone() {
            let [x, y, z] = basket.floor_center_m;
            let t = basket.wall_thickness_m;
            let [ix, iy] = basket.inner_size_m;
            let (hx, hy) = (ix / 2.0 + t, iy / 2.0 + t);
            let h = basket.wall_height_m;
            let mu = basket.friction;
            // Floor plate below the floor top face, then four walls on its rim.
            self.add_fixed_box([x, y, z - t / 2.0], [hx, hy, t / 2.0], mu);
            let wall_z = z + h / 2.0;
            self.add_fixed_box(
                [x + ix / 2.0 + t / 2.0, y, wall_z],
                [t / 2.0, hy, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                [x - ix / 2.0 - t / 2.0, y, wall_z],
                [t / 2.0, hy, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                [x, y + iy / 2.0 + t / 2.0, wall_z],
                [hx, t / 2.0, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                [x, y - iy / 2.0 - t / 2.0, wall_z],
                [hx, t / 2.0, h / 2.0],
                mu,
            );
        }
        if self.config.floor {
            self.add_fixed_box([0.0, 0.0, -0.05], [5.0, 5.0, 0.05], 0.5);
        }
    }

    /// Adds a fixed box of scenery (collides with objects and the gripper).
    pub(crate) fn add_fixed_box(
        &mut self,
        center_m: [f32; 3],
        half_extents_m: [f32; 3],
        friction: f32,
    ) -> ColliderHandle {
        let [hx, hy, hz] = half_extents_m;
        let body = RigidBodyBuilder::fixed().translation(RVec::from_array(center_m));
        let collider = ColliderBuilder::cuboid(hx, hy, hz)
            .friction(friction)
            .friction_combine_rule(CoefficientCombineRule::Multiply)
            .collision_groups(static_groups());
        let (_, c) = self.physics.insert(body, collider);
        self.scenery.push(c);
        c
    }

    /// Removes a box added with [`World::add_fixed_box`] (temporary scenery, such as the walls a
    /// pile is dropped into).
    pub(crate) fn remove_fixed_box(&mut self, collider: ColliderHandle) {
        if let Some(body) = self
            .physics
            .colliders
            .get(collider)
            .and_then(|c| c.parent())
        {
            self.physics.remove_body_with_colliders(body, true);
        }
        self.scenery.retain(|c| *c != collider);
    }

    /// The config.
    pub fn config(&self) -> &WorldConfig {
        &self.config
    }

    /// rapier's state, read-only (for debugging and advanced queries).
    pub fn physics(&self) -> &PhysicsWorld {
        &self.physics
    }

    /// Steps taken since the world was built.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Simulated time since the world was built (s): `steps · dt`.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * f64::from(self.config.dt_s)
    }

    /// The time step (s).
    pub fn dt_s(&self) -> f32 {
        self.config.dt_s
    }

    /// Advances the physics by one step (`dt_s`). Kinematic bodies (palm, arm links) move to the
    /// targets their owners set before this call.
    pub fn step(&mut self) {
        self.physics.step();
        self.steps += 1;
        if let Some(mut observer) = self.observer.take() {
            observer.after_step(self);
            self.observer = Some(observer);
        }
    }

    /// Installs (or with `None` removes) the [`StepObserver`]; returns the previous one.
    pub fn set_step_observer(
        &mut self,
        observer: Option<Box<dyn StepObserver>>,
    ) -> Option<Box<dyn StepObserver>> {
        std::mem::replace(&mut self.observer, observer)
    }

    /// Spawns `mesh` (object frame: metres, z up) as a dynamic body at `world_from_object`, with
    /// the default [`ObjectMaterial`]. The collider is the convex hull of the mesh vertices.
    pub fn spawn_object(
        &mut self,
        name: &str,
        mesh: &Mesh,
        world_from_object: &Pose,
    ) -> Result<ObjectHandle, WorldError> {
        let material = self.config.object.clone();
        self.spawn_object_with(name, mesh, world_from_object, &material)
    }

    /// [`World::spawn_object`] with an explicit material (density, mass clamp, friction).
    pub fn spawn_object_with(
        &mut self,
        name: &str,
        mesh: &Mesh,
        world_from_object: &Pose,
        material: &ObjectMaterial,
    ) -> Result<ObjectHandle, WorldError> {
        let (points, pose) = self.check_new_object(name, mesh, world_from_object, material)?;
        let shape =
            thinned_hull(&points, self.config.max_face_vertices as usize).ok_or_else(|| {
                WorldError::Hull {
                    object: name.to_string(),
                    problem: HullProblem::Failed,
                }
            })?;
        let volume = shape.mass_properties(1.0).mass();
        if !(volume.is_finite() && volume > 1e-9) {
            return Err(WorldError::Hull {
                object: name.to_string(),
                problem: HullProblem::Flat,
            });
        }
        Ok(self.insert_object(name, mesh, pose, shape, volume, material))
    }

    /// Spawns `mesh` as a dynamic body whose collider is the compound of the convex hulls of
    /// `parts` (point sets in the object frame, such as a convex decomposition of the mesh)
    /// instead of the mesh's single hull, so that hollow and concave objects keep their
    /// openings. The checks (hull of the whole mesh, size against the table), the face thinning
    /// and the material rules are [`World::spawn_object_with`]'s; the mass is the parts' total
    /// volume times the density, clamped. Parts too small or flat to have a hull are skipped.
    pub fn spawn_object_parts(
        &mut self,
        name: &str,
        mesh: &Mesh,
        parts: &[Vec<[f32; 3]>],
        world_from_object: &Pose,
        material: &ObjectMaterial,
    ) -> Result<ObjectHandle, WorldError> {
        let (_, pose) = self.check_new_object(name, mesh, world_from_object, material)?;
        let max_face = self.config.max_face_vertices as usize;
        let mut shapes = Vec::with_capacity(parts.len());
        let mut volume = 0.0f32;
        for part in parts {
            let pts: Vec<RVec> = part.iter().map(|p| RVec::from_array(*p)).collect();
            if pts.len() < 4 || !pts.iter().all(|p| p.is_finite()) {
                continue;
            }
            let Some(shape) = thinned_hull(&pts, max_face) else {
                continue;
            };
            let v = shape.mass_properties(1.0).mass();
            if v.is_finite() && v > 1e-9 {
                volume += v;
                shapes.push((RPose::IDENTITY, shape));
            }
        }
        if shapes.is_empty() {
            return Err(WorldError::Hull {
                object: name.to_string(),
                problem: HullProblem::Failed,
            });
        }
        let compound = SharedShape::compound(shapes);
        Ok(self.insert_object(name, mesh, pose, compound, volume, material))
    }

    /// The checks every spawned object passes (material, a buildable hull of the mesh, no
    /// larger than the table, a finite pose): the hull points and the pose.
    fn check_new_object(
        &self,
        name: &str,
        mesh: &Mesh,
        world_from_object: &Pose,
        material: &ObjectMaterial,
    ) -> Result<(Vec<RVec>, RPose), WorldError> {
        material.validate("material.")?;
        let points = hull_points(name, mesh)?;
        let (lo, hi) = bounds(&points);
        let extent_m = (0..3).map(|k| hi[k] - lo[k]).fold(0.0_f32, f32::max);
        let limit_m = self.config.table.size_m[0].min(self.config.table.size_m[1]);
        if extent_m > limit_m {
            return Err(WorldError::ObjectTooLarge {
                object: name.to_string(),
                extent_m,
                limit_m,
            });
        }
        let pose = pose_to_rapier(world_from_object).ok_or_else(|| WorldError::NonFinitePose {
            what: format!("object `{name}`"),
        })?;
        Ok((points, pose))
    }

    /// Inserts a dynamic object body with collider `shape` of `volume` (m³) and the material's
    /// mass rule, friction and damping.
    fn insert_object(
        &mut self,
        name: &str,
        mesh: &Mesh,
        pose: RPose,
        shape: SharedShape,
        volume: f32,
        material: &ObjectMaterial,
    ) -> ObjectHandle {
        let mass_kg =
            (volume * material.density_kg_m3).clamp(material.min_mass_kg, material.max_mass_kg);
        let collider = ColliderBuilder::new(shape)
            .mass(mass_kg)
            .friction(material.friction)
            .friction_combine_rule(CoefficientCombineRule::Multiply)
            .restitution(material.restitution)
            .collision_groups(object_groups());
        let body = RigidBodyBuilder::dynamic()
            .pose(pose)
            .angular_damping(material.angular_damping)
            .can_sleep(self.config.allow_sleep);
        let (body, collider) = self.physics.insert(body, collider);
        let handle = ObjectHandle(self.objects.len() as u32);
        self.objects.push(Some(ObjectEntry {
            name: name.to_string(),
            mesh: mesh.clone(),
            body,
            collider,
            drawn_collider: std::sync::OnceLock::new(),
        }));
        handle
    }

    /// Drops `mesh` at a random pose inside `region` (uniform x, y; upright with a uniform yaw, or
    /// a uniform orientation when `region.tumble`), its lowest point `drop_height_m` above the
    /// table, then [`settle`](World::settle)s the scene. Same RNG state, same result.
    pub fn drop_object<R: rand::Rng + ?Sized>(
        &mut self,
        name: &str,
        mesh: &Mesh,
        region: &DropRegion,
        rng: &mut R,
    ) -> Result<(ObjectHandle, SettleReport), WorldError> {
        let material = self.config.object.clone();
        self.drop_object_with(name, mesh, &material, region, rng)
    }

    /// [`World::drop_object`] with an explicit material.
    pub fn drop_object_with<R: rand::Rng + ?Sized>(
        &mut self,
        name: &str,
        mesh: &Mesh,
        material: &ObjectMaterial,
        region: &DropRegion,
        rng: &mut R,
    ) -> Result<(ObjectHandle, SettleReport), WorldError> {
        for (i, v) in region
            .center_xy_m
            .iter()
            .chain(region.half_extents_m.iter())
            .chain(std::iter::once(&region.drop_height_m))
            .enumerate()
        {
            finite(&format!("drop_region[{i}]"), *v)?;
        }
        let pose = region.sample_pose(mesh, self.config.table.top_z_m(), rng);
        let handle = self.spawn_object_with(name, mesh, &pose, material)?;
        let report = self.settle();
        Ok((handle, report))
    }

    /// Steps until every object is at rest (asleep, or below the speed thresholds of
    /// [`SettleConfig`] for `quiet_steps` steps in a row) or `max_steps` have passed, with the
    /// settling warm-start coefficient. For scene preparation (after spawning or resetting
    /// objects), not while the gripper holds something.
    pub fn settle(&mut self) -> SettleReport {
        let cfg = self.config.settle.clone();
        self.physics.integration_parameters.warmstart_coefficient = cfg.warmstart_coefficient;
        let mut report = SettleReport {
            steps: cfg.max_steps,
            settled: false,
        };
        let mut quiet = 0;
        for step in 1..=cfg.max_steps {
            self.step();
            if self.all_at_rest(cfg.max_linear_speed_m_s, cfg.max_angular_speed_rad_s) {
                quiet += 1;
                if quiet >= cfg.quiet_steps {
                    report = SettleReport {
                        steps: step,
                        settled: true,
                    };
                    break;
                }
            } else {
                quiet = 0;
            }
        }
        self.physics.integration_parameters.warmstart_coefficient =
            self.config.warmstart_coefficient;
        report
    }

    /// Whether every object is asleep or slower than the given speeds.
    pub fn all_at_rest(&self, max_linear_speed_m_s: f32, max_angular_speed_rad_s: f32) -> bool {
        self.objects.iter().flatten().all(|o| {
            let body = &self.physics.bodies[o.body];
            body.is_sleeping()
                || (body.linvel().length() < max_linear_speed_m_s
                    && body.angvel().length() < max_angular_speed_rad_s)
        })
    }

    /// Handles of the live objects, in spawn order.
    pub fn objects(&self) -> impl Iterator<Item = ObjectHandle> + '_ {
        self.objects
            .iter()
            .enumerate()
            .filter(|(_, o)| o.is_some())
            .map(|(i, _)| ObjectHandle(i as u32))
    }

    fn entry(&self, handle: ObjectHandle) -> Result<&ObjectEntry, WorldError> {
        self.objects
            .get(handle.0 as usize)
            .and_then(Option::as_ref)
            .ok_or(WorldError::UnknownObject(handle))
    }

    /// The object's name.
    pub fn object_name(&self, handle: ObjectHandle) -> Result<&str, WorldError> {
        Ok(&self.entry(handle)?.name)
    }

    /// The object's mesh (object frame).
    pub fn object_mesh(&self, handle: ObjectHandle) -> Result<&Mesh, WorldError> {
        Ok(&self.entry(handle)?.mesh)
    }

    /// The vertices of the object's collider (its simplified convex hull, or every part's of a
    /// compound collider) in the object frame (m): the shape the physics uses, within a few
    /// millimetres of the mesh.
    pub fn object_hull_points_m(&self, handle: ObjectHandle) -> Result<Vec<[f32; 3]>, WorldError> {
        let entry = self.entry(handle)?;
        let collider = &self.physics.colliders[entry.collider];
        let shape = collider.shape();
        if let Some(compound) = shape.as_compound() {
            // The parts of a compound collider (World::spawn_object_parts), in the object frame.
            return Ok(compound
                .shapes()
                .iter()
                .filter_map(|(pose, part)| part.as_convex_polyhedron().map(|h| (pose, h)))
                .flat_map(|(pose, hull)| {
                    hull.points()
                        .iter()
                        .map(|p| pose.transform_point(*p).to_array())
                })
                .collect());
        }
        Ok(shape
            .as_convex_polyhedron()
            .map(|hull| hull.points().iter().map(|p| p.to_array()).collect())
            .unwrap_or_default())
    }

    /// The object's collider as a triangle mesh in the object frame — every convex part of it,
    /// each triangle coloured like the nearest mesh triangle — so a camera can draw the shape
    /// the physics has. Built once per object, on first use.
    pub fn object_collider_mesh(&self, handle: ObjectHandle) -> Result<&Mesh, WorldError> {
        let entry = self.entry(handle)?;
        Ok(entry.drawn_collider.get_or_init(|| {
            let shape = self.physics.colliders[entry.collider].shape();
            let mut parts: Vec<Vec<RVec>> = Vec::new();
            if let Some(compound) = shape.as_compound() {
                for (pose, part) in compound.shapes() {
                    if let Some(hull) = part.as_convex_polyhedron() {
                        parts.push(
                            hull.points()
                                .iter()
                                .map(|p| pose.transform_point(*p))
                                .collect(),
                        );
                    }
                }
            } else if let Some(hull) = shape.as_convex_polyhedron() {
                parts.push(hull.points().to_vec());
            }
            collider_drawing(&parts, &entry.mesh)
        }))
    }

    /// Sets the drawing [`World::object_collider_mesh`] returns for `handle` — one built before
    /// from the same library object's same collider (a cache of [`crate::physics::shapes::LibraryShapes`]);
    /// a drawing already built is kept.
    pub(crate) fn set_object_collider_mesh(
        &mut self,
        handle: ObjectHandle,
        drawing: Mesh,
    ) -> Result<(), WorldError> {
        let entry = self.entry(handle)?;
        let _ = entry.drawn_collider.set(drawing);
        Ok(())
    }

    /// The object's pose `world_from_object` (the mesh frame in the world).
    pub fn object_pose(&self, handle: ObjectHandle) -> Result<Pose, WorldError> {
        let entry = self.entry(handle)?;
        Ok(rapier_to_pose(self.physics.bodies[entry.body].position()))
    }

    /// The object's centre of mass in the world (m).
    pub fn object_center_of_mass_m(&self, handle: ObjectHandle) -> Result<[f32; 3], WorldError> {
        let entry = self.entry(handle)?;
        Ok(self.physics.bodies[entry.body].center_of_mass().to_array())
    }

    /// The object's linear (m/s) and angular (rad/s) velocity.
    pub fn object_velocity(
        &self,
        handle: ObjectHandle,
    ) -> Result<([f32; 3], [f32; 3]), WorldError> {
        let entry = self.entry(handle)?;
        let body = &self.physics.bodies[entry.body];
        Ok((body.linvel().to_array(), body.angvel().to_array()))
    }

    /// The object's mass (kg).
    pub fn object_mass_kg(&self, handle: ObjectHandle) -> Result<f32, WorldError> {
        let entry = self.entry(handle)?;
        Ok(self.physics.bodies[entry.body].mass())
    }

    /// The object's collider (for contact queries inside the crate).
    pub(crate) fn object_collider(
        &self,
        handle: ObjectHandle,
    ) -> Result<ColliderHandle, WorldError> {
        Ok(self.entry(handle)?.collider)
    }

    /// The object whose collider is `collider`, if any.
    pub(crate) fn object_of_collider(&self, collider: ColliderHandle) -> Option<ObjectHandle> {
        self.objects
            .iter()
            .position(|o| o.as_ref().is_some_and(|o| o.collider == collider))
            .map(|i| ObjectHandle(i as u32))
    }

    /// Puts an object at `world_from_object` at rest. For scene setup and resets between
    /// attempts only — never to move a grasped object.
    pub fn reset_object_pose(
        &mut self,
        handle: ObjectHandle,
        world_from_object: &Pose,
    ) -> Result<(), WorldError> {
        let body = self.entry(handle)?.body;
        let name = self.entry(handle)?.name.clone();
        let pose = pose_to_rapier(world_from_object).ok_or_else(|| WorldError::NonFinitePose {
            what: format!("object `{name}`"),
        })?;
        let rb = &mut self.physics.bodies[body];
        rb.set_position(pose, true);
        rb.set_linvel(RVec::ZERO, true);
        rb.set_angvel(RVec::ZERO, true);
        Ok(())
    }

    /// Removes an object (e.g. once placed in a basket). Its handle becomes unknown.
    pub fn remove_object(&mut self, handle: ObjectHandle) -> Result<(), WorldError> {
        let body = self.entry(handle)?.body;
        self.physics.remove_body_with_colliders(body, true);
        self.objects[handle.0 as usize] = None;
        Ok(())
    }

    /// Checks every object's pose and velocity for NaN or infinity.
    pub fn check_finite(&self) -> Result<(), WorldError> {
        for o in self.objects.iter().flatten() {
            let body = &self.physics.bodies[o.body];
            let p = body.position();
            let ok = p.translation.is_finite()
                && p.rotation.is_finite()
                && body.linvel().is_finite()
                && body.angvel().is_finite();
            if !ok {
                return Err(WorldError::NonFiniteState {
                    object: o.name.clone(),
                    step: self.steps,
                });
            }
        }
        Ok(())
    }

    /// Whether `collider` is part of the fixed scenery (table, baskets, floor, pedestal).
    pub(crate) fn is_scenery(&self, collider: ColliderHandle) -> bool {
        self.scenery.contains(&collider)
    }
}

/// The mesh vertices as hull input, after checks (count, finite, not flat).
fn hull_points(name: &str, mesh: &Mesh) -> Result<Vec<RVec>, WorldError> {
    let err = |problem| WorldError::Hull {
        object: name.to_string(),
        problem,
    };
    if mesh.vertices.len() < 4 {
        return Err(err(HullProblem::TooFewVertices(mesh.vertices.len())));
    }
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(err(HullProblem::NonFiniteVertex(i)));
    }
    let points: Vec<RVec> = mesh.vertices.iter().map(|v| RVec::from_array(*v)).collect();
    // Flat: the smallest principal extent is below 0.1 mm.
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(nalgebra::Vector3::<f64>::zeros(), |a, p| {
            a + nalgebra::Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z))
        })
        / n;
    let mut cov = Matrix3::<f64>::zeros();
    for p in &points {
        let d = nalgebra::Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)) - mean;
        cov += d * d.transpose();
    }
    let eig = (cov / n).symmetric_eigenvalues();
    if eig.min() < 1e-8 {
        return Err(err(HullProblem::Flat));
    }
    Ok(points)
}

/// Meshes with more triangles than this are coloured from a simplified copy (vertex clustering
/// on cells of a 128th of the mesh's extent, [`Mesh::clustered`]) searched through a
/// bounding-volume tree, instead of trying every triangle for every drawn face (default 10,000;
/// the procedural library's meshes have at most 2,432, so their drawings are what they were).
/// Trying every triangle of a 2-million-triangle scan takes hours; a tree over all of them
/// takes 400 MB.
const MAX_DRAWING_COLOR_TRIANGLES: usize = 10_000;

/// Triangles of the convex hulls of `parts` (object frame), each coloured like the mesh triangle
/// nearest its centroid (of a simplified mesh above [`MAX_DRAWING_COLOR_TRIANGLES`]).
fn collider_drawing(parts: &[Vec<RVec>], mesh: &Mesh) -> Mesh {
    use rapier3d::parry::query::{PointQuery, PointQueryWithLocation};
    use rapier3d::parry::shape::{TriMesh, Triangle};
    let coarse = match mesh.bounds() {
        Some((lo, hi)) if mesh.triangles.len() > MAX_DRAWING_COLOR_TRIANGLES => {
            let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
            Some(mesh.clustered(extent / 128.0))
        }
        _ => None,
    };
    let tree = coarse.as_ref().and_then(|coarse| {
        let vertices = coarse
            .vertices
            .iter()
            .map(|v| RVec::from_array(*v))
            .collect();
        let tree = TriMesh::new(vertices, coarse.triangles.clone()).ok()?;
        Some((tree, &coarse.colors))
    });
    let mesh_triangles: Vec<(Triangle, [u8; 3])> = match tree {
        Some(_) => Vec::new(),
        None => mesh
            .triangles
            .iter()
            .zip(&mesh.colors)
            .map(|(t, c)| {
                let v = |i: u32| RVec::from_array(mesh.vertices[i as usize]);
                (Triangle::new(v(t[0]), v(t[1]), v(t[2])), *c)
            })
            .collect(),
    };
    let mut out = Mesh::new();
    for part in parts {
        if part.len() < 4 {
            continue;
        }
        let (vertices, faces) = rapier3d::parry::transformation::convex_hull(part);
        for [a, b, c] in faces {
            let (a, b, c) = (
                vertices[a as usize],
                vertices[b as usize],
                vertices[c as usize],
            );
            let centroid = (a + b + c) / 3.0;
            let color = match &tree {
                Some((tree, colors)) => {
                    let (_, (i, _)) = tree.project_local_point_and_get_location(centroid, true);
                    colors.get(i as usize).copied().unwrap_or([128; 3])
                }
                None => mesh_triangles
                    .iter()
                    .map(|(t, c)| (t.distance_to_local_point(centroid, true), *c))
                    .min_by(|x, y| x.0.total_cmp(&y.0))
                    .map_or([128; 3], |(_, c)| c),
            };
            out.push_triangle(a.to_array(), b.to_array(), c.to_array(), color);
        }
    }
    out
}

fn bounds(points: &[RVec]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lgdm_pointcloud::math::{rotation_z, translation};

    #[test]
    fn default_config_is_valid_and_reference_sized() {
        let cfg = WorldConfig::default();
        cfg.validate().unwrap();
        assert!((cfg.table.top_z_m() - 0.785).abs() < 1e-6);
        assert_eq!(cfg.baskets.len(), 2);
        assert_eq!(cfg.baskets[1].floor_center_m, [-0.7, 0.0, 0.685]);
    }

    #[test]
    fn config_validation_names_the_field() {
        let mut cfg = WorldConfig::default();
        cfg.table.size_m[2] = 0.0;
        let err = cfg.validate().unwrap_err();
        assert!(
            matches!(&err, WorldError::InvalidConfig { field, .. } if field == "table.size_m[2]"),
            "{err}"
        );
        let cfg = WorldConfig {
            dt_s: f32::NAN,
            ..WorldConfig::default()
        };
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "dt_s"
        ));
        let mut cfg = WorldConfig::default();
        cfg.baskets[1].wall_height_m = -0.1;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "baskets[1].wall_height_m"
        ));
        let mut cfg = WorldConfig::default();
        cfg.object.min_mass_kg = 1.0;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "object.min_mass_kg"
        ));
        let mut cfg = WorldConfig::default();
        cfg.settle.max_steps = 0;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "settle.max_steps"
        ));
        let cfg = WorldConfig {
            internal_pgs_iterations: 0,
            ..WorldConfig::default()
        };
        assert!(World::new(cfg).is_err());
    }

    #[test]
    fn config_serde_roundtrip_and_defaults() {
        let cfg = WorldConfig::default();
        let json = serde_json::to_string(&cfg).unwrap();
        assert_eq!(serde_json::from_str::<WorldConfig>(&json).unwrap(), cfg);
        assert_eq!(serde_json::from_str::<WorldConfig>("{}").unwrap(), cfg);
        assert!(serde_json::from_str::<WorldConfig>(r#"{"dt": 0.1}"#).is_err());
    }

    #[test]
    fn hull_errors_name_the_object() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let at = translation([0.0, -0.6, 0.9]);
        let mut flat = Mesh::new();
        flat.push_triangle([0.0; 3], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0; 3]);
        flat.push_triangle([0.1, 0.1, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0; 3]);
        let err = world.spawn_object("sheet", &flat, &at).unwrap_err();
        assert_eq!(
            err,
            WorldError::Hull {
                object: "sheet".into(),
                problem: HullProblem::Flat
            }
        );
        assert!(err.to_string().contains("sheet"), "{err}");
        let mut tiny = Mesh::new();
        tiny.push_triangle([0.0; 3], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0; 3]);
        assert!(matches!(
            world.spawn_object("tri", &tiny, &at),
            Err(WorldError::Hull {
                problem: HullProblem::TooFewVertices(3),
                ..
            })
        ));
        let mut nan = Mesh::cuboid([0.0; 3], [0.05; 3], [0; 3]);
        nan.vertices[2][1] = f32::NAN;
        assert!(matches!(
            world.spawn_object("nan", &nan, &at),
            Err(WorldError::Hull {
                problem: HullProblem::NonFiniteVertex(2),
                ..
            })
        ));
        let huge = Mesh::cuboid([0.0; 3], [0.9, 0.1, 0.1], [0; 3]);
        let err = world.spawn_object("plank", &huge, &at).unwrap_err();
        assert!(
            matches!(&err, WorldError::ObjectTooLarge { object, .. } if object == "plank"),
            "{err}"
        );
        let cube = Mesh::cuboid([0.0; 3], [0.05; 3], [0; 3]);
        let mut bad = at;
        bad.translation.x = f32::INFINITY;
        assert!(matches!(
            world.spawn_object("cube", &cube, &bad),
            Err(WorldError::NonFinitePose { .. })
        ));
        assert_eq!(world.objects().count(), 0);
    }

    #[test]
    fn mass_follows_density_and_clamp() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [0; 3]);
        let heavy = ObjectMaterial {
            density_kg_m3: 1000.0,
            ..ObjectMaterial::default()
        };
        let h = world
            .spawn_object_with("cube", &cube, &translation([0.0, -0.6, 0.8]), &heavy)
            .unwrap();
        assert!((world.object_mass_kg(h).unwrap() - 0.125).abs() < 1e-3);
        let big = Mesh::cuboid([0.0, 0.0, 0.1], [0.2; 3], [0; 3]);
        let h = world
            .spawn_object("big", &big, &translation([0.2, -0.6, 0.8]))
            .unwrap();
        assert!((world.object_mass_kg(h).unwrap() - 0.5).abs() < 1e-6);
    }

    #[test]
    fn pose_conversions_roundtrip() {
        let pose = translation([0.1, -0.2, 0.9]) * rotation_z(0.7);
        let back = rapier_to_pose(&pose_to_rapier(&pose).unwrap());
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-6);
        assert!((back.rotation.matrix() - pose.rotation.matrix()).norm() < 1e-6);
        let iso = Isometry3::new(
            nalgebra::Vector3::new(0.3, 0.1, 1.0),
            nalgebra::Vector3::new(0.2, -0.4, 1.1),
        );
        let back = rapier_to_isometry(&isometry_to_rapier(&iso).unwrap());
        assert!((back.translation.vector - iso.translation.vector).norm() < 1e-6);
        assert!(back.rotation.angle_to(&iso.rotation) < 1e-6);
    }

    #[test]
    fn remove_and_unknown_handles() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [0; 3]);
        let a = world
            .spawn_object("a", &cube, &translation([0.0, -0.6, 0.8]))
            .unwrap();
        let b = world
            .spawn_object("b", &cube, &translation([0.2, -0.6, 0.8]))
            .unwrap();
        world.remove_object(a).unwrap();
        assert_eq!(world.objects().collect::<Vec<_>>(), vec![b]);
        assert_eq!(world.object_pose(a), Err(WorldError::UnknownObject(a)));
        assert_eq!(world.object_name(b).unwrap(), "b");
        assert!(world.object_pose(ObjectHandle(99)).is_err());
    }
}
