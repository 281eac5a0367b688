//! What the depth sensor model costs (issue 43): the overview and the close-up of a table with
//! five procedural objects rendered clean (`render_*`), and the sensor model applied to a clean
//! frame (`sense_*`: axial noise, quantisation, stereo shadow, lost pixels;
//! `DepthNoise::sense`, as every robot camera does). The frame is rendered once outside the
//! timing and cloned per iteration (`iter_batched`).
//!
//! Run: `cargo bench -p lgdm-sim --bench camera` (rendering and the model use rayon's threads;
//! `RAYON_NUM_THREADS=1` for one core).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::objects::{ObjectModel, procedural_object};
use lgdm_pointcloud::sensor::DepthNoise;
use lgdm_sim::perception::camera::{CameraConfig, SceneFrame};
use lgdm_sim::physics::config::WorldConfig;
use lgdm_sim::physics::shapes::{LibraryShapes, ShapeConfig};
use lgdm_sim::physics::world::World;

fn table() -> World {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let top = world.config().table.top_z_m();
    let mut shapes = LibraryShapes::new(ShapeConfig::default(), 5);
    let places = [
        ("mug", [0.0, -0.5]),
        ("can", [0.12, -0.45]),
        ("bowl", [-0.12, -0.55]),
        ("cereal_box", [0.1, -0.62]),
        ("vase", [-0.08, -0.4]),
    ];
    for (k, (category, [x, y])) in places.into_iter().enumerate() {
        let object = ObjectModel {
            name: category.into(),
            category: category.into(),
            mesh: procedural_object(category, 0, 0).unwrap(),
            physics: Default::default(),
            parts: Vec::new(),
        };
        shapes
            .spawn(&mut world, k, category, &object, &translation([x, y, top]))
            .unwrap();
    }
    world.settle();
    world
}

fn camera(c: &mut Criterion) {
    let world = table();
    let clean = CameraConfig {
        noise: DepthNoise::off(),
        ..CameraConfig::default()
    };
    let model = CameraConfig::default().noise;
    let top = world.config().table.top_z_m();
    let mut group = c.benchmark_group("camera");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(10));
    let frames: [(&str, SceneFrame); 2] = [
        ("overview", clean.render_overview(&world).unwrap()),
        (
            "closeup",
            clean.render_closeup(&world, [0.0, -0.5, top]).unwrap(),
        ),
    ];
    group.bench_function("render_overview", |b| {
        b.iter(|| black_box(clean.render_overview(&world).unwrap()))
    });
    group.bench_function("render_closeup", |b| {
        b.iter(|| black_box(clean.render_closeup(&world, [0.0, -0.5, top]).unwrap()))
    });
    for (name, shot) in &frames {
        group.bench_function(format!("sense_{name}"), |b| {
            b.iter_batched(
                || shot.frame.clone(),
                |mut frame| {
                    model.sense(&mut frame, &shot.camera.intrinsics, 7);
                    black_box(frame)
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, camera);
criterion_main!(benches);
