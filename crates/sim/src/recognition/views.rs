//! The robot's views of an object on the table ([`orbit_features`]).
//!
//! **Where the views come from.** A virtual camera on the dataset's viewing geometry
//! ([`CameraSpec`](lgdm_pointcloud::dataset::CameraSpec): 0.75 m from a point 0.1 m above the table
//! under the object, 30° up, the Kinect-like 320×240 intrinsics) orbits the object on the table in
//! steps of [`RecognitionConfig::view_step_rad`] (36°: the small dataset's turntable step).
//! Orbiting a resting object is the turntable sequence of the object turned the other way, so the
//! robot's views are the dataset's views of the same object (same distance, elevation, pixels per
//! metre, self-occlusion), and a model trained with `lgdm train` on a generated dataset recognises
//! the robot's objects. The grasp close-up, by contrast, looks straight down from 0.5 m: a view the
//! datasets never contain (a top view of a can is a disc), and only one. Neighbours on the table
//! occlude the object as they would a real camera; only the object's own pixels are used. The views
//! draw the object's mesh ([`RecognitionConfig::draw`], what the dataset draws), and a run's views
//! go through the cameras' depth sensor model (`[cameras.noise]`, [`DepthNoise`]) as its
//! overview and close-up frames do: the model learns from noisy views what the dataset drew clean.

use lgdm_pointcloud::dataset::view_cloud;
use lgdm_pointcloud::sensor::DepthNoise;
use rand_chacha::ChaCha8Rng;

use crate::perception::camera::{LABEL_FIRST_OBJECT, render_world};
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;
use crate::timing::{WallTimes, Work};

use crate::recognition::config::RecognitionConfig;
use crate::recognition::encoder::ViewEncoder;
use crate::recognition::error::RecognitionError;

/// The encoder's features of `count` views of `object` from azimuths `k × view_step_rad`,
/// k = 0, 1, … (see the module docs); views showing fewer than `min_points` of its points are
/// skipped. Each frame goes through `sensor` (a no-op when disabled); the views' clouds are
/// subsampled with `rng`.
#[allow(clippy::too_many_arguments)]
pub fn orbit_features(
    world: &World,
    object: ObjectHandle,
    count: usize,
    config: &RecognitionConfig,
    sensor: &DepthNoise,
    encoder: &mut dyn ViewEncoder,
    rng: &mut ChaCha8Rng,
    wall: &mut WallTimes,
) -> Result<Vec<Vec<f32>>, RecognitionError> {
    let pose = world.object_pose(object)?;
    let base = [
        pose.translation.x,
        pose.translation.y,
        world.config().table.top_z_m(),
    ];
    let mut clouds = Vec::with_capacity(count);
    for k in 0..count {
        let camera = config
            .camera
            .camera_around(base, k as f32 * config.view_step_rad);
        let mut shot = wall.time(Work::Render, || render_world(world, &camera, config.draw))?;
        sensor.sense(&mut shot.frame, &shot.camera.intrinsics, world.steps());
        let Some(index) = shot.objects.iter().position(|&h| h == object) else {
            continue;
        };
        let label = LABEL_FIRST_OBJECT + index as u8;
        let max_points = config.max_points_per_view;
        let cloud = wall.time(Work::Recognition, || {
            view_cloud(&shot.frame, &shot.camera, label, max_points, rng)
        });
        if cloud.len() >= config.min_points {
            clouds.push(cloud);
        }
    }
    if clouds.is_empty() {
        return Ok(Vec::new());
    }
    // The views' clouds are in the optical frame of a camera placed around the object as the
    // dataset's camera is around the turntable's centre: to the encoder they are views of
    // the dataset's camera.
    let camera = config.camera.camera();
    let features = wall.time(Work::Recognition, || encoder.encode(&clouds, &camera));
    let features = features.map_err(|source| RecognitionError::Encoder {
        name: encoder.name().to_string(),
        source,
    })?;
    Ok(features.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;
    use crate::recognition::labels::Labels;
    use crate::recognition::recognizer::{Recognizer, TAG_VIEWS};
    use lgdm_base::seed::derive_seed;
    use lgdm_pointcloud::cache::GOOD_BINS;
    use lgdm_pointcloud::good::good_descriptor;
    use lgdm_pointcloud::math::translation;
    use lgdm_pointcloud::objects::procedural_library;
    use rand::SeedableRng;
    /// The robot's views of an object standing alone on the table are the dataset's views of
    /// it: the same camera geometry around the object gives the same cloud, hence the same
    /// GOOD features, whatever the table point.
    #[test]
    fn a_view_on_the_table_is_the_dataset_view() {
        let library = procedural_library(&["mug"], 1, 0).unwrap();
        let mut world = World::new(WorldConfig::default()).unwrap();
        let top = world.config().table.top_z_m();
        let h = world
            .spawn_object("mug_01", &library[0].mesh, &translation([0.05, -0.5, top]))
            .unwrap();
        let config = RecognitionConfig::default();
        let mut recognizer =
            Recognizer::empty(config.clone(), Labels::of_objects(&library), 0).unwrap();
        let mut wall = WallTimes::default();
        let views = recognizer.views(&world, h, 1, &mut wall).unwrap();
        assert_eq!(views.len(), 1);
        // The dataset's camera at the origin, the mesh alone at the origin.
        let camera = config.camera.camera();
        let frame = lgdm_pointcloud::render::render(
            &camera,
            &[lgdm_pointcloud::render::RenderItem {
                mesh: &library[0].mesh,
                world_from_object: lgdm_pointcloud::math::Pose::identity(),
                label: 2,
            }],
        );
        let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(0, TAG_VIEWS, 0, 0));
        let cloud = view_cloud(&frame, &camera, 2, config.max_points_per_view, &mut rng);
        let dataset = good_descriptor(&cloud.points, GOOD_BINS).unwrap();
        let l1: f32 = views[0]
            .iter()
            .zip(&dataset)
            .map(|(a, b)| (a - b).abs())
            .sum();
        // Only the table's occlusion of nothing and float rounding of the shifted frame differ.
        assert!(l1 < 0.05, "L1 distance {l1}");
    }
}
