//! Convex hulls as the physics' colliders, with their big flat faces thinned: every hull a
//! [`crate::physics::world::World`] builds — a single hull or each part of a decomposition
//! ([`crate::physics::shapes`]) — has faces of more than
//! [`crate::physics::config::WorldConfig::max_face_vertices`] vertices thinned by farthest-point
//! sampling: an upright can whose base is a 32-gon otherwise rocks until it topples. Pure geometry;
//! the world and the shapes both build on it.
//!
//! Dense meshes (scans, finely subdivided models) need one more step. parry's convex polyhedron
//! merges adjacent hull triangles whose normals differ by less than about 1.5° (`1 − √ε` of
//! f32), and it merges transitively: on a surface tessellated that finely (a 10 cm sphere of
//! 20,480 triangles) the merged "faces" are no longer flat, and the polyhedron is broken — its
//! volume comes out as zero, the object is refused as flat, and a decomposition's parts are
//! dropped. So an input of more than [`MAX_HULL_POINTS`] distinct points is first reduced to its
//! [`extreme_points`] along [`HULL_DIRECTIONS`] fixed directions, whose hull is within a
//! millimetre or so of the full one and keeps its neighbouring faces apart; and a hull of fewer
//! points that comes out broken (its volume off by more than [`HULL_VOLUME_TOLERANCE`], or a
//! face bent by more than [`HULL_FACE_BEND`]) is rebuilt from its extreme points too. No
//! procedural library object comes near either case (at most 1,262 distinct points, volumes within
//! 7.4 %, faces bent by at most 0.15), so their colliders are what they were.

use lgdm_pointcloud::mesh::Mesh;
use rapier3d::math::Vector;
use rapier3d::parry::mass_properties::MassProperties;
use rapier3d::parry::shape::ConvexPolyhedron;
use rapier3d::parry::transformation::try_convex_hull;
use rapier3d::prelude::SharedShape;

/// Hull inputs with more distinct points than this are reduced to their [`extreme_points`]
/// along [`HULL_DIRECTIONS`] directions before the hull is built (default 4,096). The
/// procedural library's meshes have at most 1,262 distinct vertices (a vase; 7,296 with
/// repeats), and a decomposition's part no more than twice its mesh's; a 10 cm sphere
/// subdivided 4 times has 2,562 (its full hull builds), 5 times 10,242 (its full hull is broken).
pub const MAX_HULL_POINTS: usize = 4096;

/// Directions along which a reduced hull keeps its extreme points (a Fibonacci sphere; default
/// 256), about 13° apart: the reduced hull of a 10 cm sphere is within 0.5 mm of it, of a 30 cm
/// one within 1.5 mm. 512 would be closer, but along a sharp rim (a dense cylinder's) the
/// extreme points then come less than 1.5° apart and parry merges the side faces again.
pub const HULL_DIRECTIONS: usize = 256;

/// A hull counts as broken when the volume of parry's polyhedron differs from the volume of
/// the hull's triangles by more than this fraction (default 0.5). Merging nearly coplanar
/// triangles into one face is benign when the face stays nearly flat — the procedural objects'
/// hulls and parts, thinning rounds included, are within 7.4 % (200 objects: seeds 0–3, 5
/// instances) — while a broken merge can lose all of the volume.
pub const HULL_VOLUME_TOLERANCE: f32 = 0.5;

/// A hull also counts as broken when one of its faces bends by more than this (default 0.5): the
/// largest distance of the face's vertices from its plane over their largest distance from its
/// first vertex. A chain of merges around a finely turned can makes its whole side one "face"
/// (a bend near 1) whose volume happens to come out about right; the procedural objects' merged
/// faces bend by at most 0.15 (the same 200 objects).
pub const HULL_FACE_BEND: f32 = 0.5;

/// Below this share of its hull's volume an object is hollow or open (a bowl, a mug, a
/// teapot with its handle, a clamp): a grasp can take a wall, a rim or a handle, so its overall
/// width says nothing about whether the gripper can take it, and one hull would fill what the
/// fingers need. A closed can, a box or a fruit fills its hull (0.84–1.0 on the procedural and
/// the paper's objects; the open ones 0.14–0.79).
pub const SOLID_FRACTION: f32 = 0.8;

/// The share of its convex hull's volume `mesh` encloses, when it encloses a volume (a closed
/// mesh). A mesh of more than [`MAX_HULL_POINTS`] vertices is measured against the hull of its
/// [`extreme_points`].
pub fn mesh_solid_fraction(mesh: &Mesh) -> Option<f32> {
    let vertices: Vec<Vector> = mesh
        .vertices
        .iter()
        .map(|v| Vector::from_array(*v))
        .collect();
    let mesh_volume = MassProperties::from_trimesh(1.0, &vertices, &mesh.triangles).mass();
    let points = if vertices.len() > MAX_HULL_POINTS {
        extreme_points(&vertices, HULL_DIRECTIONS)
    } else {
        vertices
    };
    let (hull, triangles) = try_convex_hull(&points).ok()?;
    let hull_volume = MassProperties::from_trimesh(1.0, &hull, &triangles).mass();
    let f = mesh_volume / hull_volume;
    (f.is_finite() && f > 0.0 && f <= 1.5).then_some(f)
}

/// The convex hull of `points` with faces of more than `max_face` vertices thinned (up to three
/// rounds; a round whose hull cannot be built keeps the previous one); `None` when the points have
/// no hull. Every collider [`crate::physics::world::World`] builds goes through here (see
/// [`crate::physics::config::WorldConfig::max_face_vertices`] for why). Dense inputs are reduced
/// first (see the module docs).
pub(crate) fn thinned_hull(points: &[Vector], max_face: usize) -> Option<SharedShape> {
    let mut shape = hull(points)?;
    for _ in 0..3 {
        let Some(kept) = shape
            .as_convex_polyhedron()
            .and_then(|h| thin_big_faces(h, max_face))
        else {
            break;
        };
        match checked_hull(&kept) {
            Some(thinner) => shape = SharedShape::new(thinner),
            None => break,
        }
    }
    Some(shape)
}

/// parry's convex polyhedron of `points`: of the points themselves when they are at most
/// [`MAX_HULL_POINTS`] distinct ones and their hull is not broken, else of their
/// [`extreme_points`] along [`HULL_DIRECTIONS`] directions (a quarter and a sixteenth of them
/// when that hull is broken too); `None` when none builds.
fn hull(points: &[Vector]) -> Option<SharedShape> {
    let dense = points.len() > MAX_HULL_POINTS && distinct_count(points) > MAX_HULL_POINTS;
    if !dense && let Some(h) = checked_hull(points) {
        return Some(SharedShape::new(h));
    }
    [HULL_DIRECTIONS, HULL_DIRECTIONS / 4, HULL_DIRECTIONS / 16]
        .into_iter()
        .find_map(|count| checked_hull(&extreme_points(points, count)))
        .map(SharedShape::new)
}

/// parry's convex polyhedron of `points` (the one [`SharedShape::convex_hull`] builds), `None`
/// when it cannot be built or is broken ([`HULL_VOLUME_TOLERANCE`], [`HULL_FACE_BEND`]).
fn checked_hull(points: &[Vector]) -> Option<ConvexPolyhedron> {
    let (polyhedron, defects) = hull_with_defects(points)?;
    let broken = defects.volume_error > HULL_VOLUME_TOLERANCE || defects.bend > HULL_FACE_BEND;
    (!broken).then_some(polyhedron)
}

/// How far parry's polyhedron is from the triangles of the hull it was built from.
#[derive(Debug, Clone, Copy)]
struct Defects {
    /// |polyhedron's volume / triangles' volume − 1|; 0 when the hull is flat (no volume either
    /// way: the callers refuse it).
    volume_error: f32,
    /// The largest bend of a face (see [`HULL_FACE_BEND`]).
    bend: f32,
}

/// parry's convex polyhedron of `points` and its [`Defects`]; `None` when it cannot be built.
fn hull_with_defects(points: &[Vector]) -> Option<(ConvexPolyhedron, Defects)> {
    let (vertices, triangles) = try_convex_hull(points).ok()?;
    let exact = MassProperties::from_trimesh(1.0, &vertices, &triangles).mass();
    let polyhedron = ConvexPolyhedron::from_convex_mesh(vertices, &triangles)?;
    let (faces, face_triangles) = polyhedron.to_trimesh();
    let volume = MassProperties::from_trimesh(1.0, &faces, &face_triangles).mass();
    let volume_error = if exact > 0.0 {
        (volume / exact - 1.0).abs()
    } else {
        0.0
    };
    let points = polyhedron.points();
    let adjacency = polyhedron.vertices_adj_to_face();
    let mut bend = 0.0f32;
    for face in polyhedron.faces() {
        let first = face.first_vertex_or_edge as usize;
        let ids = &adjacency[first..first + face.num_vertices_or_edges as usize];
        let origin = points[ids[0] as usize];
        let (mut off_plane, mut size) = (0.0f32, 0.0f32);
        for &i in &ids[1..] {
            let d = points[i as usize] - origin;
            off_plane = off_plane.max(face.normal.dot(d).abs());
            size = size.max(d.length());
        }
        if size > 0.0 {
            bend = bend.max(off_plane / size);
        }
    }
    let defects = Defects { volume_error, bend };
    Some((polyhedron, defects))
}

/// How many different points `points` holds (bitwise).
fn distinct_count(points: &[Vector]) -> usize {
    let mut keys: Vec<[u32; 3]> = points
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    keys.len()
}

/// `count` unit directions spread evenly over the sphere (a Fibonacci lattice), as three
/// coordinate arrays.
fn directions(count: usize) -> [Vec<f32>; 3] {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut out = [
        Vec::with_capacity(count),
        Vec::with_capacity(count),
        Vec::with_capacity(count),
    ];
    for i in 0..count {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
        let r = (1.0 - z * z).sqrt();
        let a = golden * i as f64;
        out[0].push((r * a.cos()) as f32);
        out[1].push((r * a.sin()) as f32);
        out[2].push(z as f32);
    }
    out
}

/// The points of `points` that lie farthest along at least one of `count` fixed directions (a
/// Fibonacci sphere), each once, in input order (ties: the first such point). Their hull lies
/// inside the points' hull and approaches it as `count` grows: along any direction it is short
/// by at most `R·(1 − cos α)`, `R` the points' radius and `α` the largest angle to the nearest
/// of the directions, and a smooth surface loses far less. Deterministic; O(points × count).
///
/// ```
/// use lgdm_sim::physics::hull::extreme_points;
/// use rapier3d::math::Vector;
/// let cube: Vec<Vector> = (0..1000)
///     .map(|i| Vector::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32))
///     .collect();
/// assert_eq!(extreme_points(&cube, 256).len(), 8); // the corners
/// ```
pub fn extreme_points(points: &[Vector], count: usize) -> Vec<Vector> {
    if points.len() > u32::MAX as usize {
        let candidates: Vec<Vector> = points
            .chunks(u32::MAX as usize)
            .flat_map(|chunk| extreme_points(chunk, count))
            .collect();
        return extreme_points(&candidates, count);
    }
    let [dx, dy, dz] = directions(count);
    let mut best = vec![f32::NEG_INFINITY; count];
    let mut arg = vec![u32::MAX; count];
    for (i, p) in points.iter().enumerate() {
        let i = i as u32;
        for ((((b, a), x), y), z) in best.iter_mut().zip(&mut arg).zip(&dx).zip(&dy).zip(&dz) {
            let d = x * p.x + y * p.y + z * p.z;
            let better = d > *b;
            *b = if better { d } else { *b };
            *a = if better { i } else { *a };
        }
    }
    let mut kept: Vec<u32> = arg.into_iter().filter(|&i| i != u32::MAX).collect();
    kept.sort_unstable();
    kept.dedup();
    kept.into_iter().map(|i| points[i as usize]).collect()
}

/// The hull's points without the surplus vertices of faces that have more than `max_face`:
/// `None` when no face is that big. The vertices a big face keeps are spread by farthest-point
/// sampling from its first vertex (deterministic).
fn thin_big_faces(hull: &ConvexPolyhedron, max_face: usize) -> Option<Vec<Vector>> {
    let points = hull.points();
    let adjacency = hull.vertices_adj_to_face();
    let mut drop = vec![false; points.len()];
    let mut any = false;
    for face in hull.faces() {
        let first = face.first_vertex_or_edge as usize;
        let count = face.num_vertices_or_edges as usize;
        if count <= max_face {
            continue;
        }
        any = true;
        let ids: Vec<usize> = adjacency[first..first + count]
            .iter()
            .map(|&i| i as usize)
            .collect();
        let mut kept = vec![false; count];
        kept[0] = true;
        let mut nearest: Vec<f32> = ids
            .iter()
            .map(|&i| points[i].distance_squared(points[ids[0]]))
            .collect();
        for _ in 1..max_face {
            let (next, _) = nearest
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
                .expect("a big face has vertices");
            kept[next] = true;
            let p = points[ids[next]];
            for (d, &i) in nearest.iter_mut().zip(&ids) {
                *d = d.min(points[i].distance_squared(p));
            }
        }
        for (k, &i) in ids.iter().enumerate() {
            if !kept[k] {
                drop[i] = true;
            }
        }
    }
    any.then(|| {
        points
            .iter()
            .zip(&drop)
            .filter(|(_, d)| !**d)
            .map(|(p, _)| *p)
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;
    use crate::physics::shapes::{ShapeConfig, decompose};
    use lgdm_pointcloud::objects::{CATEGORIES, procedural_library};

    /// The worst defects and the most distinct points over every hull [`thinned_hull`] builds
    /// for `points` (the first and each thinning round), built as before the reduction existed.
    /// `None` when the points have no hull (a part the world skips).
    fn worst_without_reduction(points: &[Vector], max_face: usize) -> Option<(usize, Defects)> {
        let (mut hull, mut worst) = hull_with_defects(points)?;
        let distinct = distinct_count(points);
        for _ in 0..3 {
            let Some(kept) = thin_big_faces(&hull, max_face) else {
                break;
            };
            let Some((thinner, defects)) = hull_with_defects(&kept) else {
                break;
            };
            worst.volume_error = worst.volume_error.max(defects.volume_error);
            worst.bend = worst.bend.max(defects.bend);
            hull = thinner;
        }
        Some((distinct, worst))
    }

    /// No procedural library object's hull or part is reduced or rebuilt: each has at most
    /// 1,262 distinct points (under a third of [`MAX_HULL_POINTS`]), and the hulls built from
    /// all its points, in every thinning round, are far from broken (a fifth of
    /// [`HULL_VOLUME_TOLERANCE`], a third of [`HULL_FACE_BEND`]) — so the colliders of today's
    /// runs are the ones they always were. (Over 200 objects, seeds 0–3 with 5 instances: 1,262
    /// points, volumes within 7.4 %, bends up to 0.15.)
    #[test]
    fn procedural_objects_are_never_reduced() {
        let max_face = WorldConfig::default().max_face_vertices as usize;
        let library = procedural_library(&CATEGORIES, 2, 0).unwrap();
        let mut most = 0usize;
        let (mut volume_error, mut bend) = (0.0f32, 0.0f32);
        for object in &library {
            let mesh_points: Vec<Vector> = object
                .mesh
                .vertices
                .iter()
                .map(|v| Vector::from_array(*v))
                .collect();
            let parts = decompose(&object.mesh, &ShapeConfig::default());
            let inputs = std::iter::once(mesh_points).chain(
                parts
                    .iter()
                    .map(|p| p.iter().map(|v| Vector::from_array(*v)).collect()),
            );
            for points in inputs {
                let Some((distinct, worst)) = worst_without_reduction(&points, max_face) else {
                    continue;
                };
                most = most.max(distinct);
                volume_error = volume_error.max(worst.volume_error);
                bend = bend.max(worst.bend);
            }
        }
        assert!(most <= 1262, "{most} distinct points");
        assert!(
            volume_error < HULL_VOLUME_TOLERANCE / 5.0,
            "volume error {volume_error}"
        );
        assert!(bend < HULL_FACE_BEND / 3.0, "bend {bend}");
    }
}
