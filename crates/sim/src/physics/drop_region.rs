//! Where and how objects are dropped on the table ([`DropRegion`]): a uniform position in the
//! region, upright with a uniform yaw or tumbled to a uniform orientation.

use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::mesh::Mesh;
use nalgebra::{Quaternion, Rotation3, Translation3, UnitQuaternion};
use rand::RngExt;
use serde::{Deserialize, Serialize};

/// Where and how [`World::drop_object`](crate::physics::world::World::drop_object) drops an object.
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
