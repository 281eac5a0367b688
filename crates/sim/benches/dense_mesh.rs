//! A scan-sized mesh through the physics, timed: a turned vase of 2,002,944 triangles
//! (1,001,474 vertices, 0.05 mm of noise, 20 cm tall) — its single hull
//! (`World::spawn_object`: the extreme points of a million vertices), its decomposition
//! (`decompose`: vertex clustering, VHACD, parts reduced) and everything a run does before its
//! first round (`LibraryShapes::check`: the decomposition, the compound collider and its
//! drawing). Measured on the shared 2-core machine: about 0.22 s, 1.6 s and 1.6 s. The whole
//! `lgdm sim grasp --meshes` run of one round on such an STL (loading included) is in the
//! report of issue 22.
//!
//! Run: `cargo bench -p lgdm-sim --bench dense_mesh`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use lgdm_base::seed::splitmix64;
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::objects::ObjectModel;
use lgdm_sim::physics::config::WorldConfig;
use lgdm_sim::physics::shapes::{LibraryShapes, ShapeConfig, decompose};
use lgdm_sim::physics::world::World;

/// A closed turned vase: `rings` rings of `segments` vertices (noise up to ±`noise_m` on each
/// coordinate), a centre vertex at the bottom and the top; 2·segments·rings triangles.
fn turned_vase(segments: usize, rings: usize, noise_m: f32) -> Mesh {
    let mut state = 7u64;
    let mut noise = || {
        state = splitmix64(state);
        ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 * noise_m
    };
    let mut vertices = Vec::with_capacity(segments * rings + 2);
    for j in 0..rings {
        let t = j as f32 / (rings - 1) as f32;
        let r = 0.045 + 0.025 * (t * std::f32::consts::PI * 1.5).sin().powi(2) - 0.01 * t;
        for i in 0..segments {
            let a = i as f32 * std::f32::consts::TAU / segments as f32;
            vertices.push([
                r * a.cos() + noise(),
                r * a.sin() + noise(),
                0.2 * t + noise(),
            ]);
        }
    }
    let (bottom, top) = (vertices.len() as u32, vertices.len() as u32 + 1);
    vertices.extend([[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]]);
    let id = |j: usize, i: usize| (j * segments + i % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * segments * rings);
    for j in 0..rings - 1 {
        for i in 0..segments {
            triangles.push([id(j, i), id(j, i + 1), id(j + 1, i + 1)]);
            triangles.push([id(j, i), id(j + 1, i + 1), id(j + 1, i)]);
        }
    }
    for i in 0..segments {
        triangles.push([bottom, id(0, i + 1), id(0, i)]);
        triangles.push([top, id(rings - 1, i), id(rings - 1, i + 1)]);
    }
    let colors = vec![[120, 140, 200]; triangles.len()];
    Mesh {
        vertices,
        triangles,
        colors,
    }
}

fn bench(c: &mut Criterion) {
    let vase = ObjectModel {
        name: "scan_vase".into(),
        category: "vase".into(),
        mesh: turned_vase(2048, 489, 5e-5),
        physics: Default::default(),
        parts: Vec::new(),
    };
    assert_eq!(vase.mesh.triangles.len(), 2_002_944);
    let mut group = c.benchmark_group("dense_mesh_2m_triangles");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("hull", |b| {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let at = translation([0.0, -0.5, 1.0]);
        b.iter(|| {
            let h = world.spawn_object("scan_vase", &vase.mesh, &at).unwrap();
            world.remove_object(black_box(h)).unwrap();
        });
    });
    group.bench_function("decompose", |b| {
        b.iter(|| black_box(decompose(&vase.mesh, &ShapeConfig::default())));
    });
    group.bench_function("check", |b| {
        let library = std::slice::from_ref(&vase);
        b.iter(|| {
            LibraryShapes::new(ShapeConfig::default(), 1)
                .check(&WorldConfig::default(), library, &[0])
                .unwrap();
        });
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
