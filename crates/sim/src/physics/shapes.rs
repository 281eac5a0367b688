//! Collision shapes of library objects: a convex decomposition of the mesh (the default:
//! parry's VHACD, one compound collider of convex parts via [`World::spawn_object_parts`]) or the
//! mesh's single convex hull ([`ObjectShape::Hull`], [`World::spawn_object`]).
//!
//! Why a decomposition: a single hull fills a bowl, a glass, a mug's opening and the space inside
//! its handle. Bowls (12–18 cm across) and teapots are then wider than the 85 mm stroke everywhere,
//! and a rim is no longer there to pinch. With the parts the physics keeps the openings. VHACD is
//! not exact: it keeps a bowl's rim and a mug's handle but fills a vase's narrow neck, so the
//! cameras draw the collider ([`crate::perception::camera::ObjectDrawing::Collider`], the default),
//! and what the camera sees is what the fingers meet.
//!
//! Only open objects are decomposed: a mesh that fills at least [`SOLID_FRACTION`] of its hull
//! (a can, a box, a fruit, a bottle) has nothing to keep open and gets one part, its hull.
//! VHACD split the paper's master chef can into parts that kept it rocking in the basket for
//! ever (0.2–1.4 rad/s after 12.5 s, with angular damping 5 as with 0.5); as one hull it rests.
//!
//! Two details make decomposed bodies rest like single hulls: a flat **base slab** (the mesh's
//! lowest 3 mm as one part; the other parts stop at its top), and the world's short
//! [`crate::physics::config::WorldConfig::prediction_distance_m`] — without either a bowl made of
//! parts kept wobbling on the table and in the basket. The cost: VHACD takes 0.1–0.5 s per object
//! (computed once per library object and run, on first use) and more contacts per step.
//!
//! Dense meshes (scans; more than [`MAX_DECOMPOSITION_FACES`] triangles) are simplified by
//! vertex clustering before VHACD and their parts reduced to extreme points: a 2-million-triangle
//! scan decomposes in about a second instead of 15 s. The procedural objects are far below
//! the threshold, so their decompositions are unchanged.
//!
//! Every convex hull a [`World`] builds — a single hull or each part — has its big flat faces
//! thinned to [`crate::physics::config::WorldConfig::max_face_vertices`] vertices by farthest-point
//! sampling ([`crate::physics::hull`]): an upright can whose base is a 32-gon otherwise rocks until
//! it topples.
//!
//! ```
//! use lgdm_pointcloud::objects::procedural_object;
//! use lgdm_sim::physics::shapes::{ShapeConfig, decompose};
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

use crate::physics::config::WorldConfig;
use crate::physics::drop_region::DropRegion;
use crate::physics::error::WorldError;
use crate::physics::hull::{HULL_DIRECTIONS, SOLID_FRACTION, extreme_points, mesh_solid_fraction};
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;

/// How an object's collider is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectShape {
    /// The mesh's convex hull (openings and handles are filled).
    Hull,
    /// A convex decomposition of the mesh (VHACD; default) where it is open — a mesh filling less
    /// than [`crate::physics::hull::SOLID_FRACTION`] of its hull — and its hull where it is not:
    /// openings stay open.
    #[default]
    Decomposition,
}

/// Collider shapes and the decomposition's parameters. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShapeConfig {
    /// Decomposition or hull (default decomposition).
    pub shape: ObjectShape,
    /// VHACD voxel resolution (default 64, parry's).
    pub resolution: u32,
    /// VHACD concavity threshold (default 0.01, parry's; lower: more, tighter parts).
    pub concavity: f32,
    /// Most parts per object (default 32).
    pub max_parts: u32,
    /// Where an open object's parts come from (default `vhacd`; written to `sim.toml` only
    /// when it is not the default, so records of earlier runs read the same).
    #[serde(skip_serializing_if = "PartSource::is_vhacd")]
    pub parts: PartSource,
    /// With `parts = "generator"`: every part grows inward, towards the mesh's vertical axis
    /// (the centre of its bounds), by this much (m; default 0, written to `sim.toml` only when
    /// set): a 3 mm glass wall the pads can hold, its outside still the mesh's
    /// (`docs/experiments/closeup-draws-mesh.md`). Parts on the axis do not change.
    #[serde(skip_serializing_if = "is_zero")]
    pub thicken_m: f32,
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// Where an open object's convex parts come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartSource {
    /// VHACD on the mesh, for every object (default).
    #[default]
    Vhacd,
    /// The generator's exact parts where the library object carries them
    /// ([`ObjectModel::parts`]: the procedural objects), VHACD for the others.
    Generator,
}

impl ShapeConfig {
    /// Refuses a `thicken_m` that is negative, not finite or above 5 cm (a wall grown that far
    /// fills any household object's opening), naming the field.
    pub fn validate(&self) -> Result<(), WorldError> {
        if !(self.thicken_m.is_finite() && (0.0..=0.05).contains(&self.thicken_m)) {
            return Err(WorldError::InvalidConfig {
                field: "shapes.thicken_m".into(),
                reason: format!("{} m is not between 0 and 0.05 m", self.thicken_m),
            });
        }
        Ok(())
    }
}

impl PartSource {
    fn is_vhacd(&self) -> bool {
        *self == PartSource::Vhacd
    }
}

impl Default for ShapeConfig {
    fn default() -> Self {
        Self {
            shape: ObjectShape::Decomposition,
            resolution: 64,
            concavity: 0.01,
            max_parts: 32,
            parts: PartSource::Vhacd,
            thicken_m: 0.0,
        }
    }
}

/// Meshes with more triangles than this are simplified before VHACD (default 10,000): vertex
/// clustering ([`Mesh::clustered`]) on cells of the mesh's largest extent / [`DENSE_MESH_CELLS`],
/// and each part (and the base slab) reduced to its extreme points along
/// [`crate::physics::hull::HULL_DIRECTIONS`] directions. On a 2-million-triangle scan VHACD and its
/// exact hulls took 15 s and 650 MB and gave parts of up to 150,000 points; simplified, about a
/// second. The procedural library's meshes have at most 2,432 triangles (a vase), so their
/// decompositions are what they were; a 10 cm sphere subdivided 5 times (20,480 triangles) is
/// simplified.
pub const MAX_DECOMPOSITION_FACES: usize = 10_000;

/// A dense mesh is clustered on cells of its largest extent divided by this (default 128: about
/// 0.8 mm for a 10 cm object, half a voxel of VHACD's default 64 across), so the simplified mesh
/// is within `√3` cells of the mesh.
pub const DENSE_MESH_CELLS: f32 = 128.0;

/// The convex parts of library object `object`: [`decompose`] of its mesh, or, with
/// [`PartSource::Generator`] and an open object that carries its generator's parts, those parts
/// with the same base slab.
pub fn object_parts(object: &ObjectModel, config: &ShapeConfig) -> Vec<Vec<[f32; 3]>> {
    let mesh = &object.mesh;
    if config.parts == PartSource::Vhacd
        || object.parts.is_empty()
        || mesh_solid_fraction(mesh).is_some_and(|f| f >= SOLID_FRACTION)
    {
        return decompose(mesh, config);
    }
    let mut parts = object.parts.clone();
    if config.thicken_m > 0.0
        && let Some((lo, hi)) = mesh.bounds()
    {
        let axis = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        for part in &mut parts {
            thicken_towards(part, axis, config.thicken_m);
        }
    }
    add_base_slab(mesh, &mut parts, |base| base);
    parts
}

/// Adds to `part` each of its points moved `depth` towards the vertical line through `axis`
/// (stopping on it): the hull grows inward by `depth` and keeps its outside.
fn thicken_towards(part: &mut Vec<[f32; 3]>, axis: [f32; 2], depth: f32) {
    let n = part.len();
    for i in 0..n {
        let [x, y, z] = part[i];
        let (dx, dy) = (x - axis[0], y - axis[1]);
        let r = dx.hypot(dy);
        if r > 1e-6 {
            let k = (r - depth).max(0.0) / r;
            part.push([axis[0] + dx * k, axis[1] + dy * k, z]);
        }
    }
}

/// Adds the base slab to `parts` (see the module docs), its points passed through `points`:
/// only the slab reaches the bottom, the parts above it stop at its top face.
fn add_base_slab(
    mesh: &Mesh,
    parts: &mut Vec<Vec<[f32; 3]>>,
    points: impl FnOnce(Vec<[f32; 3]>) -> Vec<[f32; 3]>,
) {
    if let Some(base) = base_slab(mesh, BASE_SLAB_M) {
        let top = base.iter().map(|v| v[2]).fold(f32::NEG_INFINITY, f32::max);
        for part in parts.iter_mut() {
            for v in part.iter_mut() {
                v[2] = v[2].max(top);
            }
        }
        parts.push(points(base));
    }
}

/// The convex parts of `mesh` (point sets in the mesh frame) by VHACD, with a base slab (see the
/// module docs) — or, for a mesh that fills at least [`SOLID_FRACTION`] of its hull, one part:
/// all its vertices. A mesh of more than [`MAX_DECOMPOSITION_FACES`] triangles is simplified
/// first. A mesh VHACD fails on is one part too (the hull).
pub fn decompose(mesh: &Mesh, config: &ShapeConfig) -> Vec<Vec<[f32; 3]>> {
    if mesh_solid_fraction(mesh).is_some_and(|f| f >= SOLID_FRACTION) {
        // Nothing to keep open: one part, the hull.
        return vec![mesh.vertices.clone()];
    }
    let dense = mesh.triangles.len() > MAX_DECOMPOSITION_FACES;
    let simplified;
    let source = match mesh.bounds() {
        Some((lo, hi)) if dense => {
            let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
            simplified = mesh.clustered(extent / DENSE_MESH_CELLS);
            &simplified
        }
        _ => mesh,
    };
    let vertices: Vec<Vector> = source
        .vertices
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]))
        .collect();
    if vertices.len() < 4 || source.triangles.is_empty() {
        return Vec::new();
    }
    let params = VHACDParameters {
        resolution: config.resolution.clamp(16, 256),
        concavity: config.concavity,
        max_convex_hulls: config.max_parts.max(1),
        ..VHACDParameters::default()
    };
    // parry's VHACD unwraps a convex hull that can fail on some voxelisations (YCB's
    // `plate`, parry 0.31: "exiting an unfinished work"). A mesh it cannot cut is
    // one part, its hull, as a solid mesh is: a loaded file never ends the process, nor
    // prints a panic's backtrace in the middle of a run.
    let hulls = quietly(|| {
        VHACD::decompose(&params, &vertices, &source.triangles, true)
            .compute_exact_convex_hulls(&vertices, &source.triangles)
    });
    let Ok(hulls) = hulls else {
        return vec![mesh.vertices.clone()];
    };
    let reduce = |points: Vec<Vector>| -> Vec<[f32; 3]> {
        let points = if dense {
            extreme_points(&points, HULL_DIRECTIONS)
        } else {
            points
        };
        points.iter().map(|p| p.to_array()).collect()
    };
    let mut parts: Vec<Vec<[f32; 3]>> = hulls
        .into_iter()
        .map(|(points, _)| reduce(points))
        .collect();
    add_base_slab(mesh, &mut parts, |base| {
        if dense {
            reduce(base.iter().map(|p| Vector::from_array(*p)).collect())
        } else {
            base
        }
    });
    parts
}

/// Thickness of the base slab added to a decomposition (m).
const BASE_SLAB_M: f32 = 0.003;

/// The object's footprint as a slab `thickness` thick: the mesh vertices within `thickness` of
/// its lowest point, and the same lifted by `thickness`. VHACD splits a flat base (a bowl's
/// foot, a mug's bottom) into several parts that meet the table along slivers, and rapier keeps
/// such a body wobbling for ever; one flat part under them rests like a single hull does.
fn base_slab(mesh: &Mesh, thickness: f32) -> Option<Vec<[f32; 3]>> {
    let lowest = mesh
        .vertices
        .iter()
        .map(|v| v[2])
        .fold(f32::INFINITY, f32::min);
    let bottom: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .filter(|v| v[2] <= lowest + thickness)
        .copied()
        .collect();
    let (lo, hi) = bottom.iter().fold(
        ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]),
        |(lo, hi), v| {
            (
                [lo[0].min(v[0]), lo[1].min(v[1])],
                [hi[0].max(v[0]), hi[1].max(v[1])],
            )
        },
    );
    // A point or a sliver (an apple's tip, a lying cylinder's line) is no base.
    if !(hi[0] - lo[0] > 2.0 * thickness && hi[1] - lo[1] > 2.0 * thickness) {
        return None;
    }
    let lifted = bottom.iter().map(|v| [v[0], v[1], v[2] + thickness]);
    Some(bottom.iter().copied().chain(lifted).collect())
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
        let material = world.config().object.with_physics(&object.physics);
        return Ok(world
            .drop_object_with(name, &object.mesh, &material, region, rng)?
            .0);
    }
    let pose = region.sample_pose(&object.mesh, world.config().table.top_z_m(), rng);
    let handle = shapes.spawn(world, index, name, object, &pose)?;
    world.settle();
    Ok(handle)
}

/// The library's collider shapes, decomposed on first use (or ahead, in parallel, by
/// [`LibraryShapes::prepare`]), and their drawings.
#[derive(Debug, Clone)]
pub struct LibraryShapes {
    config: ShapeConfig,
    parts: Vec<Option<Vec<Vec<[f32; 3]>>>>,
    drawings: Vec<Option<Mesh>>,
}

impl LibraryShapes {
    /// Shapes for a library of `n` objects.
    pub fn new(config: ShapeConfig, n: usize) -> Self {
        Self {
            config,
            parts: vec![None; n],
            drawings: vec![None; n],
        }
    }

    /// Decomposes the library objects `indices` not decomposed yet, in parallel (VHACD takes
    /// 0.1–0.5 s an object). The parts are those [`LibraryShapes::spawn`] would compute.
    pub fn prepare(&mut self, library: &[ObjectModel], indices: &[usize]) {
        use rayon::prelude::*;
        if self.config.shape != ObjectShape::Decomposition {
            return;
        }
        if self.parts.len() < library.len() {
            self.parts.resize(library.len(), None);
        }
        let mut todo: Vec<usize> = indices
            .iter()
            .copied()
            .filter(|&i| i < library.len() && self.parts[i].is_none())
            .collect();
        todo.sort_unstable();
        todo.dedup();
        let config = &self.config;
        let done: Vec<(usize, Vec<Vec<[f32; 3]>>)> = todo
            .par_iter()
            .map(|&i| (i, object_parts(&library[i], config)))
            .collect();
        for (i, parts) in done {
            self.parts[i] = Some(parts);
        }
    }

    /// Single hulls for a library of `n` objects.
    pub fn hulls(n: usize) -> Self {
        Self::new(
            ShapeConfig {
                shape: ObjectShape::Hull,
                ..ShapeConfig::default()
            },
            n,
        )
    }

    /// The config.
    pub fn config(&self) -> &ShapeConfig {
        &self.config
    }

    /// Builds the collider of every library object `indices` names (once each) in a scratch
    /// world of `world`: a mesh whose hull or parts cannot be built fails here, naming the
    /// object, instead of when its round comes.
    pub fn check(
        &mut self,
        world: &WorldConfig,
        library: &[ObjectModel],
        indices: &[usize],
    ) -> Result<(), WorldError> {
        let mut scratch = World::new(world.clone())?;
        let [x, y, _] = world.table.center_m;
        let pose = lgdm_pointcloud::math::translation([x, y, world.table.top_z_m()]);
        let mut todo: Vec<usize> = indices
            .iter()
            .copied()
            .filter(|&i| i < library.len())
            .collect();
        todo.sort_unstable();
        todo.dedup();
        for i in todo {
            let object = &library[i];
            let h = self.spawn(&mut scratch, i, &object.name, object, &pose)?;
            scratch.remove_object(h)?;
        }
        Ok(())
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
        let material = world.config().object.with_physics(&object.physics);
        let handle = match self.config.shape {
            ObjectShape::Hull => world.spawn_object_with(name, &object.mesh, pose, &material)?,
            ObjectShape::Decomposition => {
                if self.parts.len() <= index {
                    self.parts.resize(index + 1, None);
                }
                let parts =
                    self.parts[index].get_or_insert_with(|| object_parts(object, &self.config));
                world.spawn_object_parts(name, &object.mesh, parts, pose, &material)?
            }
        };
        // The collider's drawing depends on the library object only: build it once per run.
        if self.drawings.len() <= index {
            self.drawings.resize(index + 1, None);
        }
        match &self.drawings[index] {
            Some(drawing) => world.set_object_collider_mesh(handle, drawing.clone())?,
            None => self.drawings[index] = Some(world.object_collider_mesh(handle)?.clone()),
        }
        Ok(handle)
    }
}

thread_local! {
    /// Set while [`quietly`] runs its closure on this thread.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`, catching a panic, without the panic hook printing it: the hook installed once
/// here stays silent on a thread inside `quietly` and hands every other panic to the hook that
/// was there before.
fn quietly<R>(f: impl FnOnce() -> R + std::panic::UnwindSafe) -> std::thread::Result<R> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let before = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(std::cell::Cell::get) {
                before(info);
            }
        }));
    });
    QUIET.with(|q| q.set(true));
    let out = std::panic::catch_unwind(f);
    QUIET.with(|q| q.set(false));
    out
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_panic_inside_quietly_is_caught_and_the_thread_goes_on() {
        assert!(super::quietly(|| panic!("parry gave up")).is_err());
        assert_eq!(super::quietly(|| 7).unwrap(), 7);
        assert!(
            !super::QUIET.with(std::cell::Cell::get),
            "the flag is cleared"
        );
    }

    use crate::physics::config::WorldConfig;
    use crate::physics::hull::{SOLID_FRACTION, mesh_solid_fraction};
    use crate::physics::world::World;
    use lgdm_pointcloud::math::translation;
    use lgdm_pointcloud::objects::procedural_object;

    /// With `parts = "generator"` an open procedural object is its generator's exact parts and
    /// a base slab, a closed one stays one hull, and the default is VHACD's decomposition.
    #[test]
    fn generator_parts_replace_vhacd_only_where_asked_and_open() {
        use lgdm_pointcloud::objects::procedural_library;
        let library = procedural_library(&["glass", "can"], 1, 0).unwrap();
        let (glass, can) = (&library[0], &library[1]);
        let vhacd = super::ShapeConfig::default();
        let generator = super::ShapeConfig {
            parts: super::PartSource::Generator,
            ..vhacd.clone()
        };
        assert_eq!(
            super::object_parts(glass, &vhacd),
            super::decompose(&glass.mesh, &vhacd)
        );
        // The glass: its base revolved whole, 32 wall pieces, the slab.
        assert_eq!(glass.parts.len(), 33);
        assert_eq!(super::object_parts(glass, &generator).len(), 34);
        assert_eq!(super::object_parts(can, &generator).len(), 1);
        // The parts build a body.
        let mut world = World::new(WorldConfig::default()).unwrap();
        let parts = super::object_parts(glass, &generator);
        let pose = translation([0.0, 0.0, 0.8]);
        world
            .spawn_object_parts(
                "glass",
                &glass.mesh,
                &parts,
                &pose,
                &world.config().object.clone(),
            )
            .unwrap();
    }

    /// `thicken_m` grows a glass's wall pieces inward and leaves their outside and the base
    /// revolved whole as they were; a bad value is refused, naming the field.
    #[test]
    fn thickened_walls_grow_inward_only() {
        use lgdm_pointcloud::objects::procedural_library;
        let library = procedural_library(&["glass"], 1, 0).unwrap();
        let glass = &library[0];
        let exact = super::ShapeConfig {
            parts: super::PartSource::Generator,
            ..super::ShapeConfig::default()
        };
        let thick = super::ShapeConfig {
            thicken_m: 0.004,
            ..exact.clone()
        };
        let (a, b) = (
            super::object_parts(glass, &exact),
            super::object_parts(glass, &thick),
        );
        assert_eq!(a.len(), b.len());
        let (lo, hi) = glass.mesh.bounds().unwrap();
        let axis = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let radii = |part: &[[f32; 3]]| {
            part.iter()
                .map(|p| (p[0] - axis[0]).hypot(p[1] - axis[1]))
                .fold((f32::INFINITY, 0.0f32), |(lo, hi), r| {
                    (lo.min(r), hi.max(r))
                })
        };
        let mut grown = 0;
        for (pa, pb) in a.iter().zip(&b) {
            let ((ia, oa), (ib, ob)) = (radii(pa), radii(pb));
            assert!((oa - ob).abs() < 1e-6, "the outside stays: {oa} {ob}");
            if ia > 0.004 {
                assert!((ia - ib - 0.004).abs() < 1e-5, "inner {ia} -> {ib}");
                grown += 1;
            } else {
                assert!(ib >= 0.0 && ib <= ia);
            }
        }
        assert_eq!(grown, 32, "the 32 wall pieces");
        for bad in [-0.001, f32::NAN, 0.2] {
            let config = super::ShapeConfig {
                thicken_m: bad,
                ..exact.clone()
            };
            let e = config.validate().unwrap_err().to_string();
            assert!(e.contains("shapes.thicken_m"), "{e}");
        }
        assert!(thick.validate().is_ok());
    }

    /// Closed meshes fill their hulls and are one part; open ones are decomposed.
    #[test]
    fn closed_meshes_are_one_hull_and_open_ones_parts() {
        let config = super::ShapeConfig::default();
        for (category, closed) in [
            ("can", true),
            ("apple", true),
            ("book", true),
            ("cereal_box", true),
            ("mug", false),
            ("bowl", false),
            ("glass", false),
            ("teapot", false),
        ] {
            let mesh = procedural_object(category, 0, 1).unwrap();
            let f = mesh_solid_fraction(&mesh).unwrap();
            assert_eq!(
                f >= SOLID_FRACTION,
                closed,
                "{category}: fills {f} of its hull"
            );
            let parts = super::decompose(&mesh, &config);
            assert_eq!(
                parts.len() == 1,
                closed,
                "{category}: {} parts",
                parts.len()
            );
            if closed {
                assert_eq!(parts[0], mesh.vertices, "{category}");
            }
        }
    }

    /// The simplified hulls keep the meshes' extents: along 16 horizontal directions and
    /// vertically, the hull's support is within 4 mm of the mesh's, and no face has more than
    /// `max_face_vertices` vertices.
    #[test]
    fn thinned_hulls_stay_close_to_the_meshes() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let max_face = world.config().max_face_vertices as usize;
        for (i, category) in lgdm_pointcloud::objects::CATEGORIES.iter().enumerate() {
            for instance in 0..2 {
                let mesh =
                    lgdm_pointcloud::objects::procedural_object(category, instance, 5).unwrap();
                let at = translation([0.6 * (i as f32 / 10.0 - 0.5), -0.6, 1.5]);
                let h = world.spawn_object(category, &mesh, &at).unwrap();
                let hull = world.object_hull_points_m(h).unwrap();
                let mut dirs: Vec<[f32; 3]> = (0..16)
                    .map(|k| {
                        let a = k as f32 * std::f32::consts::TAU / 16.0;
                        [a.cos(), a.sin(), 0.0]
                    })
                    .collect();
                dirs.extend([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]);
                for d in dirs {
                    let support = |pts: &mut dyn Iterator<Item = [f32; 3]>| {
                        pts.map(|p| p[0] * d[0] + p[1] * d[1] + p[2] * d[2])
                            .fold(f32::NEG_INFINITY, f32::max)
                    };
                    let from_mesh = support(&mut mesh.vertices.iter().copied());
                    let from_hull = support(&mut hull.iter().copied());
                    assert!(
                        from_hull <= from_mesh + 1e-5 && from_mesh - from_hull < 4e-3,
                        "{category} {instance} along {d:?}: mesh {from_mesh} hull {from_hull}"
                    );
                }
                let collider = world.object_collider(h).unwrap();
                let shape = world.physics.colliders[collider].shape();
                let poly = shape.as_convex_polyhedron().unwrap();
                assert!(
                    poly.faces()
                        .iter()
                        .all(|f| f.num_vertices_or_edges as usize <= max_face),
                    "{category} {instance}"
                );
            }
        }
    }
}
