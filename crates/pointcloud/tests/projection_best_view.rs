//! Clouds project to 224×224 depth / RGB-D images that keep the points' depths, and best-view
//! selection prefers the view that shows more of the object.

use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::augment::occlude;
use lgdm_pointcloud::math::{look_at, rotation_z};
use lgdm_pointcloud::objects::procedural_object;
use lgdm_pointcloud::projection::{ProjectionParams, best_view, project_to_image, view_entropy};
use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};

fn view_of(category: &str, yaw: f32) -> PointCloud {
    let mesh = procedural_object(category, 0, 1).unwrap();
    let camera = Camera::new(
        Intrinsics::kinect_qvga(),
        look_at([0.0, -0.65, 0.45], [0.0, 0.0, 0.08], [0.0, 0.0, 1.0]),
    );
    let f = render(
        &camera,
        &[RenderItem {
            mesh: &mesh,
            world_from_object: rotation_z(yaw),
            label: 2,
        }],
    );
    f.backproject(&camera, 2)
}

#[test]
fn projection_keeps_depths_and_colours() {
    let cloud = view_of("mug", 0.3);
    let img = project_to_image(&cloud, &ProjectionParams::default()).unwrap();
    assert_eq!(img.size, 224);
    assert_eq!(img.depth_m.len(), 224 * 224);
    let filled: Vec<f32> = img.depth_m.iter().copied().filter(|&d| d > 0.0).collect();
    assert!(
        filled.len() > 224 * 224 / 10,
        "object covers {} pixels",
        filled.len()
    );
    let zmin = cloud.points.iter().map(|p| p[2]).fold(f32::MAX, f32::min);
    let zmax = cloud.points.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
    assert!(filled.iter().all(|&d| d >= zmin && d <= zmax));
    assert_eq!(filled.iter().copied().fold(f32::MAX, f32::min), zmin);
    let rgb = img.rgb.as_ref().unwrap();
    assert!(
        rgb.iter()
            .zip(&img.depth_m)
            .all(|(c, &d)| d > 0.0 || *c == [0, 0, 0])
    );
    let n = img.normalized_depth();
    assert!(n.iter().all(|&v| (0.0..=1.0).contains(&v)));
    // Margin: the border rows are empty.
    assert!(img.depth_m[..224].iter().all(|&d| d == 0.0));
    assert!(project_to_image(&PointCloud::default(), &ProjectionParams::default()).is_err());
}

#[test]
fn best_view_prefers_the_fuller_view() {
    let full = view_of("cereal_box", 0.6);
    let half = occlude(&full, 0.6, 0.0);
    let sliver = occlude(&full, 0.9, 1.0);
    assert!(view_entropy(&full) > view_entropy(&half));
    assert!(view_entropy(&half) > view_entropy(&sliver));
    assert_eq!(best_view(&[half.clone(), full.clone(), sliver]), Some(1));
    assert_eq!(best_view(&[]), None);
    // A box seen corner-on shows two faces: more entropy than face-on.
    let face_on = view_of("cereal_box", 0.0);
    let corner = view_of("cereal_box", std::f32::consts::FRAC_PI_4);
    assert!(view_entropy(&corner) > view_entropy(&face_on) * 0.9);
}
