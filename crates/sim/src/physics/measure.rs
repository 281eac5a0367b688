//! Measures of an object in the world that say whether a top-down grasp can take it at all: its
//! narrowest horizontal width ([`narrowest_width_m`]: what jaws around the whole object must open
//! to) and how solid it is ([`solid_fraction`]); an object wider than the stroke and solid is
//! `wider_than_gripper`, not `no_grasp_found`.

use lgdm_pointcloud::math::transform_point;

use crate::physics::hull::mesh_solid_fraction;
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;

/// Directions (about world z) at which [`narrowest_width_m`] measures: every degree of a half
/// turn.
const WIDTH_DIRECTIONS: usize = 180;

/// The narrowest horizontal width of a point set (m): the least, over the jaws' directions
/// about world z, of its extent along that direction.
fn narrowest_width(points: &[[f32; 3]]) -> Option<f32> {
    if points.is_empty() {
        return None;
    }
    (0..WIDTH_DIRECTIONS)
        .map(|k| {
            let a = std::f32::consts::PI * k as f32 / WIDTH_DIRECTIONS as f32;
            let (s, c) = a.sin_cos();
            let (lo, hi) = points.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                let d = p[0] * c + p[1] * s;
                (lo.min(d), hi.max(d))
            });
            hi - lo
        })
        .reduce(f32::min)
}

/// The narrowest horizontal width of the object's collider (m): the least, over the jaws'
/// directions about world z, of its extent along that direction — what a top-down parallel
/// grasp around the whole object must open to.
pub fn narrowest_width_m(world: &World, object: ObjectHandle) -> Option<f32> {
    let pose = world.object_pose(object).ok()?;
    let points: Vec<[f32; 3]> = world
        .object_hull_points_m(object)
        .ok()?
        .into_iter()
        .map(|p| transform_point(&pose, p))
        .collect();
    narrowest_width(&points)
}

/// The share of its convex hull's volume the object's mesh encloses, when the mesh encloses a
/// volume (a closed mesh): [`mesh_solid_fraction`] of its mesh (solid from
/// [`crate::physics::hull::SOLID_FRACTION`] on).
pub fn solid_fraction(world: &World, object: ObjectHandle) -> Option<f32> {
    mesh_solid_fraction(world.object_mesh(object).ok()?)
}
