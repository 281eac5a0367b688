//! One full grasp attempt of the robot, timed: a decomposed procedural mug settled on the table,
//! the arm at its ready pose; the attempt approaches, descends, closes, lifts, holds, carries
//! to the basket, releases and parks (`execute` + `park`: physics, IK and trajectories).
//! `perceive_and_plan` times what comes before: the overview frame, segmentation, the close-up
//! frame and crop, the analytic source and the grasp plan.
//!
//! The scene is built fresh for every iteration outside the timing (`iter_batched`). The
//! headless 750-attempt figure comes from `lgdm sim grasp` itself (its summary prints wall time
//! per attempt and where it goes); see the README.
//!
//! Run: `cargo bench -p lgdm-sim --bench attempt` (one core).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::objects::{ObjectModel, procedural_object};
use lgdm_sim::attempt::{AttemptConfig, Cell, execute, park, plan_grasp};
use lgdm_sim::config::SimConfig;
use lgdm_sim::perception::{ObjectView, Perception};
use lgdm_sim::robot::RobotConfig;
use lgdm_sim::shapes::{LibraryShapes, ShapeConfig};
use lgdm_sim::source::{AnalyticSource, GraspQuery, GraspSource};
use lgdm_sim::timing::WallTimes;
use lgdm_sim::world::{World, WorldConfig};

struct Scene {
    cell: Cell,
    view: ObjectView,
}

fn scene(shapes: &mut LibraryShapes, mug: &ObjectModel, perception: &Perception) -> Scene {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let top = world.config().table.top_z_m();
    shapes
        .spawn(&mut world, 0, "mug", mug, &translation([0.08, -0.55, top]))
        .unwrap();
    world.settle();
    let cell = Cell::at_ready(world, RobotConfig::default(), &AttemptConfig::default()).unwrap();
    let scene = perception.look(&cell.world).unwrap();
    let view = perception.close_up(&cell.world, &scene, 0).unwrap();
    Scene { cell, view }
}

fn bench(c: &mut Criterion) {
    let mug = ObjectModel {
        name: "mug".into(),
        category: "mug".into(),
        mesh: procedural_object("mug", 0, 2).unwrap(),
        physics: Default::default(),
    };
    let mut shapes = LibraryShapes::new(ShapeConfig::default(), 1);
    let perception = Perception::new(Default::default()).unwrap();
    let config = AttemptConfig::default();
    let gripper = SimConfig::default().grasp_spec();
    let mut group = c.benchmark_group("sim");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("perceive_and_plan", |b| {
        b.iter_batched(
            || scene(&mut shapes, &mug, &perception),
            |s| {
                let scene = perception.look(&s.cell.world).unwrap();
                let view = perception.close_up(&s.cell.world, &scene, 0).unwrap();
                let query = GraspQuery {
                    crop: &view.crop,
                    intrinsics: &view.shot.camera.intrinsics,
                    gripper: &gripper,
                };
                let grasps = AnalyticSource::new().grasps(&query, 3).unwrap();
                let grasp = view.grasp_in_world(&grasps[0], &config.decode).unwrap();
                black_box(plan_grasp(&s.cell, &view, &grasp, &config))
            },
            BatchSize::PerIteration,
        );
    });
    group.bench_function("full_attempt", |b| {
        b.iter_batched(
            || {
                let s = scene(&mut shapes, &mug, &perception);
                let query = GraspQuery {
                    crop: &s.view.crop,
                    intrinsics: &s.view.shot.camera.intrinsics,
                    gripper: &gripper,
                };
                let grasps = AnalyticSource::new().grasps(&query, 1).unwrap();
                let grasp = s.view.grasp_in_world(&grasps[0], &config.decode).unwrap();
                let plan = plan_grasp(&s.cell, &s.view, &grasp, &config);
                (s, plan)
            },
            |(mut s, plan)| {
                let mut wall = WallTimes::default();
                let exec = execute(&mut s.cell, &plan, s.view.object, &config, &mut wall).unwrap();
                park(&mut s.cell, plan.pregrasp_z_m, &config, &mut wall).unwrap();
                assert!(exec.placement_success, "{exec:?}");
                black_box(exec)
            },
            BatchSize::PerIteration,
        );
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
