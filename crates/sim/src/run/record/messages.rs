//! The Foxglove messages of a recording: `/scene` entities for bodies, scenery, labels and the
//! grasp, transforms and poses, colours and metadata.

use foxglove::messages::{
    ArrowPrimitive, Color, CubePrimitive, CylinderPrimitive, FrameTransform, KeyValuePair,
    LinePrimitive, Point3, Pose as FgPose, Quaternion, SceneEntity, SpherePrimitive, TextPrimitive,
    TriangleListPrimitive, Vector3,
};
use lgdm_pointcloud::dataset::foxglove_timestamp;
use lgdm_pointcloud::mesh::Mesh;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3 as NVector3};
use rapier3d::prelude::{ColliderHandle, RigidBodyHandle};

use super::storyboard::outcome_text;
use crate::grasping::attempt::Execution;
use crate::perception::camera::{BASKET_RGB, TABLE_RGB};
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::rapier_to_isometry;
use crate::physics::world::World;
use crate::run::captions::{LabelTone, ObjectLabel};
use crate::run::observe::GraspShown;

/// The root frame of every transform.
pub const WORLD_FRAME: &str = "world";

pub(super) const ARM_RGBA: [f64; 4] = [0.55, 0.62, 0.72, 1.0];
pub(super) const PALM_RGBA: [f64; 4] = [0.22, 0.22, 0.25, 1.0];
pub(super) const FINGER_RGBA: [f64; 4] = [0.78, 0.78, 0.82, 1.0];

pub(super) fn color(c: [f64; 4]) -> Color {
    Color {
        r: c[0],
        g: c[1],
        b: c[2],
        a: c[3],
    }
}

pub(super) fn rgb8(c: [u8; 3]) -> Color {
    color([
        f64::from(c[0]) / 255.0,
        f64::from(c[1]) / 255.0,
        f64::from(c[2]) / 255.0,
        1.0,
    ])
}

pub(super) fn vector3(v: [f64; 3]) -> Vector3 {
    Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

/// An f64 isometry as a foxglove pose.
pub(super) fn isometry_pose(iso: &Isometry3<f64>) -> FgPose {
    let t = iso.translation.vector;
    let q = iso.rotation;
    FgPose {
        position: Some(vector3([t.x, t.y, t.z])),
        orientation: Some(Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

pub(super) fn frame_transform(child: &str, pose: &FgPose, t_ns: u64) -> FrameTransform {
    FrameTransform {
        timestamp: Some(foxglove_timestamp(t_ns)),
        parent_frame_id: WORLD_FRAME.into(),
        child_frame_id: child.into(),
        translation: pose.position,
        rotation: pose.orientation,
    }
}

pub(super) fn metadata(pairs: &[(&str, String)]) -> Vec<KeyValuePair> {
    pairs
        .iter()
        .map(|(k, v)| KeyValuePair {
            key: (*k).to_string(),
            value: v.clone(),
        })
        .collect()
}

pub(super) fn entity(frame_id: &str, id: &str, t_ns: u64) -> SceneEntity {
    SceneEntity {
        timestamp: Some(foxglove_timestamp(t_ns)),
        frame_id: frame_id.into(),
        id: id.into(),
        frame_locked: true,
        ..SceneEntity::default()
    }
}

/// A body's colliders as primitives in its frame: boxes as cubes, balls as spheres, capsules as
/// a cylinder and two spheres.
pub(super) fn body_entity(
    world: &World,
    body: RigidBodyHandle,
    frame: &str,
    rgba: [f64; 4],
    t_ns: u64,
) -> SceneEntity {
    let mut e = entity(frame, frame, t_ns);
    let Some(rb) = world.physics.bodies.get(body) else {
        return e;
    };
    for &c in rb.colliders() {
        let Some(collider) = world.physics.colliders.get(c) else {
            continue;
        };
        let local = collider
            .position_wrt_parent()
            .map(rapier_to_isometry)
            .unwrap_or_else(Isometry3::identity);
        let shape = collider.shape();
        if let Some(cuboid) = shape.as_cuboid() {
            let h = cuboid.half_extents;
            e.cubes.push(CubePrimitive {
                pose: Some(isometry_pose(&local)),
                size: Some(vector3([
                    2.0 * f64::from(h.x),
                    2.0 * f64::from(h.y),
                    2.0 * f64::from(h.z),
                ])),
                color: Some(color(rgba)),
            });
        } else if let Some(ball) = shape.as_ball() {
            let d = 2.0 * f64::from(ball.radius);
            e.spheres.push(SpherePrimitive {
                pose: Some(isometry_pose(&local)),
                size: Some(vector3([d; 3])),
                color: Some(color(rgba)),
            });
        } else if let Some(capsule) = shape.as_capsule() {
            let a = NVector3::new(
                f64::from(capsule.segment.a.x),
                f64::from(capsule.segment.a.y),
                f64::from(capsule.segment.a.z),
            );
            let b = NVector3::new(
                f64::from(capsule.segment.b.x),
                f64::from(capsule.segment.b.y),
                f64::from(capsule.segment.b.z),
            );
            let d = 2.0 * f64::from(capsule.radius);
            let axis = b - a;
            let rotation =
                UnitQuaternion::rotation_between(&NVector3::z(), &axis).unwrap_or_else(|| {
                    UnitQuaternion::from_axis_angle(&NVector3::x_axis(), std::f64::consts::PI)
                });
            let mid = Isometry3::from_parts(Translation3::from(0.5 * (a + b)), rotation);
            e.cylinders.push(CylinderPrimitive {
                pose: Some(isometry_pose(&(local * mid))),
                size: Some(vector3([d, d, axis.norm()])),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: Some(color(rgba)),
            });
            for end in [a, b] {
                e.spheres.push(SpherePrimitive {
                    pose: Some(isometry_pose(
                        &(local * Isometry3::from_parts(end.into(), UnitQuaternion::identity())),
                    )),
                    size: Some(vector3([d; 3])),
                    color: Some(color(rgba)),
                });
            }
        }
    }
    e
}

/// The fixed boxes of the scenery (table, baskets, pedestal; not the floor: Foxglove draws a
/// grid) in the world frame.
pub(super) fn scenery_entity(world: &World, scenery: &[ColliderHandle], t_ns: u64) -> SceneEntity {
    let mut e = entity(WORLD_FRAME, "scenery", t_ns);
    let table = world.config().table.center_m;
    for &h in scenery {
        let Some(collider) = world.physics.colliders.get(h) else {
            continue;
        };
        let Some(cuboid) = collider.shape().as_cuboid() else {
            continue;
        };
        let half = cuboid.half_extents;
        if half.x > 2.0 || half.y > 2.0 {
            continue; // the floor
        }
        let pose = rapier_to_isometry(collider.position());
        let at = pose.translation.vector;
        let is_table = (0..3).all(|k| (at[k] - f64::from(table[k])).abs() < 1e-4);
        e.cubes.push(CubePrimitive {
            pose: Some(isometry_pose(&pose)),
            size: Some(vector3([
                2.0 * f64::from(half.x),
                2.0 * f64::from(half.y),
                2.0 * f64::from(half.z),
            ])),
            color: Some(rgb8(if is_table { TABLE_RGB } else { BASKET_RGB })),
        });
    }
    e
}

/// A label's colour by how the recognition went: green right, amber unknown, red wrong.
pub(super) fn tone_rgba(tone: LabelTone) -> [f64; 4] {
    match tone {
        LabelTone::Right => [0.2, 0.8, 0.3, 1.0],
        LabelTone::Unknown => [1.0, 0.7, 0.1, 1.0],
        LabelTone::Wrong => [0.9, 0.2, 0.2, 1.0],
    }
}

/// The `/labels` entity id of the object in `frame`.
pub(super) fn label_id(frame: &str) -> String {
    format!("label/{frame}")
}

/// A billboard text `height_m` above the origin of the object `frame`.
pub(super) fn label_entity(
    frame: &str,
    height_m: f64,
    label: &ObjectLabel,
    t_ns: u64,
) -> SceneEntity {
    let mut e = entity(frame, &label_id(frame), t_ns);
    e.metadata = metadata(&label.metadata);
    e.texts.push(TextPrimitive {
        pose: Some(isometry_pose(&Isometry3::translation(0.0, 0.0, height_m))),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(color(tone_rgba(label.tone))),
        text: label.text.clone(),
    });
    e
}

/// An object's mesh as a triangle list (per-vertex colours from the per-triangle colours) in
/// its frame.
pub(super) fn object_entity(
    frame: &str,
    name: &str,
    handle: ObjectHandle,
    mesh: &Mesh,
    t_ns: u64,
) -> SceneEntity {
    let mut e = entity(frame, frame, t_ns);
    e.metadata = metadata(&[("name", name.to_string()), ("handle", handle.0.to_string())]);
    let mut tri = TriangleListPrimitive {
        pose: Some(isometry_pose(&Isometry3::identity())),
        ..TriangleListPrimitive::default()
    };
    tri.points.reserve(3 * mesh.triangles.len());
    tri.colors.reserve(3 * mesh.triangles.len());
    for (t, c) in mesh.triangles.iter().zip(&mesh.colors) {
        for &i in t {
            let Some(v) = mesh.vertices.get(i as usize) else {
                continue;
            };
            tri.points.push(Point3 {
                x: f64::from(v[0]),
                y: f64::from(v[1]),
                z: f64::from(v[2]),
            });
            tri.colors.push(rgb8(*c));
        }
    }
    e.triangles.push(tri);
    e
}

/// The planned grasp in the world: the two pads at the tool centre, the opening line between
/// them, the approach arrow from the pre-grasp, a label; coloured by `outcome` when known.
pub(super) fn grasp_entity(
    shown: &GraspShown<'_>,
    outcome: Option<&Execution>,
    t_ns: u64,
) -> SceneEntity {
    let plan = shown.plan;
    let g = shown.gripper;
    let mut e = entity(WORLD_FRAME, "grasp", t_ns);
    e.frame_locked = false;
    let rgba = match outcome {
        None => [1.0, 0.85, 0.1, 0.9],
        Some(x) if x.placement_success => [0.15, 0.85, 0.25, 0.9],
        Some(x) if x.grasp_success => [1.0, 0.55, 0.1, 0.9],
        Some(_) => [0.9, 0.15, 0.15, 0.9],
    };
    let yaw = plan.grasp.yaw_rad;
    let rotation = UnitQuaternion::from_axis_angle(&NVector3::z_axis(), yaw);
    let tcp = NVector3::from(plan.tcp_m);
    let half_open = 0.5 * plan.grasp.opening_m;
    let thick = f64::from(g.finger_thickness_m);
    let axis = rotation * NVector3::x();
    let mut pads = Vec::new();
    for side in [-1.0, 1.0] {
        let centre = tcp + axis * side * (half_open + 0.5 * thick);
        pads.push(centre);
        e.cubes.push(CubePrimitive {
            pose: Some(isometry_pose(&Isometry3::from_parts(
                centre.into(),
                rotation,
            ))),
            size: Some(vector3([
                thick,
                f64::from(g.finger_width_m),
                f64::from(g.finger_length_m),
            ])),
            color: Some(color(rgba)),
        });
    }
    let point = |v: NVector3<f64>| Point3 {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    e.lines.push(LinePrimitive {
        r#type: 0,
        pose: Some(isometry_pose(&Isometry3::identity())),
        thickness: 0.003,
        scale_invariant: false,
        points: vec![point(pads[0]), point(pads[1])],
        color: Some(color(rgba)),
        colors: Vec::new(),
        indices: Vec::new(),
    });
    let drop = (plan.pregrasp_z_m - plan.tcp_m[2]).max(0.0);
    let head = drop.min(0.03);
    // The arrow points along its pose's +x: turned to −z, it starts at the pre-grasp.
    let down = UnitQuaternion::from_axis_angle(&NVector3::y_axis(), std::f64::consts::FRAC_PI_2);
    e.arrows.push(ArrowPrimitive {
        pose: Some(isometry_pose(&Isometry3::from_parts(
            Translation3::new(tcp.x, tcp.y, plan.pregrasp_z_m),
            down,
        ))),
        shaft_length: (drop - head).max(0.0),
        shaft_diameter: 0.004,
        head_length: head,
        head_diameter: 0.012,
        color: Some(color(rgba)),
    });
    let mut label = format!(
        "rank {} q {:.2} {:.0} mm",
        shown.rank,
        plan.grasp.quality,
        1000.0 * plan.grasp.opening_m
    );
    if let Some(x) = outcome {
        label.push_str(": ");
        label.push_str(&outcome_text(x));
    }
    e.texts.push(TextPrimitive {
        pose: Some(isometry_pose(&Isometry3::translation(
            tcp.x,
            tcp.y,
            plan.pregrasp_z_m + 0.03,
        ))),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(color([1.0, 1.0, 1.0, 1.0])),
        text: label,
    });
    let mut meta = vec![
        ("object", shown.object.unwrap_or("").to_string()),
        ("rank", shown.rank.to_string()),
        ("quality", format!("{}", plan.grasp.quality)),
        ("opening_m", format!("{}", plan.grasp.opening_m)),
        ("commanded_opening_m", format!("{}", plan.opening_m)),
        ("yaw_rad", format!("{}", plan.grasp.yaw_rad)),
        (
            "tcp_m",
            format!("{} {} {}", plan.tcp_m[0], plan.tcp_m[1], plan.tcp_m[2]),
        ),
    ];
    meta.push((
        "outcome",
        outcome.map_or_else(|| "planned".to_string(), outcome_text),
    ));
    e.metadata = metadata(&meta);
    e
}
