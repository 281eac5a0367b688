//! Small 3D helpers on `[f32; 3]` vectors (the crate's points, vertices and normals), rigid
//! poses ([`Pose`], nalgebra's `IsometryMatrix3<f32>`) with the constructors the renderer
//! needs, and seed derivation.
//!
//! Lengths are metres and angles radians throughout the crate.
//!
//! ```
//! use lgdm_pointcloud::math::{rotation_z, transform_point, translation};
//! let world_from_object = translation([0.0, 0.0, 0.5]) * rotation_z(std::f32::consts::FRAC_PI_2);
//! let p = transform_point(&world_from_object, [1.0, 0.0, 0.0]);
//! assert!((p[1] - 1.0).abs() < 1e-6 && (p[2] - 0.5).abs() < 1e-6);
//! let back = transform_point(&world_from_object.inverse(), p);
//! assert!((back[0] - 1.0).abs() < 1e-6);
//! ```

use nalgebra::{IsometryMatrix3, Matrix3, Point3, Rotation3, Translation3, Vector3};

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

/// The median of `values` (sorted in place by [`f32::total_cmp`]; the mean of the middle two
/// when their count is even); `None` when there are none. The one median of depth windows and
/// height maps (a grasp's centre depth, the top at a grasp centre).
pub fn median(values: &mut [f32]) -> Option<f32> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    values.sort_unstable_by(f32::total_cmp);
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    })
}

/// A rigid transform `target_from_source`: `p_target = rotation · p_source + translation`,
/// nalgebra's [`IsometryMatrix3`] (the rotation is a 3×3 matrix, not a quaternion, so that
/// rotating a point rounds exactly as the row-by-row dot products the datasets were made with).
///
/// Name variables after the frames they map between (`world_from_object`,
/// `camera_from_world`), so that compositions read right to left:
/// `a_from_c = a_from_b * b_from_c`. Build poses with [`translation`], [`rotation_z`],
/// [`rotation_axis_angle`] and [`look_at`]; apply them to `[f32; 3]` points with
/// [`transform_point`] and to directions with [`rotate_vector`]. In JSON a pose is
/// `{"rotation": [[row 0], [row 1], [row 2]], "translation": [x, y, z]}` ([`pose_serde`]).
///
/// nalgebra's products give the same floats as the hand-written row-major code they replace
/// (matrix × vector and matrix × matrix accumulate `m[i][0]·v[0] + m[i][1]·v[1] + m[i][2]·v[2]`
/// left to right, adding the translation last); [`Pose::inverse`] computes `Rᵀ·(−t)` where
/// the old code computed `−(Rᵀ·t)`, which can differ only in the sign of an exactly-zero
/// translation component. The unit tests below check both against a copy of the old code.
pub type Pose = IsometryMatrix3<f32>;

/// A pure translation by `t` metres.
pub fn translation(t: [f32; 3]) -> Pose {
    Pose::translation(t[0], t[1], t[2])
}

/// A pose with rotation matrix `rows` (row-major) and translation `t`; the rotation is not
/// checked for orthonormality.
pub fn pose_from_rows(rows: [[f32; 3]; 3], t: [f32; 3]) -> Pose {
    let [r0, r1, r2] = rows;
    Pose::from_parts(
        Translation3::from(t),
        Rotation3::from_matrix_unchecked(Matrix3::new(
            r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2],
        )),
    )
}

/// The rotation matrix of `pose`, row-major.
pub fn rotation_rows(pose: &Pose) -> [[f32; 3]; 3] {
    let m = pose.rotation.matrix();
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Rotation by `angle` (radians, right-handed) about the z axis.
pub fn rotation_z(angle: f32) -> Pose {
    let (s, c) = angle.sin_cos();
    pose_from_rows([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], [0.0; 3])
}

/// Rotation by `angle` (radians, right-handed) about `axis` (normalised here; Rodrigues).
pub fn rotation_axis_angle(axis: [f32; 3], angle: f32) -> Pose {
    let [x, y, z] = normalize(axis);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    pose_from_rows(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ],
        [0.0; 3],
    )
}

/// A camera pose `world_from_camera` for a camera at `eye` looking at `target`, in the
/// optical convention (x right, y down, z forward). `up` is the world's up direction.
/// (nalgebra's `look_at_rh` is a view matrix in the OpenGL convention, not this.)
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
    pose_from_columns([right, down, forward], eye)
}

/// A pose whose rotation has the given columns (the source frame's axes in the target frame).
pub fn pose_from_columns(columns: [[f32; 3]; 3], t: [f32; 3]) -> Pose {
    let [x, y, z] = columns;
    pose_from_rows(
        [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]],
        t,
    )
}

/// `pose` applied to the point `p`: `rotation · p + translation`.
#[inline]
pub fn transform_point(pose: &Pose, p: [f32; 3]) -> [f32; 3] {
    pose.transform_point(&Point3::from(p)).into()
}

/// Only the rotation of `pose` applied to `v` (for directions and normals).
#[inline]
pub fn rotate_vector(pose: &Pose, v: [f32; 3]) -> [f32; 3] {
    pose.transform_vector(&Vector3::from(v)).into()
}

/// Serde for a [`Pose`] in the manifest's form `{"rotation": [[f32; 3]; 3] (row-major),
/// "translation": [f32; 3]}`; use with `#[serde(with = "crate::math::pose_serde")]`.
pub mod pose_serde {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::{Pose, pose_from_rows, rotation_rows};

    #[derive(Serialize, Deserialize)]
    struct PoseWire {
        rotation: [[f32; 3]; 3],
        translation: [f32; 3],
    }

    /// Writes `{"rotation": …, "translation": …}`.
    pub fn serialize<S: Serializer>(pose: &Pose, serializer: S) -> Result<S::Ok, S::Error> {
        PoseWire {
            rotation: rotation_rows(pose),
            translation: pose.translation.vector.into(),
        }
        .serialize(serializer)
    }

    /// Reads `{"rotation": …, "translation": …}`.
    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Pose, D::Error> {
        let w = PoseWire::deserialize(deserializer)?;
        Ok(pose_from_rows(w.rotation, w.translation))
    }
}

pub use lgdm_base::seed::{derive_seed, splitmix64};

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-5)
    }

    #[test]
    fn inverse_undoes_pose() {
        let p = rotation_axis_angle([1.0, 2.0, 0.5], 0.7) * translation([0.1, -0.2, 0.3]);
        let q = [0.3, 0.4, -0.5];
        assert!(close(
            transform_point(&p.inverse(), transform_point(&p, q)),
            q
        ));
    }

    #[test]
    fn look_at_points_z_to_target() {
        let world_from_camera = look_at([0.0, -1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let camera_from_world = world_from_camera.inverse();
        let t = transform_point(&camera_from_world, [0.0, 0.0, 0.0]);
        assert!(t[0].abs() < 1e-6 && t[1].abs() < 1e-6);
        assert!((t[2] - 2f32.sqrt()).abs() < 1e-5);
        // World up appears as negative y (image up) in the optical frame.
        let up = rotate_vector(&camera_from_world, [0.0, 0.0, 1.0]);
        assert!(up[1] < 0.0);
    }

    #[test]
    fn json_form_is_row_major_rotation_and_translation() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct Holder {
            #[serde(with = "pose_serde")]
            pose: Pose,
        }
        let pose = pose_from_rows(
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            [0.5, -0.25, 2.0],
        );
        let json = serde_json::to_string(&Holder { pose }).unwrap();
        assert_eq!(
            json,
            r#"{"pose":{"rotation":[[0.0,-1.0,0.0],[1.0,0.0,0.0],[0.0,0.0,1.0]],"translation":[0.5,-0.25,2.0]}}"#
        );
        let back: Holder = serde_json::from_str(&json).unwrap();
        assert_eq!(back.pose, pose);
    }

    /// The hand-written row-major pose that `Pose` replaced, kept as the reference for the
    /// bit-identity checks below.
    #[derive(Clone, Copy)]
    struct OldPose {
        rotation: [[f32; 3]; 3],
        translation: [f32; 3],
    }

    impl OldPose {
        fn of(p: &Pose) -> Self {
            Self {
                rotation: rotation_rows(p),
                translation: p.translation.vector.into(),
            }
        }
        fn rotate(&self, v: [f32; 3]) -> [f32; 3] {
            let r = &self.rotation;
            [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
        }
        fn apply(&self, p: [f32; 3]) -> [f32; 3] {
            add(self.rotate(p), self.translation)
        }
        fn compose(&self, other: &OldPose) -> OldPose {
            let (a, b) = (&self.rotation, &other.rotation);
            let mut rotation = [[0.0f32; 3]; 3];
            for (i, row) in rotation.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
                }
            }
            OldPose {
                rotation,
                translation: self.apply(other.translation),
            }
        }
        fn inverse(&self) -> OldPose {
            let r = &self.rotation;
            let rotation = [
                [r[0][0], r[1][0], r[2][0]],
                [r[0][1], r[1][1], r[2][1]],
                [r[0][2], r[1][2], r[2][2]],
            ];
            let inv = OldPose {
                rotation,
                translation: [0.0; 3],
            };
            let rt = inv.rotate(self.translation);
            OldPose {
                rotation,
                translation: [-rt[0], -rt[1], -rt[2]],
            }
        }
    }

    fn bits3(v: [f32; 3]) -> [u32; 3] {
        v.map(f32::to_bits)
    }

    fn bits33(m: [[f32; 3]; 3]) -> [[u32; 3]; 3] {
        m.map(bits3)
    }

    /// Poses like the ones the crate builds: cameras from `look_at`, turntable and tilt
    /// rotations, translations (some with exact zeros), and their products.
    fn sample_poses(rng: &mut ChaCha8Rng) -> Vec<Pose> {
        let mut v = || rng.random_range(-1.0f32..1.0);
        let mut poses = vec![
            Pose::identity(),
            look_at([0.0, -0.65, 0.475], [0.0, 0.0, 0.1], [0.0, 0.0, 1.0]),
            look_at([0.01, -0.02, 0.5], [0.02, 0.01, 0.0], [0.0, 1.0, 0.0]),
            look_at([0.0; 3], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]),
        ];
        for _ in 0..200 {
            let eye = [v(), v(), v() + 1.5];
            let target = [0.1 * v(), 0.1 * v(), 0.1 * v()];
            poses.push(look_at(eye, target, [0.0, 0.0, 1.0]));
            poses.push(rotation_z(4.0 * v()) * translation([0.1 * v(), 0.1 * v(), 0.0]));
            poses.push(rotation_axis_angle([v(), v(), 0.0], v()));
            poses.push(translation([v(), 0.0, v()]) * rotation_z(v()));
        }
        poses
    }

    #[test]
    fn nalgebra_products_give_the_floats_of_the_row_major_code() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let poses = sample_poses(&mut rng);
        for (i, a) in poses.iter().enumerate() {
            let old_a = OldPose::of(a);
            let b = &poses[(i * 7 + 3) % poses.len()];
            let old_b = OldPose::of(b);
            // Pose × pose.
            let ab = a * b;
            let old_ab = old_a.compose(&old_b);
            assert_eq!(
                bits33(rotation_rows(&ab)),
                bits33(old_ab.rotation),
                "pose {i}"
            );
            assert_eq!(
                bits3(ab.translation.vector.into()),
                bits3(old_ab.translation),
                "pose {i}"
            );
            // Pose × point and rotation × vector.
            for _ in 0..20 {
                let p = [
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(0.0f32..2.0),
                ];
                assert_eq!(bits3(transform_point(a, p)), bits3(old_a.apply(p)));
                assert_eq!(bits3(rotate_vector(a, p)), bits3(old_a.rotate(p)));
            }
            // Inverse: the rotation is the transpose, bit for bit; the translation equal as
            // floats (Rᵀ·(−t) versus −(Rᵀ·t) may differ in the sign of an exact zero only).
            let inv = a.inverse();
            let old_inv = old_a.inverse();
            assert_eq!(bits33(rotation_rows(&inv)), bits33(old_inv.rotation));
            let t: [f32; 3] = inv.translation.vector.into();
            for (new, old) in t.into_iter().zip(old_inv.translation) {
                assert!(new == old, "pose {i}");
                if new != 0.0 {
                    assert_eq!(new.to_bits(), old.to_bits(), "pose {i}");
                }
            }
        }
    }
}
