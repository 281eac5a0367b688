//! Collision shapes of library objects: the mesh's single convex hull (the default, the world's
//! [`World::spawn_object`]) or a convex decomposition ([`ObjectShape::Decomposition`]: parry's
//! VHACD, one compound collider of convex parts via [`World::spawn_object_parts`]).
//!
//! Why a decomposition: the cameras draw the real mesh, as the dataset does, so a grasp source
//! sees a glass's opening, a bowl's rim and a mug's handle — but a single hull fills them. A
//! finger aimed inside a glass's rim then lands on the hull's lid. With the parts, the physics
//! has the openings the camera shows. The cost: VHACD takes 0.1–1 s per object (computed once
//! per library object and run, on first use) and more contacts per step.
//!
//! **Experimental.** The world's settling and contact tuning was done for single hulls; objects
//! made of parts were measured to keep jittering on the basket floor (0.3–2.4 rad/s after the
//! 1000-step settle, sunk ~1.7 mm), so their placements are often judged "not at rest".
//!
//! ```
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_sim::shapes::{ShapeConfig, decompose};
//! let glass = procedural_object("glass", 0, 1).unwrap();
//! let parts = decompose(&glass, &ShapeConfig::default());
//! assert!(parts.len() > 1); // the wall is split around the opening
//! ```

use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::objects::ObjectModel;
use rapier3d::math::Vector;
use rapier3d::parry::transformation::vhacd::{VHACD, VHACDParameters};
use serde::{Deserialize, Serialize};

use crate::world::{DropRegion, ObjectHandle, World, WorldError};

/// How an object's collider is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectShape {
    /// The mesh's convex hull (default; openings and handles are filled).
    #[default]
    Hull,
    /// A convex decomposition of the mesh (VHACD): openings stay open.
    Decomposition,
}

/// Collider shapes and the decomposition's parameters. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShapeConfig {
    /// Hull or decomposition (default hull).
    pub shape: ObjectShape,
    /// VHACD voxel resolution (default 64, parry's).
    pub resolution: u32,
    /// VHACD concavity threshold (default 0.01, parry's; lower: more, tighter parts).
    pub concavity: f32,
    /// Most parts per object (default 32).
    pub max_parts: u32,
}

impl Default for ShapeConfig {
    fn default() -> Self {
        Self {
            shape: ObjectShape::Hull,
            resolution: 64,
            concavity: 0.01,
            max_parts: 32,
        }
    }
}

/// The convex parts of `mesh` (point sets in the mesh frame) by VHACD.
pub fn decompose(mesh: &Mesh, config: &ShapeConfig) -> Vec<Vec<[f32; 3]>> {
    let vertices: Vec<Vector> = mesh
        .vertices
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]))
        .collect();
    if vertices.len() < 4 || mesh.triangles.is_empty() {
        return Vec::new();
    }
    let params = VHACDParameters {
        resolution: config.resolution.clamp(16, 256),
        concavity: config.concavity,
        max_convex_hulls: config.max_parts.max(1),
        ..VHACDParameters::default()
    };
    let d = VHACD::decompose(&params, &vertices, &mesh.triangles, true);
    d.compute_exact_convex_hulls(&vertices, &mesh.triangles)
        .into_iter()
        .map(|(points, _)| points.iter().map(|p| p.to_array()).collect())
        .collect()
}

/// Drops library object `index` like [`World::drop_object`] (the same draws from `rng`: x, y,
/// then the orientation) with its collider shape, and settles the scene.
pub fn drop_object<R: rand::Rng + ?Sized>(
    shapes: &mut LibraryShapes,
    world: &mut World,
    index: usize,
    name: &str,
    object: &ObjectModel,
    region: &DropRegion,
    rng: &mut R,
) -> Result<ObjectHandle, WorldError> {
    if shapes.config.shape == ObjectShape::Hull {
        return Ok(world.drop_object(name, &object.mesh, region, rng)?.0);
    }
    let pose = region.sample_pose(&object.mesh, world.config().table.top_z_m(), rng);
    let handle = shapes.spawn(world, index, name, object, &pose)?;
    world.settle();
    Ok(handle)
}

/// The library's collider shapes, decomposed on first use.
#[derive(Debug, Clone)]
pub struct LibraryShapes {
    config: ShapeConfig,
    parts: Vec<Option<Vec<Vec<[f32; 3]>>>>,
}

impl LibraryShapes {
    /// Shapes for a library of `n` objects.
    pub fn new(config: ShapeConfig, n: usize) -> Self {
        Self {
            config,
            parts: vec![None; n],
        }
    }

    /// Single hulls for a library of `n` objects.
    pub fn hulls(n: usize) -> Self {
        Self::new(ShapeConfig::default(), n)
    }

    /// The config.
    pub fn config(&self) -> &ShapeConfig {
        &self.config
    }

    /// Spawns library object `index` (`object`) at `pose` with its collider shape.
    pub fn spawn(
        &mut self,
        world: &mut World,
        index: usize,
        name: &str,
        object: &ObjectModel,
        pose: &Pose,
    ) -> Result<ObjectHandle, WorldError> {
        match self.config.shape {
            ObjectShape::Hull => world.spawn_object(name, &object.mesh, pose),
            ObjectShape::Decomposition => {
                if self.parts.len() <= index {
                    self.parts.resize(index + 1, None);
                }
                let parts =
                    self.parts[index].get_or_insert_with(|| decompose(&object.mesh, &self.config));
                let material = world.config().object.clone();
                world.spawn_object_parts(name, &object.mesh, parts, pose, &material)
            }
        }
    }
}
