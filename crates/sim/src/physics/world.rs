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
//! Here: the [`World`] (scenery, objects, stepping, settling, drops in a [`DropRegion`]). Beside
//! it: its configuration ([`crate::physics::config`], validated by [`World::new`]), its errors
//! ([`crate::physics::error`]), the handles and drawings of its objects
//! ([`crate::physics::object`]), drop regions ([`crate::physics::drop_region`]) and the conversions
//! at the boundary to rapier's math types (`physics::rapier`). How collider shapes are built —
//! decompositions in [`crate::physics::shapes`], the thinning of big hull faces and the reduction
//! of dense meshes' hulls (a scan of millions of triangles) in [`crate::physics::hull`].
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_pointcloud::math::translation;
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
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
use nalgebra::Matrix3;
use rapier3d::prelude::{
    CoefficientCombineRule, ColliderBuilder, ColliderHandle, FrictionModel, PhysicsWorld,
    RigidBodyBuilder, RigidBodyHandle, SharedShape, SpringCoefficients,
};
use serde::{Deserialize, Serialize};

use crate::physics::config::{FrictionKind, ObjectMaterial, WorldConfig, finite};
use crate::physics::drop_region::DropRegion;
use crate::physics::error::{HullProblem, WorldError};
use crate::physics::hull::thinned_hull;
use crate::physics::object::{ObjectHandle, collider_drawing};
use crate::physics::rapier::{
    RPose, RVec, object_groups, pose_to_rapier, rapier_to_pose, static_groups,
};

#[derive(Debug, Clone)]
struct ObjectEntry {
    name: String,
    mesh: Mesh,
    body: RigidBodyHandle,
    collider: ColliderHandle,
    /// The collider drawn as triangles in the mesh's colours, built on first use.
    drawn_collider: std::sync::OnceLock<Mesh>,
}

/// The result of [`World::settle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettleReport {
    /// Steps taken.
    pub steps: u32,
    /// Whether every object came to rest before the step cap.
    pub settled: bool,
}

/// What a piece of the fixed scenery is part of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scenery {
    /// The table.
    Table,
    /// Basket `i` of the config (its floor plate or a wall).
    Basket(usize),
    /// The floor plane under everything.
    Floor,
    /// The pedestal the arm stands on.
    Pedestal,
    /// A temporary wall (the walls a pile is dropped into).
    Wall,
}

impl std::fmt::Display for Scenery {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Scenery::Table => f.write_str("the table"),
            Scenery::Basket(i) => write!(f, "basket {i}"),
            Scenery::Floor => f.write_str("the floor"),
            Scenery::Pedestal => f.write_str("the pedestal"),
            Scenery::Wall => f.write_str("a pile wall"),
        }
    }
}

/// The physics world: rapier's state plus the scenery and the objects.
pub struct World {
    config: WorldConfig,
    pub(crate) physics: PhysicsWorld,
    objects: Vec<Option<ObjectEntry>>,
    scenery: Vec<(ColliderHandle, Scenery)>,
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
        self.add_fixed_box(
            Scenery::Table,
            [cx, cy, cz],
            [sx / 2.0, sy / 2.0, sz / 2.0],
            table.friction,
        );
        for (b, basket) in self.config.baskets.clone().into_iter().enumerate() {
            let [x, y, z] = basket.floor_center_m;
            let t = basket.wall_thickness_m;
            let [ix, iy] = basket.inner_size_m;
            let (hx, hy) = (ix / 2.0 + t, iy / 2.0 + t);
            let h = basket.wall_height_m;
            let mu = basket.friction;
            // Floor plate below the floor top face, then four walls on its rim.
            self.add_fixed_box(
                Scenery::Basket(b),
                [x, y, z - t / 2.0],
                [hx, hy, t / 2.0],
                mu,
            );
            let wall_z = z + h / 2.0;
            self.add_fixed_box(
                Scenery::Basket(b),
                [x + ix / 2.0 + t / 2.0, y, wall_z],
                [t / 2.0, hy, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                Scenery::Basket(b),
                [x - ix / 2.0 - t / 2.0, y, wall_z],
                [t / 2.0, hy, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                Scenery::Basket(b),
                [x, y + iy / 2.0 + t / 2.0, wall_z],
                [hx, t / 2.0, h / 2.0],
                mu,
            );
            self.add_fixed_box(
                Scenery::Basket(b),
                [x, y - iy / 2.0 - t / 2.0, wall_z],
                [hx, t / 2.0, h / 2.0],
                mu,
            );
        }
        if self.config.floor {
            self.add_fixed_box(Scenery::Floor, [0.0, 0.0, -0.05], [5.0, 5.0, 0.05], 0.5);
        }
    }

    /// Adds a fixed box of scenery (collides with objects and the gripper).
    pub(crate) fn add_fixed_box(
        &mut self,
        what: Scenery,
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
        self.scenery.push((c, what));
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
        self.scenery.retain(|(c, _)| *c != collider);
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
    /// [`SettleConfig`](crate::physics::config::SettleConfig) for `quiet_steps` steps in a row) or
    /// `max_steps` have passed, with the settling warm-start coefficient. For scene preparation
    /// (after spawning or resetting objects), not while the gripper holds something.
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
    /// from the same library object's same collider (a cache of
    /// [`crate::physics::shapes::LibraryShapes`]); a drawing already built is kept.
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
        self.scenery.iter().any(|(c, _)| *c == collider)
    }

    /// The fixed scenery's colliders and what each is part of.
    pub fn scenery(&self) -> &[(ColliderHandle, Scenery)] {
        &self.scenery
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
    use lgdm_pointcloud::math::translation;

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
