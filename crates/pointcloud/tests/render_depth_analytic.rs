//! Rendering a primitive at a known pose gives the analytically expected depth at chosen
//! pixels, and depth → cloud → depth is a round trip.

use lgdm_pointcloud::math::{Pose, look_at, rotation_axis_angle, rotation_z, translation};
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, depth_from_cloud, render};

/// Camera at the world origin whose optical frame equals the world frame (z forward, y down).
fn camera() -> Camera {
    Camera::new(
        Intrinsics::kinect_vga(),
        look_at([0.0; 3], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]),
    )
}

fn pixel_of(k: &Intrinsics, x_over_z: f32, y_over_z: f32) -> (usize, usize) {
    (
        (k.fx * x_over_z + k.cx).round() as usize,
        (k.fy * y_over_z + k.cy).round() as usize,
    )
}

#[test]
fn box_front_face_depth_is_exact() {
    // A 0.2 m cube centred 0.9 m in front of the camera, rotated 30° about the optical axis:
    // its front face is the plane z = 0.8 whatever the in-plane rotation.
    let cube = Mesh::cuboid([0.0; 3], [0.2, 0.2, 0.2], [200, 50, 50]);
    let pose = translation([0.0, 0.0, 0.9]) * rotation_z(0.5);
    let cam = camera();
    let f = render(
        &cam,
        &[RenderItem {
            mesh: &cube,
            world_from_object: pose,
            label: 3,
        }],
    );
    let k = cam.intrinsics;
    for (x, y) in [(0.0, 0.0), (0.05, -0.03), (-0.06, 0.04)] {
        let (u, v) = pixel_of(&k, x / 0.8, y / 0.8);
        let i = v * k.width as usize + u;
        assert_eq!(f.label[i], 3);
        assert!(
            (f.depth_m[i] - 0.8).abs() < 1e-5,
            "depth at ({u},{v}) = {}",
            f.depth_m[i]
        );
    }
}

#[test]
fn tilted_plane_depth_matches_ray_intersection() {
    // Plane through (0, 0, 1) with normal n = normalize(0, 0.5, -1) (tilted about x).
    let n = {
        let l = (0.25f32 + 1.0).sqrt();
        [0.0, 0.5 / l, -1.0 / l]
    };
    // Build a big quad in that plane.
    let (a, b) = (
        [1.0, 0.0, 0.0],
        [
            0.0,
            1.0 / (1.0f32 + 0.25).sqrt(),
            0.5 / (1.0f32 + 0.25).sqrt(),
        ],
    );
    let p0 = [0.0, 0.0, 1.0];
    let corner = |s: f32, t: f32| {
        [
            p0[0] + s * a[0] + t * b[0],
            p0[1] + s * a[1] + t * b[1],
            p0[2] + s * a[2] + t * b[2],
        ]
    };
    let mut quad = Mesh::new();
    quad.push_triangle(
        corner(-0.5, -0.5),
        corner(0.5, -0.5),
        corner(0.5, 0.5),
        [9, 9, 9],
    );
    quad.push_triangle(
        corner(-0.5, -0.5),
        corner(0.5, 0.5),
        corner(-0.5, 0.5),
        [9, 9, 9],
    );
    let cam = camera();
    let f = render(
        &cam,
        &[RenderItem {
            mesh: &quad,
            world_from_object: Pose::identity(),
            label: 1,
        }],
    );
    let k = cam.intrinsics;
    for (u, v) in [(320usize, 240usize), (100, 300), (500, 150), (330, 400)] {
        // Ray d = ((u-cx)/fx, (v-cy)/fy, 1); depth z = (n·p0)/(n·d).
        let d = [(u as f32 - k.cx) / k.fx, (v as f32 - k.cy) / k.fy, 1.0];
        let z = (n[0] * p0[0] + n[1] * p0[1] + n[2] * p0[2])
            / (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);
        let i = v * k.width as usize + u;
        assert_eq!(f.label[i], 1, "pixel ({u},{v}) not covered");
        assert!(
            (f.depth_m[i] - z).abs() < 1e-4 * z,
            "pixel ({u},{v}): {} vs {z}",
            f.depth_m[i]
        );
    }
}

#[test]
fn sphere_depth_within_tessellation_error() {
    // A finely tessellated sphere of radius 0.1 m at distance 1 m: the depth along the optical
    // axis is 0.9 m (up to the chord error of the tessellation, < 1 mm here).
    let n = 64;
    let profile: Vec<[f32; 2]> = (0..=n)
        .map(|i| {
            let a = -std::f32::consts::FRAC_PI_2 + std::f32::consts::PI * i as f32 / n as f32;
            [0.1 * a.cos(), 0.1 * a.sin()]
        })
        .collect();
    let sphere = Mesh::lathe(&profile, 128, [255, 255, 255]);
    // Lathe axis is z; put the centre at (0, 0, 1) — the camera looks at a pole.
    let cam = camera();
    let f = render(
        &cam,
        &[RenderItem {
            mesh: &sphere,
            world_from_object: translation([0.0, 0.0, 1.0]),
            label: 1,
        }],
    );
    let k = cam.intrinsics;
    let (u, v) = pixel_of(&k, 0.0, 0.0);
    assert!((f.depth_m[v * k.width as usize + u] - 0.9).abs() < 1e-3);
    // Off-axis pixel: ray-sphere intersection.
    let (u, v) = pixel_of(&k, 0.05, 0.03);
    let d = [(u as f32 - k.cx) / k.fx, (v as f32 - k.cy) / k.fy, 1.0f32];
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    // |t d - c|² = r², c = (0,0,1): t² dd - 2 t d_z + 1 - r² = 0.
    let t = (d[2] - (d[2] * d[2] - dd * (1.0 - 0.01)).sqrt()) / dd;
    let z = t * d[2];
    assert!(
        (f.depth_m[v * k.width as usize + u] - z).abs() < 1.5e-3,
        "{} vs {z}",
        f.depth_m[v * k.width as usize + u]
    );
}

#[test]
fn depth_cloud_depth_round_trip() {
    let cube = Mesh::cuboid([0.0, 0.0, 0.0], [0.15, 0.1, 0.12], [10, 200, 10]);
    let pose = translation([0.02, -0.01, 0.7]) * rotation_axis_angle([1.0, 1.0, 0.2], 0.6);
    let cam = camera();
    let f = render(
        &cam,
        &[RenderItem {
            mesh: &cube,
            world_from_object: pose,
            label: 5,
        }],
    );
    let cloud = f.backproject(&cam, 5);
    assert!(cloud.len() > 1000);
    let depth = depth_from_cloud(&cloud, &cam.intrinsics);
    for (i, &got) in depth.iter().enumerate() {
        let expected = if f.label[i] == 5 { f.depth_m[i] } else { 0.0 };
        assert!(
            (got - expected).abs() <= 1e-6 * expected.max(1.0),
            "pixel {i}: {got} vs {expected}"
        );
    }
}
