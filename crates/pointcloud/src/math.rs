//! Small 3D helpers on `[f32; 3]` vectors and a rigid [`Pose`] (rotation + translation).
//!
//! Lengths are metres and angles radians throughout the crate.
//!
//! ```
//! use lgdm_pointcloud::math::Pose;
//! let world_from_object = Pose::rotation_z(std::f32::consts::FRAC_PI_2);
//! let p = world_from_object.apply([1.0, 0.0, 0.0]);
//! assert!((p[1] - 1.0).abs() < 1e-6);
//! ```

use serde::{Deserialize, Serialize};

/// `a + b`.
#[inline]
pub fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a - b`.
#[inline]
pub fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a * s`.
#[inline]
pub fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product.
#[inline]
pub fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product.
#[inline]
pub fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Euclidean length.
#[inline]
pub fn norm(a: [f32; 3]) -> f32 {
    dot(a, a).sqrt()
}

/// `a / |a|`, or `a` unchanged when its length is zero.
#[inline]
pub fn normalize(a: [f32; 3]) -> [f32; 3] {
    let n = norm(a);
    if n > 0.0 { scale(a, 1.0 / n) } else { a }
}

/// A rigid transform `target_from_source`: `p_target = rotation · p_source + translation`.
///
/// Name variables after the frames they map between (`world_from_object`,
/// `camera_from_world`), so that compositions read right to left.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Row-major 3×3 rotation matrix.
    pub rotation: [[f32; 3]; 3],
    /// Translation in metres.
    pub translation: [f32; 3],
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// The identity transform.
    pub const IDENTITY: Pose = Pose {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0, 0.0, 0.0],
    };

    /// A pure translation.
    pub fn translation(t: [f32; 3]) -> Pose {
        Pose {
            translation: t,
            ..Pose::IDENTITY
        }
    }

    /// Rotation by `angle` (radians, right-handed) about the z axis.
    pub fn rotation_z(angle: f32) -> Pose {
        let (s, c) = angle.sin_cos();
        Pose {
            rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        }
    }

    /// Rotation by `angle` (radians, right-handed) about a unit `axis` (Rodrigues).
    pub fn rotation_axis_angle(axis: [f32; 3], angle: f32) -> Pose {
        let [x, y, z] = normalize(axis);
        let (s, c) = angle.sin_cos();
        let t = 1.0 - c;
        Pose {
            rotation: [
                [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
            ],
            translation: [0.0; 3],
        }
    }

    /// Uniform scaling is not rigid; this builds the rotation-free "pose" `p ↦ s·p` that the
    /// mesh transforms accept for convenience.
    pub fn uniform_scale(s: f32) -> Pose {
        Pose {
            rotation: [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]],
            translation: [0.0; 3],
        }
    }

    /// Applies the transform to a point.
    #[inline]
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        add(self.rotate(p), self.translation)
    }

    /// Applies only the rotation (for directions and normals).
    #[inline]
    pub fn rotate(&self, v: [f32; 3]) -> [f32; 3] {
        let r = &self.rotation;
        [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
    }

    /// `self ∘ other`: first `other`, then `self` (`a_from_c = a_from_b.then(b_from_c)` is
    /// written `a_from_b.compose(&b_from_c)`).
    pub fn compose(&self, other: &Pose) -> Pose {
        let a = &self.rotation;
        let b = &other.rotation;
        let mut rotation = [[0.0f32; 3]; 3];
        for (i, row) in rotation.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
            }
        }
        Pose {
            rotation,
            translation: self.apply(other.translation),
        }
    }

    /// The inverse of a rigid transform (rotation transposed).
    pub fn inverse(&self) -> Pose {
        let r = &self.rotation;
        let rotation = [
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ];
        let t = self.translation;
        let inv = Pose {
            rotation,
            translation: [0.0; 3],
        };
        let rt = inv.rotate(t);
        Pose {
            rotation,
            translation: [-rt[0], -rt[1], -rt[2]],
        }
    }

    /// A camera pose `world_from_camera` for a camera at `eye` looking at `target`, in the
    /// optical convention (x right, y down, z forward). `up` is the world's up direction.
    pub fn look_at(eye: [f32; 3], target: [f32; 3], up: [f32; 3]) -> Pose {
        let forward = normalize(sub(target, eye));
        let mut right = cross(forward, up);
        if norm(right) < 1e-6 {
            // Looking straight along `up`: pick any perpendicular right direction.
            right = cross(forward, [0.0, 1.0, 0.0]);
            if norm(right) < 1e-6 {
                right = [1.0, 0.0, 0.0];
            }
        }
        let right = normalize(right);
        let down = cross(forward, right);
        // Columns of world_from_camera are the camera axes in world coordinates.
        Pose {
            rotation: [
                [right[0], down[0], forward[0]],
                [right[1], down[1], forward[1]],
                [right[2], down[2], forward[2]],
            ],
            translation: eye,
        }
    }
}

/// SplitMix64 step: mixes a 64-bit value into a well-distributed one (used to derive
/// independent per-stream seeds from the dataset seed).
pub fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Derives a seed for a named stream (`tag`) and indices from a base seed.
pub fn derive_seed(seed: u64, tag: u64, a: u64, b: u64) -> u64 {
    splitmix64(
        splitmix64(splitmix64(seed ^ splitmix64(tag)) ^ a) ^ b.wrapping_mul(0x2545_F491_4F6C_DD1D),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-5)
    }

    #[test]
    fn inverse_undoes_pose() {
        let p = Pose::rotation_axis_angle([1.0, 2.0, 0.5], 0.7)
            .compose(&Pose::translation([0.1, -0.2, 0.3]));
        let q = [0.3, 0.4, -0.5];
        assert!(close(p.inverse().apply(p.apply(q)), q));
    }

    #[test]
    fn look_at_points_z_to_target() {
        let world_from_camera = Pose::look_at([0.0, -1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let camera_from_world = world_from_camera.inverse();
        let t = camera_from_world.apply([0.0, 0.0, 0.0]);
        assert!(t[0].abs() < 1e-6 && t[1].abs() < 1e-6);
        assert!((t[2] - 2f32.sqrt()).abs() < 1e-5);
        // World up appears as negative y (image up) in the optical frame.
        let up = camera_from_world.rotate([0.0, 0.0, 1.0]);
        assert!(up[1] < 0.0);
    }
}
