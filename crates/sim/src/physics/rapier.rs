//! The boundary to rapier: its glam-based math types ([`RVec`], [`RQuat`], [`RPose`]), the
//! conversions of lgdm poses (f32, rotation matrix) and the arm's f64 isometries to and from
//! them, and the collision groups of the scenery, the objects, the gripper and the arm.

use lgdm_pointcloud::math::Pose;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use rapier3d::prelude::{Group, InteractionGroups, InteractionTestMode};

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

#[cfg(test)]
mod tests {
    use super::*;
    use lgdm_pointcloud::math::{rotation_z, translation};

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
}
